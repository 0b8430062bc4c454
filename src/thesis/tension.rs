//! Fig. 3.4c (§3.2.7): the springs' tension of the simple harmonic oscillator (Table 3.1) as
//! each solver steps it. Implicit Euler damps the motion by itself — its amplification
//! factor per step is 1/√(1 + ω²Δt²), so the oscillation's energy decays at
//! ln(1 + ω²Δt²)/Δt — and the tension's swing dies with it; velocity Verlet keeps it. The
//! entry runs both at Δt = 0.01 s for 100 s, writes each solver's `tension_*.parquet` and
//! `energy_*.parquet` and `tension.png`, and compares implicit Euler's measured decay rate of
//! the oscillation's energy (the total less the springs' static energy at rest, ½·k·(l − L)²
//! each) with the scheme's own.

use super::ThesisError;
use crate::sim::model::Solver;
use crate::sim::output::{write_energy, write_tension};
use crate::sim::scenario::{build, Params};
use crate::sim::{simulate, SimError, SimOptions};
use std::path::Path;

/// Table 3.1's static energy: two springs k = 1 N/m stretched from 0.25 to 0.55 m.
const STATIC_J: f64 = 2.0 * 0.5 * 1.0 * 0.3 * 0.3;

/// The entry: implicit Euler's decay rate of the oscillation energy, 1/s.
pub fn fig_3_4(dir: &Path) -> Result<f64, ThesisError> {
    let mut curves = Vec::new();
    let mut rate = None;
    for (name, solver) in [
        ("implicit-euler", Solver::ImplicitEuler),
        ("verlet", Solver::Verlet),
    ] {
        let mut m = build("sho", &Params(vec![("grid".into(), 0.0)]))?;
        m.system.solver = solver;
        let out = simulate(
            &m,
            &SimOptions {
                trajectory_every: Some(10),
                snapshot_every: None,
            },
        )?;
        let f = &out.trajectory;
        write_tension(&dir.join(format!("tension_{name}.parquet")), f)?;
        write_energy(&dir.join(format!("energy_{name}.parquet")), f)?;
        curves.push((
            name,
            f.iter()
                .map(|fr| (fr.t, fr.tension.first().copied().unwrap_or(0.0)))
                .collect::<Vec<_>>(),
        ));
        if solver == Solver::ImplicitEuler {
            let osc = |k: usize| f[k].energy.map_or(0.0, |e| e[0] + e[1] - STATIC_J);
            let (first, last) = (osc(0), osc(f.len() - 1));
            if first <= 0.0 || last <= 0.0 {
                return Err(SimError::Solver("the oscillation's energy vanished".into()).into());
            }
            rate = Some(-(last / first).ln() / f[f.len() - 1].t);
        }
    }
    // Drawn with the Verlet curve first (points) and implicit Euler's as a line.
    curves.reverse();
    let named: Vec<(&str, Vec<(f64, f64)>)> = curves
        .into_iter()
        .map(|(n, c)| {
            let label = match n {
                "verlet" => "velocity Verlet (points)",
                _ => "implicit Euler (line)",
            };
            (label, c)
        })
        .collect();
    crate::plot::sim::curves_png(
        &dir.join("tension.png"),
        "Fig. 3.4c: tension of one spring of the SHO, Δt = 0.01 s",
        "time, s",
        "tension, N",
        &named,
    )?;
    rate.ok_or(ThesisError::Measure {
        id: "fig-3.4",
        message: "no implicit run".into(),
    })
}
