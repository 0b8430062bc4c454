//! The simulator's input: one struct for both input formats (the thesis's sectioned file of
//! Appendix A, parsed in [`super::input`], and the equivalent TOML, read by serde), checked
//! once into a valid model by [`ModelFile::check`].

use super::SimError;
use serde::{Deserialize, Serialize};

/// ODE solver for the mass/spring model (ch. 3.2.3–3.2.6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Solver {
    /// Explicit (symplectic) Euler, Alg. 1: u ← u + Δt·a(r, u), then r ← r + Δt·u.
    ExplicitEuler,
    /// Classical fourth-order Runge–Kutta, Alg. 3.
    Rk4,
    /// Velocity Verlet, Alg. 4.
    Verlet,
    /// Linearised implicit Euler, Eq. 3.2.29, solved by Jacobi-preconditioned BiCGSTAB on a
    /// sparse matrix assembled each step. The default, as in the thesis.
    ImplicitEuler,
}

impl Solver {
    /// The solvers by their number in `--param solver=N` (a number, so that `--sweep
    /// solver=0:3:4` steps through them): 0 explicit Euler, 1 RK4, 2 Verlet, 3 implicit Euler.
    pub const BY_NUMBER: [Solver; 4] = [
        Solver::ExplicitEuler,
        Solver::Rk4,
        Solver::Verlet,
        Solver::ImplicitEuler,
    ];

    /// The solver numbered `n`; an error for any other value (a typo never runs the
    /// default).
    pub fn numbered(n: f64) -> Result<Solver, SimError> {
        Solver::BY_NUMBER
            .iter()
            .enumerate()
            .find(|(k, _)| *k as f64 == n)
            .map(|(_, s)| *s)
            .ok_or_else(|| {
                SimError::Model(format!(
                    "solver={n}: 0 (explicit-euler), 1 (rk4), 2 (verlet) or 3 (implicit-euler), or one of those names"
                ))
            })
    }

    /// Its number in `--param solver=N`.
    pub fn number(self) -> usize {
        Solver::BY_NUMBER
            .iter()
            .position(|s| *s == self)
            .expect("every solver is numbered")
    }
}

impl std::str::FromStr for Solver {
    type Err = SimError;
    /// The names of the TOML (`explicit-euler`, `rk4`, `verlet`, `implicit-euler`) and the
    /// Appendix-A file's words (`EEuler`, `IEuler`, `VVerlet`, …), case-insensitive.
    fn from_str(word: &str) -> Result<Solver, SimError> {
        Ok(match word.to_ascii_lowercase().as_str() {
            "ieuler" | "implicit" | "implicit-euler" => Solver::ImplicitEuler,
            "eeuler" | "euler" | "explicit-euler" => Solver::ExplicitEuler,
            "rk4" => Solver::Rk4,
            "verlet" | "vverlet" | "velocity-verlet" => Solver::Verlet,
            _ => {
                return Err(SimError::Model(format!(
                    "solver {word:?}: expected implicit-euler (IEuler), explicit-euler (EEuler), rk4 or verlet"
                )))
            }
        })
    }
}

pub use super::order::Order;

/// Limits on the sizes a model file states (checked in [`ModelFile::check`]): 10⁸
/// mass/spring steps, 10⁶ masses, 16.8 M acoustic cells (4 096², about 1 GiB of fields).
pub const MAX_ITERATIONS: usize = 100_000_000;
pub const MAX_NODES: usize = 1_000_000;
pub const MAX_GRID_CELLS: usize = 1 << 24;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct System {
    /// Mass/spring time step, s.
    pub dt: f64,
    /// Frictional damping coefficient b, kg/s (Eq. 3.2.2), the same for every mass.
    #[serde(default)]
    pub damping: f64,
    /// Number of mass/spring steps after t = 0.
    pub iterations: usize,
    #[serde(default = "default_solver")]
    pub solver: Solver,
    /// Relax to equilibrium before t = 0 (Alg. 7). Without it the given positions are used
    /// as they are.
    #[serde(default = "yes")]
    pub relax: bool,
}

