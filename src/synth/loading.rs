//! How a synthetic test is loaded, and when it emits: a monotonic test to failure (the
//! demo's, [`super::load_curve`]), or a load–unload–reload test of N cycles whose truth
//! states where AE resumes on each reload; and, optionally, source amplitudes drawn so that
//! the hits' energies follow a stated power law.
//!
//! **Cycles.** Over a test of duration D, cycle k < N loads linearly from its valley (0 N,
//! then `VALLEY_N`) to P_k = `PEAK_N`·k/N and unloads linearly to the valley; the last
//! cycle loads along the demo's curve to `PEAK_N` and falls past it as the crack grows. The non-final cycles take
//! D/(N+1) each (70 % loading, 30 % unloading), the last the rest; every corner falls on the
//! 10 Hz grid of the test machine's series, so its linear interpolation at a hit is exact.
//! AE is emitted only while a cycle loads, from its resume load on (and through the last
//! cycle's break): cycle 1 from ¼ P₁; reload k ≥ 2 from FR_k·P_{k−1}, the designed Felicity
//! ratio FR_k = max(0.5, 1.2 − 0.1 k) (1.0 on the first reload: the Kaiser effect, then
//! falling as damage accumulates, as Fowler's FRP vessels and paper do). Source times are
//! uniform over those windows. Extension: elastic (`COMPLIANCE_M_PER_N` × load) plus a
//! permanent set growing with the highest load so far.
//!
//! **Energies.** With an exponent α the source's peak amplitude A is drawn from a power law
//! with density ∝ A^−(2α−1) above `A_MIN_V`, truncated at `A_MAX_V` (redrawn above it): a
//! hit's energy is its waveform's squared amplitude times the waveform's own factor, so
//! the energies follow density ∝ E^−α above their smallest. α must lie in [1.35, 3]: below,
//! more than 2 % of the draws would fall beyond the ADC's range (the truncation then bends
//! the law).

use crate::model::Mechanism;
use crate::util::Rng;

/// The last cycle's peak load, N (the demo's).
pub const PEAK_N: f64 = 60.0;
/// The load a cycle unloads to, N.
pub const VALLEY_N: f64 = 2.0;
/// The elastic compliance of the strip, m/N (0.8 mm at 60 N).
pub const COMPLIANCE_M_PER_N: f64 = 0.8e-3 / 60.0;
/// The power-law amplitudes' range, V.
pub const A_MIN_V: f64 = 0.5e-3;
pub const A_MAX_V: f64 = 0.2;
/// The exponents `--energy-exponent` accepts.
pub const EXPONENTS: std::ops::RangeInclusive<f64> = 1.35..=3.0;

/// A synthetic test's shape: `synth-experiment --cycles N --energy-exponent A`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Shape {
    /// 0 or 1: monotonic to failure; 2 to `MAX_CYCLES`: load–unload–reload.
    pub cycles: usize,
    pub energy_exponent: Option<f64>,
    /// The sources' mechanism mix (`--shares`).
    pub shares: Shares,
}

/// The sources' mechanism mix: `synth-experiment --shares
/// bond_failure=…,fibre_failure=…,both=…,erroneous=…`, named by the truth's `mechanism`
/// values. The default is the demo's mix (84 / 2 / 10 / 4 %), which holds about a dozen
/// fibre failures in a test: a fibre failure's recall needs a mix that holds more.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shares {
    pub bond_failure: f64,
    pub fibre_failure: f64,
    pub both: f64,
    pub erroneous: f64,
}

impl Default for Shares {
    fn default() -> Shares {
        Shares {
            bond_failure: 0.84,
            fibre_failure: 0.02,
            both: 0.10,
            erroneous: 0.04,
        }
    }
}

impl Shares {
    /// The mechanism of a source from a uniform draw `u` in [0, 1): fibre failure, both,
    /// erroneous, then bond failure, in that order along [0, 1).
    pub fn draw(&self, u: f64) -> Mechanism {
        if u < self.fibre_failure {
            Mechanism::FibreFailure
        } else if u < self.fibre_failure + self.both {
            Mechanism::Both
        } else if u < self.fibre_failure + self.both + self.erroneous {
            Mechanism::Erroneous
        } else {
            Mechanism::BondFailure
        }
    }

