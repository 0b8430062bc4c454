//! `aepipe thesis`: the thesis's computed results by one command, each beside the thesis's
//! own value, with the tolerance and a verdict. The entries are declared once, in
//! [`ENTRIES`]: each names its thesis section, runs what the thesis ran (a scenario or a
//! sweep), writes its figure (PNG) and data (Parquet) into `OUT/<id>/`, and compares one
//! number. `docs/thesis.md` is the reproduction record; a test checks that every entry it
//! names is declared here.
//!
//! The first entries are the simulator's (ch. 3–4 and §6.2); the rest of the record
//! (`docs/thesis.md`) says what is not yet an entry.

mod damage;
mod ensemble;
mod field;
mod spring;
mod tension;

use crate::sim::scenario::{parse_sweep, Params};
use crate::sim::{SimJob, SimOptions};
use std::path::{Path, PathBuf};

/// Why an entry could not be run.
#[derive(Debug, thiserror::Error)]
pub enum ThesisError {
    #[error("unknown entry {0:?}; known: {1}")]
    Unknown(String, String),
    #[error(transparent)]
    Sim(#[from] crate::sim::SimError),
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
    #[error("{id}: {message}")]
    Measure { id: &'static str, message: String },
}

impl crate::util::HasKind for ThesisError {
    fn kind(&self) -> crate::util::ErrorKind {
        match self {
            ThesisError::Unknown(..) => crate::util::ErrorKind::Usage,
            ThesisError::Sim(e) => e.kind(),
            ThesisError::Plot(e) => e.kind(),
            ThesisError::Measure { .. } => crate::util::ErrorKind::Failed,
        }
    }
}

/// One computed result of the thesis.
#[derive(Debug, Clone, Copy)]
pub struct Entry {
    /// `fig-3.14`, `table-3.8`, …: the contract of `aepipe thesis ID`.
    pub id: &'static str,
    /// Where the thesis has it.
    pub section: &'static str,
    /// What is compared, and its unit.
    pub compared: &'static str,
    /// The thesis's value, in that unit.
    pub thesis: f64,
    /// Relative tolerance of the verdict.
    pub tolerance: f64,
    /// What runs.
    pub how: How,
    /// What the verdict rests on that the reader must know, printed under it (the record,
    /// docs/thesis.md, says it at length).
    pub caveat: Option<&'static str>,
}

/// How an entry is computed.
#[derive(Debug, Clone, Copy)]
pub enum How {
    /// A scenario swept as `aepipe simulate --sweep` runs it.
    Sweep {
        /// The scenario, its parameters and its sweep (`key=LO..HI[:STEP]`).
        scenario: &'static str,
        params: &'static [(&'static str, f64)],
        sweep: &'static str,
        /// Node trajectories kept (a model without a grid is measured from its nodes).
        trajectories: bool,
        /// The number aepipe compares, from the sweep's table.
        measure: fn(&crate::sim::sweep::SweepTable) -> Option<f64>,
    },
    /// Its own computation, which writes its figure and data into the folder it is given
    /// and returns the number compared ([`field`]).
    Own(fn(&Path) -> Result<f64, ThesisError>),
}

