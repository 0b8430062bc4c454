//! Load–unload–reload tests: the load cycles of a test, and for each reload the Felicity
//! ratio and the Kaiser effect.
//!
//! * **Cycles.** A cycle starts where the load begins to rise (the test's start, or the
//!   valley after an unloading) and peaks before the next unloading. A drop counts as an
//!   unloading, and a rise after it as a reload, only when it exceeds the hysteresis h =
//!   max(`cycle_drop_fraction` × the load's span, 5 σ) with σ the channel's noise
//!   ([`super::load::LoadCheck`]): a noisy plateau never makes cycles, and a final break
//!   (a drop with no reload) ends the last cycle.
//! * **Felicity ratio** (Fowler 1977; ASTM E1067 and E1118 for FRP): on the reload of cycle
//!   k ≥ 2, FR = P_onset / P_max, P_max the highest load before the reload began and
//!   P_onset the load at the AE onset of the reload's loading part (its first
//!   `felicity_onset_sources` sources at or above `felicity_onset_db`; the load of the
//!   source that completes that count). AE during the unloading and after the cycle's peak
//!   does not count.
//! * **Kaiser effect** (Kaiser 1950): no emission before the previous maximum is passed,
//!   i.e. FR ≥ `kaiser_min_ratio` (1 by definition; a noisy load channel may warrant a
//!   little less). A reload with no onset at all up to its peak keeps the effect (and has no
//!   ratio).

use super::load::LoadCheck;
use crate::model::columns as cols;
use crate::store::read::TableScan;
use crate::store::{ColType, ColumnSpec, StoreError, Table, Value};
use std::collections::BTreeMap;
use std::path::Path;

/// The rules of cycles and onsets, from `[evolution]` (checked there).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleParams {
    pub drop_fraction: f64,
    pub onset_sources: usize,
    pub onset_db: f64,
    pub kaiser_min_ratio: f64,
}

impl CycleParams {
    pub fn of(c: &super::settings::EvolutionConfig) -> CycleParams {
        CycleParams {
            drop_fraction: c.cycle_drop_fraction,
            onset_sources: c.felicity_onset_sources.max(1),
            onset_db: c.felicity_onset_db,
            kaiser_min_ratio: c.kaiser_min_ratio,
        }
    }
}

/// One load cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct Cycle {
    /// 1-based, in time order.
    pub index: u32,
    /// Where its loading starts: the test's first load value, or the valley of the
    /// unloading before it.
    pub start_s: f64,
    pub start_load_n: f64,
    pub peak_s: f64,
    pub peak_load_n: f64,
    /// The highest load before `start_s` (None for the first cycle).
    pub previous_max_n: Option<f64>,
}

/// Finds a test's cycles in its load series: a first pass judges the channel
/// ([`LoadCheck`]) and its span, a second ([`CycleFinder::cycles`]) walks the series with
/// the hysteresis they give. Only the turning points are kept.
#[derive(Debug, Clone)]
pub struct CycleFinder {
    h: f64,
    /// Loading (tracking the peak) or unloading (tracking the valley).
    loading: bool,
    extreme: Option<(f64, f64)>,
    start: Option<(f64, f64)>,
    max_so_far: f64,
    last_t: f64,
    cycles: Vec<Cycle>,
}

impl CycleFinder {
    /// The finder for a series whose first pass gave `check`; None when the channel is not
    /// a load (no cycles can be told from noise).
    pub fn new(check: &LoadCheck, min_span_n: f64, p: &CycleParams) -> Option<CycleFinder> {
        if !check.verdict(min_span_n).is_load() {
            return None;
        }
        let h = (p.drop_fraction * check.span()).max(5.0 * check.noise_n().unwrap_or(0.0));
        Some(CycleFinder {
            h,
            loading: true,
            extreme: None,
            start: None,
            max_so_far: f64::NEG_INFINITY,
            last_t: f64::NEG_INFINITY,
            cycles: Vec::new(),
        })
    }

    /// The next (time, load) of the series; values out of time order or not finite are
    /// left out.
    pub fn push(&mut self, t: f64, load: f64) {
        if !(t.is_finite() && load.is_finite()) || t < self.last_t {
            return;
        }
        self.last_t = t;
        let Some((te, le)) = self.extreme else {
            self.start = Some((t, load));
            self.extreme = Some((t, load));
            return;
        };
        if self.loading {
            if load > le {
                self.extreme = Some((t, load));
            } else if load < le - self.h {
                // An unloading: the cycle peaked at (te, le).
                self.close(te, le);
                self.loading = false;
                self.extreme = Some((t, load));
            }
        } else if load < le {
            self.extreme = Some((t, load));
        } else if load > le + self.h {
            // A reload from the valley (te, le).
            self.start = Some((te, le));
            self.loading = true;
            self.extreme = Some((t, load));
        }
    }