fn default_solver() -> Solver {
    Solver::ImplicitEuler
}
fn yes() -> bool {
    true
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NodeSpec {
    pub x: f64,
    pub y: f64,
    /// Height, m: a node with a z makes the model three-dimensional (§6.2); absent in a
    /// plane model (Appendix A).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub z: Option<f64>,
    /// kg
    pub mass: f64,
    /// Clamped for the whole simulation.
    #[serde(default)]
    pub fixed: bool,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpringSpec {
    pub a: usize,
    pub b: usize,
    /// Young's modulus, Pa.
    pub e: f64,
    /// Equilibrium length L, m. Absent: the distance of the two nodes as given.
    #[serde(default)]
    pub length: Option<f64>,
    /// Thickness t and width w, m (k = E·t·w/L, Eq. 3.2.5).
    pub t: f64,
    pub w: f64,
    /// Poisson's ratio ν (Eq. 3.2.9).
    #[serde(default)]
    pub poisson: f64,
    /// Fibre id: a bond failure keeps the springs of the lower fibre id on the old mass.
    #[serde(default)]
    pub fibre: u32,
}

/// Initial condition kind (ch. 3.2.8).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum IcKind {
    /// Equilibrium IC: held at the displaced position while the rest relaxes, released at 0.
    Eq,
    /// Stretching IC: held at the displaced position for the whole simulation (a load).
    St,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InitialSpec {
    pub node: usize,
    #[serde(default)]
    pub dx: f64,
    #[serde(default)]
    pub dy: f64,
    /// Velocity at t = 0 (applied when the node is released), m/s.
    #[serde(default)]
    pub du: f64,
    #[serde(default)]
    pub dv: f64,
    /// Displacement and velocity along z (a 3-D model only).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub dz: f64,
    #[serde(default, skip_serializing_if = "is_zero")]
    pub dw: f64,
    pub kind: IcKind,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForceSpec {
    pub node: usize,
    pub fx: f64,
    pub fy: f64,
    /// Along z (a 3-D model only).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub fz: f64,
    /// Applied for start ≤ t < finish, s (t < 0 is the relaxation).
    pub start: f64,
    pub finish: f64,
}

/// A damage event (ch. 4.5.2, 4.6.2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum DamageSpec {
    /// Fibre/fibre bond failure (Alg. 8): the bond mass splits in two, each half keeping one
    /// fibre's pair of opposing springs; a bond held by an initial condition is released.
    Bond { node: usize, time: f64 },
    /// Fibre failure (Alg. 9): the spring's stiffness becomes zero (it is removed).
    Fibre { spring: usize, time: f64 },
}

impl DamageSpec {
    pub fn time(&self) -> f64 {
        match self {
            DamageSpec::Bond { time, .. } | DamageSpec::Fibre { time, .. } => *time,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    pub x1: f64,
    pub x2: f64,
    pub y1: f64,
    pub y2: f64,
    pub nx: usize,
    pub ny: usize,
    /// Acoustic time step, s (the sensors' sampling interval); a whole multiple of the
    /// mass/spring step.
    pub dt: f64,
    /// Fluid density, kg/m³, and speed of sound, m/s.
    pub rho: f64,
    pub c: f64,
    pub order: Order,
    /// The dipole moment's arm, m: a mass's ± sources (Eq. 3.4.6) stand half a cell either
    /// side of the fibre, so their moment is ρ·ℓ·aₙ times the cell. None: the cell (the
    /// thesis's coupling). A grid refined by `grid_um` keeps its original cell here, so that
    /// a fibre radiates the same dipole whatever the cell (grid convergence).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dipole_m: Option<f64>,
    /// A third axis, z1…z2 in nz cells (cubic: (z2 − z1)/nz = Δx): the field of a 3-D
    /// model ([`super::acoustic3d`]). Absent: the plane grid of ch. 3.3.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub z: Option<ZAxis>,
}

/// The z extent of a 3-D grid.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZAxis {
    pub z1: f64,
    pub z2: f64,
    pub nz: usize,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

impl GridSpec {
    pub fn dx(&self) -> f64 {
        (self.x2 - self.x1) / self.nx as f64
    }
    pub fn dy(&self) -> f64 {
        (self.y2 - self.y1) / self.ny as f64
    }
    /// The cell of this grid holding the centre of cell (i, j) of the grid it was refined
    /// from by `grid_um` (whose cell `dipole_m` keeps); (i, j) itself for a grid never
    /// refined. Sensors given in the original grid's cells stay where they were.
    pub fn original_cell(&self, i: usize, j: usize) -> Option<(usize, usize)> {
        let Some(h0) = self.dipole_m else {
            return Some((i, j));
        };
        self.cell(
            self.x1 + (i as f64 + 0.5) * h0,
            self.y1 + (j as f64 + 0.5) * h0,
        )
    }

    /// The 3-D field's grid, for a grid with a z axis.
    pub fn grid3(&self) -> Option<super::acoustic3d::Grid3> {
        let z = self.z?;
        Some(super::acoustic3d::Grid3 {
            x1: self.x1,
            y1: self.y1,
            z1: z.z1,
            h: self.dx(),
            nx: self.nx,
            ny: self.ny,
            nz: z.nz,
            dt: self.dt,
            c: self.c,
            rho: self.rho,
            order: self.order,
        })
    }

    /// Courant number α = c·Δt/Δh.
    pub fn alpha(&self) -> f64 {
        self.c * self.dt / self.dx()
    }
    /// Cell (i, j) holding the point (x, y), if inside.
    pub fn cell(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        let i = ((x - self.x1) / self.dx()).floor();
        let j = ((y - self.y1) / self.dy()).floor();
        (i >= 0.0 && j >= 0.0 && (i as usize) < self.nx && (j as usize) < self.ny)
            .then_some((i as usize, j as usize))
    }
    /// Centre of cell (i, j).
    pub fn centre(&self, i: usize, j: usize) -> (f64, f64) {
        (
            self.x1 + (i as f64 + 0.5) * self.dx(),
            self.y1 + (j as f64 + 0.5) * self.dy(),
        )
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorSpec {
    /// Grid cell.
    pub i: usize,
    pub j: usize,
    /// Layer of a 3-D grid. Absent: the sheet's surface, the first layer above the highest
    /// mass ([`ModelFile::surface_k`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k: Option<usize>,
}

/// A whole simulation input.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelFile {
    /// Name written to the `experiment` column.
    #[serde(default = "default_name")]
    pub name: String,
    /// Ground-truth label of the signals (`bond_failure`, `fibre_failure`, …).
    #[serde(default)]
    pub label: Option<String>,
    pub system: System,
    pub nodes: Vec<NodeSpec>,
    #[serde(default)]
    pub springs: Vec<SpringSpec>,
    #[serde(default)]
    pub initial: Vec<InitialSpec>,
    #[serde(default)]
    pub forces: Vec<ForceSpec>,
    #[serde(default)]
    pub damage: Vec<DamageSpec>,
    #[serde(default)]
    pub grid: Option<GridSpec>,
    #[serde(default)]
    pub sensors: Vec<SensorSpec>,
}

fn default_name() -> String {
    "simulation".into()
}

fn bad(msg: String) -> SimError {
    SimError::Model(msg)
}

impl ModelFile {
    /// Check every index, length and the acoustic stability condition once.
    pub fn check(&self) -> Result<(), SimError> {
        self.check_system()?;
        let n = self.nodes.len();
        self.check_nodes_and_springs(n)?;
        self.check_damage(n)?;
        self.check_dims()?;
        if let Some(g) = &self.grid {
            self.check_grid(g)?;
        } else if !self.sensors.is_empty() {
            return Err(bad("sensors need a grid".into()));
        }
        Ok(())
    }

    /// `[system]`'s sizes and steps, and the node count, bounded before anything is allocated.
    fn check_system(&self) -> Result<(), SimError> {
        let s = &self.system;
        // Sizes are claims of an input file: bounded before anything is allocated or looped.
        if s.iterations > MAX_ITERATIONS {
            return Err(bad(format!(
                "system.iterations = {} exceeds the limit of {MAX_ITERATIONS}",
                s.iterations
            )));
        }
        if self.nodes.len() > MAX_NODES {
            return Err(bad(format!(
                "{} nodes exceed the limit of {MAX_NODES}",
                self.nodes.len()
            )));
        }
        if !(s.dt > 0.0 && s.dt.is_finite()) {
            return Err(bad(format!("system.dt must be > 0, got {}", s.dt)));
        }
        if s.damping < 0.0 || !s.damping.is_finite() {
            return Err(bad(format!(
                "system.damping must be ≥ 0, got {}",
                s.damping
            )));
        }
        if self.nodes.is_empty() {
            return Err(bad("the model has no nodes".into()));
        }
        Ok(())
    }

    /// Nodes' masses, springs' nodes and sizes, and the nodes of initial conditions and forces.
    fn check_nodes_and_springs(&self, n: usize) -> Result<(), SimError> {
        for (i, nd) in self.nodes.iter().enumerate() {
            if !(nd.mass > 0.0 && nd.mass.is_finite() && nd.x.is_finite() && nd.y.is_finite()) {
                return Err(bad(format!("node {i}: mass must be > 0 and x, y finite")));
            }
        }
        for (k, sp) in self.springs.iter().enumerate() {
            if sp.a >= n || sp.b >= n || sp.a == sp.b {
                return Err(bad(format!(
                    "spring {k}: nodes {} and {} (the model has {n} nodes)",
                    sp.a, sp.b
                )));
            }
            let l0 = self.rest_length(k);
            if !(sp.e > 0.0 && sp.t > 0.0 && sp.w > 0.0 && l0 > 0.0) {
                return Err(bad(format!(
                    "spring {k}: E, t, w and its length must be > 0"
                )));
            }
            if !(0.0..0.5).contains(&sp.poisson) {
                return Err(bad(format!(
                    "spring {k}: Poisson's ratio {} outside [0, 0.5)",
                    sp.poisson
                )));
            }
        }
        for ic in &self.initial {
            if ic.node >= n {
                return Err(bad(format!("initial condition on node {} of {n}", ic.node)));
            }
        }
        for f in &self.forces {
            if f.node >= n {
                return Err(bad(format!("force on node {} of {n}", f.node)));
            }
        }
        Ok(())
    }

    /// Every damage event: its node (of `n`) joins two fibres, or its spring exists.
    fn check_damage(&self, n: usize) -> Result<(), SimError> {
        for d in &self.damage {
            match d {
                DamageSpec::Bond { node, .. } if *node >= n => {
                    return Err(bad(format!("bond failure at node {node} of {n}")))
                }
                DamageSpec::Bond { node, .. } => {
                    let fibres: std::collections::BTreeSet<u32> = self
                        .springs
                        .iter()
                        .filter(|s| s.a == *node || s.b == *node)
                        .map(|s| s.fibre)
                        .collect();
                    if fibres.len() < 2 {
                        return Err(bad(format!(
                            "bond failure at node {node}: its springs belong to {} fibre(s); a bond joins two",
                            fibres.len()
                        )));
                    }
                }
                DamageSpec::Fibre { spring, .. } if *spring >= self.springs.len() => {
                    return Err(bad(format!(
                        "fibre failure of spring {spring} of {}",
                        self.springs.len()
                    )))
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// The grid's size, shape and step, the acoustic stability condition and the sensors' cells.
    fn check_grid(&self, g: &GridSpec) -> Result<(), SimError> {
        let s = &self.system;
        // A 3-D grid's cells are capped by `acoustic3d::MAX_CELLS` (check_dims).
        if g.z.is_none() && g.nx.checked_mul(g.ny).is_none_or(|c| c > MAX_GRID_CELLS) {
            return Err(bad(format!(
                "grid: {} × {} cells exceed the limit of {MAX_GRID_CELLS}",
                g.nx, g.ny
            )));
        }
        if g.nx < 8 || g.ny < 8 || g.x2 <= g.x1 || g.y2 <= g.y1 || g.x1.is_nan() || g.y1.is_nan() {
            return Err(bad(
                "grid: need x2 > x1, y2 > y1 and at least 8×8 cells".into()
            ));
        }
        if g.dipole_m.is_some_and(|d| !(d.is_finite() && d > 0.0)) {
            return Err(bad(format!(
                "grid: dipole_m must be > 0, got {:?}",
                g.dipole_m
            )));
        }
        if ((g.dx() - g.dy()) / g.dx()).abs() > 1e-6 {
            return Err(bad(format!(
                "grid: cells must be square (Δx = {:e}, Δy = {:e})",
                g.dx(),
                g.dy()
            )));
        }
        let ratio = g.dt / s.dt;
        if (ratio - ratio.round()).abs() > 1e-6 || ratio.round() < 1.0 {
            return Err(bad(format!(
                "grid.dt {:e} must be a whole multiple of system.dt {:e}",
                g.dt, s.dt
            )));
        }
        let a = g.alpha();
        let (limit, name) = match g.order {
            Order::Second => (
                std::f64::consts::FRAC_1_SQRT_2,
                "1/√2 (2nd order, Eq. 3.3.12)",
            ),
            Order::Fourth => ((3.0f64 / 8.0).sqrt(), "√(3/8) (4th order, Eq. 3.3.14)"),
        };
        if a >= limit {
            return Err(bad(format!(
                "grid: unstable, α = c·Δt/Δh = {a:.4} must be < {name}; reduce dt or refine less"
            )));
        }
        for (k, se) in self.sensors.iter().enumerate() {
            if se.i >= g.nx || se.j >= g.ny {
                return Err(bad(format!(
                    "sensor {k}: cell ({}, {}) outside the {}×{} grid",
                    se.i, se.j, g.nx, g.ny
                )));
            }
        }
        Ok(())
    }

    /// Equilibrium length of spring k: given, or the distance of its nodes as given.
    pub fn rest_length(&self, k: usize) -> f64 {
        let sp = &self.springs[k];
        sp.length.unwrap_or_else(|| {
            let (a, b) = (&self.nodes[sp.a], &self.nodes[sp.b]);
            let plane = (b.x - a.x).powi(2) + (b.y - a.y).powi(2);
            match (a.z, b.z) {
                (None, None) => plane.sqrt(),
                (za, zb) => (plane + (zb.unwrap_or(0.0) - za.unwrap_or(0.0)).powi(2)).sqrt(),
            }
        })
    }

    /// 3 when a node has a height or the grid a z axis (§6.2's third dimension), else 2.
    pub fn dims(&self) -> usize {
        let grid3 = self.grid.as_ref().is_some_and(|g| g.z.is_some());
        if grid3 || self.nodes.iter().any(|n| n.z.is_some()) {
            3
        } else {
            2
        }
    }

    /// The sheet's surface in a 3-D grid: the first layer above the one holding the highest
    /// mass (where a sensor stands unless its `k` says otherwise).
    pub fn surface_k(&self) -> Option<usize> {
        let g = self.grid.as_ref()?;
        let z = g.z?;
        let top = self
            .nodes
            .iter()
            .map(|n| n.z.unwrap_or(0.0))
            .fold(f64::NEG_INFINITY, f64::max);
        let k = ((top - z.z1) / g.dx()).floor() + 1.0;
        Some(k.clamp(0.0, z.nz.saturating_sub(1) as f64) as usize)
    }

    /// The cell a 3-D model's sensor reads: (i, j, its k or the surface).
    pub fn sensor_cell3(&self, s: &SensorSpec) -> (usize, usize, usize) {
        (s.i, s.j, s.k.or(self.surface_k()).unwrap_or(0))
    }

    /// What a 3-D model needs besides the plane checks: a z axis on its grid with cubic cells
    /// inside the cell cap at a stable Courant number, finite heights, sensors' layers inside;
    /// a plane model uses no z at all.
    fn check_dims(&self) -> Result<(), SimError> {
        let uses_z = self.initial.iter().any(|ic| ic.dz != 0.0 || ic.dw != 0.0)
            || self.forces.iter().any(|f| f.fz != 0.0)
            || self.sensors.iter().any(|s| s.k.is_some());
        if self.dims() == 2 {
            return match uses_z {
                true => Err(bad(
                    "dz, dw, fz or a sensor's k need a 3-D model (nodes with z, a grid with z)"
                        .into(),
                )),
                false => Ok(()),
            };
        }
        if let Some(i) = self
            .nodes
            .iter()
            .position(|n| n.z.is_some_and(|z| !z.is_finite()))
        {
            return Err(bad(format!("node {i}: z must be finite")));
        }
        let Some(g) = &self.grid else {
            return Ok(());
        };
        let Some(z) = g.z else {
            return Err(bad(
                "nodes with z need a grid with a z axis (z1, z2, nz), or no grid".into(),
            ));
        };
        if !(z.z2 > z.z1 && z.z1.is_finite() && z.z2.is_finite()) {
            return Err(bad("grid: need z2 > z1".into()));
        }
        if z.nz == 0 || ((z.z2 - z.z1) / z.nz as f64 - g.dx()).abs() > 1e-6 * g.dx() {
            return Err(bad(format!(
                "grid: cells must be cubes (Δz = {:e}, Δx = {:e})",
                (z.z2 - z.z1) / z.nz.max(1) as f64,
                g.dx()
            )));
        }
        g.grid3().expect("a z axis").check()?;
        for (k, se) in self.sensors.iter().enumerate() {
            let (_, _, layer) = self.sensor_cell3(se);
            if layer >= z.nz {
                return Err(bad(format!(
                    "sensor {k}: layer {layer} outside the grid's {} layers",
                    z.nz
                )));
            }
        }
        Ok(())
    }
}
