//! A scenario's parameters (`--param key=value`) and sweeps (`--sweep key=a:b:n`): the
//! values every builder reads, below the builders and the registry that names them. A key
//! given but never read by the scenario's builder is refused by name ([`asked_only`]).

use super::SimError;

/// Knobs a scenario takes (`--param key=value`); each scenario reads the ones it knows.
#[derive(Debug, Clone, Default)]
pub struct Params(pub Vec<(String, f64)>);

thread_local! {
    /// The keys [`Params::get`] and [`Params::has`] were asked for while a scenario is built on
    /// this thread: a key given but never asked for is a typo, reported by name.
    static ASKED: std::cell::RefCell<Option<std::collections::BTreeSet<String>>> =
        const { std::cell::RefCell::new(None) };
}

/// Whether no build is recording the keys it asks (outside [`asked_only`]).
#[cfg(test)]
pub(super) fn recorder_is_off() -> bool {
    ASKED.with(|a| a.borrow().is_none())
}

fn asked(key: &str) {
    ASKED.with(|a| {
        if let Some(s) = a.borrow_mut().as_mut() {
            s.insert(key.to_string());
        }
    });
}

impl Params {
    pub fn get(&self, key: &str, default: f64) -> f64 {
        asked(key);
        self.0
            .iter()
            .rev()
            .find(|(k, _)| k == key)
            .map(|(_, v)| *v)
            .unwrap_or(default)
    }

    /// Whether `key` was given.
    pub fn has(&self, key: &str) -> bool {
        asked(key);
        self.0.iter().any(|(k, _)| k == key)
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

/// Run `f` and refuse, by name, a parameter it never asked for (a typo never runs the
/// default).
pub(super) fn asked_only<T>(
    name: &str,
    p: &Params,
    f: impl FnOnce(&Params) -> Result<T, SimError>,
) -> Result<T, SimError> {
    ASKED.with(|a| *a.borrow_mut() = Some(Default::default()));
    let built = f(p);
    let asked = ASKED.with(|a| a.borrow_mut().take()).unwrap_or_default();
    let m = built?;
    let unknown: Vec<&str> =
        p.0.iter()
            .map(|(k, _)| k.as_str())
            .filter(|k| !asked.contains(*k))
            .collect();
    if !unknown.is_empty() {
        return Err(SimError::Model(format!(
            "scenario {name:?} has no parameter {}; it reads {}",
            unknown.join(", "),
            asked.into_iter().collect::<Vec<_>>().join(", ")
        )));
    }
    Ok(m)
}
