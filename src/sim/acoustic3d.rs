//! The acoustic pressure wave equation in three dimensions (§6.2: "expand it to the third
//! dimension"): the scheme of ch. 3.3 with a third axis — explicit FDTD of 2nd (Eq. 3.3.11)
//! or 4th (Eq. 3.3.13) spatial order, the one-way boundaries of Eq. 3.3.21 on all six faces,
//! point sources as a forcing c²·Δt²·s (Eq. 3.4.5). The step runs in parallel over z-slabs
//! (each cell of the next level depends only on the two levels before it, so any split gives
//! the same numbers).
//!
//! Stability: α = cΔt/Δh with α²·3·max S < 1, max S = 1 (2nd order) or 4/3 (4th): α < 1/√3
//! or 1/2 (in 2-D the same rule gives Eq. 3.3.12's 1/√2 and √(3/8)).
//!
//! This is the 3-D field alone, verified against the free-space answers (a point source's
//! pressure falls as 1/r, its front travels at c); the 3-D masses and their coupling are not
//! built yet.

use super::order::Order;
use super::SimError;
use rayon::prelude::*;

/// At most this many cells (three levels and the sources at 8 bytes each: 1 GiB).
pub const MAX_CELLS: usize = 1 << 25;

/// A box of cubic cells: cell (i, j, k) is centred at (x1 + (i + ½)h, y1 + …, z1 + …).
#[derive(Debug, Clone, PartialEq)]
pub struct Grid3 {
    pub x1: f64,
    pub y1: f64,
    pub z1: f64,
    /// Cell size, m.
    pub h: f64,
    pub nx: usize,
    pub ny: usize,
    pub nz: usize,
    /// Time step, s.
    pub dt: f64,
    /// Speed of sound, m/s, and density, kg/m³.
    pub c: f64,
    pub rho: f64,
    pub order: Order,
}

impl Grid3 {
    /// n³ cells of size `h` from the origin, 4th order (not yet checked).
    pub fn cube(n: usize, h: f64, dt: f64, c: f64, rho: f64) -> Grid3 {
        Grid3 {
            x1: 0.0,
            y1: 0.0,
            z1: 0.0,
            h,
            nx: n,
            ny: n,
            nz: n,
            dt,
            c,
            rho,
            order: Order::Fourth,
        }
    }

    /// Courant number cΔt/Δh.
    pub fn alpha(&self) -> f64 {
        self.c * self.dt / self.h
    }

    /// The largest stable Courant number of the order.
    pub fn alpha_max(&self) -> f64 {
        match self.order {
            Order::Second => 1.0 / 3f64.sqrt(),
            Order::Fourth => 0.5,
        }
    }

    /// Size, stability and the cell cap, checked before anything is allocated.
    pub fn check(&self) -> Result<(), SimError> {
        let bad = |w: String| SimError::Model(format!("3-D grid: {w}"));
        for (k, v) in [
            ("h", self.h),
            ("dt", self.dt),
            ("c", self.c),
            ("rho", self.rho),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(bad(format!("{k} must be > 0, got {v}")));
            }
        }
        if self.nx < 8 || self.ny < 8 || self.nz < 8 {
            return Err(bad(format!(
                "{} × {} × {} cells: at least 8 along each axis",
                self.nx, self.ny, self.nz
            )));
        }
        let cells = self
            .nx
            .checked_mul(self.ny)
            .and_then(|v| v.checked_mul(self.nz));
        if cells.is_none_or(|c| c > MAX_CELLS) {
            return Err(bad(format!(
                "{} × {} × {} cells exceed the limit of {MAX_CELLS}",
                self.nx, self.ny, self.nz
            )));
        }
        if self.alpha() >= self.alpha_max() {
            return Err(bad(format!(
                "Courant number cΔt/Δh = {:.4} above the stable {:.4} of the {:?} order",
                self.alpha(),
                self.alpha_max(),
                self.order
            )));
        }
        Ok(())
    }

    /// The cell holding (x, y, z), if inside.
    pub fn cell(&self, x: f64, y: f64, z: f64) -> Option<(usize, usize, usize)> {
        let f = |v: f64, o: f64, n: usize| {
            let i = ((v - o) / self.h).floor();
            (i >= 0.0 && (i as usize) < n).then_some(i as usize)
        };
        Some((
            f(x, self.x1, self.nx)?,
            f(y, self.y1, self.ny)?,
            f(z, self.z1, self.nz)?,
        ))
    }

    /// The centre of cell (i, j, k).
    pub fn centre(&self, i: usize, j: usize, k: usize) -> [f64; 3] {
        [
            self.x1 + (i as f64 + 0.5) * self.h,
            self.y1 + (j as f64 + 0.5) * self.h,
            self.z1 + (k as f64 + 0.5) * self.h,
        ]
    }
}

/// Pressure at three time levels; cell (i, j, k) is `p[(k·ny + j)·nx + i]`.
#[derive(Debug, Clone)]
pub struct Field3 {
    pub nx: usize,
    pub ny: usize,
    pub nz: usize,
    alpha: f64,
    order: Order,
    src_scale: f64,
    pub prev: Vec<f64>,
    pub cur: Vec<f64>,
    next: Vec<f64>,
    sources: Vec<f64>,
}

