//! The mass/spring model (ch. 3.2): forces with Poisson's ratio, the four solvers, the
//! initial-condition relaxation of Alg. 7 and the damage events of Alg. 8 and 9 — in the
//! thesis's plane (`D` = 2) or in space (`D` = 3, §6.2). The arithmetic is written once for
//! both: every sum over components starts from its first term and adds the rest in order,
//! so the plane model computes exactly what it computed before it had a third axis.

// Index loops over nodes and 2×2 components read like the equations they implement.
#![allow(clippy::needless_range_loop)]

mod implicit;

use super::model::{DamageSpec, ForceSpec, IcKind, ModelFile, Solver};
use super::SimError;

/// One spring with its material (Eq. 3.2.5, 3.2.9).
#[derive(Debug, Clone)]
pub struct Spring {
    pub a: usize,
    pub b: usize,
    pub l0: f64,
    pub e: f64,
    pub t: f64,
    pub w: f64,
    pub nu: f64,
    pub fibre: u32,
    /// Removed by a fibre failure (stiffness zero).
    pub broken: bool,
    /// Cross-section used for the stiffness (Eq. 3.2.9 at the load).
    pub area: f64,
}

impl Spring {
    /// Tension f(l) = k·(l − L) and df/dl = k, with k = E·A/L (Eq. 3.2.5) and A the
    /// cross-section of Eq. 3.2.9 at the load, i.e. at the strain of t = 0 (see
    /// [`Mech::freeze_areas`]).
    #[inline]
    pub fn tension(&self, l: f64) -> (f64, f64) {
        let k = self.e * self.area / self.l0;
        (k * (l - self.l0), k)
    }

    /// Cross-section of Eq. 3.2.9 at length l: A = t·w·(1 − ν·ΔL/L)².
    pub fn area_at(&self, l: f64) -> f64 {
        let c = 1.0 - self.nu * (l - self.l0) / self.l0;
        self.t * self.w * c * c
    }

    /// Small-strain stiffness E·t·w/L.
    pub fn k0(&self) -> f64 {
        self.e * self.t * self.w / self.l0
    }
}

/// The state and structure of a mass/spring model in `D` dimensions.
#[derive(Debug, Clone)]
pub struct Mech<const D: usize> {
    pub r: Vec<[f64; D]>,
    pub u: Vec<[f64; D]>,
    pub m: Vec<f64>,
    /// Clamped now (fixed nodes, and nodes held by an initial condition).
    pub held: Vec<bool>,
    /// Clamped for good (type 1 in the Nodes section).
    pub fixed: Vec<bool>,
    pub springs: Vec<Spring>,
    pub damping: f64,
    pub forces: Vec<ForceSpec>,
    /// Velocity Verlet keeps the acceleration between steps.
    acc: Vec<[f64; D]>,
    acc_valid: bool,
    implicit: implicit::Implicit<D>,
    /// Scratch of the explicit solvers, reused from step to step.
    work: Vec<Vec<[f64; D]>>,
}

/// a − b.
#[inline]
fn sub<const D: usize>(a: [f64; D], b: [f64; D]) -> [f64; D] {
    std::array::from_fn(|c| a[c] - b[c])
}

/// a·b, summed from the first component on.
#[inline]
fn dotv<const D: usize>(a: [f64; D], b: [f64; D]) -> f64 {
    let mut s = a[0] * b[0];
    for c in 1..D {
        s += a[c] * b[c];
    }
    s
}

/// A D×D block times a vector (row by row, as [`dotv`]).
#[inline]
fn block_mul<const D: usize>(m: &[[f64; D]; D], x: [f64; D]) -> [f64; D] {
    std::array::from_fn(|a| dotv(m[a], x))
}

