//! Whether the reference signals have converged (issue 51): each reference of the embedded
//! library (its scenarios' parameter points at Table 4.1's mean material, heard at the
//! library's sensors) simulated at three acoustic grid spacings, three mass/spring time
//! steps and, where the scenario has them, fibre splits 1/2/3 — one axis at a time from the
//! library's resolution — and measured as the library's features see it: the band-limited
//! pressure's dominant frequency and Eq. 4.5.4's 25 power ratios (100 kHz bands, 0–2.5 MHz).
//!
//! Along each axis the resolution to use is the coarsest whose every reference lies within
//! 5 % (dominant frequency) and 0.02 (each ratio, absolute) of the next finer one; where no
//! step of the axis holds, the axis has not converged within this machine's means, and the
//! table says so instead of choosing.

use super::reference::ReferenceFile;
use super::scenario::{self, Params};
use super::SimError;
use rayon::prelude::*;

/// Tolerances of "converged": relative, on the dominant frequency.
pub const FREQ_TOL: f64 = 0.05;
/// Absolute, on each power ratio.
pub const RATIO_TOL: f64 = 0.02;
/// Power-ratio bands (Eq. 4.5.4): 25 of 100 kHz.
const BANDS: usize = super::output::POWER_BANDS;

/// What is refined.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    Grid,
    Step,
    Split,
}

impl Axis {
    pub fn name(self) -> &'static str {
        match self {
            Axis::Grid => "grid",
            Axis::Step => "time step",
            Axis::Split => "fibre split",
        }
    }
}

/// One resolution: the library's (72 µm, 10 ns, split 1) or it with one axis refined.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Resolution {
    pub grid_um: f64,
    pub dt_s: f64,
    pub split: u32,
}

/// The library's resolution: Appendix A's grid and step, its fibre as drawn.
pub const BASE: Resolution = Resolution {
    grid_um: 72.0,
    dt_s: 1e-8,
    split: 1,
};

impl Resolution {
    /// The axis this resolution refines (None: the library's own, where every axis starts).
    pub fn axis(&self) -> Option<Axis> {
        if self.grid_um != BASE.grid_um {
            Some(Axis::Grid)
        } else if self.dt_s != BASE.dt_s {
            Some(Axis::Step)
        } else if self.split != BASE.split {
            Some(Axis::Split)
        } else {
            None
        }
    }

    /// "72 µm", "5 ns", "split 2": the value `axis` reads.
    fn label(&self, axis: Axis) -> String {
        match axis {
            Axis::Grid => format!("{} µm", self.grid_um),
            Axis::Step => format!("{} ns", self.dt_s * 1e9),
            Axis::Split => format!("split {}", self.split),
        }
    }
}

/// Each axis's three resolutions, coarsest first (the first is the library's).
pub fn axes() -> Vec<(Axis, [Resolution; 3])> {
    // (grid µm, step s, split) of each axis's three.
    let axis = |axis, points: [(f64, f64, u32); 3]| {
        (
            axis,
            points.map(|(grid_um, dt_s, split)| Resolution {
                grid_um,
                dt_s,
                split,
            }),
        )
    };
    let (g, dt, k) = (BASE.grid_um, BASE.dt_s, BASE.split);
    vec![
        axis(Axis::Grid, [(g, dt, k), (48.0, dt, k), (36.0, dt, k)]),
        axis(Axis::Step, [(g, dt, k), (g, 5e-9, k), (g, 2.5e-9, k)]),
        axis(Axis::Split, [(g, dt, k), (g, dt, 2), (g, dt, 3)]),
    ]
}

/// One reference signal at one resolution.
#[derive(Debug, Clone)]
pub struct Measured {
    pub scenario: String,
    /// The reference's parameters (JSON), without the resolution's.
    pub params: String,
    /// 1-based, the library's sensor order.
    pub sensor: u32,
    pub res: Resolution,
    pub dominant_hz: f64,
    pub ratios: [f64; BANDS],
    /// The run's wall time (all its sensors), s.
    pub run_s: f64,
}