    /// Checked once: each share in [0, 1], the four summing to 1 (a name not given is 0).
    fn check(self) -> Result<Shares, super::SynthError> {
        let all = [
            self.bond_failure,
            self.fibre_failure,
            self.both,
            self.erroneous,
        ];
        if all.iter().any(|v| !(0.0..=1.0).contains(v)) {
            return Err(super::SynthError::Shape(format!(
                "--shares {self}: each share must lie in 0–1"
            )));
        }
        let sum: f64 = all.iter().sum();
        if (sum - 1.0).abs() > 1e-6 {
            return Err(super::SynthError::Shape(format!(
                "--shares {self}: the shares sum to {sum}, not 1"
            )));
        }
        Ok(self)
    }
}

impl std::fmt::Display for Shares {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "bond_failure={},fibre_failure={},both={},erroneous={}",
            self.bond_failure, self.fibre_failure, self.both, self.erroneous
        )
    }
}

impl std::str::FromStr for Shares {
    type Err = String;
    /// `name=share,…` with the truth's mechanism names; a name not given is 0, a name
    /// given twice or not a mechanism is refused by name. The sum is checked with the
    /// test's shape ([`Shape::check`]).
    fn from_str(s: &str) -> Result<Shares, String> {
        let mut out = Shares {
            bond_failure: 0.0,
            fibre_failure: 0.0,
            both: 0.0,
            erroneous: 0.0,
        };
        let mut seen = Vec::new();
        for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let (k, v) = part
                .split_once('=')
                .ok_or_else(|| format!("{part:?}: expected name=share"))?;
            let (k, v) = (k.trim(), v.trim());
            let v: f64 = v
                .parse()
                .map_err(|_| format!("{k}={v}: the share is not a number"))?;
            if seen.contains(&k) {
                return Err(format!("{k} given twice"));
            }
            seen.push(k);
            let slot = match Mechanism::parse(k) {
                Some(Mechanism::BondFailure) => &mut out.bond_failure,
                Some(Mechanism::FibreFailure) => &mut out.fibre_failure,
                Some(Mechanism::Both) => &mut out.both,
                Some(Mechanism::Erroneous) => &mut out.erroneous,
                _ => {
                    return Err(format!(
                        "{k:?} is not a mechanism; the names are bond_failure, fibre_failure, both, erroneous"
                    ))
                }
            };
            *slot = v;
        }
        if seen.is_empty() {
            return Err("no shares given".into());
        }
        Ok(out)
    }
}

/// The most cycles a 60 s test holds (each non-final cycle ≥ 6 s).
pub const MAX_CYCLES: usize = 9;

impl Shape {
    /// Checked once, before anything is built.
    pub fn check(self) -> Result<Shape, super::SynthError> {
        if self.cycles > MAX_CYCLES {
            return Err(super::SynthError::Shape(format!(
                "--cycles {}: at most {MAX_CYCLES} (each cycle needs 6 s of the 60 s test)",
                self.cycles
            )));
        }
        if let Some(a) = self.energy_exponent {
            if !EXPONENTS.contains(&a) {
                return Err(super::SynthError::Shape(format!(
                    "--energy-exponent {a}: must lie in {}–{} (below, over 2 % of the amplitudes would exceed the ADC's range and bend the law)",
                    EXPONENTS.start(),
                    EXPONENTS.end()
                )));
            }
        }
        self.shares.check()?;
        Ok(self)
    }
}

/// The designed Felicity ratio of reload k ≥ 2.
pub fn designed_felicity(k: usize) -> f64 {
    (1.2 - 0.1 * k as f64).max(0.5)
}

/// One cycle of a cyclic test, as designed.
#[derive(Debug, Clone, PartialEq)]
pub struct CycleDesign {
    /// 1-based.
    pub index: usize,
    pub start_s: f64,
    pub start_load_n: f64,
    pub peak_s: f64,
    pub peak_load_n: f64,
    /// Where the cycle's unloading ends (the last cycle: the test's end).
    pub end_s: f64,
    /// The load and time at which AE resumes.
    pub resume_load_n: f64,
    pub resume_s: f64,
    /// The highest load before the cycle (None for the first).
    pub previous_max_n: Option<f64>,
    /// The last cycle: loads along the demo's curve and falls past its peak.
    pub last: bool,
}