/// The inverse of a 2×2 or 3×3 block (the block-Jacobi preconditioner), by cofactors.
fn block_inverse<const D: usize>(m: &[[f64; D]; D]) -> [[f64; D]; D] {
    let mut out = [[0.0; D]; D];
    if D == 2 {
        let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        out[0][0] = m[1][1] / det;
        out[0][1] = -m[0][1] / det;
        out[1][0] = -m[1][0] / det;
        out[1][1] = m[0][0] / det;
    } else {
        // Cofactor C[i][j] from the rows and columns other than i and j, cyclically.
        let cof = |i: usize, j: usize| {
            let (i1, i2, j1, j2) = ((i + 1) % 3, (i + 2) % 3, (j + 1) % 3, (j + 2) % 3);
            m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1]
        };
        let det = m[0][0] * cof(0, 0) + m[0][1] * cof(0, 1) + m[0][2] * cof(0, 2);
        for i in 0..D {
            for j in 0..D {
                out[i][j] = cof(j, i) / det;
            }
        }
    }
    out
}

/// A node's position in `D` dimensions (z is 0 where the file gives none).
fn position<const D: usize>(nd: &super::model::NodeSpec) -> [f64; D] {
    let v = [nd.x, nd.y, nd.z.unwrap_or(0.0)];
    std::array::from_fn(|c| v[c])
}

/// What the relaxation did.
#[derive(Debug, Clone, Copy)]
pub struct Relaxed {
    pub steps: usize,
    pub converged: bool,
    /// Largest force on a free node at the end, relative to the largest spring tension.
    pub residual: f64,
}

impl<const D: usize> Mech<D> {
    pub fn new(model: &ModelFile) -> Mech<D> {
        let n = model.nodes.len();
        let springs = model
            .springs
            .iter()
            .enumerate()
            .map(|(k, s)| Spring {
                a: s.a,
                b: s.b,
                l0: model.rest_length(k),
                e: s.e,
                t: s.t,
                w: s.w,
                nu: s.poisson,
                fibre: s.fibre,
                broken: false,
                area: s.t * s.w,
            })
            .collect();
        let fixed: Vec<bool> = model.nodes.iter().map(|nd| nd.fixed).collect();
        Mech {
            r: model.nodes.iter().map(position::<D>).collect(),
            u: vec![[0.0; D]; n],
            m: model.nodes.iter().map(|nd| nd.mass).collect(),
            held: fixed.clone(),
            fixed,
            springs,
            damping: model.system.damping,
            forces: model.forces.clone(),
            acc: vec![[0.0; D]; n],
            acc_valid: false,
            implicit: implicit::Implicit::default(),
            work: Vec::new(),
        }
    }

    pub fn len(&self) -> usize {
        self.r.len()
    }

    pub fn is_empty(&self) -> bool {
        self.r.is_empty()
    }

    /// Spring and applied forces at time `t` on every node, positions `r` (no damping).
    fn spring_forces(&self, r: &[[f64; D]], t: f64, out: &mut [[f64; D]]) {
        out.iter_mut().for_each(|f| *f = [0.0; D]);
        for s in self.springs.iter().filter(|s| !s.broken) {
            let d = sub(r[s.b], r[s.a]);
            let l = dotv(d, d).sqrt();
            if l == 0.0 {
                continue;
            }
            let (f, _) = s.tension(l);
            for c in 0..D {
                let g = f * d[c] / l;
                out[s.a][c] += g;
                out[s.b][c] -= g;
            }
        }
        for fs in &self.forces {
            if t >= fs.start && t < fs.finish {
                let v = [fs.fx, fs.fy, fs.fz];
                for c in 0..D {
                    out[fs.node][c] += v[c];
                }
            }
        }
    }

    /// Accelerations (Eq. 3.2.10a) with damping `b`; zero for held nodes.
    fn accel(&self, r: &[[f64; D]], u: &[[f64; D]], t: f64, b: f64, out: &mut [[f64; D]]) {
        self.spring_forces(r, t, out);
        for i in 0..out.len() {
            if self.held[i] {
                out[i] = [0.0; D];
            } else {
                let inv = 1.0 / self.m[i];
                for c in 0..D {
                    out[i][c] = (out[i][c] - b * u[i][c]) * inv;
                }
            }
        }
    }