/// Every entry, in the thesis's order.
pub const ENTRIES: &[Entry] = &[
    Entry {
        id: "fig-3.4",
        section: "§3.2.7, Fig. 3.4c, Table 3.1",
        compared: "the SHO by implicit Euler at Δt = 0.01 s: decay rate of its oscillation's energy (1/s), against the scheme's own ln(1 + ω²Δt²)/Δt with Table 3.1's ω² = 2k(1 − L/l)/m",
        thesis: 0.054530,
        tolerance: 0.02,
        how: How::Own(tension::fig_3_4),
        caveat: None,
    },
    Entry {
        id: "fig-3.14",
        section: "§3.2.9, Fig. 3.14",
        compared: "γ of the plucked paper fibre, implicit Euler at Δt = 4.5e-8 s, b = 0 (1/s)",
        thesis: 5.0e4,
        tolerance: 0.15,
        how: How::Sweep {
            scenario: "paper-fibre",
            params: &[("grid", 0.0), ("damping", 0.0)],
            sweep: "dt=1.5e-8..4.5e-8:1e-8",
            trajectories: true,
            measure:     |t| gamma_at(t, 4.5e-8),
        },
        caveat: None,
    },
    Entry {
        id: "fig-3.23",
        section: "§3.3.5, Fig. 3.23",
        compared: "quadrupole pulse (two opposite dipoles) heard on a ring 3 wavelengths out: correlation of its amplitude with the analytic |sin 2θ| (1: the four lobes exactly)",
        thesis: 1.0,
        tolerance: 0.03,
        how: How::Own(field::fig_3_23),
        caveat: None,
    },
    Entry {
        id: "fig-3.27",
        section: "§3.3.6, Fig. 3.27",
        compared: "continuous dipole, settled, 6 m out on its axis: share of the pressure's power a sine at the drive's frequency explains (1: \"sinusoidal without any significant high frequency component\")",
        thesis: 1.0,
        tolerance: 0.01,
        how: How::Own(field::fig_3_27),
        caveat: None,
    },
    Entry {
        id: "table-3.8",
        section: "§3.5.3, Table 3.8 (§4.4)",
        compared: "fundamental of the plucked paper fibre (kHz)",
        thesis: 253.91,
        tolerance: 0.05,
        how: How::Sweep {
            scenario: "paper-fibre",
            params: &[("grid", 0.0), ("damping", 0.0), ("amplitude", 1e-6)],
            sweep: "stretch=0.01..0.01:0.01",
            trajectories: true,
            measure:     |t| first(t).map(|r| r.dominant_frequency_hz / 1e3),
        },
        caveat: None,
    },
    Entry {
        id: "fig-3.31",
        section: "§3.5.2, Figs. 3.31–3.32",
        compared: "fundamental of the plucked rubber band (Hz)",
        thesis: 189.21,
        tolerance: 0.03,
        how: How::Sweep {
            scenario: "rubber-band",
            params: &[],
            sweep: "damping=7e-4..7e-4:1e-4",
            trajectories: true,
            measure:     |t| first(t).map(|r| r.dominant_frequency_hz),
        },
        caveat: None,
    },
    Entry {
        id: "eq-3.5.2",
        section: "§3.5.2, Eqs. 3.5.1–3.5.2",
        compared: "α = γ/b of the plucked rubber band at b = 5.5e-4 kg/s (1/kg)",
        thesis: 3.15e4,
        tolerance: 0.10,
        how: How::Sweep {
            scenario: "rubber-band",
            params: &[],
            sweep: "damping=5.5e-4..5.5e-4:1e-4",
            trajectories: true,
            measure:     |t| {
                first(t).and_then(|r| {
                    r.decay
                        .as_ref()
                        .and_then(|d| r.damping_kg_s.and_then(|b| d.alpha_per_kg(b)))
                })
            },
        },
        caveat: None,
    },
    Entry {
        id: "fig-4.10",
        section: "§4.5.3, Fig. 4.10",
        compared: "bond failure (1) in the 3×3 mesh, sensor 1, dominant (kHz)",
        thesis: 250.0,
        tolerance: 0.10,
        how: How::Sweep {
            scenario: "mesh3x3-bond-failure",
            params: &[("t2", -1.0)],
            sweep: "kink=1e-5..1e-5:1e-5",
            trajectories: false,
            measure:     |t| at_sensor(t, 1, 1e-5).map(|f| f / 1e3),
        },
        caveat: None,
    },
    Entry {
        id: "fig-4.12",
        section: "§4.5.4, Fig. 4.12",
        compared: "CWT of the ensemble-average bond failure (the mesh's bond failure (1) over E ×0.9…×1.1, sensor 1): its upper dominant component, the strongest peak above 500 kHz of |W|² summed over time (kHz)",
        thesis: 750.0,
        tolerance: 0.10,
        how: How::Own(ensemble::fig_4_12),
        caveat: None,
    },
    Entry {
        id: "fig-4.17",
        section: "§4.5.5, Fig. 4.17",
        compared: "plucked fibre at 0.6 % extension, sensor 1 (kHz; the thesis's line F = 1.27e7·x + 115.21)",
        thesis: 191.41,
        tolerance: 0.05,
        how: How::Sweep {
            scenario: "paper-fibre",
            params: &[],
            sweep: "stretch=0.002..0.010:0.002",
            trajectories: false,
            measure:     |t| at_sensor(t, 1, 0.006).map(|f| f / 1e3),
        },
        caveat: None,
    },
    Entry {
        id: "eq-4.5.6",
        section: "§4.5.5, Eq. 4.5.6, Tables 4.2–4.3, Fig. 4.18",
        compared: "Eq. 4.5.6b: Pearson's r of the 200–300 kHz power ratio against AE number, over 8 random sequences of the 9 bond failures of Fig. 4.8's mesh, each simulated in what the earlier ones left (the thesis's Table 4.2, one paper test; the verdict asks the same sign, at most twice as strong; Eq. 4.5.6a's 700–800 kHz r is in trends.parquet)",
        thesis: 0.19,
        tolerance: 1.0,
        how: How::Own(damage::eq_4_5_6),
        caveat: None,
    },
    Entry {
        id: "fig-4.20",
        section: "§4.6.1, Fig. 4.20, Eq. 4.6.1",
        compared: "a broken fibre as Fig. 3.1's mass on a spring, free length 0.5 mm, paper (Table 4.1), m the free length's mass: simulated (kHz) against Eq. 4.6.1",
        thesis: 1537.6,
        tolerance: 0.01,
        how: How::Own(spring::fig_4_20),
        caveat: None,
    },
    Entry {
        id: "fig-4.26",
        section: "§4.6.3, Fig. 4.26",
        compared: "fibre failure at break point 1, 36 µm grid, sensor 1 (kHz)",
        thesis: 800.0,
        tolerance: 0.10,
        how: How::Sweep {
            scenario: "structure2x1-fibre-failure",
            params: &[("grid_um", 36.0)],
            sweep: "point=1..1",
            trajectories: false,
            measure:     |t| at_sensor(t, 1, 1.0).map(|f| f / 1e3),
        },
        caveat: None,
    },
    Entry {
        id: "fig-4.27",
        section: "§4.6.3, Fig. 4.27",
        compared: "fibre failure at break point 12, 36 µm grid, sensor 1 (kHz)",
        thesis: 1750.0,
        tolerance: 0.10,
        how: How::Sweep {
            scenario: "structure2x1-fibre-failure",
            params: &[("grid_um", 36.0)],
            sweep: "point=12..12",
            trajectories: false,
            measure:     |t| at_sensor(t, 1, 12.0).map(|f| f / 1e3),
        },
        caveat: None,
    },
    Entry {
        id: "fig-4.28",
        section: "§4.6.3, Fig. 4.28",
        compared: "fibre failure at break point 7, 36 µm grid, sensor 1 (kHz)",
        thesis: 1250.0,
        tolerance: 0.10,
        how: How::Sweep {
            scenario: "structure2x1-fibre-failure",
            params: &[("grid_um", 36.0)],
            sweep: "point=7..7",
            trajectories: false,
            measure:     |t| at_sensor(t, 1, 7.0).map(|f| f / 1e3),
        },
        caveat: None,
    },
];