    fn close(&mut self, peak_s: f64, peak_load_n: f64) {
        let (start_s, start_load_n) = self.start.take().unwrap_or((peak_s, peak_load_n));
        let previous = (!self.cycles.is_empty()).then_some(self.max_so_far);
        self.cycles.push(Cycle {
            index: self.cycles.len() as u32 + 1,
            start_s,
            start_load_n,
            peak_s,
            peak_load_n,
            previous_max_n: previous,
        });
        self.max_so_far = self.max_so_far.max(peak_load_n);
    }

    /// The cycles found (a cycle still loading at the end peaks at its highest value).
    pub fn cycles(mut self) -> Vec<Cycle> {
        if self.loading {
            if let Some((te, le)) = self.extreme {
                self.close(te, le);
            }
        }
        self.cycles
    }
}

/// What a reload's onset gave one series in one cycle: a row of `cycles.parquet`.
#[derive(Debug, Clone, PartialEq)]
pub struct CycleRow {
    pub experiment: String,
    pub class: String,
    pub cycle: Cycle,
    /// The series' sources in the cycle (loading, unloading and after its peak).
    pub sources: u64,
    pub onset_time_s: Option<f64>,
    pub onset_load_n: Option<f64>,
    pub felicity_ratio: Option<f64>,
    /// None for the first cycle (nothing to remember yet).
    pub kaiser: Option<bool>,
}

impl CycleRow {
    /// A reload's reading for a person: "0.934" or "1.002 (Kaiser)", or "no AE to its
    /// peak (Kaiser)"; None for a first loading.
    pub fn reading(&self) -> Option<String> {
        self.cycle.previous_max_n?;
        let mark = if self.kaiser == Some(true) {
            " (Kaiser)"
        } else {
            ""
        };
        Some(match (self.felicity_ratio, self.onset_time_s) {
            (Some(r), _) => format!("{r:.3}{mark}"),
            (None, None) => format!("no AE to its peak{mark}"),
            (None, Some(_)) => "onset at an unknown load".to_string(),
        })
    }
}

/// What [`Felicity::step`] says of one source.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AtSource {
    pub cycle: Option<u32>,
    /// On the source that is its reload's onset only.
    pub felicity_ratio: Option<f64>,
    pub kaiser: Option<bool>,
}

/// One series' walk through its experiment's cycles, source by source in time order.
pub struct Felicity<'a> {
    experiment: &'a str,
    class: &'a str,
    cycles: &'a [Cycle],
    p: CycleParams,
    /// The cycle being walked (an index into `cycles`), its sources and onset count.
    at: usize,
    sources: u64,
    counted: usize,
    onset: Option<(f64, Option<f64>)>,
    rows: Vec<CycleRow>,
}

impl<'a> Felicity<'a> {
    pub fn new(experiment: &'a str, class: &'a str, cycles: &'a [Cycle], p: &CycleParams) -> Self {
        Felicity {
            experiment,
            class,
            cycles,
            p: *p,
            at: 0,
            sources: 0,
            counted: 0,
            onset: None,
            rows: Vec::new(),
        }
    }

    /// The cycle's row, and the walk moved to the next.
    fn close(&mut self) {
        let c = &self.cycles[self.at];
        let ratio = match (self.onset, c.previous_max_n) {
            (Some((_, Some(p))), Some(max)) if max > 0.0 => Some(p / max),
            _ => None,
        };
        // No onset: the effect held to the peak; an onset whose load (or a previous maximum
        // > 0) is unknown: unknown.
        let kaiser = match (c.previous_max_n, self.onset, ratio) {
            (None, _, _) => None,
            (Some(_), None, _) => Some(true),
            (Some(_), Some(_), Some(r)) => Some(r >= self.p.kaiser_min_ratio),
            (Some(_), Some(_), None) => None,
        };
        self.rows.push(CycleRow {
            experiment: self.experiment.to_string(),
            class: self.class.to_string(),
            cycle: c.clone(),
            sources: self.sources,
            onset_time_s: self.onset.map(|o| o.0),
            onset_load_n: self.onset.and_then(|o| o.1),
            felicity_ratio: ratio,
            kaiser,
        });
        self.at += 1;
        self.sources = 0;
        self.counted = 0;
        self.onset = None;
    }

