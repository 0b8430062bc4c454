//! Damage evolution over a test: per experiment and class, the cumulative sources (events,
//! or hits where no events were built), their hits and their energy against time and load,
//! and two statistics of the amplitude distribution over sliding windows of sources.
//!
//! * **b-value**, the maximum-likelihood estimate of Aki (1965), "Maximum likelihood estimate
//!   of b in the formula log N = a − bM and its confidence limits", Bull. Earthq. Res. Inst.
//!   43, 237–239: b = log₁₀ e / (M̄ − M_c), the mean over the magnitudes M ≥ M_c, for
//!   continuous magnitudes (amplitudes are not binned here, so Utsu's half-bin correction does
//!   not apply). AE practice takes M = A_dB / 20 (Colombo, Main & Forde 2003; Shiotani et al.
//!   2001), so M_c = completeness_db / 20. Aki's standard error is b / √n.
//! * **Ib-value** (improved b-value) of Shiotani, Fujii, Aoki & Amou (1994), "Evaluation of
//!   progressive failure using AE sources and improved b-value on slope model tests", Progress
//!   in AE VII, 529–534, in the form of Shiotani, Yuyama, Li & Ohtsu (2001), J. Acoustic
//!   Emission 19, 118–133: Ib = [log₁₀ N(μ − α₁σ) − log₁₀ N(μ + α₂σ)] / ((α₁ + α₂)σ), N(x) the
//!   number of sources of the window with M ≥ x, μ and σ the mean and standard deviation of M
//!   (sample, n − 1). For a Gutenberg–Richter distribution above M_c, Ib = b (α₁ = α₂ = 1 puts
//!   μ − σ at M_c), which the tests use.
//!
//! A falling b (or Ib) means the large events gain on the small ones: macro-cracks taking over
//! from distributed micro-damage, the classic precursor of final failure.

use super::settings::EvolutionConfig;
use crate::model::columns as cols;
use crate::store::{ColType, ColumnSpec, HitKey, Table, Value};

/// One source of a series, in time order: the row that stands for it (an event's first hit,
/// or a hit) and what it contributes.
#[derive(Debug, Clone, PartialEq)]
pub struct Source {
    pub key: HitKey,
    pub time_s: Option<f64>,
    pub load_n: Option<f64>,
    pub extension_m: Option<f64>,
    /// The test's strain energy ∫P dx up to this source (see [`StrainEnergy`]).
    pub strain_energy_j: Option<f64>,
    /// Peak amplitude of the source's first hit, dB_AE.
    pub amplitude_db: Option<f64>,
    /// Energy of the source's first hit (the sensor nearest to it), eu.
    pub energy_eu: Option<f64>,
    /// Hits the source made (an event's hits; 1 for a hit outside events).
    pub hits: u64,
    pub class: String,
}

/// A row of `evolution.parquet`: the state of one series after one more source.
#[derive(Debug, Clone, PartialEq)]
pub struct EvolutionRow {
    pub experiment: String,
    /// `all`, or one class.
    pub class: String,
    pub key: HitKey,
    pub time_s: Option<f64>,
    pub load_n: Option<f64>,
    pub extension_m: Option<f64>,
    pub strain_energy_j: Option<f64>,
    /// ln(Es / Ea): Es the strain energy, Ea the series' cumulative AE energy.
    pub sentry: Option<f64>,
    pub cum_sources: u64,
    pub cum_hits: u64,
    pub cum_energy_eu: f64,
    pub b_value: Option<f64>,
    pub ib_value: Option<f64>,
    /// The load cycle the source falls in, its reload's Felicity ratio and Kaiser flag
    /// (on the onset's row only): [`super::cycles::Felicity::step`].
    pub at_cycle: super::cycles::AtSource,
}

/// The sliding windows' parameters, checked once.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EvolutionParams {
    pub window: usize,
    pub m_c: f64,
    pub alpha1: f64,
    pub alpha2: f64,
}

impl EvolutionParams {
    /// From `[evolution]` (already checked by the config's validation).
    pub fn of(c: &EvolutionConfig) -> EvolutionParams {
        EvolutionParams {
            window: c.window.max(2),
            m_c: c.completeness_db / 20.0,
            alpha1: c.ib_alpha1,
            alpha2: c.ib_alpha2,
        }
    }
}

