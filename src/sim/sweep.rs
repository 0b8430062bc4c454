//! What a `--sweep` shows: per run and sensor, the swept values, the dominant frequency,
//! the peak and the decay (Eqs. 3.5.1–3.5.2), as `DIR/sweep.parquet`
//! (`data-schema/sim_sweep.md`). Figs. 4.7 and 4.17 (frequency against material and
//! extension) and 3.17–3.18 (the decay against b) are this table drawn
//! (`plot::sim`).

use super::decay::Decay;
use super::SimError;
use crate::store::{self, ColType, ColumnSpec, TableSchema, TableWriter, Value};
use std::path::Path;

/// One run's signal at one sensor (sensor 0: the free node that moves most, for a model
/// without a grid, from its trajectory).
#[derive(Debug, Clone)]
pub struct SweepRow {
    /// The run's number (1-based, as `hit` in `waveforms.parquet`).
    pub hit: u64,
    /// The swept parameters' values, in the order of [`SweepTable::keys`].
    pub values: Vec<f64>,
    /// Every parameter of the run as JSON (`sim_params`).
    pub params: String,
    pub sensor: u32,
    pub dominant_frequency_hz: f64,
    /// Largest |p| (Pa) of the band-limited pressure, or |y − mean| (m) of the node.
    pub peak: f64,
    pub decay: Option<Decay>,
    /// The model's frictional damping b, kg/s (none: the model's damping is not a b, as
    /// the stiff string's α in 1/s).
    pub damping_kg_s: Option<f64>,
    /// Wall time of the run (relaxation and steps), s: Fig. 3.16's run time against Δt.
    pub run_s: f64,
}

/// A sweep's rows, with the swept keys.
#[derive(Debug, Clone, Default)]
pub struct SweepTable {
    pub keys: Vec<String>,
    pub rows: Vec<SweepRow>,
}

impl SweepTable {
    /// An empty table for `sweeps`' keys.
    pub fn of(sweeps: &[super::params::Sweep]) -> SweepTable {
        SweepTable {
            keys: sweeps.iter().map(|s| s.key.clone()).collect(),
            rows: Vec::new(),
        }
    }

    /// The rows of run `hit` (1-based) with the swept `values`: one per place it was heard
    /// ([`super::heard`]), with the model's damping b and the run's wall time.
    pub fn push_run(
        &mut self,
        hit: u64,
        values: Vec<f64>,
        params: &str,
        heard: &[super::Heard],
        (damping_kg_s, run_s): (Option<f64>, f64),
    ) {
        self.rows.extend(heard.iter().map(|h| SweepRow {
            hit,
            values: values.clone(),
            params: params.to_string(),
            sensor: h.sensor,
            dominant_frequency_hz: h.dominant_hz,
            peak: h.peak,
            decay: h.decay.clone(),
            damping_kg_s,
            run_s,
        }));
    }

    /// Write `DIR/sweep.parquet` with its line (and why, when nothing was measured).
    pub fn write_into(&self, dir: &Path, lines: &mut Vec<String>) -> Result<(), SimError> {
        let p = dir.join("sweep.parquet");
        let n = self.write(&p)?;
        lines.push(format!(
            "{n} sweep rows (frequency and decay per run) → {}",
            p.display()
        ));
        if n == 0 {
            lines.push(
                "  (no sensors and no trajectories: a model without a grid is measured from its \
                 nodes; give --trajectories 1)"
                    .into(),
            );
        }
        Ok(())
    }

    /// The table's schema: fixed columns, then one float64 column per swept key.
    pub fn schema(&self) -> TableSchema {
        let f = |n: &str, unit: &str, doc: &str| ColumnSpec::new(n, ColType::Float64, unit, doc);
        let mut columns = vec![
            ColumnSpec::new("hit", ColType::Int64, "", "the run (as `hit` in waveforms.parquet)"),
            ColumnSpec::new("sim_params", ColType::Utf8, "", "every parameter of the run, JSON"),
            ColumnSpec::new(
                "sensor",
                ColType::Int32,
                "",
                "sensor number (1-based); 0: the free node that moves most (a model without a grid)",
            ),
            f("dominant_frequency_hz", "Hz", "dominant frequency of the band-limited pressure (sensor) or of the node's y (zero crossings)"),
            f("peak", "Pa or m", "largest absolute value of the band-limited pressure (Pa), or of the node’s y about its mean (m)"),
            f("run_s", "s", "wall time of the run on the machine that ran it (relaxation and steps)"),
            f("decay_gamma_hz", "1/s", "γ of Eq. 3.5.1 (`sim::decay`)").nullable(),
            f("decay_alpha_per_kg", "1/kg", "α = γ/b of Eq. 3.5.2").nullable(),
            f("decay_fit_r2", "", "R² of the fit of ln(envelope)").nullable(),
            f("damping_kg_s", "kg/s", "the model's frictional damping b; null for a model whose damping is not a b (the stiff string's α, 1/s, is in sim_params)").nullable(),
        ];
        for k in &self.keys {
            // A key named like a fixed column is prefixed rather than shadowing it.
            let name = if columns.iter().any(|c| &c.name == k) {
                format!("swept_{k}")
            } else {
                k.clone()
            };
            columns.push(f(&name, "", "the swept parameter's value in this run"));
        }
        TableSchema {
            name: "sim_sweep".into(),
            columns,
        }
    }

    /// Write `path` (atomic, like every table); the number of rows.
    pub fn write(&self, path: &Path) -> Result<u64, SimError> {
        let io = |e: store::StoreError| SimError::Io(e.to_string());
        let mut w = TableWriter::create(path, self.schema(), &[], 1024).map_err(io)?;
        for r in &self.rows {
            let d = r.decay.as_ref();
            let mut cells = vec![
                Value::I64(Some(r.hit as i64)),
                Value::Str(Some(r.params.clone())),
                Value::I32(Some(r.sensor as i32)),
                Value::F64(Some(r.dominant_frequency_hz)),
                Value::F64(Some(r.peak)),
                Value::F64(Some(r.run_s)),
                Value::F64(d.map(|d| d.gamma_hz)),
                Value::F64(d.and_then(|d| r.damping_kg_s.and_then(|b| d.alpha_per_kg(b)))),
                Value::F64(d.map(|d| d.r2)),
                Value::F64(r.damping_kg_s),
            ];
            cells.extend(r.values.iter().map(|v| Value::F64(Some(*v))));
            w.push(store::Row::new(cells)).map_err(io)?;
        }
        w.finish().map_err(io)
    }
}
