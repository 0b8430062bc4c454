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
    pub scale_v_per_pa: f64,
}

/// The simulated sensor "triggers" at this fraction of its peak.
pub const TRIGGER_FRACTION: f64 = 0.05;

/// Rows of the simulated waveform table, one per sensor.
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
        .map(|(k, (sig, spec))| {
            let (x, y) = g.centre(spec.i, spec.j);
            // Trigger where an AE system would: the first sample reaching 5 % of the peak.
            let peak = sig.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            let pretrigger = sig
                .iter()
                .position(|v| v.abs() >= TRIGGER_FRACTION * peak)
                .unwrap_or(0) as i32;
            let samples: Vec<f32> = sig
                .iter()
                .map(|p| (p * run.scale_v_per_pa) as f32)
                .collect();
            vec![
                Value::Str(Some(run.model.name.clone())),
                Value::I32(Some(k as i32 + 1)),
                Value::I64(Some(run.hit as i64)),
                Value::F64(Some(0.0)),
                Value::F64(Some(run.out.sample_rate_hz)),
                Value::I32(Some(pretrigger)),
                Value::I32(Some(samples.len() as i32)),
                Value::F64(None),
                Value::F64(None),
                Value::Str(run.model.label.clone()),
                Value::F64(None),
                Value::F32s(Some(samples)),
                Value::Str(Some(run.source.clone())),
                Value::Str(Some(run.source.clone())),
                Value::Str(Some(run.params.clone())),
                Value::F64(Some(x)),
                Value::F64(Some(y)),
                Value::F64(Some(run.scale_v_per_pa)),
                Value::F64(Some(super::dominant_frequency(sig, run.out.sample_rate_hz))),
            ]
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