/// Aki's maximum-likelihood b-value of the magnitudes `m` at or above `m_c` (None with fewer
/// than two such, or when their mean does not exceed `m_c`).
pub fn b_value(m: &[f64], m_c: f64) -> Option<f64> {
    let (mut n, mut sum) = (0usize, 0.0f64);
    for &x in m {
        if x >= m_c {
            n += 1;
            sum += x;
        }
    }
    if n < 2 {
        return None;
    }
    let excess = sum / n as f64 - m_c;
    (excess > 0.0).then(|| std::f64::consts::LOG10_E / excess)
}

/// Shiotani's Ib-value of the magnitudes `m` (None for fewer than three, σ = 0, or no
/// magnitude at or above μ + α₂σ).
pub fn ib_value(m: &[f64], alpha1: f64, alpha2: f64) -> Option<f64> {
    let n = m.len();
    if n < 3 {
        return None;
    }
    let mu = m.iter().sum::<f64>() / n as f64;
    let var = m.iter().map(|x| (x - mu) * (x - mu)).sum::<f64>() / (n - 1) as f64;
    let sigma = var.sqrt();
    if sigma.is_nan() || sigma <= 0.0 {
        return None;
    }
    let count = |x: f64| m.iter().filter(|&&v| v >= x).count();
    let (lo, hi) = (count(mu - alpha1 * sigma), count(mu + alpha2 * sigma));
    if hi == 0 {
        return None;
    }
    Some(((lo as f64).log10() - (hi as f64).log10()) / ((alpha1 + alpha2) * sigma))
}

/// One series of an experiment's evolution (`all` first, then each class in name order;
/// each in the sources' order) as its sources stream by (`all`, or one class's): the running
/// sums and the window of the last magnitudes.
pub struct Series<'a> {
    experiment: &'a str,
    class: &'a str,
    p: EvolutionParams,
    n: u64,
    hits: u64,
    energy: f64,
    mags: std::collections::VecDeque<f64>,
}

impl<'a> Series<'a> {
    pub fn new(experiment: &'a str, class: &'a str, p: &EvolutionParams) -> Series<'a> {
        Series {
            experiment,
            class,
            p: *p,
            n: 0,
            hits: 0,
            energy: 0.0,
            mags: std::collections::VecDeque::with_capacity(p.window),
        }
    }

    /// The series' row after one more source.
    pub fn step(&mut self, s: &Source) -> EvolutionRow {
        let p = &self.p;
        self.n += 1;
        self.hits += s.hits;
        self.energy += s.energy_eu.filter(|e| e.is_finite()).unwrap_or(0.0);
        if let Some(a) = s.amplitude_db.filter(|a| a.is_finite()) {
            if self.mags.len() == p.window {
                self.mags.pop_front();
            }
            self.mags.push_back(a / 20.0);
        }
        let (b, ib) = if self.mags.len() == p.window {
            let window = self.mags.make_contiguous();
            (b_value(window, p.m_c), ib_value(window, p.alpha1, p.alpha2))
        } else {
            (None, None)
        };
        let sentry = match s.strain_energy_j {
            Some(es) if es > 0.0 && self.energy > 0.0 => Some((es / self.energy).ln()),
            _ => None,
        };
        EvolutionRow {
            experiment: self.experiment.to_string(),
            class: self.class.to_string(),
            key: s.key.clone(),
            time_s: s.time_s,
            load_n: s.load_n,
            extension_m: s.extension_m,
            strain_energy_j: s.strain_energy_j,
            sentry,
            cum_sources: self.n,
            cum_hits: self.hits,
            cum_energy_eu: self.energy,
            b_value: b,
            ib_value: ib,
            at_cycle: Default::default(),
        }
    }
}

/// The strain energy of a test, Es = ∫P dx by the trapezoid rule over the sources'
/// (extension, load) in time order. A source without both adds nothing; `None` until a
/// second point with both (a test without load or extension has no Es).
#[derive(Debug, Clone, Default)]
pub struct StrainEnergy {
    last: Option<(f64, f64)>,
    sum: Option<f64>,
}

