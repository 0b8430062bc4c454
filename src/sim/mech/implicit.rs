//! The linearised implicit Euler step of Eq. 3.2.29 (the thesis's default solver): the
//! sparse D×D-block matrix assembled each step on a pattern rebuilt only when a damage event
//! changes the topology, solved by Jacobi-preconditioned BiCGSTAB.

// Index loops over nodes and D×D components read like the equations they implement.
#![allow(clippy::needless_range_loop)]

use super::{block_inverse, block_mul, dotv, sub, Mech, Spring};
use crate::sim::SimError;

impl<const D: usize> Mech<D> {
    /// Eq. 3.2.29: (I − Δt·M⁻¹·∂F/∂u − Δt²·M⁻¹·∂F/∂r)·Δu = Δt·M⁻¹·(F + Δt·∂F/∂r·u), with
    /// the spring Jacobians of Eq. 3.2.30b, ∂F/∂u = −b·I, and
    /// held masses as identity rows (M⁻¹ = 0): the matrix is not symmetric, hence BiCGSTAB.
    pub(super) fn implicit_step(&mut self, dt: f64, t: f64) -> Result<(), SimError> {
        let n = self.len();
        if !self.implicit.pattern_valid {
            self.implicit.build_pattern(n, &self.springs);
        }
        let b = self.damping;
        let mut f = std::mem::take(&mut self.acc);
        self.spring_forces(&self.r, t, &mut f);
        let im = &mut self.implicit;
        im.vals.iter_mut().for_each(|v| *v = [[0.0; D]; D]);
        im.rhs.clear();
        im.rhs.resize(D * n, 0.0);
        // ∂F/∂r·u accumulates in ku.
        let mut ku = vec![[0.0f64; D]; n];
        for (k, s) in self.springs.iter().enumerate() {
            if s.broken {
                continue;
            }
            let d = sub(self.r[s.b], self.r[s.a]);
            let l = dotv(d, d).sqrt();
            if l == 0.0 {
                continue;
            }
            let (fl, dfl) = s.tension(l);
            let nx: [f64; D] = std::array::from_fn(|c| d[c] / l);
            let g = fl / l;
            // K = f'·n̂n̂ᵀ + (f/l)(I − n̂n̂ᵀ)
            let kk: [[f64; D]; D] = std::array::from_fn(|a| {
                std::array::from_fn(|c| {
                    if a == c {
                        dfl * nx[a] * nx[a] + g * (1.0 - nx[a] * nx[a])
                    } else {
                        (dfl - g) * nx[a.min(c)] * nx[a.max(c)]
                    }
                })
            });
            let kd = block_mul(&kk, sub(self.u[s.b], self.u[s.a]));
            for c in 0..D {
                ku[s.a][c] += kd[c];
                ku[s.b][c] -= kd[c];
            }
            let (ab, ba) = im.spring_slots[k];
            for (node, off) in [(s.a, ab), (s.b, ba)] {
                if self.held[node] {
                    continue;
                }
                let c = dt * dt / self.m[node];
                let di = im.diag[node];
                for q in 0..D {
                    for w in 0..D {
                        im.vals[di][q][w] += c * kk[q][w];
                        im.vals[off][q][w] -= c * kk[q][w];
                    }
                }
            }
        }
        for i in 0..n {
            let di = im.diag[i];
            if self.held[i] {
                im.vals[di] = std::array::from_fn(|a| std::array::from_fn(|c| f64::from(a == c)));
                continue;
            }
            let damp = 1.0 + dt * b / self.m[i];
            for q in 0..D {
                im.vals[di][q][q] += damp;
            }
            let c = dt / self.m[i];
            for q in 0..D {
                let force = f[i][q] - b * self.u[i][q];
                im.rhs[D * i + q] = c * (force + dt * ku[i][q]);
            }
        }
        self.acc = f;
        im.x.resize(D * n, 0.0);
        im.solve()?;
        for i in 0..n {
            if self.held[i] {
                continue;
            }
            for q in 0..D {
                self.u[i][q] += self.implicit.x[D * i + q];
                self.r[i][q] += dt * self.u[i][q];
            }
        }
        self.acc_valid = false;
        Ok(())
    }
}

/// The implicit solver's sparse matrix (D×D blocks, CSR by node) and BiCGSTAB workspace.
/// The pattern is rebuilt only when the topology changes (a damage event); the values are
/// assembled each step.
#[derive(Debug, Clone)]
pub(super) struct Implicit<const D: usize> {
    pub(super) pattern_valid: bool,
    row_ptr: Vec<usize>,
    cols: Vec<usize>,
    vals: Vec<[[f64; D]; D]>,
    diag: Vec<usize>,
    /// Per spring: the (a, b) block in row a and the (b, a) block in row b.
    spring_slots: Vec<(usize, usize)>,
    rhs: Vec<f64>,
    /// Δu, kept between steps as the next initial guess.
    x: Vec<f64>,
    work: Vec<Vec<f64>>,
    pinv: Vec<[[f64; D]; D]>,
    pub iterations: usize,
}

impl<const D: usize> Default for Implicit<D> {
    fn default() -> Self {
        Implicit {
            pattern_valid: false,
            row_ptr: Vec::new(),
            cols: Vec::new(),
            vals: Vec::new(),
            diag: Vec::new(),
            spring_slots: Vec::new(),
            rhs: Vec::new(),
            x: Vec::new(),
            work: Vec::new(),
            pinv: Vec::new(),
            iterations: 0,
        }
    }
}

