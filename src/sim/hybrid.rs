//! The hybrid loop of ch. 3.4: the mass/spring model steps, every acoustic step its masses'
//! accelerations become sources of the pressure field, and the sensors read the field. One
//! loop for the thesis's plane (`Mech<2>` in the 2-D field of [`super::acoustic`]) and for
//! §6.2's third dimension (`Mech<3>` in the 3-D field of [`super::acoustic3d`]); what differs
//! is only how a mass radiates ([`Medium`]).

use super::acoustic::Field;
use super::acoustic3d::Field3;
use super::geometry::strands;
use super::mech::Mech;
use super::model::{GridSpec, ModelFile, SensorSpec};
use super::{Frame, SimError, SimOptions, SimOutput};

/// Run a model. Damage events fire at the first step whose time reaches theirs.
pub fn simulate(model: &ModelFile, opts: &SimOptions) -> Result<SimOutput, SimError> {
    model.check()?;
    if model.dims() == 3 {
        let mut space = match &model.grid {
            Some(g) => Some(Space::new(model, g)?),
            None => None,
        };
        run::<3>(model, opts, space.as_mut().map(|s| s as &mut dyn Medium<3>))
    } else {
        let mut plane = model.grid.as_ref().map(|g| Plane {
            f: Field::new(g),
            g,
        });
        run::<2>(model, opts, plane.as_mut().map(|p| p as &mut dyn Medium<2>))
    }
}

/// What the masses radiate into.
trait Medium<const D: usize> {
    /// Add the sources of the masses' accelerations over the acoustic step (`u_prev` the
    /// velocities one acoustic step ago).
    fn couple(&mut self, mech: &Mech<D>, u_prev: &[[f64; D]]);
    fn step(&mut self);
    /// Pressure at sensor `k` of the model, Pa.
    fn read(&self, k: usize, s: &SensorSpec) -> f64;
    /// The field as a plane picture (nx × ny): the whole plane, or the sensors' layer.
    fn snapshot(&self) -> Vec<f64>;
}

/// A node's coordinates in three (z 0 in the plane).
fn lift<const D: usize>(v: &[[f64; D]]) -> Vec<[f64; 3]> {
    v.iter()
        .map(|p| std::array::from_fn(|c| if c < D { p[c] } else { 0.0 }))
        .collect()
}

fn run<const D: usize>(
    model: &ModelFile,
    opts: &SimOptions,
    mut medium: Option<&mut dyn Medium<D>>,
) -> Result<SimOutput, SimError> {
    let sys = &model.system;
    let mut mech = Mech::<D>::new(model);
    let relaxed = mech.relax(model, sys.relax);
    let ratio = model
        .grid
        .as_ref()
        .map(|g| (g.dt / sys.dt).round() as usize)
        .unwrap_or(1);
    let mut events = model.damage.clone();
    events.sort_by(|a, b| a.time().total_cmp(&b.time()));
    let mut next_event = 0;
    let mut u_prev = mech.u.clone();
    let mut out = SimOutput {
        sensors: vec![Vec::with_capacity(sys.iterations / ratio + 1); model.sensors.len()],
        sample_rate_hz: model.grid.as_ref().map(|g| 1.0 / g.dt).unwrap_or(0.0),
        relaxed,
        trajectory: Vec::new(),
        snapshots: Vec::new(),
        solver_iterations: 0,
        mass_steps: sys.iterations,
        dims: D,
    };
    let keep_frame = |n: usize| {
        opts.trajectory_every
            .is_some_and(|e| e > 0 && n.is_multiple_of(e))
    };
    let frame = |t: f64, mech: &Mech<D>| Frame {
        t,
        r: lift(&mech.r),
        u: lift(&mech.u),
        tension: mech.tensions(),
        energy: Some(mech.energy()),
    };
    if keep_frame(0) {
        out.trajectory.push(frame(0.0, &mech));
    }
    for n in 0..sys.iterations {
        let t = n as f64 * sys.dt;
        while next_event < events.len() && events[next_event].time() <= t + 0.5 * sys.dt {
            if let Some(j) = mech.damage(&events[next_event]) {
                debug_assert_eq!(j, u_prev.len());
                u_prev.push(mech.u[j]);
            }
            next_event += 1;
        }
        mech.step(sys.solver, sys.dt, t)?;
        if keep_frame(n + 1) {
            out.trajectory.push(frame(t + sys.dt, &mech));
        }
        if let Some(f) = medium.as_deref_mut() {
            if (n + 1) % ratio == 0 {
                f.couple(&mech, &u_prev);
                u_prev.clone_from(&mech.u);
                f.step();
                for (k, (s, spec)) in out.sensors.iter_mut().zip(&model.sensors).enumerate() {
                    s.push(f.read(k, spec));
                }
                let k = (n + 1) / ratio;
                if opts
                    .snapshot_every
                    .is_some_and(|e| e > 0 && k.is_multiple_of(e))
                {
                    out.snapshots.push((t + sys.dt, f.snapshot()));
                }
            }
        }
    }
    out.solver_iterations = mech.solver_iterations();
    Ok(out)
}