    /// The next source of the series (time order).
    pub fn step(&mut self, time_s: Option<f64>, load_n: Option<f64>, db: Option<f64>) -> AtSource {
        let Some(t) = time_s.filter(|t| t.is_finite()) else {
            return AtSource::default();
        };
        if self.cycles.is_empty() {
            return AtSource::default();
        }
        while self.at + 1 < self.cycles.len() && t >= self.cycles[self.at + 1].start_s {
            self.close();
        }
        let c = &self.cycles[self.at];
        self.sources += 1;
        let mut out = AtSource {
            cycle: Some(c.index),
            ..Default::default()
        };
        let loading = t <= c.peak_s;
        let loud = db.is_some_and(|a| a >= self.p.onset_db);
        if loading && loud && self.onset.is_none() {
            self.counted += 1;
            if self.counted == self.p.onset_sources {
                self.onset = Some((t, load_n));
                if let Some(max) = c.previous_max_n.filter(|m| *m > 0.0) {
                    let ratio = load_n.map(|p| p / max);
                    out.felicity_ratio = ratio;
                    out.kaiser = ratio.map(|r| r >= self.p.kaiser_min_ratio);
                }
            }
        }
        out
    }

    /// Every cycle's row (cycles the series never reached included: no sources, no onset).
    pub fn finish(mut self) -> Vec<CycleRow> {
        while self.at < self.cycles.len() {
            self.close();
        }
        self.rows
    }
}

/// Every experiment's cycles from its load series in `parametric.parquet` (rows with a
/// `load_n`, in file order: the series as recorded). Two passes: the channel and its span,
/// then the turning points. An experiment whose load is no load (or absent) has none.
pub fn cycles_of_table(
    parametric: &Path,
    min_span_n: f64,
    p: &CycleParams,
) -> Result<BTreeMap<String, Vec<Cycle>>, StoreError> {
    let t = TableScan::open(parametric)?;
    let sel = [cols::EXPERIMENT.name, cols::TIME_S.name, cols::LOAD_N.name];
    let pass = |f: &mut dyn FnMut(&str, f64, f64)| -> Result<(), StoreError> {
        for b in t.batches(&sel) {
            let (_, df) = b?;
            let e = t.strings(&df, cols::EXPERIMENT.name)?;
            let time = t.f64s(&df, cols::TIME_S.name)?;
            let load = t.f64s(&df, cols::LOAD_N.name)?;
            for ((e, tt), l) in e.into_iter().zip(time).zip(load) {
                if let (Some(e), Some(tt), Some(l)) = (e, tt, l) {
                    f(&e, tt, l);
                }
            }
        }
        Ok(())
    };
    let mut checks: BTreeMap<String, LoadCheck> = BTreeMap::new();
    pass(&mut |e, _, l| checks.entry(e.to_string()).or_default().push(l))?;
    let mut finders: BTreeMap<String, CycleFinder> = checks
        .iter()
        .filter_map(|(e, c)| Some((e.clone(), CycleFinder::new(c, min_span_n, p)?)))
        .collect();
    pass(&mut |e, tt, l| {
        if let Some(f) = finders.get_mut(e) {
            f.push(tt, l)
        }
    })?;
    Ok(finders.into_iter().map(|(e, f)| (e, f.cycles())).collect())
}