    /// Largest tension in an intact spring (a force scale).
    pub fn max_tension(&self) -> f64 {
        self.springs
            .iter()
            .filter(|s| !s.broken)
            .map(|s| {
                let l = dist(self.r[s.a], self.r[s.b]);
                s.tension(l).0.abs()
            })
            .fold(0.0, f64::max)
    }

    /// Highest angular frequency of a single mass on its springs (bound for explicit steps).
    pub fn omega_max(&self) -> f64 {
        let mut ksum = vec![0.0; self.len()];
        for s in self.springs.iter().filter(|s| !s.broken) {
            ksum[s.a] += s.k0();
            ksum[s.b] += s.k0();
        }
        (0..self.len())
            .filter(|&i| !self.held[i])
            .map(|i| 2.0 * (ksum[i] / self.m[i]).sqrt())
            .fold(0.0, f64::max)
    }

    /// Poisson's ratio (Eq. 3.2.9): set each spring's cross-section from its strain under the
    /// load, i.e. in the current (t = 0) configuration, and keep it while the structure
    /// vibrates. Updating it with every oscillation would make the tension E·A(l)·ε fall with
    /// strain beyond ε = 1/(3ν) (the rubber band of Table 3.7 is stretched 347 %): the chain
    /// then collapses longitudinally, which is not what the thesis's model shows.
    pub fn freeze_areas(&mut self) {
        for s in &mut self.springs {
            let l = dist(self.r[s.a], self.r[s.b]);
            s.area = s.area_at(l);
        }
    }

    /// Alg. 7: displace the nodes with an initial condition and hold them; let the rest find
    /// its equilibrium by RK4 with a damping that starts at zero and grows slowly (too fast a
    /// growth stops the system in a false equilibrium, Fig. 3.10); then release the EqIC nodes
    /// with their initial velocities and keep the StIC nodes held.
    pub fn relax(&mut self, model: &ModelFile, enabled: bool) -> Relaxed {
        for ic in &model.initial {
            let d = [ic.dx, ic.dy, ic.dz];
            for c in 0..D {
                self.r[ic.node][c] += d[c];
            }
            self.held[ic.node] = true;
        }
        self.freeze_areas();
        let mut out = Relaxed {
            steps: 0,
            converged: true,
            residual: 0.0,
        };
        let free: Vec<usize> = (0..self.len()).filter(|&i| !self.held[i]).collect();
        if enabled && !free.is_empty() {
            let w = self.omega_max().max(1e-300);
            let dt = 1.0 / w;
            let m_min = free
                .iter()
                .map(|&i| self.m[i])
                .fold(f64::INFINITY, f64::min);
            // Damping rates b/2m from 1e-4·ω_max up to 0.05·ω_max, growing 0.02 % per step
            // after 2 000 undamped steps. (Mass-proportional damping decays every mode at
            // b/2m until it passes the mode's critical value; beyond, the slow modes crawl.)
            let b_max = 0.1 * m_min * w;
            let mut b = 0.0;
            let l_min = self
                .springs
                .iter()
                .map(|s| s.l0)
                .fold(f64::INFINITY, f64::min);
            let mut f = vec![[0.0; D]; self.len()];
            let max_steps = 100_000;
            out.converged = false;
            while out.steps < max_steps {
                self.rk4(dt, -1.0, b);
                out.steps += 1;
                if out.steps == 2000 {
                    b = 2e-4 * m_min * w;
                } else if out.steps > 2000 {
                    b = (b * 1.0002).min(b_max);
                }
                if out.steps.is_multiple_of(200) {
                    self.spring_forces(&self.r, -1.0, &mut f);
                    let scale = self.max_tension().max(1e-300);
                    let fmax = free.iter().map(|&i| norm(f[i])).fold(0.0, f64::max);
                    let umax = free.iter().map(|&i| norm(self.u[i])).fold(0.0, f64::max);
                    out.residual = fmax / scale;
                    if out.residual < 1e-8 && umax * dt < 1e-11 * l_min {
                        out.converged = true;
                        break;
                    }
                }
            }
        }
        if enabled && !free.is_empty() && !out.converged {
            // Finish with Newton steps on the static equilibrium: an implicit Euler step
            // from rest with a step far beyond every period is one (Δr = K⁻¹F).
            self.acc_valid = false;
            self.implicit.pattern_valid = false;
            let damping = std::mem::replace(&mut self.damping, 0.0);
            let mut f = vec![[0.0; D]; self.len()];
            for _ in 0..20 {
                self.u.iter_mut().for_each(|u| *u = [0.0; D]);
                if self.implicit_step(1.0, -1.0).is_err() {
                    break;
                }
                out.steps += 1;
                self.spring_forces(&self.r, -1.0, &mut f);
                let scale = self.max_tension().max(1e-300);
                out.residual = free.iter().map(|&i| norm(f[i])).fold(0.0, f64::max) / scale;
                if out.residual < 1e-10 {
                    out.converged = true;
                    break;
                }
            }
            self.damping = damping;
        }
        self.freeze_areas();
        self.u.iter_mut().for_each(|u| *u = [0.0; D]);
        for ic in &model.initial {
            if ic.kind == IcKind::Eq && !self.fixed[ic.node] {
                self.held[ic.node] = false;
                let v = [ic.du, ic.dv, ic.dw];
                self.u[ic.node] = std::array::from_fn(|c| v[c]);
            }
        }
        self.acc_valid = false;
        self.implicit.pattern_valid = false;
        out
    }