/// The plane field of ch. 3.3.
struct Plane<'a> {
    f: Field,
    g: &'a GridSpec,
}

impl Medium<2> for Plane<'_> {
    /// The coupling of ch. 3.4: each mass's acceleration over the acoustic step displaces
    /// fluid. A mass standing for fibre length ℓ moving with normal acceleration aₙ is a
    /// volumetric acceleration ℓ·aₙ per unit depth: a source +ρ·ℓ·aₙ/Δh² just in front of the
    /// fibre and −ρ·ℓ·aₙ/Δh² just behind (a dipole, Fig. 3.28), each split bilinearly over
    /// the four nearest cells. A free fibre end (after a fibre failure) also pushes or leaves
    /// fluid with its end face (width w): one source ρ·w·aₒ/Δh² ahead of it, which is the
    /// monopole of Fig. 4.21.
    fn couple(&mut self, mech: &Mech<2>, u_prev: &[[f64; 2]]) {
        let (g, f) = (self.g, &mut self.f);
        let h = g.dx();
        let inv_area = 1.0 / (h * h);
        let arm = g.dipole_m.map_or(1.0, |d| d / h);
        for st in strands(mech) {
            let i = st.node;
            if mech.held[i] {
                continue;
            }
            let a = [
                (mech.u[i][0] - u_prev[i][0]) / g.dt,
                (mech.u[i][1] - u_prev[i][1]) / g.dt,
            ];
            let tg = st.tangent;
            let nrm = [-tg[1], tg[0]];
            let an = a[0] * nrm[0] + a[1] * nrm[1];
            let s = g.rho * st.length * an * inv_area * arm;
            let r = mech.r[i];
            splat(f, g, [r[0] + 0.5 * h * nrm[0], r[1] + 0.5 * h * nrm[1]], s);
            splat(f, g, [r[0] - 0.5 * h * nrm[0], r[1] - 0.5 * h * nrm[1]], -s);
            if st.count == 1 {
                let o = [-tg[0], -tg[1]];
                let ao = a[0] * o[0] + a[1] * o[1];
                let se = g.rho * st.width * ao * inv_area;
                splat(f, g, [r[0] + 0.5 * h * o[0], r[1] + 0.5 * h * o[1]], se);
            }
        }
    }

    fn step(&mut self) {
        self.f.step();
    }

    fn read(&self, _: usize, s: &SensorSpec) -> f64 {
        self.f.at(s.i, s.j)
    }

    fn snapshot(&self) -> Vec<f64> {
        self.f.cur.clone()
    }
}

/// Add `s` at point p, split bilinearly over the four nearest cell centres.
fn splat(f: &mut Field, g: &GridSpec, p: [f64; 2], s: f64) {
    let h = g.dx();
    let fx = (p[0] - g.x1) / h - 0.5;
    let fy = (p[1] - g.y1) / h - 0.5;
    let (i0, j0) = (fx.floor(), fy.floor());
    let (wx, wy) = (fx - i0, fy - j0);
    for (di, dj, w) in [
        (0, 0, (1.0 - wx) * (1.0 - wy)),
        (1, 0, wx * (1.0 - wy)),
        (0, 1, (1.0 - wx) * wy),
        (1, 1, wx * wy),
    ] {
        let (i, j) = (i0 as i64 + di, j0 as i64 + dj);
        if i >= 0 && j >= 0 && (i as usize) < g.nx && (j as usize) < g.ny && w > 0.0 {
            f.add_source(i as usize, j as usize, s * w);
        }
    }
}

/// The 3-D field of §6.2.
struct Space<'a> {
    f: Field3,
    g: &'a GridSpec,
    /// Each sensor's cell, in the model's order.
    cells: Vec<(usize, usize, usize)>,
    /// The layer a snapshot shows: the first sensor's, or the sheet's surface.
    layer: usize,
}

