//! A scenario's parameters: `--param key=value` as given ([`Params`]), read once into the
//! scenario's own typed parameters (a struct per group of keys, declared with
//! [`scenario_params!`]), and sweeps (`--sweep key=a:b:n`). Below the builders and the
//! registry that names them. A scenario declares the keys it takes; a key given that it does
//! not take is refused by name before anything is built ([`Scenario::check`]).

use super::SimError;

/// `--param key=value` as given (a repeated key keeps its last value): the wire form every
/// caller builds, read into a scenario's typed parameters by [`Param`].
#[derive(Debug, Clone, Default)]
pub struct Params(pub Vec<(String, f64)>);

impl Params {
    /// The value given for `key` (the last if repeated).
    fn given(&self, key: &str) -> Option<f64> {
        self.0.iter().rev().find(|(k, _)| k == key).map(|(_, v)| *v)
    }

    /// `key` read as its type, or `default` when not given; a value the type refuses is an
    /// error naming the key.
    pub fn take<T: Param>(&self, key: &str, default: T) -> Result<T, SimError> {
        match self.given(key) {
            None => Ok(default),
            Some(v) => {
                T::read(v).map_err(|why| SimError::Model(format!("--param {key}={v}: {why}")))
            }
        }
    }

    /// The parameters as a JSON object (sorted keys; a repeated key keeps its last value),
    /// for the `sim_params` column.
    pub fn to_json(&self) -> String {
        let map: std::collections::BTreeMap<&str, f64> =
            self.0.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        serde_json::to_string(&map).unwrap_or_else(|_| "{}".into())
    }

    /// Parse `key=value`; `solver=<name>` (`verlet`, `rk4`, …) is the solver's number.
    pub fn parse_one(s: &str) -> Result<(String, f64), SimError> {
        let (k, v) = s
            .split_once('=')
            .ok_or_else(|| SimError::Model(format!("--param {s}: expected key=value")))?;
        if k.trim() == "solver" && v.trim().parse::<f64>().is_err() {
            let solver: super::model::Solver = v.trim().parse()?;
            return Ok(("solver".into(), solver.number() as f64));
        }
        let v: f64 = v
            .trim()
            .parse()
            .map_err(|_| SimError::Model(format!("--param {s}: {v} is not a number")))?;
        Ok((k.trim().to_string(), v))
    }
}

/// A parameter's type: how a `--param` number becomes it (every value on the command line
/// is a number; `solver=verlet` is turned into its number by [`Params::parse_one`]).
pub trait Param: Sized {
    fn read(v: f64) -> Result<Self, String>;
}

impl Param for f64 {
    fn read(v: f64) -> Result<f64, String> {
        Ok(v)
    }
}

/// A count or an index: a whole number ≥ 0 (ranges are the builder's to check).
impl Param for u32 {
    fn read(v: f64) -> Result<u32, String> {
        if v.fract() == 0.0 && (0.0..=u32::MAX as f64).contains(&v) {
            Ok(v as u32)
        } else {
            Err("must be a whole number ≥ 0".into())
        }
    }
}

/// A switch: 0 off, 1 on.
impl Param for bool {
    fn read(v: f64) -> Result<bool, String> {
        match v {
            0.0 => Ok(false),
            1.0 => Ok(true),
            _ => Err("must be 0 (off) or 1 (on)".into()),
        }
    }
}

impl Param for super::model::Solver {
    fn read(v: f64) -> Result<Self, String> {
        super::model::Solver::numbered(v).map_err(|e| e.to_string())
    }
}

/// A value with no fixed default (the scenario's own, or "leave as built").
impl<T: Param> Param for Option<T> {
    fn read(v: f64) -> Result<Option<T>, String> {
        T::read(v).map(Some)
    }
}