impl CycleDesign {
    pub fn designed_felicity(&self) -> Option<f64> {
        self.previous_max_n.map(|m| self.resume_load_n / m)
    }
}

/// Round to the 10 Hz grid.
fn grid(t: f64) -> f64 {
    (t * 10.0).round() / 10.0
}

/// The cycles of an N-cycle test of `duration_s` (N ≥ 2).
pub fn design(cycles: usize, duration_s: f64) -> Vec<CycleDesign> {
    let n = cycles.max(2);
    let span = duration_s / (n + 1) as f64;
    let mut out: Vec<CycleDesign> = Vec::with_capacity(n);
    let mut t = 0.0;
    for k in 1..=n {
        let start_load = if k == 1 { 0.0 } else { VALLEY_N };
        let previous = out.last().map(|c| c.peak_load_n);
        let last = k == n;
        let (peak_s, end_s, peak) = if last {
            (grid(t + 0.8 * (duration_s - t)), duration_s, PEAK_N)
        } else {
            (
                grid(t + 0.7 * span),
                grid(t + span),
                PEAK_N * k as f64 / n as f64,
            )
        };
        let resume = match previous {
            None => 0.25 * peak,
            Some(p) => designed_felicity(k) * p,
        };
        let mut c = CycleDesign {
            index: k,
            start_s: t,
            start_load_n: start_load,
            peak_s,
            peak_load_n: peak,
            end_s,
            resume_load_n: resume,
            resume_s: 0.0,
            previous_max_n: previous,
            last,
        };
        c.resume_s = c.loading_time_of(resume);
        out.push(c);
        t = end_s;
    }
    out
}

impl CycleDesign {
    /// The load at `t` within the cycle.
    fn load(&self, t: f64) -> f64 {
        let last = self.last;
        let (t0, l0, tp, lp) = (
            self.start_s,
            self.start_load_n,
            self.peak_s,
            self.peak_load_n,
        );
        if t <= tp {
            let u = ((t - t0) / (tp - t0)).clamp(0.0, 1.0);
            if last {
                l0 + (lp - l0) * (1.6 * u - 0.6 * u * u)
            } else {
                l0 + (lp - l0) * u
            }
        } else if last {
            let w = (t - tp) / (tp - t0);
            (lp * (1.0 - 2.5 * w * w)).max(0.0)
        } else {
            let u = ((t - tp) / (self.end_s - tp)).clamp(0.0, 1.0);
            lp + (VALLEY_N - lp) * u
        }
    }

    /// When the loading part reaches `load` (its start if below).
    fn loading_time_of(&self, load: f64) -> f64 {
        let (t0, l0, tp, lp) = (
            self.start_s,
            self.start_load_n,
            self.peak_s,
            self.peak_load_n,
        );
        let f = ((load - l0) / (lp - l0)).clamp(0.0, 1.0);
        let u = if self.last {
            // 1.6u − 0.6u² = f, the root in [0, 1].
            (1.6 - (1.6f64 * 1.6 - 2.4 * f).sqrt()) / 1.2
        } else {
            f
        };
        t0 + u * (tp - t0)
    }
}

/// The load of a cyclic test at `t`.
pub fn cyclic_load(design: &[CycleDesign], t: f64) -> f64 {
    let k = design.iter().rposition(|c| c.start_s <= t).unwrap_or(0);
    design[k].load(t)
}

/// The extension of a cyclic test at `t`: elastic plus a permanent set of 0.1 mm × (the
/// highest load so far / `PEAK_N`)².
pub fn cyclic_extension(design: &[CycleDesign], t: f64) -> f64 {
    let load = cyclic_load(design, t);
    let highest = design
        .iter()
        .filter(|c| c.start_s <= t)
        .map(|c| if t >= c.peak_s { c.peak_load_n } else { load })
        .fold(load, f64::max);
    COMPLIANCE_M_PER_N * load + 1e-4 * (highest / PEAK_N).powi(2)
}