impl StrainEnergy {
    /// Add a source; Es so far.
    pub fn add(&mut self, extension_m: Option<f64>, load_n: Option<f64>) -> Option<f64> {
        if let (Some(x), Some(p)) = (extension_m, load_n) {
            if x.is_finite() && p.is_finite() {
                if let Some((x0, p0)) = self.last {
                    *self.sum.get_or_insert(0.0) += 0.5 * (p + p0) * (x - x0);
                }
                self.last = Some((x, p));
            }
        }
        self.sum
    }
}

/// The columns of the test's mechanics: extension, strain energy and the sentry function.
fn strain_columns(t: Table<EvolutionRow>) -> Table<EvolutionRow> {
    t
        .col(
            ColumnSpec::new(
                cols::EXTENSION_M.name,
                ColType::Float64,
                "m",
                "test-machine extension at the source (null: none)",
            )
            .nullable(),
            |r| Value::F64(r.extension_m),
        )
        .col(
            ColumnSpec::new(
                "strain_energy_j",
                ColType::Float64,
                "J",
                "the test's strain energy up to the source, ∫P dx by the trapezoid rule over every source's (extension, load) in time order, whatever its class (null without load and extension, or a load that is no load)",
            )
            .nullable(),
            |r| Value::F64(r.strain_energy_j),
        )
        .col(
            ColumnSpec::new(
                "sentry",
                ColType::Float64,
                "1",
                "the sentry function ln(Es / Ea) (Minak et al. 2012): Es = strain_energy_j in J, Ea = cum_energy_eu in eu (so its level depends on the units; its rises, where the material stores energy, and drops, where damage releases it, are what is read); null without Es or before any AE energy",
            )
            .nullable(),
            |r| Value::F64(r.sentry),
        )
        .col(
            ColumnSpec::new(
                "sentry_p",
                ColType::Float64,
                "N",
                "P(x)·ln(Es / Ea): the sentry function weighted by the load at the source (null where either is)",
            )
            .nullable(),
            |r| Value::F64(r.sentry.zip(r.load_n).map(|(f, p)| f * p)),
        )
}

/// The columns of a load–unload–reload test ([`super::cycles`]).
fn cycle_columns(t: Table<EvolutionRow>) -> Table<EvolutionRow> {
    t.col(
        ColumnSpec::new(
            "cycle",
            ColType::Int32,
            "",
            "the load cycle the source falls in, 1-based (a cycle runs from the valley its loading starts at to the next; a monotonic test is one cycle); null without a load, or a load that is no load",
        )
        .nullable(),
        |r| Value::I32(r.at_cycle.cycle.map(|c| c as i32)),
    )
    .col(
        ColumnSpec::new(
            "felicity_ratio",
            ColType::Float64,
            "1",
            "on the row of a reload's AE onset (the series' [evolution] felicity_onset_sources-th source at or above felicity_onset_db while the cycle loads): its load over the highest load before the reload; null on every other row (cycles.parquet has every cycle)",
        )
        .nullable(),
        |r| Value::F64(r.at_cycle.felicity_ratio),
    )
    .col(
        ColumnSpec::new(
            "kaiser",
            ColType::Bool,
            "",
            "on the same row: whether the Kaiser effect held, felicity_ratio ≥ [evolution] kaiser_min_ratio",
        )
        .nullable(),
        |r| Value::Bool(r.at_cycle.kaiser),
    )
}