    /// Apply a damage event (Alg. 8 or 9). Returns the index of a node it created.
    pub fn damage(&mut self, d: &DamageSpec) -> Option<usize> {
        self.acc_valid = false;
        self.implicit.pattern_valid = false;
        match *d {
            DamageSpec::Fibre { spring, .. } => {
                self.springs[spring].broken = true;
                None
            }
            DamageSpec::Bond { node, .. } => {
                let keep = self
                    .springs
                    .iter()
                    .filter(|s| !s.broken && (s.a == node || s.b == node))
                    .map(|s| s.fibre)
                    .min()?;
                let j = self.len();
                self.r.push(self.r[node]);
                self.u.push(self.u[node]);
                // The bond's mass is the sum of the two fibres' masses; each fibre takes
                // back half.
                self.m[node] *= 0.5;
                self.m.push(self.m[node]);
                let fixed = self.fixed[node];
                self.fixed.push(fixed);
                self.held[node] = fixed;
                self.held.push(fixed);
                self.acc.push([0.0; D]);
                for s in self.springs.iter_mut() {
                    if s.fibre != keep {
                        if s.a == node {
                            s.a = j;
                        }
                        if s.b == node {
                            s.b = j;
                        }
                    }
                }
                Some(j)
            }
        }
    }

    /// One step of `solver` from time t.
    pub fn step(&mut self, solver: Solver, dt: f64, t: f64) -> Result<(), SimError> {
        let b = self.damping;
        match solver {
            Solver::ExplicitEuler => {
                let mut a = std::mem::take(&mut self.acc);
                self.accel(&self.r, &self.u, t, b, &mut a);
                for i in 0..self.len() {
                    if !self.held[i] {
                        for c in 0..D {
                            self.u[i][c] += dt * a[i][c];
                            self.r[i][c] += dt * self.u[i][c];
                        }
                    }
                }
                self.acc = a;
                self.acc_valid = false;
            }
            Solver::Rk4 => self.rk4(dt, t, b),
            Solver::Verlet => {
                let n = self.len();
                let mut a = std::mem::take(&mut self.acc);
                if !self.acc_valid {
                    self.accel(&self.r, &self.u, t, b, &mut a);
                }
                let mut w = std::mem::take(&mut self.work);
                if w.is_empty() {
                    w.push(Vec::new());
                }
                let uh = &mut w[0];
                uh.resize(n, [0.0; D]);
                for i in 0..n {
                    if self.held[i] {
                        continue;
                    }
                    for c in 0..D {
                        self.r[i][c] += self.u[i][c] * dt + 0.5 * a[i][c] * dt * dt;
                        uh[i][c] = self.u[i][c] + 0.5 * a[i][c] * dt;
                    }
                }
                self.accel(&self.r, uh, t + dt, b, &mut a);
                for i in 0..n {
                    if !self.held[i] {
                        for c in 0..D {
                            self.u[i][c] = uh[i][c] + 0.5 * a[i][c] * dt;
                        }
                    }
                }
                self.work = w;
                self.acc = a;
                self.acc_valid = true;
            }
            Solver::ImplicitEuler => self.implicit_step(dt, t)?,
        }
        Ok(())
    }

