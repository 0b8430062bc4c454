//! Simulator output: sensor signals as labelled rows of the canonical waveform table (plus
//! the simulation columns of `data-schema/sim_waveforms.md`), node trajectories, and pressure
//! field snapshots like Fig. 3.24c.

use super::model::ModelFile;
use super::{Frame, SimError, SimOutput};
use crate::store::{self, ColType, ColumnSpec, TableSchema, TableWriter, Value};
use sha2::Digest as _;
use std::path::Path;

/// `waveforms` columns, then the simulation's own.
pub fn sim_waveforms_table() -> TableSchema {
    let mut t = store::waveforms_table();
    t.name = "sim_waveforms".into();
    t.columns.extend([
        ColumnSpec::new(
            "sim_model",
            ColType::Utf8,
            "",
            "scenario name or model file the signal was simulated from",
        ),
        ColumnSpec::new(
            "sim_params",
            ColType::Utf8,
            "",
            "scenario parameters as JSON (`{}` for a model file)",
        ),
        ColumnSpec::new(
            "sensor_x_m",
            ColType::Float64,
            "m",
            "x of the sensor cell's centre",
        ),
        ColumnSpec::new(
            "sensor_y_m",
            ColType::Float64,
            "m",
            "y of the sensor cell's centre",
        ),
        ColumnSpec::new(
            "pressure_scale_v_per_pa",
            ColType::Float64,
            "V/Pa",
            "sensor sensitivity: samples_v = pressure × this",
        ),
        ColumnSpec::new(
            "dominant_frequency_hz",
            ColType::Float64,
            "Hz",
            "peak of the signal's power spectrum",
        ),
    ]);
    t
}

/// Node trajectory table.
pub fn trajectory_table() -> TableSchema {
    TableSchema {
        name: "sim_trajectories".into(),
        columns: vec![
            ColumnSpec::new("t_s", ColType::Float64, "s", "simulation time"),
            ColumnSpec::new(
                "node",
                ColType::Int32,
                "",
                "node index (nodes made by bond failures are numbered after the given ones)",
            ),
            ColumnSpec::new("x_m", ColType::Float64, "m", "position"),
            ColumnSpec::new("y_m", ColType::Float64, "m", "position"),
            ColumnSpec::new("u_m_s", ColType::Float64, "m/s", "velocity, x"),
            ColumnSpec::new("v_m_s", ColType::Float64, "m/s", "velocity, y"),
        ],
    }
}

/// One simulated run to be written.
pub struct Run<'a> {
    pub model: &'a ModelFile,
    pub out: &'a SimOutput,
    /// Scenario name or model path.
    pub source: String,
    /// Scenario parameters as JSON.
    pub params: String,
    /// Hit number of this run in the experiment.
    pub hit: u64,
    pub acq: &'a Acquisition,
}

/// How the simulated sensor records a hit, the way an AE system does: the pressure,
/// band-limited to what the grid carries ([`super::acoustic::band_limit`]), times the
/// sensitivity, plus the electronics' white noise; the record starts `pretrigger` samples
/// before the first sample whose magnitude reaches the threshold, and runs to the end of the
/// simulation. Before the simulation starts (t < 0) the field is silent, so a pretrigger
/// longer than the signal's delay is noise alone, exactly.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Acquisition {
    /// Volts per pascal. The 2-D model's pressure is per unit depth, so its level is not a
    /// physical one: the default puts the reference library's hits at 70–100 dB_AE.
    pub scale_v_per_pa: f64,
    /// Detection threshold, dB_AE (1 µV = 0 dB); recorded in `threshold_v`.
    pub threshold_db: f64,
    /// RMS of the white noise added to every sample, dB_AE (none below −100).
    pub noise_db: f64,
    /// Samples recorded before the trigger (the thesis's records: 500 at 10 MHz).
    pub pretrigger: usize,
    /// Seed of the noise (each signal's noise also depends on its hit and channel).
    pub seed: u64,
}

impl Default for Acquisition {
    fn default() -> Self {
        Acquisition {
            scale_v_per_pa: 3e-5,
            threshold_db: 40.0,
            noise_db: 26.0,
            pretrigger: 500,
            seed: 2008,
        }
    }
}

/// A recorded hit: samples (V), the trigger's index and the threshold.
#[derive(Debug, Clone, PartialEq)]
pub struct Recorded {
    pub samples: Vec<f32>,
    pub pretrigger: usize,
    pub threshold_v: f64,
}

impl Acquisition {
    pub fn threshold_v(&self) -> f64 {
        crate::model::db_to_v(self.threshold_db)
    }

    /// Record a pressure signal (Pa, already band-limited): `None` when it never reaches the
    /// threshold (an AE system records nothing). `key` makes each signal's noise its own.
    pub fn record(&self, pressure: &[f64], key: u64) -> Option<Recorded> {
        let thr = self.threshold_v();
        let sigma = if self.noise_db > -100.0 {
            crate::model::db_to_v(self.noise_db)
        } else {
            0.0
        };
        let mut rng = crate::util::Rng::new(
            self.seed
                .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                .wrapping_add(key),
        );
        let pre = self.pretrigger;
        // Noise alone before t = 0, then signal plus noise.
        let stream: Vec<f64> = (0..pre)
            .map(|_| 0.0)
            .chain(pressure.iter().map(|p| p * self.scale_v_per_pa))
            .map(|v| v + sigma * rng.normal())
            .collect();
        let first = stream.iter().position(|v| v.abs() >= thr)?;
        let start = first.saturating_sub(pre);
        Some(Recorded {
            samples: stream[start..].iter().map(|&v| v as f32).collect(),
            pretrigger: first - start,
            threshold_v: thr,
        })
    }
}