/// Write an entry's data to `path`: float64 columns (name, unit, meaning), a row per item.
fn write_floats<const N: usize>(
    path: &Path,
    table: &str,
    columns: [(&str, &str, &str); N],
    rows: impl IntoIterator<Item = [f64; N]>,
) -> Result<(), ThesisError> {
    use crate::store::{ColType, ColumnSpec, Table, Value};
    let mut t: Table<[f64; N]> = Table::new(table);
    for (k, (name, unit, doc)) in columns.into_iter().enumerate() {
        t = t.col(
            ColumnSpec::new(name, ColType::Float64, unit, doc),
            move |r: &[f64; N]| Value::F64(Some(r[k])),
        );
    }
    t.write_all(path, &[], 4096, rows)
        .map_err(|e| crate::sim::SimError::Io(e.to_string()))?;
    Ok(())
}

/// The first row of the table.
fn first(t: &crate::sim::sweep::SweepTable) -> Option<&crate::sim::sweep::SweepRow> {
    t.rows.first()
}

/// The dominant frequency at `sensor` of the run whose (first) swept value is `value`.
fn at_sensor(t: &crate::sim::sweep::SweepTable, sensor: u32, value: f64) -> Option<f64> {
    t.rows
        .iter()
        .find(|r| r.sensor == sensor && (r.values[0] - value).abs() <= 1e-9 * value.abs())
        .map(|r| r.dominant_frequency_hz)
}

