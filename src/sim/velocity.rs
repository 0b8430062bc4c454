//! §3.3.3, the particle-velocity form of the acoustic model: for irrotational flow each
//! component of the particle velocity obeys the same scalar wave equation as the pressure
//! (Eq. 3.3.17), so u and v are each stepped by the pressure scheme's stencil (Eqs.
//! 3.3.19–3.3.20, 2nd or 4th order) with Eq. 3.3.21's one-way boundaries. (Eq. 3.3.20a
//! prints the 4th-order neighbour weight as α²/3; Eq. 3.3.20b and Eq. 3.3.13 have 4α²/3,
//! which is the consistent one and the one used.)
//!
//! A source of the pressure form (∂²p/∂t² = c²∇²p + c²·s) is a velocity source through
//! ρ·∂u/∂t = −∇p: with S = ∫s dt, u sees −∂(S·δ)/∂x / ρ and v −∂(S·δ)/∂y / ρ — a dipole
//! along x in u and along y in v, the derivative central over two cells. The two forms are
//! checked against each other on one grid (`tests/it/sim.rs`).

use super::acoustic::Field;
use super::model::GridSpec;

/// The particle velocity (u, v) on a grid.
#[derive(Debug, Clone)]
pub struct VelocityField {
    pub u: Field,
    pub v: Field,
    h: f64,
    rho: f64,
}

impl VelocityField {
    /// `g` must have passed the model check (stability, square cells).
    pub fn new(g: &GridSpec) -> VelocityField {
        VelocityField {
            u: Field::new(g),
            v: Field::new(g),
            h: g.dx(),
            rho: g.rho,
        }
    }

    /// The pressure form's point source at cell (i, j) (inside, one cell from the edge),
    /// given as its time integral S = ∫s dt up to the coming step.
    pub fn add_pressure_source(&mut self, i: usize, j: usize, s_integral: f64) {
        // −∂(S·δ)/∂x: the central difference of a delta at i is −S/2h one cell on, +S/2h
        // one cell back.
        let a = s_integral / (2.0 * self.h * self.rho);
        self.u.add_source(i + 1, j, a);
        self.u.add_source(i - 1, j, -a);
        self.v.add_source(i, j + 1, a);
        self.v.add_source(i, j - 1, -a);
    }

    pub fn step(&mut self) {
        self.u.step();
        self.v.step();
    }

    /// (u, v) at cell (i, j), m/s.
    pub fn at(&self, i: usize, j: usize) -> (f64, f64) {
        (self.u.at(i, j), self.v.at(i, j))
    }
}