/// `cycles.parquet`: per experiment, series (`all` or a class) and load cycle.
pub fn cycles_table() -> Table<CycleRow> {
    let f = |name: &str, unit: &str, doc: &str| ColumnSpec::new(name, ColType::Float64, unit, doc);
    Table::new("cycles")
        .col(
            ColumnSpec::of(cols::EXPERIMENT, "", "experiment id"),
            |r: &CycleRow| Value::Str(Some(r.experiment.clone())),
        )
        .col(
            ColumnSpec::new("class", ColType::Utf8, "", "`all`, or the class whose sources are counted (as in evolution.parquet)"),
            |r| Value::Str(Some(r.class.clone())),
        )
        .col(
            ColumnSpec::new("cycle", ColType::Int32, "", "the load cycle, 1-based in time order"),
            |r| Value::I32(Some(r.cycle.index as i32)),
        )
        .col(f("start_s", "s", "where its loading starts: the load series' first value, or the valley of the unloading before"), |r| Value::F64(Some(r.cycle.start_s)))
        .col(f("start_load_n", "N", "the load there"), |r| Value::F64(Some(r.cycle.start_load_n)))
        .col(f("peak_s", "s", "the cycle's peak (before its unloading, or the series' highest value in the last cycle)"), |r| Value::F64(Some(r.cycle.peak_s)))
        .col(f("peak_load_n", "N", "the load there"), |r| Value::F64(Some(r.cycle.peak_load_n)))
        .col(f("previous_max_n", "N", "the highest load before the cycle's loading began (null: the first cycle)").nullable(), |r| Value::F64(r.cycle.previous_max_n))
        .col(
            ColumnSpec::new("sources", ColType::Int64, "", "the series' sources in the cycle, loading and unloading"),
            |r| Value::I64(Some(r.sources as i64)),
        )
        .col(f("onset_time_s", "s", "the AE onset while the cycle loads: the time of its [evolution] felicity_onset_sources-th source at or above felicity_onset_db (null: none before the peak)").nullable(), |r| Value::F64(r.onset_time_s))
        .col(f("onset_load_n", "N", "the load at the onset").nullable(), |r| Value::F64(r.onset_load_n))
        .col(f("felicity_ratio", "1", "onset_load_n / previous_max_n (null: the first cycle, or no onset)").nullable(), |r| Value::F64(r.felicity_ratio))
        .col(
            ColumnSpec::new("kaiser", ColType::Bool, "", "whether the Kaiser effect held: felicity_ratio ≥ [evolution] kaiser_min_ratio, or no onset before the peak (null: the first cycle, or an onset whose load is unknown)").nullable(),
            |r| Value::Bool(r.kaiser),
        )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> CycleParams {
        CycleParams {
            drop_fraction: 0.1,
            onset_sources: 1,
            onset_db: 0.0,
            kaiser_min_ratio: 1.0,
        }
    }

    /// Piecewise-linear load through the corners, sampled every `dt`, with Gaussian noise.
    fn series(corners: &[(f64, f64)], dt: f64, noise: f64, seed: u64) -> Vec<(f64, f64)> {
        let mut rng = crate::util::Rng::new(seed);
        let end = corners.last().unwrap().0;
        let n = (end / dt).round() as usize;
        (0..=n)
            .map(|k| {
                let t = k as f64 * dt;
                let j = corners.iter().rposition(|c| c.0 <= t).unwrap();
                let (t0, l0) = corners[j];
                let l = match corners.get(j + 1) {
                    Some(&(t1, l1)) => l0 + (l1 - l0) * (t - t0) / (t1 - t0),
                    None => l0,
                };
                (t, l + noise * rng.normal())
            })
            .collect()
    }

    fn find(s: &[(f64, f64)]) -> Vec<Cycle> {
        let mut check = LoadCheck::new();
        s.iter().for_each(|&(_, l)| check.push(l));
        let Some(mut f) = CycleFinder::new(&check, 1.0, &params()) else {
            return vec![];
        };
        s.iter().for_each(|&(t, l)| f.push(t, l));
        f.cycles()
    }

    /// Three cycles to 20, 40 and 60 N, unloading to 2 N, the last to a break: their
    /// corners, found to the sample in a noisy series.
    #[test]
    fn cycles_of_a_load_unload_reload_test() {
        let corners = [
            (0.0, 0.0),
            (10.0, 20.0),
            (15.0, 2.0),
            (30.0, 40.0),
            (35.0, 2.0),
            (55.0, 60.0),
            (56.0, 0.0),
            (60.0, 0.0),
        ];
        let s = series(&corners, 0.1, 0.05, 3);
        let c = find(&s);
        assert_eq!(c.len(), 3, "{c:?}");
        for (got, (start, peak, prev)) in c.iter().zip([
            ((0.0, 0.0), (10.0, 20.0), None),
            ((15.0, 2.0), (30.0, 40.0), Some(20.0)),
            ((35.0, 2.0), (55.0, 60.0), Some(40.0)),
        ]) {
            // A noisy corner is found within a few samples of its place and 0.2 N of its load.
            assert!((got.start_s - start.0).abs() <= 0.5, "{got:?}");
            assert!((got.start_load_n - start.1).abs() <= 0.2, "{got:?}");
            assert!((got.peak_s - peak.0).abs() <= 0.5, "{got:?}");
            assert!((got.peak_load_n - peak.1).abs() <= 0.2, "{got:?}");
            match (got.previous_max_n, prev) {
                (Some(a), Some(b)) => assert!((a - b).abs() <= 0.2, "{got:?}"),
                (a, b) => assert_eq!(a.is_some(), b.is_some()),
            }
        }
        // A monotonic test to a break is one cycle; noise alone is none.
        let mono = series(
            &[(0.0, 0.0), (50.0, 60.0), (51.0, 0.0), (60.0, 0.0)],
            0.1,
            0.05,
            4,
        );
        assert_eq!(find(&mono).len(), 1);
        let noise = series(&[(0.0, 0.0), (60.0, 0.0)], 0.1, 0.3, 5);
        assert!(find(&noise).is_empty());
        // A small wobble (below 10 % of the span) in a ramp is no unloading.
        let wobble = series(
            &[(0.0, 0.0), (20.0, 30.0), (21.0, 27.0), (40.0, 60.0)],
            0.1,
            0.05,
            6,
        );
        assert_eq!(find(&wobble).len(), 1);
    }

    fn cycle(index: u32, start_s: f64, peak_s: f64, peak: f64, prev: Option<f64>) -> Cycle {
        Cycle {
            index,
            start_s,
            start_load_n: 0.0,
            peak_s,
            peak_load_n: peak,
            previous_max_n: prev,
        }
    }

    /// Felicity and Kaiser by hand: cycle 2 resumes at 36 N of a previous 40 N (FR 0.9),
    /// cycle 3 only past its previous 50 N (FR 1.04), cycle 4 not at all.
    #[test]
    fn felicity_and_kaiser_by_hand() {
        let cycles = [
            cycle(1, 0.0, 10.0, 40.0, None),
            cycle(2, 15.0, 25.0, 50.0, Some(40.0)),
            cycle(3, 30.0, 40.0, 60.0, Some(50.0)),
            cycle(4, 45.0, 55.0, 55.0, Some(60.0)),
        ];
        let p = CycleParams {
            onset_sources: 2,
            onset_db: 40.0,
            ..params()
        };
        let mut f = Felicity::new("e", "all", &cycles, &p);
        // (time, load, dB): cycle 1: one source while loading, one after its peak (one
        // short of an onset); cycle 2: a quiet source (35 dB) that does not count, the
        // onset's two at 30 and 36 N, one on the unloading; cycle 3: two while loading, at
        // 52 and 53 N; cycle 4: one after its peak.
        let sources = [
            (5.0, 20.0, 50.0),
            (14.0, 10.0, 60.0),
            (16.0, 20.0, 35.0),
            (18.0, 30.0, 45.0),
            (20.0, 36.0, 45.0),
            (27.0, 30.0, 60.0),
            (36.0, 52.0, 50.0),
            (37.0, 53.0, 50.0),
            (57.0, 20.0, 60.0),
        ];
        let at: Vec<AtSource> = sources
            .iter()
            .map(|&(t, l, a)| f.step(Some(t), Some(l), Some(a)))
            .collect();
        let cyc: Vec<Option<u32>> = at.iter().map(|a| a.cycle).collect();
        assert_eq!(
            cyc,
            [1, 1, 2, 2, 2, 2, 3, 3, 4].map(Some).to_vec(),
            "each source in its cycle"
        );
        assert_eq!(at[4].felicity_ratio, Some(36.0 / 40.0));
        assert_eq!(at[4].kaiser, Some(false));
        assert_eq!(at[7].felicity_ratio, Some(53.0 / 50.0));
        assert_eq!(at[7].kaiser, Some(true));
        let onsets = at.iter().filter(|a| a.felicity_ratio.is_some()).count();
        assert_eq!(onsets, 2, "only onset rows carry a ratio");
        let rows = f.finish();
        assert_eq!(rows.len(), 4);
        assert_eq!(
            rows[0].kaiser, None,
            "a first loading has nothing to remember"
        );
        assert_eq!(rows[0].onset_load_n, None);
        assert_eq!(rows[1].sources, 4);
        assert_eq!(rows[1].onset_time_s, Some(20.0));
        assert_eq!(rows[2].felicity_ratio, Some(53.0 / 50.0));
        // Cycle 4: its only source comes after its peak: no onset, the effect holds.
        assert_eq!((rows[3].felicity_ratio, rows[3].kaiser), (None, Some(true)));
        assert_eq!(rows[3].sources, 1);
    }
}