/// γ of the run whose swept value is `value`.
fn gamma_at(t: &crate::sim::sweep::SweepTable, value: f64) -> Option<f64> {
    t.rows
        .iter()
        .find(|r| (r.values[0] - value).abs() <= 1e-9 * value.abs())
        .and_then(|r| r.decay.as_ref().map(|d| d.gamma_hz))
}

/// What an entry gave.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub entry: Entry,
    pub aepipe: f64,
    /// aepipe / thesis − 1.
    pub deviation: f64,
    pub pass: bool,
    pub dir: PathBuf,
    pub seconds: f64,
}

/// The entries named (all for none), in declared order; an unknown id is refused before
/// anything runs.
pub fn select(ids: &[String]) -> Result<Vec<Entry>, ThesisError> {
    for id in ids {
        if !ENTRIES.iter().any(|e| e.id == id) {
            let known: Vec<&str> = ENTRIES.iter().map(|e| e.id).collect();
            return Err(ThesisError::Unknown(id.clone(), known.join(", ")));
        }
    }
    Ok(ENTRIES
        .iter()
        .filter(|e| ids.is_empty() || ids.iter().any(|i| i == e.id))
        .copied()
        .collect())
}

/// Run one entry into `out/<id>/`: the simulation's tables, `sweep.parquet`, `sweep.png`
/// and `envelopes.png`, and the comparison.
pub fn run(e: &Entry, out: &Path) -> Result<Outcome, ThesisError> {
    let t0 = std::time::Instant::now();
    let dir = out.join(e.id);
    let aepipe = match e.how {
        How::Own(f) => {
            std::fs::create_dir_all(&dir)
                .map_err(|x| crate::sim::SimError::Io(format!("{}: {x}", dir.display())))?;
            f(&dir)?
        }
        How::Sweep {
            scenario,
            params,
            sweep,
            trajectories,
            measure,
        } => swept(e.id, &dir, scenario, params, sweep, trajectories, measure)?,
    };
    let deviation = aepipe / e.thesis - 1.0;
    Ok(Outcome {
        entry: *e,
        aepipe,
        deviation,
        pass: deviation.abs() <= e.tolerance,
        dir,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// A scenario swept into `dir` (its tables, `sweep.parquet`, `sweep.png`, `envelopes.png`),
/// and the number measured from the sweep's table.
fn swept(
    id: &'static str,
    dir: &Path,
    scenario: &str,
    params: &[(&str, f64)],
    sweep: &str,
    trajectories: bool,
    measure: fn(&crate::sim::sweep::SweepTable) -> Option<f64>,
) -> Result<f64, ThesisError> {
    let job = SimJob {
        model: None,
        scenario: Some(scenario.to_string()),
        params: Params(params.iter().map(|(k, v)| (k.to_string(), *v)).collect()),
        sweep: vec![parse_sweep(sweep)?],
        solver: None,
        out: dir.to_path_buf(),
        run: SimOptions {
            trajectory_every: trajectories.then_some(1),
            snapshot_every: None,
        },
        acquisition: Default::default(),
    };
    let rep = crate::sim::run_job(&job)?;
    let table = rep.sweep.ok_or_else(|| ThesisError::Measure {
        id,
        message: "the run wrote no sweep table".into(),
    })?;
    crate::plot::sim::sweep_png(&dir.join("sweep.png"), &table)?;
    crate::plot::sim::envelopes_png(&dir.join("envelopes.png"), &table)?;
    measure(&table).ok_or_else(|| ThesisError::Measure {
        id,
        message: "the compared value is not in the run's table".into(),
    })
}
