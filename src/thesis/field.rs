//! The entries of the acoustic field's own test cases (ch. 3.3.5–3.3.6): each runs a source
//! of [`crate::sim::sources`] and writes `directivity.parquet` (the ring's amplitudes beside
//! the analytic directivity), `on_axis.parquet` (the pressure on the strongest axis),
//! `directivity.png` and `field.png` (the field at the end, Fig. 3.23's picture).

use super::ThesisError;
use crate::sim::sources::{run, sine_share, Drive, Heard, Pole, PERIOD_S};
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
    super::write_floats(
        &dir.join("directivity.parquet"),
        "thesis_directivity",
        [
            ("theta_deg", "°", "direction from the x axis"),
            ("amplitude_pa", "Pa", "amplitude heard on the ring"),
            (
                "analytic_pa",
                "Pa",
                "the analytic directivity, scaled to the measured peak",
            ),
        ],
        (0..h.theta.len()).map(|k| [h.theta[k].to_degrees(), h.amplitude[k], h.analytic[k]]),
    )?;
    super::write_floats(
        &dir.join("on_axis.parquet"),
        "thesis_on_axis",
        [
            ("t_s", "s", "time"),
            (
                "pressure_pa",
                "Pa",
                "pressure 6 m out on the strongest axis",
            ),
        ],
        h.on_axis
            .iter()
            .enumerate()
            .map(|(k, p)| [(k + 1) as f64 / h.sample_rate_hz, *p]),
    )?;
    crate::plot::sim::directivity_png(&dir.join("directivity.png"), h)?;
    let max = h.field.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    crate::sim::output::snapshot_png(&dir.join("field.png"), &h.field, h.nx, h.ny, max)?;
    Ok(())
}