/// One axis step for one scenario: resolution `k` against `k + 1` over its references.
#[derive(Debug, Clone)]
pub struct Step {
    pub axis: Axis,
    pub scenario: String,
    pub coarse: Resolution,
    pub fine: Resolution,
    /// References (parameter point × sensor) compared; those whose dominant frequency, whose
    /// every ratio, and whose both are within tolerance.
    pub compared: usize,
    pub freq_within: usize,
    pub ratios_within: usize,
    pub within: usize,
    pub worst_freq: f64,
    pub worst_ratio: f64,
    /// The reference with the worst frequency change: "{params} sensor s".
    pub worst_at: String,
}

/// Per axis: the resolution chosen (None: not converged) and each resolution's run time, s.
pub type Chosen = (Axis, Option<Resolution>, [f64; 3]);

/// The whole measurement.
#[derive(Debug, Clone)]
pub struct Convergence {
    pub rows: Vec<Measured>,
    pub steps: Vec<Step>,
    /// Each axis: the coarsest resolution that holds (None: not converged) and, per
    /// resolution, the wall time of all its runs.
    pub chosen: Vec<Chosen>,
    /// Scenarios an axis could not refine (the mesh has no split), by axis.
    pub skipped: Vec<(Axis, String)>,
}

/// Whether a scenario can be refined along `axis`.
fn refinable(name: &str, axis: Axis) -> bool {
    match axis {
        Axis::Split => name == "structure2x1-fibre-failure",
        _ => true,
    }
}

/// The library's references: each scenario's parameter points at the mean material (no
/// draws), with the resolution's keys replaced.
fn references(f: &ReferenceFile) -> Vec<(String, Vec<(String, f64)>)> {
    let mut cfg = f.reference.clone();
    cfg.variants = 1;
    cfg.material_spread = 0.0;
    super::reference::expand(&cfg)
        .into_iter()
        .map(|(name, p, _)| (name, p.0))
        .collect()
}

/// Run one reference at one resolution; its sensors' features.
fn measure(
    f: &ReferenceFile,
    name: &str,
    base: &[(String, f64)],
    res: Resolution,
) -> Result<Vec<Measured>, SimError> {
    let mut kv: Vec<(String, f64)> = base
        .iter()
        .filter(|(k, _)| k != "e_scale" && k != "t_scale" && k != "w_scale")
        .cloned()
        .collect();
    let shown = Params(kv.clone()).to_json();
    // The run lasts as long at every step: the library's steps at its step, scaled.
    let iterations = kv
        .iter()
        .find(|(k, _)| k == "iterations")
        .map_or(4000.0, |(_, v)| *v);
    kv.retain(|(k, _)| k != "iterations");
    kv.push((
        "iterations".into(),
        (iterations * BASE.dt_s / res.dt_s).round(),
    ));
    match res.axis() {
        Some(Axis::Step) => kv.push(("dt".into(), res.dt_s)),
        Some(Axis::Grid) => kv.push(("grid_um".into(), res.grid_um)),
        Some(Axis::Split) => kv.push(("split".into(), res.split as f64)),
        None => {}
    }
    let mut m = scenario::build(name, &Params(kv))?;
    let g = m
        .grid
        .clone()
        .ok_or_else(|| SimError::Model(format!("{name}: a reference without a grid")))?;
    m.sensors = super::reference::library_sensors(&f.reference.sensors, &g);
    m.check()?;
    let t0 = std::time::Instant::now();
    let out = super::simulate(&m, &Default::default())?;
    let run_s = t0.elapsed().as_secs_f64();
    let fs = out.sample_rate_hz;
    Ok(out
        .sensors
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let p = super::output::band_limited(s, &g);
            Measured {
                scenario: name.to_string(),
                params: shown.clone(),
                sensor: k as u32 + 1,
                res,
                dominant_hz: super::dominant_frequency(&p, fs),
                // A silent signal has no ratios: zeros, as Eq. 4.5.4's reader leaves them.
                ratios: super::output::power_ratios(&p, fs).unwrap_or([0.0; BANDS]),
                run_s,
            }
        })
        .collect())
}