/// The pressure a sensor passes on: the simulated signal band-limited to what the grid
/// carries (nothing above the grid's `stop_hz` is a sound wave of the model).
pub fn band_limited(sig: &[f64], g: &super::model::GridSpec) -> Vec<f64> {
    let b = super::acoustic::band_limit(g);
    super::acoustic::low_pass(sig, 1.0 / g.dt, b.pass_hz, b.stop_hz)
}

/// Rows of the simulated waveform table, one per sensor that triggered.
pub fn rows(run: &Run) -> Vec<store::Row> {
    let g = match &run.model.grid {
        Some(g) => g,
        None => return vec![],
    };
    run.out
        .sensors
        .iter()
        .zip(&run.model.sensors)
        .enumerate()
        .filter_map(|(k, (sig, spec))| {
            let (x, y) = g.centre(spec.i, spec.j);
            let p = band_limited(sig, g);
            let rec = run.acq.record(&p, (run.hit << 16) | k as u64)?;
            Some(vec![
                Value::Str(Some(run.model.name.clone())),
                Value::I32(Some(k as i32 + 1)),
                Value::I64(Some(run.hit as i64)),
                Value::F64(Some(0.0)),
                Value::F64(Some(run.out.sample_rate_hz)),
                Value::I32(Some(rec.pretrigger as i32)),
                Value::I32(Some(rec.samples.len() as i32)),
                Value::F64(None),
                Value::F64(None),
                Value::Str(run.model.label.clone()),
                Value::F64(Some(rec.threshold_v)),
                Value::F32s(Some(rec.samples)),
                Value::Str(Some(run.source.clone())),
                Value::Str(Some(run.source.clone())),
                Value::Str(Some(run.params.clone())),
                Value::F64(Some(x)),
                Value::F64(Some(y)),
                Value::F64(Some(run.acq.scale_v_per_pa)),
                Value::F64(Some(super::dominant_frequency(&p, run.out.sample_rate_hz))),
            ])
        })
        .collect()
}

/// Write the simulated waveform table (atomic, like every table).
pub fn write_waveforms(path: &Path, runs: &[Run]) -> Result<u64, SimError> {
    let io = |e: store::StoreError| SimError::Io(e.to_string());
    // The models' digest plays the role of the pipeline configuration's.
    let mut h = sha2::Sha256::new();
    for run in runs {
        sha2::Digest::update(&mut h, serde_json::to_vec(run.model).unwrap_or_default());
        sha2::Digest::update(&mut h, run.params.as_bytes());
    }
    let digest: String = sha2::Digest::finalize(h)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    let meta = [("aepipe.config_sha256".to_string(), digest)];
    let mut w = TableWriter::create(path, sim_waveforms_table(), &meta, 256).map_err(io)?;
    for run in runs {
        for row in rows(run) {
            w.push(row).map_err(io)?;
        }
    }
    w.finish().map_err(io)
}

pub fn write_trajectories(path: &Path, frames: &[Frame]) -> Result<u64, SimError> {
    let io = |e: store::StoreError| SimError::Io(e.to_string());
    let mut w = TableWriter::create(path, trajectory_table(), &[], 65_536).map_err(io)?;
    for f in frames {
        for (i, (r, u)) in f.r.iter().zip(&f.u).enumerate() {
            w.push(vec![
                Value::F64(Some(f.t)),
                Value::I32(Some(i as i32)),
                Value::F64(Some(r[0])),
                Value::F64(Some(r[1])),
                Value::F64(Some(u[0])),
                Value::F64(Some(u[1])),
            ])
            .map_err(io)?;
        }
    }
    w.finish().map_err(io)
}

/// A pressure snapshot as a PNG, one pixel block per cell, red positive, blue negative,
/// white zero, symmetric scale ±`max` (north up).
pub fn snapshot_png(
    path: &Path,
    p: &[f64],
    nx: usize,
    ny: usize,
    max: f64,
) -> Result<(), SimError> {
    use plotters::prelude::*;
    let px = (600 / nx.max(1)).max(1) as u32;
    let (w, h) = (nx as u32 * px, ny as u32 * px);
    let e = |x: String| SimError::Io(format!("{}: {x}", path.display()));
    {
        let root = BitMapBackend::new(path, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|x| e(x.to_string()))?;
        let scale = if max > 0.0 { max } else { 1.0 };
        for j in 0..ny {
            for i in 0..nx {
                let v = (p[j * nx + i] / scale).clamp(-1.0, 1.0);
                let c = if v >= 0.0 {
                    let k = (255.0 * (1.0 - v)) as u8;
                    RGBColor(255, k, k)
                } else {
                    let k = (255.0 * (1.0 + v)) as u8;
                    RGBColor(k, k, 255)
                };
                let (x0, y0) = ((i as u32 * px) as i32, ((ny - 1 - j) as u32 * px) as i32);
                root.draw(&Rectangle::new(
                    [(x0, y0), (x0 + px as i32, y0 + px as i32)],
                    c.filled(),
                ))
                .map_err(|x| e(x.to_string()))?;
            }
        }
        root.present().map_err(|x| e(x.to_string()))?;
    }
    Ok(())
}
