//! The entries of the acoustic field's own test cases (ch. 3.3.5–3.3.6): each runs a source
//! of [`crate::sim::sources`] and writes `directivity.parquet` (the ring's amplitudes beside
//! the analytic directivity), `on_axis.parquet` (the pressure on the strongest axis),
//! `directivity.png` and `field.png` (the field at the end, Fig. 3.23's picture).

use super::ThesisError;
use crate::sim::sources::{run, sine_share, Drive, Heard, Pole, PERIOD_S};
use crate::sim::SimError;
use crate::store::{ColType, ColumnSpec, Table, TableWriter, Value};
use std::path::Path;

/// Directions heard on the ring.
const DIRECTIONS: usize = 72;

/// Fig. 3.23: the quadrupole pulse's directivity against |sin 2θ| (Pearson's r).
pub fn fig_3_23(dir: &Path) -> Result<f64, ThesisError> {
    let h = run(Pole::Quadrupole, Drive::Pulse, DIRECTIONS);
    write(dir, &h)?;
    Ok(h.agreement)
}

/// Fig. 3.27: how pure a sine the continuous dipole settles into, 6 m out on its axis (the
/// last two periods).
pub fn fig_3_27(dir: &Path) -> Result<f64, ThesisError> {
    let h = run(Pole::Dipole, Drive::Continuous, DIRECTIONS);
    write(dir, &h)?;
    let per = (PERIOD_S * h.sample_rate_hz).round() as usize;
    let settled = &h.on_axis[h.on_axis.len().saturating_sub(2 * per)..];
    Ok(sine_share(settled, h.sample_rate_hz, 1.0 / PERIOD_S))
}

fn write(dir: &Path, h: &Heard) -> Result<(), ThesisError> {
    let io = |e: crate::store::StoreError| SimError::Io(e.to_string());
    let f = |name: &str, unit: &str, doc: &str| ColumnSpec::new(name, ColType::Float64, unit, doc);
    let ring: Table<(f64, f64, f64)> = Table::new("thesis_directivity")
        .col(
            f("theta_deg", "°", "direction from the x axis"),
            |r: &(f64, f64, f64)| Value::F64(Some(r.0)),
        )
        .col(
            f("amplitude_pa", "Pa", "amplitude heard on the ring"),
            |r| Value::F64(Some(r.1)),
        )
        .col(
            f(
                "analytic_pa",
                "Pa",
                "the analytic directivity, scaled to the measured peak",
            ),
            |r| Value::F64(Some(r.2)),
        );
    let mut w = TableWriter::create(&dir.join("directivity.parquet"), ring.schema(), &[], 1024)
        .map_err(io)?;
    for k in 0..h.theta.len() {
        w.push(ring.row((h.theta[k].to_degrees(), h.amplitude[k], h.analytic[k])))
            .map_err(io)?;
    }
    w.finish().map_err(io)?;
    let axis: Table<(f64, f64)> = Table::new("thesis_on_axis")
        .col(f("t_s", "s", "time"), |r: &(f64, f64)| {
            Value::F64(Some(r.0))
        })
        .col(
            f(
                "pressure_pa",
                "Pa",
                "pressure 6 m out on the strongest axis",
            ),
            |r| Value::F64(Some(r.1)),
        );
    let mut w =
        TableWriter::create(&dir.join("on_axis.parquet"), axis.schema(), &[], 4096).map_err(io)?;
    for (k, p) in h.on_axis.iter().enumerate() {
        w.push(axis.row(((k + 1) as f64 / h.sample_rate_hz, *p)))
            .map_err(io)?;
    }
    w.finish().map_err(io)?;
    crate::plot::sim::directivity_png(&dir.join("directivity.png"), h)?;
    let max = h.field.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    crate::sim::output::snapshot_png(&dir.join("field.png"), &h.field, h.nx, h.ny, max)?;
    Ok(())
}