/// Measure every reference of `f` at every resolution (in parallel on the current pool).
pub fn convergence(f: &ReferenceFile) -> Result<Convergence, SimError> {
    let refs = references(f);
    let axes = axes();
    // Each (reference, resolution) once: the library's resolution starts every axis.
    let mut jobs: Vec<(usize, Resolution)> = Vec::new();
    let mut skipped = Vec::new();
    for (axis, res) in &axes {
        for (r, (name, _)) in refs.iter().enumerate() {
            if !refinable(name, *axis) {
                if !skipped.contains(&(*axis, name.clone())) {
                    skipped.push((*axis, name.clone()));
                }
                continue;
            }
            for res in res {
                if !jobs.contains(&(r, *res)) {
                    jobs.push((r, *res));
                }
            }
        }
    }
    let done: Vec<Vec<Measured>> = jobs
        .par_iter()
        .map(|&(r, res)| measure(f, &refs[r].0, &refs[r].1, res))
        .collect::<Result<_, _>>()?;
    let rows: Vec<Measured> = done.into_iter().flatten().collect();
    let (steps, chosen) = compare(&rows, &axes);
    Ok(Convergence {
        rows,
        steps,
        chosen,
        skipped,
    })
}

/// Each axis step per scenario, and per axis the coarsest resolution at which every
/// reference of every scenario refined along it is within both tolerances of the next finer
/// (None: no step holds), with each resolution's total run time over those scenarios.
pub fn compare(rows: &[Measured], axes: &[(Axis, [Resolution; 3])]) -> (Vec<Step>, Vec<Chosen>) {
    let key = |m: &Measured| (m.scenario.clone(), m.params.clone(), m.sensor);
    let mut scenarios: Vec<String> = rows.iter().map(|m| m.scenario.clone()).collect();
    scenarios.dedup();
    scenarios.sort();
    scenarios.dedup();
    let mut steps = Vec::new();
    let mut chosen = Vec::new();
    for (axis, res) in axes {
        let at = |k: usize, sc: Option<&str>| {
            rows.iter()
                .filter(|m| {
                    m.res == res[k]
                        && refinable(&m.scenario, *axis)
                        && sc.is_none_or(|s| m.scenario == s)
                })
                .collect::<Vec<&Measured>>()
        };
        let cost: [f64; 3] = std::array::from_fn(|k| {
            // Each run's time once (its sensors share it).
            let mut seen = std::collections::BTreeSet::new();
            at(k, None)
                .iter()
                .filter(|m| seen.insert((m.scenario.clone(), m.params.clone())))
                .map(|m| m.run_s)
                .sum()
        });
        let mut holds = [true, true];
        let mut any = [false, false];
        for sc in &scenarios {
            for (k, h) in holds.iter_mut().enumerate() {
                let (coarse, fine) = (at(k, Some(sc)), at(k + 1, Some(sc)));
                let mut s = Step {
                    axis: *axis,
                    scenario: sc.clone(),
                    coarse: res[k],
                    fine: res[k + 1],
                    compared: 0,
                    freq_within: 0,
                    ratios_within: 0,
                    within: 0,
                    worst_freq: 0.0,
                    worst_ratio: 0.0,
                    worst_at: String::new(),
                };
                for c in &coarse {
                    let Some(fm) = fine.iter().find(|m| key(m) == key(c)) else {
                        continue;
                    };
                    let df = (c.dominant_hz / fm.dominant_hz - 1.0).abs();
                    let dr = c
                        .ratios
                        .iter()
                        .zip(&fm.ratios)
                        .fold(0.0f64, |w, (a, b)| w.max((a - b).abs()));
                    s.compared += 1;
                    s.freq_within += usize::from(df <= FREQ_TOL);
                    s.ratios_within += usize::from(dr <= RATIO_TOL);
                    s.within += usize::from(df <= FREQ_TOL && dr <= RATIO_TOL);
                    if s.worst_at.is_empty() || df > s.worst_freq {
                        s.worst_freq = df;
                        s.worst_at = format!("{} sensor {}", c.params, c.sensor);
                    }
                    s.worst_ratio = s.worst_ratio.max(dr);
                }
                if s.compared > 0 {
                    any[k] = true;
                    *h &= s.within == s.compared;
                    steps.push(s);
                }
            }
        }
        let pick = (0..2).find(|&k| any[k] && holds[k]).map(|k| res[k]);
        chosen.push((*axis, pick, cost));
    }
    (steps, chosen)
}

