//! The 2-D acoustic pressure wave equation (ch. 3.3): explicit FDTD of 2nd (Eq. 3.3.11) or
//! 4th (Eq. 3.3.13) spatial order with the non-reflecting boundaries of Eq. 3.3.21, and
//! point sources added as a pressure forcing c²·Δt²·s (ch. 3.4, Eq. 3.4.5).

use super::model::{GridSpec, Order};

/// Pressure on an nx × ny grid at three time levels. Cell (i, j) is `p[j·nx + i]`.
#[derive(Debug, Clone)]
pub struct Field {
    pub nx: usize,
    pub ny: usize,
    pub alpha: f64,
    pub order: Order,
    /// c²·Δt², the factor of a source term.
    pub src_scale: f64,
    pub prev: Vec<f64>,
    pub cur: Vec<f64>,
    next: Vec<f64>,
    /// Sources of the step being built (added to `next`).
    pub sources: Vec<f64>,
}

impl Field {
    /// `spec` must have passed [`super::model::ModelFile::check`] (stability, square cells).
    pub fn new(spec: &GridSpec) -> Field {
        let n = spec.nx * spec.ny;
        Field {
            nx: spec.nx,
            ny: spec.ny,
            alpha: spec.alpha(),
            order: spec.order,
            src_scale: spec.c * spec.c * spec.dt * spec.dt,
            prev: vec![0.0; n],
            cur: vec![0.0; n],
            next: vec![0.0; n],
            sources: vec![0.0; n],
        }
    }

    #[inline]
    pub fn idx(&self, i: usize, j: usize) -> usize {
        j * self.nx + i
    }

    /// Add a source of strength `s` (the right-hand side of ∂²p/∂t² = c²∇²p + c²·s, in
    /// Pa/m²) at cell (i, j) for the coming step.
    pub fn add_source(&mut self, i: usize, j: usize, s: f64) {
        let k = self.idx(i, j);
        self.sources[k] += s;
    }

    /// Advance one time step.
    pub fn step(&mut self) {
        let (nx, ny) = (self.nx, self.ny);
        let a2 = self.alpha * self.alpha;
        let (p, q) = (&self.cur, &self.prev);
        let out = &mut self.next;
        match self.order {
            Order::Second => {
                let c0 = 2.0 * (1.0 - 2.0 * a2);
                for j in 1..ny - 1 {
                    let row = j * nx;
                    for i in 1..nx - 1 {
                        let k = row + i;
                        out[k] =
                            c0 * p[k] - q[k] + a2 * (p[k + 1] + p[k - 1] + p[k + nx] + p[k - nx]);
                    }
                }
            }
            Order::Fourth => {
                let c0 = 2.0 - 5.0 * a2;
                let c1 = 4.0 / 3.0 * a2;
                let c2 = a2 / 12.0;
                for j in 2..ny - 2 {
                    let row = j * nx;
                    for i in 2..nx - 2 {
                        let k = row + i;
                        out[k] = c0 * p[k] - q[k]
                            + c1 * (p[k + 1] + p[k - 1] + p[k + nx] + p[k - nx])
                            - c2 * (p[k + 2] + p[k - 2] + p[k + 2 * nx] + p[k - 2 * nx]);
                    }
                }
            }
        }
        // Non-reflecting boundaries (Eq. 3.3.21): for 4th order the inner ring first, then
        // the outer ring.
        let rings: &[usize] = match self.order {
            Order::Second => &[0],
            Order::Fourth => &[1, 0],
        };
        for &b in rings {
            self.boundary_ring(b);
        }
        for (o, s) in self.next.iter_mut().zip(self.sources.iter_mut()) {
            *o += self.src_scale * *s;
            *s = 0.0;
        }
        std::mem::swap(&mut self.prev, &mut self.cur);
        std::mem::swap(&mut self.cur, &mut self.next);
    }

    /// Eq. 3.3.21 on ring `b` (0 = outermost): each cell looks one and two cells inwards.
    fn boundary_ring(&mut self, b: usize) {
        let (nx, ny, a) = (self.nx, self.ny, self.alpha);
        let (p, q) = (&self.cur, &self.prev);
        let out = &mut self.next;
        let mut set = |k: usize, k1: usize, k2: usize| {
            out[k] = p[k] + p[k1] - q[k1] + a * (p[k1] - p[k] - (q[k2] - q[k1]));
        };
        // South (j = b) and north (j = ny−1−b) rows, over the ring's extent.
        for i in b..nx - b {
            let (s, n) = (b, ny - 1 - b);
            set(s * nx + i, (s + 1) * nx + i, (s + 2) * nx + i);
            set(n * nx + i, (n - 1) * nx + i, (n - 2) * nx + i);
        }
        // West and east columns, without the corners already set.
        for j in b + 1..ny - 1 - b {
            let (w, e) = (b, nx - 1 - b);
            set(j * nx + w, j * nx + w + 1, j * nx + w + 2);
            set(j * nx + e, j * nx + e - 1, j * nx + e - 2);
        }
    }

    pub fn at(&self, i: usize, j: usize) -> f64 {
        self.cur[self.idx(i, j)]
    }

    /// Σp² over the grid (a measure of the acoustic energy left in the domain).
    pub fn energy(&self) -> f64 {
        self.cur.iter().map(|v| v * v).sum()
    }
}