/// A group of parameters as a typed struct: each field a key (its name), its type and its
/// default; `KEYS` lists them and `read` takes them from [`Params`] once.
macro_rules! scenario_params {
    ($(#[$m:meta])* pub struct $name:ident {
        $($(#[$fm:meta])* $field:ident : $ty:ty = $default:expr,)*
    }) => {
        $(#[$m])*
        #[derive(Debug, Clone, PartialEq)]
        pub struct $name {
            $($(#[$fm])* pub $field: $ty,)*
        }

        impl $name {
            /// The keys, as `--param` names them.
            pub const KEYS: &'static [&'static str] = &[$(stringify!($field)),*];

            /// The keys read from the given parameters, each its default where not given.
            #[allow(unused_variables)]
            pub fn read(
                p: &$crate::sim::params::Params,
            ) -> Result<Self, $crate::sim::SimError> {
                Ok($name {
                    $($field: p.take(stringify!($field), $default)?,)*
                })
            }
        }
    };
}
pub(crate) use scenario_params;

/// A mass/spring scenario in a registry: its name, the groups of keys its builder reads
/// (besides [`Common`]'s, which every one takes), and the builder.
pub struct Scenario {
    pub name: &'static str,
    pub keys: &'static [&'static [&'static str]],
    pub build: Builder,
}

impl Scenario {
    pub const fn new(
        name: &'static str,
        keys: &'static [&'static [&'static str]],
        build: Builder,
    ) -> Scenario {
        Scenario { name, keys, build }
    }

    /// Every group of keys it takes: its own, then [`Common`]'s.
    pub fn groups(&self) -> impl Iterator<Item = &'static [&'static str]> {
        self.keys.iter().copied().chain([Common::KEYS])
    }

    /// Refuse, by name, a key given that it does not take (a typo never runs the default),
    /// before anything is built.
    pub fn check(&self, p: &Params) -> Result<(), SimError> {
        takes_only(self.name, p, &self.groups().collect::<Vec<_>>())
    }
}

/// Refuse, by name, a key given that none of `groups` holds, saying what `name` reads.
pub fn takes_only(name: &str, p: &Params, groups: &[&[&str]]) -> Result<(), SimError> {
    let takes = |k: &str| groups.iter().any(|g| g.contains(&k));
    let mut unknown: Vec<&str> = Vec::new();
    for k in p.0.iter().map(|(k, _)| k.as_str()).filter(|k| !takes(k)) {
        if !unknown.contains(&k) {
            unknown.push(k);
        }
    }
    if unknown.is_empty() {
        return Ok(());
    }
    let mut known: Vec<&str> = groups.iter().flat_map(|g| g.iter().copied()).collect();
    known.sort_unstable();
    known.dedup();
    Err(SimError::Model(format!(
        "scenario {name:?} has no parameter {}; it reads {}",
        unknown.join(", "),
        known.join(", ")
    )))
}

scenario_params! {
    /// What every mass/spring scenario takes besides its own keys, applied to the structure
    /// it built: the solver (its number or name), the step and damping (each scenario has
    /// its own defaults), relaxation iterations, the acoustic grid off (`grid=0`) or refined
    /// (`grid_um`), and the material's variation (Table 4.1 gives ranges) or another material
    /// (`sim::material`): Young's modulus, thickness, width and density scaled, Poisson's
    /// ratio set.
    pub struct Common {
        solver: Option<super::model::Solver> = None,
        dt: Option<f64> = None,
        damping: Option<f64> = None,
        iterations: Option<u32> = None,
        grid: bool = true,
        grid_um: Option<f64> = None,
        e_scale: f64 = 1.0,
        t_scale: f64 = 1.0,
        w_scale: f64 = 1.0,
        rho_scale: f64 = 1.0,
        nu: Option<f64> = None,
    }
}

/// A mass/spring scenario's builder: handed the given parameters (it reads its own keys
/// from them) and the [`Common`] keys, read once by `scenario::build`, which applies them
/// to what it built.
pub type Builder = fn(&Params, &Common) -> Result<super::model::ModelFile, SimError>;

/// The most runs one `--sweep` may ask for.
pub const MAX_SWEEP_VALUES: usize = 10_000;

/// One swept parameter: `--sweep key=LO..HI` (integers, step 1: `point=1..12`) or
/// `--sweep key=LO..HI:STEP` (real values: `stretch=0.010..0.020:0.002`).
#[derive(Debug, Clone, PartialEq)]
pub struct Sweep {
    pub key: String,
    /// LO, LO + STEP, …, HI: each the decimal its 12 significant digits give, so that
    /// `0.010..0.020:0.002` runs 0.016, not 0.016000000000000004.
    pub values: Vec<f64>,
}

/// Parse `key=LO..HI[:STEP]`. HI must be LO plus a whole number of STEPs; without STEP both
/// bounds are integers.
pub fn parse_sweep(s: &str) -> Result<Sweep, SimError> {
    let bad = |why: &str| {
        SimError::Model(format!(
            "--sweep {s}: {why}; expected key=LO..HI (integers, e.g. point=1..12) or \
             key=LO..HI:STEP (e.g. stretch=0.010..0.020:0.002)"
        ))
    };
    let (k, r) = s.split_once('=').ok_or_else(|| bad("no '='"))?;
    let (range, step) = match r.split_once(':') {
        Some((range, step)) => (range, Some(step)),
        None => (r, None),
    };
    let (lo, hi) = range.split_once("..").ok_or_else(|| bad("no '..'"))?;
    let num = |v: &str| -> Result<f64, SimError> {
        v.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| bad(&format!("{v:?} is not a number")))
    };
    let (lo, hi) = (num(lo)?, num(hi)?);
    let step = match step {
        Some(st) => num(st)?,
        None if lo.fract() == 0.0 && hi.fract() == 0.0 => 1.0,
        None => return Err(bad("real bounds need a step")),
    };
    if step <= 0.0 {
        return Err(bad("the step must be > 0"));
    }
    if lo > hi {
        return Err(bad("empty range (LO > HI)"));
    }
    let n = (hi - lo) / step;
    let whole = n.round();
    if (n - whole).abs() > 1e-6 * whole.max(1.0) {
        return Err(bad(&format!(
            "HI is not LO plus a whole number of steps ({n:.4})"
        )));
    }
    if whole as usize >= MAX_SWEEP_VALUES {
        return Err(bad(&format!("more than {MAX_SWEEP_VALUES} values")));
    }
    let decimal = |v: f64| format!("{v:.11e}").parse::<f64>().unwrap_or(v);
    let values = (0..=whole as usize)
        .map(|i| decimal(lo + i as f64 * step))
        .collect();
    Ok(Sweep {
        key: k.trim().to_string(),
        values,
    })
}

/// Several sweeps checked before their combinations are made: no key twice (the first would
/// silently do nothing), and at most [`MAX_SWEEP_VALUES`] runs in all.
pub fn check_sweeps(sweeps: &[Sweep]) -> Result<usize, SimError> {
    for (i, s) in sweeps.iter().enumerate() {
        if sweeps[..i].iter().any(|o| o.key == s.key) {
            return Err(SimError::Model(format!(
                "--sweep {}: the key is swept twice",
                s.key
            )));
        }
    }
    sweeps
        .iter()
        .try_fold(1usize, |n, s| n.checked_mul(s.values.len()))
        .filter(|&n| n <= MAX_SWEEP_VALUES)
        .ok_or_else(|| {
            SimError::Model(format!("--sweep: more than {MAX_SWEEP_VALUES} runs in all"))
        })
}

/// The runs of several sweeps: every combination, the first sweep varying slowest.
pub fn sweep_grid(sweeps: &[Sweep]) -> Vec<Vec<(String, f64)>> {
    let mut runs: Vec<Vec<(String, f64)>> = vec![Vec::new()];
    for s in sweeps {
        runs = runs
            .into_iter()
            .flat_map(|r| {
                s.values.iter().map(move |&v| {
                    let mut r = r.clone();
                    r.push((s.key.clone(), v));
                    r
                })
            })
            .collect();
    }
    runs
}
