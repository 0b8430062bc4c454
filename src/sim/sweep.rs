//! What a `--sweep` shows: per run and sensor, the swept values, the dominant frequency,
//! the peak and the decay (Eqs. 3.5.1–3.5.2), as `DIR/sweep.parquet`
//! (`data-schema/sim_sweep.md`). Figs. 4.7 and 4.17 (frequency against material and
//! extension) and 3.17–3.18 (the decay against b) are this table drawn
//! (`plot::sim`).

use super::decay::{self, Decay};
use super::model::ModelFile;
use super::{SimError, SimOutput};
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
    /// The rows of run `hit` (1-based) of model `m` with output `out`, the swept `values`,
    /// which took `run_s` seconds.
    pub fn push_run(
        &mut self,
        hit: u64,
        values: Vec<f64>,
        params: &str,
        (m, out): (&ModelFile, &SimOutput),
        run_s: f64,
    ) {
        let row = |sensor: u32, f: f64, peak: f64, decay: Option<Decay>| SweepRow {
            hit,
            values: values.clone(),
            params: params.to_string(),
            sensor,
            dominant_frequency_hz: f,
            peak,
            decay,
            damping_kg_s: Some(m.system.damping),
            run_s,
        };
        if let Some(g) = &m.grid {
            for (k, s) in out.sensors.iter().enumerate() {
                let p = super::output::band_limited(s, g);
                let peak = p.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                let f = super::dominant_frequency(&p, out.sample_rate_hz);
                let d = decay::fit(&p, 1.0 / out.sample_rate_hz, 1.0 / f);
                self.rows.push(row(k as u32 + 1, f, peak, d));
            }
        } else if let Some((node, f, d)) = super::node_frequency(m, out) {
            let y: Vec<f64> = out.trajectory.iter().map(|fr| fr.r[node][1]).collect();
            let mean = y.iter().sum::<f64>() / y.len() as f64;
            let peak = y.iter().fold(0.0f64, |a, v| a.max((v - mean).abs()));
            self.rows.push(row(0, f, peak, d));
        }
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