/// `evolution.parquet`.
pub fn evolution_table() -> Table<EvolutionRow> {
    Table::new("evolution")
        .col(
            ColumnSpec::of(cols::EXPERIMENT, "", "experiment id"),
            |r: &EvolutionRow| Value::Str(Some(r.experiment.clone())),
        )
        .col(
            ColumnSpec::new(
                "class",
                ColType::Utf8,
                "",
                "`all`, or the class (the SOM's) whose series this row continues",
            ),
            |r| Value::Str(Some(r.class.clone())),
        )
        .col(
            ColumnSpec::new(
                cols::CHANNEL.name,
                ColType::Int32,
                "",
                "the source's row: 0 for an event (its first hit's row in the profile), else the hit's channel",
            ),
            |r| Value::I32(Some(r.key.1)),
        )
        .col(
            ColumnSpec::of(cols::HIT, "", "the source's first hit"),
            |r| Value::I64(Some(r.key.2)),
        )
        .col(
            ColumnSpec::of(cols::TIME_S, "s", "the source's time").nullable(),
            |r| Value::F64(r.time_s),
        )
        .col(
            ColumnSpec::new(
                cols::LOAD_N.name,
                ColType::Float64,
                "N",
                "test-machine load at the source (null: none)",
            )
            .nullable(),
            |r| Value::F64(r.load_n),
        )
        .pipe(strain_columns)
        .pipe(cycle_columns)
        .col(
            ColumnSpec::new(
                "cum_sources",
                ColType::Int64,
                "",
                "sources of the series so far, this one included (events; hits where no events were built)",
            ),
            |r| Value::I64(Some(r.cum_sources as i64)),
        )
        .col(
            ColumnSpec::new(
                "cum_hits",
                ColType::Int64,
                "",
                "hits those sources made at all sensors",
            ),
            |r| Value::I64(Some(r.cum_hits as i64)),
        )
        .col(
            ColumnSpec::new(
                "cum_energy_eu",
                ColType::Float64,
                "eu",
                "energy of those sources' first hits, summed (missing energies count 0)",
            ),
            |r| Value::F64(Some(r.cum_energy_eu)),
        )
        .col(
            ColumnSpec::new(
                "b_value",
                ColType::Float64,
                "",
                "Aki's maximum-likelihood b-value of the series' last [evolution] window sources, M = A_dB/20, M ≥ completeness_db/20 (null: fewer sources)",
            )
            .nullable(),
            |r| Value::F64(r.b_value),
        )
        .col(
            ColumnSpec::new(
                "ib_value",
                ColType::Float64,
                "",
                "Shiotani's Ib-value of the same window (α₁, α₂ of [evolution]; null: fewer sources or σ = 0)",
            )
            .nullable(),
            |r| Value::F64(r.ib_value),
        )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::Rng;

    /// The whole evolution of one experiment at once, as the workflow streams it: `all` first, then each class in name order; each in the
    /// sources' order. The windows hold the last `window` sources with an amplitude; a row's
    /// b- and Ib-value are null until its series has that many.
    fn evolve(experiment: &str, sources: &[Source], p: &EvolutionParams) -> Vec<EvolutionRow> {
        let mut classes: Vec<&str> = sources.iter().map(|s| s.class.as_str()).collect();
        classes.sort_unstable();
        classes.dedup();
        let mut out = Vec::new();
        for class in std::iter::once("all").chain(classes) {
            let mut series = Series::new(experiment, class, p);
            for s in sources
                .iter()
                .filter(|s| class == "all" || s.class == class)
            {
                out.push(series.step(s));
            }
        }
        out
    }

    /// Magnitudes above `m_c` with a Gutenberg–Richter law of slope `b`: M − M_c is
    /// exponential with rate b·ln 10.
    fn gutenberg_richter(n: usize, b: f64, m_c: f64, seed: u64) -> Vec<f64> {
        let mut r = Rng::new(seed);
        (0..n)
            .map(|_| m_c - (1.0 - r.uniform()).ln() / (b * std::f64::consts::LN_10))
            .collect()
    }

    #[test]
    fn aki_by_hand() {
        // Above M_c = 2: 2.5, 3.0, 2.1 (1.9 is left out): mean excess 0.5333….
        let b = b_value(&[2.5, 1.9, 3.0, 2.1], 2.0).unwrap();
        assert!((b - std::f64::consts::LOG10_E / (7.6 / 3.0 - 2.0)).abs() < 1e-15);
        assert_eq!(b_value(&[2.5], 2.0), None);
        assert_eq!(b_value(&[2.0, 2.0], 2.0), None);
    }

    #[test]
    fn b_and_ib_recover_a_gutenberg_richter_slope() {
        for (b, seed) in [(1.0, 1), (1.5, 2), (0.7, 3)] {
            let m = gutenberg_richter(40_000, b, 2.0, seed);
            let got = b_value(&m, 2.0).unwrap();
            // Aki's standard error is b/√n = 0.5 %: 3 % is six of them.
            assert!((got - b).abs() < 0.03 * b, "b {b}: {got}");
            let ib = ib_value(&m, 1.0, 1.0).unwrap();
            assert!((ib - b).abs() < 0.05 * b, "Ib for b {b}: {ib}");
        }
        // Smaller slopes (more large events) give smaller values: the ordering the
        // evolution is read by.
        let lo = gutenberg_richter(5000, 0.8, 2.0, 9);
        let hi = gutenberg_richter(5000, 1.6, 2.0, 9);
        assert!(b_value(&lo, 2.0).unwrap() < b_value(&hi, 2.0).unwrap());
        assert!(ib_value(&lo, 1.0, 1.0).unwrap() < ib_value(&hi, 1.0, 1.0).unwrap());
        assert_eq!(ib_value(&[3.0, 3.0, 3.0], 1.0, 1.0), None);
    }

    /// A linear-elastic test, P = k·x, with one AE source of 3 eu per step: the trapezoid
    /// integral is exact, Es = k·x²/2, and the sentry function is ln(k·x²/2 / (3·n)) at the
    /// n-th source (n ≥ 1 after the first point). Without extension there is none.
    #[test]
    fn strain_energy_and_sentry_of_an_analytic_series() {
        let k = 2.0e5; // N/m
        let p = EvolutionParams::of(&EvolutionConfig::default());
        let mut series = Series::new("e", "all", &p);
        let mut strain = StrainEnergy::default();
        for n in 0..50i64 {
            let x = 1e-5 * n as f64;
            let es = strain.add(Some(x), Some(k * x));
            let row = series.step(&Source {
                key: ("e".into(), 1, n),
                time_s: Some(n as f64),
                load_n: Some(k * x),
                extension_m: Some(x),
                strain_energy_j: es,
                amplitude_db: None,
                energy_eu: Some(3.0),
                hits: 1,
                class: "b".into(),
            });
            if n == 0 {
                assert_eq!(row.strain_energy_j, None);
                assert_eq!(row.sentry, None);
                continue;
            }
            let want_es = k * x * x / 2.0;
            assert!((row.strain_energy_j.unwrap() - want_es).abs() < 1e-12 * want_es.max(1e-30));
            let want = (want_es / (3.0 * (n + 1) as f64)).ln();
            assert!((row.sentry.unwrap() - want).abs() < 1e-12, "n {n}");
        }
        let mut none = StrainEnergy::default();
        assert_eq!(none.add(None, Some(1.0)), None);
        assert_eq!(none.add(Some(1.0), None), None);
    }

    #[test]
    fn series_count_every_source_once_and_window_from_full() {
        let src = |i: i64, class: &str, amp: f64| Source {
            key: ("e".into(), 0, i),
            time_s: Some(i as f64),
            load_n: None,
            extension_m: None,
            strain_energy_j: None,
            amplitude_db: Some(amp),
            energy_eu: Some(2.0),
            hits: 2,
            class: class.into(),
        };
        let mut r = Rng::new(5);
        let sources: Vec<Source> = (1..=30)
            .map(|i| {
                let c = if i % 3 == 0 { "fibre" } else { "bond" };
                src(i, c, 40.0 + 40.0 * r.uniform())
            })
            .collect();
        let p = EvolutionParams {
            window: 10,
            m_c: 2.0,
            alpha1: 1.0,
            alpha2: 1.0,
        };
        let rows = evolve("e", &sources, &p);
        assert_eq!(rows.len(), 60);
        let all: Vec<&EvolutionRow> = rows.iter().filter(|r| r.class == "all").collect();
        assert_eq!(all.len(), 30);
        assert_eq!(all[29].cum_sources, 30);
        assert_eq!(all[29].cum_hits, 60);
        assert_eq!(all[29].cum_energy_eu, 60.0);
        assert!(all[..9].iter().all(|r| r.b_value.is_none()));
        // Row 10's window is the first ten sources' amplitudes.
        let m: Vec<f64> = sources[..10]
            .iter()
            .map(|s| s.amplitude_db.unwrap() / 20.0)
            .collect();
        assert_eq!(all[9].b_value, b_value(&m, 2.0));
        let m: Vec<f64> = sources[20..]
            .iter()
            .map(|s| s.amplitude_db.unwrap() / 20.0)
            .collect();
        assert_eq!(all[29].ib_value, ib_value(&m, 1.0, 1.0));
        let fibre: Vec<&EvolutionRow> = rows.iter().filter(|r| r.class == "fibre").collect();
        assert_eq!(fibre.len(), 10);
        assert_eq!(fibre[9].cum_sources, 10);
        assert!(fibre[9].b_value.is_some() && fibre[8].b_value.is_none());
    }
}
