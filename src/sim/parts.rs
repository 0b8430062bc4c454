//! The building blocks the scenarios share: the paper fibre's material (Table 4.1), masses,
//! springs, initial conditions, the system and the Appendix-A acoustic grid. The registry
//! (`scenario`) and the structures (`paper`, `network3d`) are built from them.

use super::model::*;

/// Paper fibre material of Table 4.1: E 35 GPa, t 2.8 µm, w 35 µm, ν 0.28, density 1.5 g/cm³.
pub const FIBRE_E: f64 = 3.5e10;
pub const FIBRE_T: f64 = 2.8e-6;
pub const FIBRE_W: f64 = 3.5e-5;
pub const FIBRE_NU: f64 = 0.28;
pub const FIBRE_RHO: f64 = 1500.0;

#[allow(clippy::too_many_arguments)]
pub(super) fn spring(
    a: usize,
    b: usize,
    e: f64,
    l: Option<f64>,
    t: f64,
    w: f64,
    nu: f64,
    fibre: u32,
) -> SpringSpec {
    SpringSpec {
        a,
        b,
        e,
        length: l,
        t,
        w,
        poisson: nu,
        fibre,
    }
}

pub(super) fn node(x: f64, y: f64, mass: f64, fixed: bool) -> NodeSpec {
    NodeSpec {
        x,
        y,
        z: None,
        mass,
        fixed,
    }
}

/// An equilibrium initial condition (Alg. 7's EqIC): node displaced in the plane, at rest.
pub fn eq(node: usize, dx: f64, dy: f64) -> InitialSpec {
    InitialSpec {
        node,
        dx,
        dy,
        du: 0.0,
        dv: 0.0,
        dz: 0.0,
        dw: 0.0,
        kind: IcKind::Eq,
    }
}

/// A static initial condition (StIC): [`eq`]'s, held for the whole run.
pub(super) fn st(node: usize, dx: f64, dy: f64) -> InitialSpec {
    InitialSpec {
        kind: IcKind::St,
        ..eq(node, dx, dy)
    }
}

pub(super) fn system(dt: f64, damping: f64, iterations: usize) -> System {
    System {
        dt,
        damping,
        iterations,
        solver: Solver::ImplicitEuler,
        relax: true,
    }
}

/// The Appendix-A acoustic grid: ±9 mm, 250 × 250 cells (72 µm), Δt 0.1 µs (10 MHz), air
/// (ρ 1.25 kg/m³, c 350 m/s), 4th order.
pub fn paper_grid() -> GridSpec {
    GridSpec {
        x1: -9e-3,
        x2: 9e-3,
        y1: -9e-3,
        y2: 9e-3,
        nx: 250,
        ny: 250,
        dt: 1e-7,
        rho: 1.25,
        c: 350.0,
        order: Order::Fourth,
        dipole_m: None,
        z: None,
    }
}