/// `n` source times of a cyclic test, sorted: uniform over the cycles' emitting windows
/// (resume → peak; the last cycle's resume → the end).
pub fn cyclic_times(design: &[CycleDesign], n: usize, rng: &mut Rng) -> Vec<f64> {
    let windows: Vec<(f64, f64)> = design
        .iter()
        .map(|c| {
            let end = if c.last { c.end_s } else { c.peak_s };
            (c.resume_s, end)
        })
        .collect();
    let total: f64 = windows.iter().map(|(a, b)| b - a).sum();
    let mut times: Vec<f64> = (0..n)
        .map(|_| {
            let mut x = rng.uniform() * total;
            for &(a, b) in &windows {
                if x < b - a {
                    return a + x;
                }
                x -= b - a;
            }
            windows.last().map(|w| w.1).unwrap_or(0.0)
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times
}

/// A peak amplitude, V, whose squared-amplitude energies follow density ∝ E^−`alpha`.
pub fn power_law_amplitude(alpha: f64, rng: &mut Rng) -> f64 {
    let a_exp = 2.0 * alpha - 1.0;
    loop {
        let a = A_MIN_V * (1.0 - rng.uniform()).powf(-1.0 / (a_exp - 1.0));
        if a <= A_MAX_V {
            return a;
        }
    }
}

/// One designed cycle with the first specimen source the test made in it: a row of
/// `truth_cycles.parquet`.
#[derive(Debug, Clone, PartialEq)]
pub struct CycleTruth {
    pub experiment: String,
    pub design: CycleDesign,
    /// The earliest hit of a specimen source in the cycle (what a zone-filtered analysis
    /// sees first), and the load there.
    pub first_hit_s: Option<f64>,
    pub first_hit_load_n: Option<f64>,
}

/// `truth_cycles.parquet`: the designed cycles of a cyclic synthetic test.
pub fn cycle_truth_table() -> crate::store::Table<CycleTruth> {
    use crate::model::columns as cols;
    use crate::store::{ColType, ColumnSpec, Value};
    let f = |name: &str, unit: &str, doc: &str| ColumnSpec::new(name, ColType::Float64, unit, doc);
    crate::store::Table::new("truth_cycles")
        .col(
            ColumnSpec::of(cols::EXPERIMENT, "", "experiment id"),
            |r: &CycleTruth| Value::Str(Some(r.experiment.clone())),
        )
        .col(
            ColumnSpec::new("cycle", ColType::Int32, "", "the load cycle, 1-based"),
            |r| Value::I32(Some(r.design.index as i32)),
        )
        .col(f("start_s", "s", "where its loading starts"), |r| Value::F64(Some(r.design.start_s)))
        .col(f("start_load_n", "N", "the load there"), |r| Value::F64(Some(r.design.start_load_n)))
        .col(f("peak_s", "s", "its peak"), |r| Value::F64(Some(r.design.peak_s)))
        .col(f("peak_load_n", "N", "the load there"), |r| Value::F64(Some(r.design.peak_load_n)))
        .col(f("end_s", "s", "where its unloading ends (the last cycle: the test's end)"), |r| Value::F64(Some(r.design.end_s)))
        .col(f("previous_max_n", "N", "the highest load before it (null: the first cycle)").nullable(), |r| Value::F64(r.design.previous_max_n))
        .col(f("resume_load_n", "N", "the load from which the cycle emits AE (the first: ¼ of its peak)"), |r| Value::F64(Some(r.design.resume_load_n)))
        .col(f("resume_s", "s", "when the loading reaches it"), |r| Value::F64(Some(r.design.resume_s)))
        .col(f("felicity_ratio", "1", "the designed Felicity ratio resume_load_n / previous_max_n (null: the first cycle)").nullable(), |r| Value::F64(r.design.designed_felicity()))
        .col(f("first_hit_s", "s", "the earliest hit of a specimen source in the cycle (null: none)").nullable(), |r| Value::F64(r.first_hit_s))
        .col(f("first_hit_load_n", "N", "the load there: what an onset rule of one source measures").nullable(), |r| Value::F64(r.first_hit_load_n))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_design_of_three_cycles() {
        let d = design(3, 60.0);
        assert_eq!(d.len(), 3);
        // Peaks at 20, 40, 60 N; reloads resume at 1.0 × 20 and 0.9 × 40 N.
        let peaks: Vec<f64> = d.iter().map(|c| c.peak_load_n).collect();
        assert_eq!(peaks, [20.0, 40.0, 60.0]);
        assert_eq!(d[1].designed_felicity(), Some(1.0));
        assert!((d[2].designed_felicity().unwrap() - 0.9).abs() < 1e-12);
        for c in &d {
            // The load is continuous at each corner, and at the resume time it is the
            // resume load.
            assert!((c.load(c.resume_s) - c.resume_load_n).abs() < 1e-9, "{c:?}");
            assert!((cyclic_load(&d, c.start_s) - c.start_load_n).abs() < 1e-9);
            assert!((cyclic_load(&d, c.peak_s) - c.peak_load_n).abs() < 1e-9);
            assert_eq!(grid(c.peak_s), c.peak_s);
        }
        // Unloaded to the valley before each reload; past its peak at the end, as the
        // demo's curve (60·(1 − 2.5·0.25²) N a quarter of the loading time after it).
        assert!((cyclic_load(&d, d[1].start_s - 1e-9) - VALLEY_N).abs() < 1e-6);
        assert!((cyclic_load(&d, 60.0) - 60.0 * (1.0 - 2.5 / 16.0)).abs() < 1e-9);
        // The sources fall only in the emitting windows.
        let mut rng = Rng::new(1);
        for t in cyclic_times(&d, 2000, &mut rng) {
            let c = d.iter().rfind(|c| c.start_s <= t).unwrap();
            assert!(t >= c.resume_s && (c.index == 3 || t <= c.peak_s), "{t}");
        }
    }

    /// The amplitudes' law: the MLE of the amplitude exponent 2α − 1 from 10⁵ draws (the
    /// truncation at A_MAX_V removes 0.25 % of the law at α = 1.5).
    #[test]
    fn amplitudes_follow_their_law() {
        let mut rng = Rng::new(2);
        let a: Vec<f64> = (0..100_000)
            .map(|_| power_law_amplitude(1.5, &mut rng))
            .collect();
        let mle = 1.0 + a.len() as f64 / a.iter().map(|x| (x / A_MIN_V).ln()).sum::<f64>();
        assert!((mle - 2.0).abs() < 0.02, "{mle}");
        assert!(a.iter().all(|x| (A_MIN_V..=A_MAX_V).contains(x)));
    }

    #[test]
    fn shares_are_named_as_the_truth_names_mechanisms_and_checked_once() {
        let s: Shares = "fibre_failure=0.35, bond_failure=0.45,both=0.1,erroneous=0.1"
            .parse()
            .unwrap();
        assert_eq!((s.bond_failure, s.fibre_failure), (0.45, 0.35));
        let shape = |sh: Shares| {
            Shape {
                shares: sh,
                ..Default::default()
            }
            .check()
        };
        assert!(shape(s).is_ok());
        // The default mix as the CLI shows and reads it (`default_value_t`: Display, then
        // FromStr) is the default mix.
        let d: Shares = Shares::default().to_string().parse().unwrap();
        assert_eq!(d, Shares::default());
        assert_eq!(
            Shares::default().to_string(),
            "bond_failure=0.84,fibre_failure=0.02,both=0.1,erroneous=0.04"
        );
        // A name not given is 0; the sum must be 1.
        let only: Shares = "bond_failure=1".parse().unwrap();
        assert!(shape(only).is_ok());
        let e = shape("bond_failure=0.5,fibre_failure=0.2".parse().unwrap()).unwrap_err();
        assert!(e.to_string().contains("sum to 0.7"), "{e}");
        let e = shape("bond_failure=1.5,fibre_failure=-0.5".parse().unwrap()).unwrap_err();
        assert!(e.to_string().contains("0–1"), "{e}");
        for (bad, says) in [
            ("fibre=0.5,bond_failure=0.5", "\"fibre\" is not a mechanism"),
            ("bond_failure=0.5,bond_failure=0.5", "given twice"),
            ("bond_failure", "expected name=share"),
            ("bond_failure=x", "not a number"),
            ("", "no shares"),
        ] {
            let e = bad.parse::<Shares>().unwrap_err();
            assert!(e.contains(says), "{bad}: {e}");
        }
        // Drawn in order along [0, 1): fibre, both, erroneous, then bond.
        let m = |u| s.draw(u);
        assert_eq!(m(0.0), Mechanism::FibreFailure);
        assert_eq!(m(0.34), Mechanism::FibreFailure);
        assert_eq!(m(0.36), Mechanism::Both);
        assert_eq!(m(0.5), Mechanism::Erroneous);
        assert_eq!(m(0.56), Mechanism::BondFailure);
    }
}