/// Write every measurement to `path` (`convergence.parquet`, a row per reference, sensor and
/// resolution).
pub fn write(path: &std::path::Path, c: &Convergence) -> Result<u64, SimError> {
    table()
        .write_all(path, &[], 4096, c.rows.iter().cloned())
        .map_err(|e| SimError::Io(e.to_string()))
}

/// `convergence.parquet`'s columns (data-schema/sim_convergence.md).
pub fn table() -> crate::store::Table<Measured> {
    use crate::store::{ColType, ColumnSpec, Table, Value};
    let s = |name: &str, doc: &str| ColumnSpec::new(name, ColType::Utf8, "", doc);
    let f = |name: &str, unit: &str, doc: &str| ColumnSpec::new(name, ColType::Float64, unit, doc);
    let mut t: Table<Measured> = Table::new("sim_convergence")
        .col(s("scenario", "the reference's scenario"), |m: &Measured| {
            Value::Str(Some(m.scenario.clone()))
        })
        .col(
            s(
                "params",
                "its parameters (JSON), the resolution's keys not included",
            ),
            |m: &Measured| Value::Str(Some(m.params.clone())),
        )
        .col(
            ColumnSpec::new(
                "sensor",
                ColType::Int32,
                "1",
                "the library's sensor, 1-based",
            ),
            |m: &Measured| Value::I32(Some(m.sensor as i32)),
        )
        .col(
            s(
                "axis",
                "what this resolution refines: grid, time step or fibre split; library: the library's own, where every axis starts",
            ),
            |m: &Measured| Value::Str(Some(m.res.axis().map_or("library", Axis::name).into())),
        )
        .col(f("grid_um", "µm", "acoustic cell size"), |m: &Measured| {
            Value::F64(Some(m.res.grid_um))
        })
        .col(f("dt_s", "s", "mass/spring time step"), |m: &Measured| {
            Value::F64(Some(m.res.dt_s))
        })
        .col(
            ColumnSpec::new(
                "split",
                ColType::Int32,
                "1",
                "springs each spring is cut into",
            ),
            |m: &Measured| Value::I32(Some(m.res.split as i32)),
        )
        .col(
            f(
                "dominant_hz",
                "Hz",
                "the band-limited pressure's dominant frequency",
            ),
            |m: &Measured| Value::F64(Some(m.dominant_hz)),
        )
        .col(
            f("run_s", "s", "the run's wall time (all its sensors)"),
            |m: &Measured| Value::F64(Some(m.run_s)),
        );
    for b in 0..BANDS {
        let name = format!("pr_{}_{}khz", b * 100, (b + 1) * 100);
        t = t.col(
            ColumnSpec::new(
                name,
                ColType::Float64,
                "1",
                "Eq. 4.5.4's power ratio of the band",
            ),
            move |m: &Measured| Value::F64(Some(m.ratios[b])),
        );
    }
    t
}