impl Field3 {
    /// A silent field on `g` (checked first: nothing is allocated for a grid that fails).
    pub fn new(g: &Grid3) -> Result<Field3, SimError> {
        g.check()?;
        let n = g.nx * g.ny * g.nz;
        Ok(Field3 {
            nx: g.nx,
            ny: g.ny,
            nz: g.nz,
            alpha: g.alpha(),
            order: g.order,
            src_scale: g.c * g.c * g.dt * g.dt,
            prev: vec![0.0; n],
            cur: vec![0.0; n],
            next: vec![0.0; n],
            sources: vec![0.0; n],
        })
    }

    #[inline]
    pub fn idx(&self, i: usize, j: usize, k: usize) -> usize {
        (k * self.ny + j) * self.nx + i
    }

    /// Add a source of strength `s` (∂²p/∂t² = c²∇²p + c²·s, Pa/m²) at cell (i, j, k) for
    /// the coming step.
    pub fn add_source(&mut self, i: usize, j: usize, k: usize, s: f64) {
        let n = self.idx(i, j, k);
        self.sources[n] += s;
    }

    pub fn at(&self, i: usize, j: usize, k: usize) -> f64 {
        self.cur[self.idx(i, j, k)]
    }

    /// Σp² over the grid.
    pub fn energy(&self) -> f64 {
        self.cur.iter().map(|v| v * v).sum()
    }

    /// Advance one time step.
    pub fn step(&mut self) {
        let (nx, ny, nz) = (self.nx, self.ny, self.nz);
        let plane = nx * ny;
        let a2 = self.alpha * self.alpha;
        let order = self.order;
        let (p, q) = (&self.cur, &self.prev);
        let m = match order {
            Order::Second => 1,
            Order::Fourth => 2,
        };
        self.next
            .par_chunks_mut(plane)
            .enumerate()
            .filter(|(k, _)| *k >= m && *k < nz - m)
            .for_each(|(k, out)| {
                let base = k * plane;
                for j in m..ny - m {
                    for i in m..nx - m {
                        let l = j * nx + i;
                        let g = base + l;
                        out[l] = match order {
                            Order::Second => {
                                2.0 * (1.0 - 3.0 * a2) * p[g] - q[g]
                                    + a2 * (p[g + 1]
                                        + p[g - 1]
                                        + p[g + nx]
                                        + p[g - nx]
                                        + p[g + plane]
                                        + p[g - plane])
                            }
                            Order::Fourth => {
                                (2.0 - 7.5 * a2) * p[g] - q[g]
                                    + 4.0 / 3.0
                                        * a2
                                        * (p[g + 1]
                                            + p[g - 1]
                                            + p[g + nx]
                                            + p[g - nx]
                                            + p[g + plane]
                                            + p[g - plane])
                                    - a2 / 12.0
                                        * (p[g + 2]
                                            + p[g - 2]
                                            + p[g + 2 * nx]
                                            + p[g - 2 * nx]
                                            + p[g + 2 * plane]
                                            + p[g - 2 * plane])
                            }
                        };
                    }
                }
            });
        // Eq. 3.3.21 on every face: for 4th order the inner shell first, then the outer.
        let shells: &[usize] = match order {
            Order::Second => &[0],
            Order::Fourth => &[1, 0],
        };
        for &b in shells {
            self.boundary_shell(b);
        }
        let scale = self.src_scale;
        self.next
            .par_iter_mut()
            .zip(self.sources.par_iter_mut())
            .for_each(|(o, s)| {
                *o += scale * *s;
                *s = 0.0;
            });
        std::mem::swap(&mut self.prev, &mut self.cur);
        std::mem::swap(&mut self.cur, &mut self.next);
    }

    /// Eq. 3.3.21 on shell `b` (0 = outermost): each cell looks one and two cells inwards
    /// along the normal of its face (z faces whole, then y faces, then x faces, each without
    /// the cells an earlier face set).
    fn boundary_shell(&mut self, b: usize) {
        let (nx, ny, nz, a) = (self.nx, self.ny, self.nz, self.alpha);
        let plane = nx * ny;
        let (p, q) = (&self.cur, &self.prev);
        let out = &mut self.next;
        let idx = |i: usize, j: usize, k: usize| (k * ny + j) * nx + i;
        let mut set = |n: usize, n1: usize, n2: usize| {
            out[n] = p[n] + p[n1] - q[n1] + a * (p[n1] - p[n] - (q[n2] - q[n1]));
        };
        let (zl, zh) = (b, nz - 1 - b);
        for j in b..ny - b {
            for i in b..nx - b {
                let (lo, hi) = (idx(i, j, zl), idx(i, j, zh));
                set(lo, lo + plane, lo + 2 * plane);
                set(hi, hi - plane, hi - 2 * plane);
            }
        }
        let (yl, yh) = (b, ny - 1 - b);
        for k in b + 1..nz - 1 - b {
            for i in b..nx - b {
                let (lo, hi) = (idx(i, yl, k), idx(i, yh, k));
                set(lo, lo + nx, lo + 2 * nx);
                set(hi, hi - nx, hi - 2 * nx);
            }
        }
        let (xl, xh) = (b, nx - 1 - b);
        for k in b + 1..nz - 1 - b {
            for j in b + 1..ny - 1 - b {
                let (lo, hi) = (idx(xl, j, k), idx(xh, j, k));
                set(lo, lo + 1, lo + 2);
                set(hi, hi - 1, hi - 2);
            }
        }
    }
}