    fn rk4(&mut self, dt: f64, t: f64, b: f64) {
        let n = self.len();
        // Scratch kept between steps (the relaxation runs up to 100 000 of them):
        // r0, u0, rt, ut, then K1…K4 of the accelerations and of the velocities.
        let mut w = std::mem::take(&mut self.work);
        w.resize(12, Vec::new());
        for v in w.iter_mut() {
            v.resize(n, [0.0; D]);
        }
        let (state, k) = w.split_at_mut(4);
        let [r0, u0, rt, ut] = state else {
            unreachable!()
        };
        let (ka, kv) = k.split_at_mut(4);
        r0.copy_from_slice(&self.r);
        u0.copy_from_slice(&self.u);
        rt.copy_from_slice(&self.r);
        ut.copy_from_slice(&self.u);
        let frac = [0.0, 0.5, 0.5, 1.0];
        for s in 0..4 {
            if s > 0 {
                for i in 0..n {
                    for c in 0..D {
                        rt[i][c] = r0[i][c] + frac[s] * dt * kv[s - 1][i][c];
                        ut[i][c] = u0[i][c] + frac[s] * dt * ka[s - 1][i][c];
                    }
                }
            }
            self.accel(rt, ut, t + frac[s] * dt, b, &mut ka[s]);
            for i in 0..n {
                kv[s][i] = if self.held[i] { [0.0; D] } else { ut[i] };
            }
        }
        for i in 0..n {
            if self.held[i] {
                continue;
            }
            for c in 0..D {
                self.r[i][c] = r0[i][c]
                    + dt / 6.0
                        * (kv[0][i][c] + 2.0 * kv[1][i][c] + 2.0 * kv[2][i][c] + kv[3][i][c]);
                self.u[i][c] = u0[i][c]
                    + dt / 6.0
                        * (ka[0][i][c] + 2.0 * ka[1][i][c] + 2.0 * ka[2][i][c] + ka[3][i][c]);
            }
        }
        self.work = w;
        self.acc_valid = false;
    }
}

pub fn dist<const D: usize>(a: [f64; D], b: [f64; D]) -> f64 {
    let mut s = (b[0] - a[0]).powi(2);
    for c in 1..D {
        s += (b[c] - a[c]).powi(2);
    }
    s.sqrt()
}

fn norm<const D: usize>(a: [f64; D]) -> f64 {
    dotv(a, a).sqrt()
}

impl<const D: usize> Mech<D> {
    /// Each spring's tension now, N (0 for a broken one): Fig. 3.4c, Storage `Tension`.
    pub fn tensions(&self) -> Vec<f64> {
        self.springs
            .iter()
            .map(|s| match s.broken {
                true => 0.0,
                false => s.tension(dist(self.r[s.a], self.r[s.b])).0,
            })
            .collect()
    }

    /// Kinetic energy of the free masses and elastic energy ½k(l − L)² of the intact
    /// springs, J (Storage `Energy`).
    pub fn energy(&self) -> [f64; 2] {
        let kinetic = (0..self.len())
            .filter(|&i| !self.held[i])
            .map(|i| 0.5 * self.m[i] * dotv(self.u[i], self.u[i]))
            .sum();
        let potential = self
            .springs
            .iter()
            .filter(|s| !s.broken)
            .map(|s| {
                let (f, k) = s.tension(dist(self.r[s.a], self.r[s.b]));
                0.5 * f * f / k
            })
            .sum();
        [kinetic, potential]
    }

    /// BiCGSTAB iterations so far (implicit solver).
    pub fn solver_iterations(&self) -> usize {
        self.implicit.iterations
    }
}
