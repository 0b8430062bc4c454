//! Fig. 4.20 (§4.6.1): the frequency a failing fibre would ring at if, once broken, it were
//! Fig. 3.1's simple mass on a spring: Eq. 4.6.1, F = (1/2π)·√(E·t·w/(L·m)), with the paper
//! fibre's material (Table 4.1) and m the mass of the free length L (ρ·t·w·L, so F =
//! √(E/ρ)/(2πL)). The entry simulates that system — one mass on one spring of length L from a
//! fixed point, pulled 1 % along it and let go, RK4 at 1/400 of the period — for L from 0.1 to
//! 1 mm, and writes the curve beside the equation's (`curve.parquet`, `curve.png`).

use super::ThesisError;
use crate::sim::model::*;
use crate::sim::scenario::{eq, FIBRE_E, FIBRE_NU, FIBRE_RHO, FIBRE_T, FIBRE_W};
use crate::sim::{simulate, zero_crossing_frequency, SimError, SimOptions};
use std::path::Path;

/// Eq. 4.6.1 for the paper fibre's free length `l`, Hz.
pub fn eq_4_6_1(l: f64) -> f64 {
    let m = FIBRE_RHO * FIBRE_T * FIBRE_W * l;
    (FIBRE_E * FIBRE_T * FIBRE_W / (l * m)).sqrt() / (2.0 * std::f64::consts::PI)
}

/// The simple system of Fig. 3.1 with free length `l`, simulated: its frequency, Hz.
pub fn simulated(l: f64) -> Result<f64, SimError> {
    let m = FIBRE_RHO * FIBRE_T * FIBRE_W * l;
    let period = 1.0 / eq_4_6_1(l);
    let dt = period / 400.0;
    let node = |x: f64, fixed: bool| NodeSpec {
        x,
        y: 0.0,
        z: None,
        mass: m,
        fixed,
    };
    let model = ModelFile {
        name: "fig-4.20".into(),
        label: None,
        system: System {
            dt,
            damping: 0.0,
            iterations: 4000,
            solver: Solver::Rk4,
            relax: false,
        },
        nodes: vec![node(0.0, true), node(l, false)],
        springs: vec![SpringSpec {
            a: 0,
            b: 1,
            e: FIBRE_E,
            length: Some(l),
            t: FIBRE_T,
            w: FIBRE_W,
            // Poisson's ratio thins the spring at the 1 % pull (frequency × (1 − ν·0.01),
            // −0.28 %), which Eq. 4.6.1 omits: the entry's tolerance says so.
            poisson: FIBRE_NU,
            fibre: 0,
        }],
        initial: vec![eq(1, 0.01 * l, 0.0)],
        forces: vec![],
        damage: vec![],
        grid: None,
        sensors: vec![],
    };
    let out = simulate(
        &model,
        &SimOptions {
            trajectory_every: Some(1),
            snapshot_every: None,
        },
    )?;
    let t: Vec<f64> = out.trajectory.iter().map(|f| f.t).collect();
    let x: Vec<f64> = out.trajectory.iter().map(|f| f.r[1][0]).collect();
    zero_crossing_frequency(&t, &x)
        .ok_or_else(|| SimError::Solver("the mass did not oscillate".into()))
}

/// The entry: the curve from 0.1 to 1 mm, compared at L = 0.5 mm (kHz).
pub fn fig_4_20(dir: &Path) -> Result<f64, ThesisError> {
    let lengths: Vec<f64> = (1..=10).map(|k| k as f64 * 1e-4).collect();
    let mut rows = Vec::new();
    for &l in &lengths {
        rows.push((l, simulated(l)?, eq_4_6_1(l)));
    }
    super::write_floats(
        &dir.join("curve.parquet"),
        "thesis_fig_4_20",
        [
            ("length_m", "m", "free vibrating length L"),
            ("simulated_hz", "Hz", "the mass/spring model's frequency"),
            ("eq_4_6_1_hz", "Hz", "Eq. 4.6.1"),
        ],
        rows.iter().map(|r| [r.0, r.1, r.2]),
    )?;
    let khz = |v: &[(f64, f64, f64)], pick: fn(&(f64, f64, f64)) -> f64| -> Vec<(f64, f64)> {
        v.iter().map(|r| (r.0 * 1e3, pick(r) / 1e3)).collect()
    };
    crate::plot::sim::curves_png(
        &dir.join("curve.png"),
        "Fig. 4.20: a fibre once broken as Fig. 3.1's mass on a spring",
        "free length L, mm",
        "frequency, kHz",
        &[
            ("simulated (points)", khz(&rows, |r| r.1)),
            ("Eq. 4.6.1 (line)", khz(&rows, |r| r.2)),
        ],
    )?;
    Ok(rows[4].1 / 1e3)
}