impl<const D: usize> Implicit<D> {
    fn build_pattern(&mut self, n: usize, springs: &[Spring]) {
        let mut nb: Vec<Vec<usize>> = (0..n).map(|i| vec![i]).collect();
        for s in springs.iter().filter(|s| !s.broken) {
            nb[s.a].push(s.b);
            nb[s.b].push(s.a);
        }
        self.row_ptr = vec![0];
        self.cols.clear();
        self.diag = vec![0; n];
        for (i, row) in nb.iter_mut().enumerate() {
            row.sort_unstable();
            row.dedup();
            for &c in row.iter() {
                if c == i {
                    self.diag[i] = self.cols.len();
                }
                self.cols.push(c);
            }
            self.row_ptr.push(self.cols.len());
        }
        let find = |row_ptr: &[usize], cols: &[usize], r: usize, c: usize| {
            let (lo, hi) = (row_ptr[r], row_ptr[r + 1]);
            lo + cols[lo..hi]
                .binary_search(&c)
                .expect("pattern holds every spring")
        };
        self.spring_slots = springs
            .iter()
            .map(|s| {
                if s.broken {
                    (0, 0)
                } else {
                    (
                        find(&self.row_ptr, &self.cols, s.a, s.b),
                        find(&self.row_ptr, &self.cols, s.b, s.a),
                    )
                }
            })
            .collect();
        self.vals = vec![[[0.0; D]; D]; self.cols.len()];
        self.x = vec![0.0; D * n];
        self.pattern_valid = true;
    }

    fn matvec(&self, x: &[f64], y: &mut [f64]) {
        let block = |c: usize| -> [f64; D] { std::array::from_fn(|q| x[D * c + q]) };
        for i in 0..self.row_ptr.len() - 1 {
            let mut yi = [0.0; D];
            for k in self.row_ptr[i]..self.row_ptr[i + 1] {
                let v = block_mul(&self.vals[k], block(self.cols[k]));
                for q in 0..D {
                    yi[q] += v[q];
                }
            }
            y[D * i..D * i + D].copy_from_slice(&yi);
        }
    }

    fn precond(&self, x: &[f64], y: &mut [f64]) {
        for (i, p) in self.pinv.iter().enumerate() {
            let xi: [f64; D] = std::array::from_fn(|q| x[D * i + q]);
            y[D * i..D * i + D].copy_from_slice(&block_mul(p, xi));
        }
    }

    /// Right-preconditioned BiCGSTAB (block-Jacobi), warm-started from the last Δu.
    fn solve(&mut self) -> Result<(), SimError> {
        let n2 = self.rhs.len();
        self.pinv = self
            .diag
            .iter()
            .map(|&d| block_inverse(&self.vals[d]))
            .collect();
        if self.work.len() != 7 || self.work[0].len() != n2 {
            self.work = vec![vec![0.0; n2]; 7];
        }
        let mut w = std::mem::take(&mut self.work);
        let [r, rh, p, v, y, s, z] = &mut w[..] else {
            unreachable!()
        };
        let bnorm = dot(&self.rhs, &self.rhs).sqrt();
        if bnorm == 0.0 {
            self.x.iter_mut().for_each(|x| *x = 0.0);
            self.work = w;
            return Ok(());
        }
        let tol = 1e-12 * bnorm;
        self.matvec(&self.x, r);
        for k in 0..n2 {
            r[k] = self.rhs[k] - r[k];
        }
        rh.copy_from_slice(r);
        p.iter_mut().for_each(|x| *x = 0.0);
        v.iter_mut().for_each(|x| *x = 0.0);
        let (mut rho, mut alpha, mut omega) = (1.0f64, 1.0f64, 1.0f64);
        let mut t = vec![0.0; n2];
        let mut it = 0;
        let mut res = dot(r, r).sqrt();
        while res > tol {
            if it >= 2000 {
                self.work = w;
                return Err(SimError::Solver(format!(
                    "BiCGSTAB did not converge in 2000 iterations (relative residual {:.1e})",
                    res / bnorm
                )));
            }
            it += 1;
            let rho1 = dot(rh, r);
            if rho1 == 0.0 || omega == 0.0 {
                self.work = w;
                return Err(SimError::Solver("BiCGSTAB broke down (ρ or ω = 0)".into()));
            }
            let beta = (rho1 / rho) * (alpha / omega);
            for k in 0..n2 {
                p[k] = r[k] + beta * (p[k] - omega * v[k]);
            }
            self.precond(p, y);
            self.matvec(y, v);
            alpha = rho1 / dot(rh, v);
            for k in 0..n2 {
                s[k] = r[k] - alpha * v[k];
            }
            if dot(s, s).sqrt() <= tol {
                for k in 0..n2 {
                    self.x[k] += alpha * y[k];
                }
                break;
            }
            self.precond(s, z);
            self.matvec(z, &mut t);
            omega = dot(&t, s) / dot(&t, &t);
            for k in 0..n2 {
                self.x[k] += alpha * y[k] + omega * z[k];
                r[k] = s[k] - omega * t[k];
            }
            rho = rho1;
            res = dot(r, r).sqrt();
        }
        self.iterations += it;
        self.work = w;
        Ok(())
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