impl<'a> Space<'a> {
    fn new(m: &ModelFile, g: &'a GridSpec) -> Result<Space<'a>, SimError> {
        let f = Field3::new(&g.grid3().expect("a 3-D model's grid has a z axis"))?;
        let cells: Vec<_> = m.sensors.iter().map(|s| m.sensor_cell3(s)).collect();
        let layer = cells.first().map(|c| c.2).or(m.surface_k()).unwrap_or(0);
        Ok(Space { f, g, cells, layer })
    }

    /// Add `s` at point p, split trilinearly over the eight nearest cell centres.
    fn splat(&mut self, p: [f64; 3], s: f64) {
        let g = self.g;
        let h = g.dx();
        let z1 = g.z.map_or(0.0, |z| z.z1);
        let fr = [
            (p[0] - g.x1) / h - 0.5,
            (p[1] - g.y1) / h - 0.5,
            (p[2] - z1) / h - 0.5,
        ];
        let base = fr.map(f64::floor);
        let w1: [f64; 3] = std::array::from_fn(|c| fr[c] - base[c]);
        let n = [self.f.nx, self.f.ny, self.f.nz];
        for corner in 0..8usize {
            let mut idx = [0usize; 3];
            let mut w = 1.0;
            let mut inside = true;
            for c in 0..3 {
                let up = (corner >> c) & 1;
                let k = base[c] as i64 + up as i64;
                w *= if up == 1 { w1[c] } else { 1.0 - w1[c] };
                inside &= k >= 0 && (k as usize) < n[c];
                idx[c] = k.max(0) as usize;
            }
            if inside && w > 0.0 {
                self.f.add_source(idx[0], idx[1], idx[2], s * w);
            }
        }
    }
}

impl Medium<3> for Space<'_> {
    /// Ch. 3.4's coupling in space. A mass standing for fibre length ℓ accelerates across
    /// its fibre: the fluid in front of the fibre's face is pushed and the fluid behind it
    /// follows. The fibre is a ribbon lying flat in the sheet, width w across the fibre in
    /// the sheet's plane (ê_w) and thickness t through it (ê_t = tangent × ê_w): moving along
    /// ê_t it pushes with its face ℓ·w, along ê_w with ℓ·t. So each mass is two dipoles, as
    /// in the plane (a source ±ρ·ℓ·w·a_t/Δh³ half a cell either side along ê_t, and
    /// ±ρ·ℓ·t·a_w/Δh³ along ê_w), each source split over the eight nearest cells — linear in
    /// the acceleration, so no harmonic is made by the coupling. A free fibre end also pushes
    /// fluid with its end face w·t (a monopole ρ·w·t·aₒ/Δh³ ahead of it, Fig. 4.21's).
    fn couple(&mut self, mech: &Mech<3>, u_prev: &[[f64; 3]]) {
        let g = self.g;
        let h = g.dx();
        let inv_vol = 1.0 / (h * h * h);
        let arm = g.dipole_m.map_or(1.0, |d| d / h);
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        for st in strands(mech) {
            let i = st.node;
            if mech.held[i] {
                continue;
            }
            let a: [f64; 3] = std::array::from_fn(|c| (mech.u[i][c] - u_prev[i][c]) / g.dt);
            let tg = st.tangent;
            let r = mech.r[i];
            // The ribbon's width lies in the sheet's plane across the fibre; a fibre standing
            // upright has its width along x.
            let flat = [-tg[1], tg[0], 0.0];
            let l = dot(flat, flat).sqrt();
            let ew = if l > 1e-12 {
                flat.map(|v| v / l)
            } else {
                [1.0, 0.0, 0.0]
            };
            let et = [
                tg[1] * ew[2] - tg[2] * ew[1],
                tg[2] * ew[0] - tg[0] * ew[2],
                tg[0] * ew[1] - tg[1] * ew[0],
            ];
            for (dir, face) in [(et, st.width), (ew, st.thickness)] {
                let s = g.rho * st.length * face * dot(a, dir) * inv_vol * arm;
                if s != 0.0 {
                    self.splat(std::array::from_fn(|c| r[c] + 0.5 * h * dir[c]), s);
                    self.splat(std::array::from_fn(|c| r[c] - 0.5 * h * dir[c]), -s);
                }
            }
            if st.count == 1 {
                let o = tg.map(|v| -v);
                let se = g.rho * st.width * st.thickness * dot(a, o) * inv_vol;
                self.splat(std::array::from_fn(|c| r[c] + 0.5 * h * o[c]), se);
            }
        }
    }

    fn step(&mut self) {
        self.f.step();
    }

    fn read(&self, k: usize, _: &SensorSpec) -> f64 {
        let (i, j, l) = self.cells[k];
        self.f.at(i, j, l)
    }

    fn snapshot(&self) -> Vec<f64> {
        let plane = self.f.nx * self.f.ny;
        self.f.cur[self.layer * plane..(self.layer + 1) * plane].to_vec()
    }
}