/// The table for the terminal and docs/fidelity.md.
pub fn lines(c: &Convergence) -> Vec<String> {
    let mut l = vec![format!(
        "convergence of the reference library's features (dominant frequency within {:.0} %, each of 25 power ratios within {RATIO_TOL}), one axis at a time from 72 µm, 10 ns, split 1:",
        FREQ_TOL * 100.0
    )];
    for s in &c.steps {
        l.push(format!(
            "  {:<11} {:>9} → {:<9} {:<29} {:>2}/{:<2} within (frequency {:>2}, ratios {:>2}); worst frequency change {:>5.1} % ({}), worst ratio change {:.3}",
            s.axis.name(),
            s.coarse.label(s.axis),
            s.fine.label(s.axis),
            s.scenario,
            s.within,
            s.compared,
            s.freq_within,
            s.ratios_within,
            100.0 * s.worst_freq,
            s.worst_at,
            s.worst_ratio
        ));
    }
    for (axis, pick, cost) in &c.chosen {
        let (_, res) = axes()
            .into_iter()
            .find(|(a, _)| a == axis)
            .expect("an axis");
        let costs = res
            .iter()
            .zip(cost)
            .map(|(r, s)| format!("{} {s:.1} s", r.label(*axis)))
            .collect::<Vec<_>>()
            .join(", ");
        l.push(match pick {
            Some(r) => format!("  {}: converged at {} (run time {costs})", axis.name(), r.label(*axis)),
            None => format!(
                "  {}: NOT converged within 3 resolutions (run time {costs}); no resolution is chosen for it",
                axis.name()
            ),
        });
    }
    for (axis, name) in &c.skipped {
        l.push(format!(
            "  {}: {name} has no such parameter, not refined",
            axis.name()
        ));
    }
    l
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(scenario: &str, sensor: u32, res: Resolution, f: f64, r0: f64) -> Measured {
        let mut ratios = [0.0; BANDS];
        ratios[0] = r0;
        ratios[1] = 1.0 - r0;
        Measured {
            scenario: scenario.into(),
            params: "{}".into(),
            sensor,
            res,
            dominant_hz: f,
            ratios,
            run_s: 1.0,
        }
    }

    #[test]
    fn the_coarsest_resolution_within_both_tolerances_of_the_next_is_chosen_or_none() {
        let axes = axes();
        // Every axis starts from the library's resolution, which refines none.
        assert!(axes.iter().all(|(_, r)| r[0] == BASE));
        assert_eq!(BASE.axis(), None);
        for (axis, r) in &axes {
            assert!(r[1..].iter().all(|x| x.axis() == Some(*axis)), "{axis:?}");
        }
        let grid = axes[0].1;
        // Scenario a: 72 → 48 moves the frequency 6 % (out), 48 → 36 by 1 % (in).
        // Scenario b: both steps within, but its ratio moves 0.03 at 72 → 48.
        let mut rows = vec![
            row("a", 1, grid[0], 1.06e6, 0.5),
            row("a", 1, grid[1], 1.00e6, 0.5),
            row("a", 1, grid[2], 0.99e6, 0.51),
            row("b", 1, grid[0], 2.0e5, 0.53),
            row("b", 1, grid[1], 2.0e5, 0.50),
            row("b", 1, grid[2], 2.0e5, 0.50),
        ];
        let (steps, chosen) = compare(&rows, &axes[..1]);
        assert_eq!(steps.len(), 4);
        let a0 = &steps[0];
        assert_eq!(
            (a0.scenario.as_str(), a0.compared, a0.freq_within),
            ("a", 1, 0)
        );
        assert!((a0.worst_freq - 0.06).abs() < 1e-9, "{a0:?}");
        let b0 = steps
            .iter()
            .find(|s| s.scenario == "b" && s.coarse == grid[0])
            .unwrap();
        assert_eq!((b0.freq_within, b0.ratios_within), (1, 0));
        assert!((b0.worst_ratio - 0.03).abs() < 1e-12);
        // 48 µm holds for both: it is the grid to use.
        assert_eq!(chosen[0].1, Some(grid[1]));
        // Just within the tolerances is within.
        rows[0].dominant_hz = 1.049e6;
        rows[3].ratios[0] = 0.519;
        rows[3].ratios[1] = 0.481;
        let (_, chosen) = compare(&rows, &axes[..1]);
        assert_eq!(chosen[0].1, Some(grid[0]));
        // A second step that fails too: nothing is chosen.
        rows[2].dominant_hz = 0.5e6;
        rows[0].dominant_hz = 1.2e6;
        let (_, chosen) = compare(&rows, &axes[..1]);
        assert_eq!(chosen[0].1, None);
        // Each resolution's cost counts a run once whatever its sensors.
        rows.push(row("a", 2, grid[0], 1.0e6, 0.5));
        let (_, chosen) = compare(&rows, &axes[..1]);
        assert_eq!(chosen[0].2, [2.0, 2.0, 2.0]);
    }
}
