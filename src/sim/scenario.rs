//! Built-in scenarios: the thesis's test cases (Tables 3.1, 3.3, 3.5, 3.7, 3.8 / Appendix A)
//! and its two damage structures (Fig. 4.8, Fig. 4.19), built with the material of Table 4.1.

use super::model::*;
use super::paper::{damaged_mesh, mesh3x3, structure2x1, DamagedMesh, Mesh, Split, Structure};
pub use super::params::Common;
pub use super::params::{check_sweeps, parse_sweep, sweep_grid, Params, Sweep, MAX_SWEEP_VALUES};
use super::params::{scenario_params, Scenario};
pub use super::parts::{eq, paper_grid, FIBRE_E, FIBRE_NU, FIBRE_RHO, FIBRE_T, FIBRE_W};
use super::parts::{node, spring, st, system};
use super::SimError;

scenario_params! {
    /// [`sho`]'s keys: the moving mass (kg) and how far it is lifted (m).
    pub struct Sho {
        mass: f64 = 0.2,
        amplitude: f64 = 0.1,
    }
}

scenario_params! {
    /// The chapter-3 fibres' lift (m): [`five_mass`]'s centre, [`single_constraint`]'s mass.
    pub struct Lift {
        amplitude: f64 = 0.1,
    }
}

scenario_params! {
    /// [`two_fibres`]' keys: the initial conditions (1, 2 or 3), the stretch of the ends (m)
    /// and the bond's lift (m).
    pub struct TwoFibres {
        ic: f64 = 1.0,
        stretch: f64 = 0.1,
        amplitude: f64 = 0.03,
    }
}

scenario_params! {
    /// [`rubber_band`]'s pluck (m at the centre).
    pub struct RubberBand {
        amplitude: f64 = 0.010,
    }
}

scenario_params! {
    /// [`paper_fibre`]'s keys: its length (m), node mass (kg), stretch (strain) and lift (m).
    pub struct PaperFibre {
        length: f64 = 1e-3,
        mass: f64 = 5.1e-12,
        stretch: f64 = 0.01,
        amplitude: f64 = 1e-5,
    }
}

/// The plane scenarios: the thesis's test cases and damage structures.
const PLANE: &[Scenario] = &[
    Scenario::new("sho", &[Sho::KEYS], sho),
    Scenario::new("five-mass-fibre", &[Lift::KEYS], five_mass),
    Scenario::new("fibre-single-constraint", &[Lift::KEYS], single_constraint),
    Scenario::new(
        "fibre-multiple-constraints",
        &[Lift::KEYS],
        multiple_constraints,
    ),
    Scenario::new("two-fibres", &[TwoFibres::KEYS], two_fibres),
    Scenario::new("rubber-band", &[RubberBand::KEYS], rubber_band),
    Scenario::new("paper-fibre", &[PaperFibre::KEYS], paper_fibre),
    Scenario::new("mesh3x3-bond-failure", &[Mesh::KEYS], mesh3x3),
    Scenario::new(
        "mesh3x3-damaged-bond-failure",
        &[DamagedMesh::KEYS],
        damaged_mesh,
    ),
    Scenario::new(
        "structure2x1-fibre-failure",
        &[Structure::KEYS, Split::KEYS],
        structure2x1,
    ),
];

/// Every mass/spring scenario: the plane ones, then the 3-D ones.
fn registry() -> impl Iterator<Item = &'static Scenario> {
    PLANE.iter().chain(super::network3d::SCENARIOS)
}

/// Every mass/spring scenario's name (what a reference library may run).
pub fn model_names() -> impl Iterator<Item = &'static str> {
    registry().map(|s| s.name)
}

/// Every scenario's name, for the CLI and errors (the stiff string's last).
pub fn names() -> impl Iterator<Item = &'static str> {
    model_names().chain([super::string::NAME])
}

/// The keys a scenario takes (its own, then the [`Common`] ones; the stiff string's own),
/// `None` for a name that is not a scenario.
pub fn keys(name: &str) -> Option<Vec<&'static str>> {
    if name == super::string::NAME {
        return Some(super::string::StringParams::KEYS.to_vec());
    }
    let s = registry().find(|s| s.name == name)?;
    Some(s.groups().flatten().copied().collect())
}

/// Build a scenario by name. `params` overrides its defaults; a key it does not take is
/// refused by name before anything is built ([`keys`] lists them; so does docs/simulator.md).
pub fn build(name: &str, p: &Params) -> Result<ModelFile, SimError> {
    if name == super::string::NAME {
        return Err(SimError::Model(format!(
            "{name} is a continuum model, not a mass/spring one: `aepipe simulate --scenario \
             {name}` runs it"
        )));
    }
    let Some(s) = registry().find(|s| s.name == name) else {
        return Err(SimError::Model(format!(
            "unknown scenario {name:?}; known: {}",
            names().collect::<Vec<_>>().join(", ")
        )));
    };
    s.check(p)?;
    let common = Common::read(p)?;
    let mut m = (s.build)(p, &common)?;
    common.apply(name, &mut m)?;
    m.check()?;
    Ok(m)
}

/// The stiff string of §6.2 from its parameters ([`super::string::StiffString::from_params`]).
pub fn build_string(p: &Params) -> Result<super::string::StiffString, SimError> {
    super::string::StiffString::from_params(p)
}

impl Common {
    /// Apply the keys given to the structure `name` built.
    fn apply(&self, name: &str, m: &mut ModelFile) -> Result<(), SimError> {
        if let Some(s) = self.solver {
            m.system.solver = s;
        }
        if let Some(dt) = self.dt {
            m.system.dt = dt;
        }
        if let Some(b) = self.damping {
            m.system.damping = b;
        }
        if let Some(n) = self.iterations {
            m.system.iterations = n as usize;
        }
        if !self.grid {
            m.grid = None;
            m.sensors.clear();
        }
        if let Some(um) = self.grid_um {
            refine(m, um * 1e-6)?;
        }
        // Masses follow thickness × width × density.
        let (es, ts, ws, rs) = (self.e_scale, self.t_scale, self.w_scale, self.rho_scale);
        if (es, ts, ws, rs) != (1.0, 1.0, 1.0, 1.0) {
            if !(es > 0.0 && ts > 0.0 && ws > 0.0 && rs > 0.0) {
                return Err(SimError::Model(format!(
                    "{name}: e_scale, t_scale, w_scale and rho_scale must be > 0"
                )));
            }
            for s in &mut m.springs {
                s.e *= es;
                s.t *= ts;
                s.w *= ws;
            }
            for n in &mut m.nodes {
                n.mass *= ts * ws * rs;
            }
        }
        if let Some(nu) = self.nu {
            if !(0.0..0.5).contains(&nu) {
                return Err(SimError::Model(format!("{name}: nu must be in [0, 0.5)")));
            }
            for s in &mut m.springs {
                s.poisson = nu;
            }
        }
        Ok(())
    }
}

/// `grid_um`: the scenario's acoustic grid at cell size `h` (m) over the same extent, its
/// step the largest whole multiple of the mass/spring step that keeps the scenario's Courant
/// number (Appendix A: 0.486), the sensors moved to the cells holding their centres. Halving
/// the cell (36 µm) doubles the frequency the grid carries (to ~3 MHz, `band_limit`).
fn refine(m: &mut ModelFile, h: f64) -> Result<(), SimError> {
    let Some(g) = m.grid.as_mut() else {
        return Err(SimError::Model(format!(
            "{}: grid_um needs the acoustic grid (not with grid=0)",
            m.name
        )));
    };
    if !(h.is_finite() && h > 0.0) {
        return Err(SimError::Model(format!(
            "grid_um must be > 0, got {}",
            h * 1e6
        )));
    }
    let (w, hgt) = (g.x2 - g.x1, g.y2 - g.y1);
    let (nx, ny) = ((w / h).round(), (hgt / h).round());
    let nz = g.z.map_or(1.0, |z| ((z.z2 - z.z1) / h).round());
    let cap = match g.z {
        Some(_) => super::acoustic3d::MAX_CELLS,
        None => crate::sim::model::MAX_GRID_CELLS,
    };
    if nx < 8.0 || ny < 8.0 || nz < 1.0 || nx * ny * nz > cap as f64 {
        return Err(SimError::Model(format!(
            "{}: grid_um = {} µm makes a {nx} × {ny}{} grid (at least 8 × 8, at most {cap} cells)",
            m.name,
            h * 1e6,
            g.z.map_or(String::new(), |_| format!(" × {nz}")),
        )));
    }
    let courant = g.alpha();
    let old_z1 = g.z.map(|z| z.z1);
    let h0 = g.dipole_m.unwrap_or(g.dx());
    g.dipole_m = Some(h0);
    g.nx = nx as usize;
    g.ny = ny as usize;
    let cell = g.dx();
    if let Some(z) = g.z.as_mut() {
        // Cubic cells: the z extent is nz cells of the new size about the same centre.
        let centre = 0.5 * (z.z1 + z.z2);
        z.nz = nz as usize;
        z.z1 = centre - 0.5 * nz * cell;
        z.z2 = centre + 0.5 * nz * cell;
    }
    let ratio = (courant * g.dx() / g.c / m.system.dt + 1e-9)
        .floor()
        .max(1.0);
    g.dt = ratio * m.system.dt;
    let z0 = old_z1.zip(g.z.map(|z| z.z1));
    for s in &mut m.sensors {
        (s.i, s.j) = g.original_cell(s.i, s.j).unwrap_or((s.i, s.j));
        // A sensor's layer: the one holding its old cell's centre.
        if let (Some(k), Some((before, now))) = (s.k.as_mut(), z0) {
            *k = ((before + (*k as f64 + 0.5) * h0 - now) / cell).floor() as usize;
        }
    }
    Ok(())
}

/// A straight chain of equal masses from x0 to x1 on y = 0, ends fixed, with springs of the
/// given material and rest length.
#[allow(clippy::too_many_arguments)]
fn chain(
    n: usize,
    x0: f64,
    x1: f64,
    mass: f64,
    e: f64,
    l: f64,
    t: f64,
    w: f64,
    nu: f64,
) -> (Vec<NodeSpec>, Vec<SpringSpec>) {
    let nodes = (0..n)
        .map(|i| {
            let x = x0 + (x1 - x0) * i as f64 / (n - 1) as f64;
            node(x, 0.0, mass, i == 0 || i == n - 1)
        })
        .collect();
    let springs = (0..n - 1)
        .map(|i| spring(i, i + 1, e, Some(l), t, w, nu, 0))
        .collect();
    (nodes, springs)
}

/// Table 3.1: one 0.2 kg mass between two fixed masses 0.55 m away on springs of rest length
/// 0.25 m (k = 1 N/m), lifted 0.1 m. With `grid=1` (default) it radiates into a 20 m × 20 m
/// air-less test domain (c = 1 m/s, Section 3.3.6) for Fig. 3.29/3.30.
fn sho(p: &Params, c: &Common) -> Result<ModelFile, SimError> {
    let s = Sho::read(p)?;
    let (mut nodes, springs) = chain(3, -0.55, 0.55, 0.2, 1.0, 0.25, 1.0, 0.25, 0.0);
    nodes[1].mass = s.mass;
    let dt = c.dt.unwrap_or(0.01);
    Ok(ModelFile {
        name: "sho".into(),
        label: Some("sho".into()),
        system: system(dt, 0.0, 10_000),
        nodes,
        springs,
        initial: vec![eq(1, 0.0, s.amplitude)],
        forces: vec![],
        damage: vec![],
        grid: Some(test_grid(dt * 10.0)),
        sensors: vec![SensorSpec {
            i: 50,
            j: 60,
            k: None,
        }],
    })
}

/// The acoustic test grid of Section 3.3.6: −10…10 m, Δh = 0.2 m, c = 1 m/s, ρ = 1 kg/m³.
pub fn test_grid(dt: f64) -> GridSpec {
    GridSpec {
        x1: -10.0,
        x2: 10.0,
        y1: -10.0,
        y2: 10.0,
        nx: 100,
        ny: 100,
        dt,
        rho: 1.0,
        c: 1.0,
        order: Order::Fourth,
        dipole_m: None,
        z: None,
    }
}

/// Table 3.3: five masses, the three inner ones lifted 0.05, 0.1, 0.05 m.
fn five_mass(p: &Params, c: &Common) -> Result<ModelFile, SimError> {
    let (nodes, springs) = chain(5, -0.55, 0.55, 0.2, 1.0, 0.25, 1.0, 0.25, 0.0);
    let a = Lift::read(p)?.amplitude;
    Ok(ModelFile {
        name: "five-mass-fibre".into(),
        label: None,
        system: system(c.dt.unwrap_or(0.01), 0.0, 10_000),
        nodes,
        springs,
        initial: vec![eq(1, 0.0, 0.5 * a), eq(2, 0.0, a), eq(3, 0.0, 0.5 * a)],
        forces: vec![],
        damage: vec![],
        grid: None,
        sensors: vec![],
    })
}

/// Table 3.5: 21 masses (1/21 kg) from −0.5 to 0.6 m, rest length 0.05 m, only the central
/// mass lifted 0.1 m: the relaxation (Alg. 7) shapes the rest of the fibre.
fn single_constraint(p: &Params, c: &Common) -> Result<ModelFile, SimError> {
    let (nodes, springs) = chain(21, -0.5, 0.6, 1.0 / 21.0, 1.0, 0.05, 1.0, 0.25, 0.0);
    Ok(ModelFile {
        name: "fibre-single-constraint".into(),
        label: None,
        system: system(c.dt.unwrap_or(0.01), 0.0, 2_000),
        nodes,
        springs,
        initial: vec![eq(10, 0.0, Lift::read(p)?.amplitude)],
        forces: vec![],
        damage: vec![],
        grid: None,
        sensors: vec![],
    })
}

/// Table 3.6: the fibre of Table 3.5 with two more constraints — masses 9 and 11 held where
/// they are while mass 10 is lifted and the rest relaxes (Fig. 3.8a), all three let go at
/// t = 0: a kink that excites the fibre's high modes (Figs. 3.8–3.9).
fn multiple_constraints(p: &Params, c: &Common) -> Result<ModelFile, SimError> {
    let mut m = single_constraint(p, c)?;
    m.name = "fibre-multiple-constraints".into();
    m.initial.push(eq(9, 0.0, 0.0));
    m.initial.push(eq(11, 0.0, 0.0));
    Ok(m)
}

/// Figs. 3.11–3.13: two fibres of Table 3.5's material (21 masses, 1 m at rest) crossing at
/// their centres, where they share a bond mass. `ic` 3 (Fig. 3.13): the four ends pulled out
/// by `stretch` (StICs); 1 (Fig. 3.11): and the bond lifted by `amplitude` (an EqIC); 2
/// (Fig. 3.12): and the horizontal fibre's quarter points lifted by half that too. Alg. 7
/// relaxes the rest; the motion after t = 0 is the release.
fn two_fibres(p: &Params, c: &Common) -> Result<ModelFile, SimError> {
    let TwoFibres {
        ic,
        stretch,
        amplitude: amp,
    } = TwoFibres::read(p)?;
    if ![1.0, 2.0, 3.0].contains(&ic) {
        return Err(SimError::Model(format!(
            "two-fibres: ic must be 1 (a single displacement), 2 (several) or 3 (stretching only), got {ic}"
        )));
    }
    let m = 1.0 / 21.0;
    let (mut nodes, mut springs) = chain(21, -0.5, 0.5, m, 1.0, 0.05, 1.0, 0.25, 0.0);
    // The vertical fibre: its own 20 masses, its centre the horizontal fibre's (node 10).
    let mut ids = Vec::new();
    for k in 0..21 {
        if k == 10 {
            nodes[10].mass += m;
            ids.push(10);
        } else {
            nodes.push(node(0.0, -0.5 + 0.05 * k as f64, m, k == 0 || k == 20));
            ids.push(nodes.len() - 1);
        }
    }
    for w in ids.windows(2) {
        springs.push(spring(w[0], w[1], 1.0, Some(0.05), 1.0, 0.25, 0.0, 1));
    }
    let d = 0.5 * stretch;
    let mut initial = vec![
        st(0, -d, 0.0),
        st(20, d, 0.0),
        st(ids[0], 0.0, -d),
        st(ids[20], 0.0, d),
    ];
    if ic != 3.0 {
        initial.push(eq(10, 0.0, amp));
    }
    if ic == 2.0 {
        // The quarter points where the stretch puts them, lifted by half.
        initial.push(eq(5, -0.25 * stretch, 0.5 * amp));
        initial.push(eq(15, 0.25 * stretch, 0.5 * amp));
    }
    Ok(ModelFile {
        name: "two-fibres".into(),
        label: None,
        system: system(c.dt.unwrap_or(0.01), 0.0, 2_000),
        nodes,
        springs,
        initial,
        forces: vec![],
        damage: vec![],
        grid: None,
        sensors: vec![],
    })
}

/// Table 3.7: a rubber band of 11 masses over ±76 mm, plucked 10 mm at the centre
/// (triangle), damping 7e-4 kg/s.
fn rubber_band(p: &Params, c: &Common) -> Result<ModelFile, SimError> {
    let (nodes, springs) = chain(
        11, -0.076, 0.076, 1.96e-5, 8.63e5, 3.4e-3, 1e-3, 6e-3, 0.144,
    );
    let a = RubberBand::read(p)?.amplitude;
    let initial = (1..10)
        .map(|i| eq(i, 0.0, a * (5.0 - (i as f64 - 5.0).abs()) / 5.0))
        .collect();
    Ok(ModelFile {
        name: "rubber-band".into(),
        label: Some("rubber_band".into()),
        system: system(c.dt.unwrap_or(2e-5), c.damping.unwrap_or(7e-4), 5_000),
        nodes,
        springs,
        initial,
        forces: vec![],
        damage: vec![],
        grid: None,
        sensors: vec![],
    })
}

/// Appendix A / Table 3.8: a 1 mm paper fibre of 29 masses, stretched 1 % by StICs on its
/// end masses (±5 µm), plucked in its fundamental mode shape (10 µm at the centre), implicit
/// Euler at 10 ns, b = 1.5e-6 kg/s, 40 µs. Rest lengths are the node spacing (the file's
/// 3.6e-5 m is that spacing rounded); node masses 5.1e-12 kg as in the file.
fn paper_fibre(p: &Params, c: &Common) -> Result<ModelFile, SimError> {
    let PaperFibre {
        length: len,
        mass,
        stretch,
        amplitude: amp,
    } = PaperFibre::read(p)?;
    let n = 29;
    let a = len / (n - 1) as f64;
    let (nodes, springs) = chain(
        n,
        -len / 2.0,
        len / 2.0,
        mass,
        FIBRE_E,
        a,
        FIBRE_T,
        FIBRE_W,
        FIBRE_NU,
    );
    let mut initial = vec![
        st(0, -stretch * len / 2.0, 0.0),
        st(n - 1, stretch * len / 2.0, 0.0),
    ];
    // The interior masses start where the 1 % stretch puts them (uniformly spread, the
    // equilibrium of the stretched fibre), lifted in the fundamental mode shape: the file's
    // dy column is 10 µm·sin(πi/28). (Leaving them at the unstretched spacing, as the file
    // literally does, puts the whole stretch into the two end springs at release.)
    for i in 1..n - 1 {
        let s = (std::f64::consts::PI * i as f64 / (n - 1) as f64).sin();
        let x = -len / 2.0 + len * i as f64 / (n - 1) as f64;
        initial.push(eq(i, stretch * x, amp * s));
    }
    Ok(ModelFile {
        name: "paper-fibre".into(),
        label: Some("fibre_vibration".into()),
        system: system(c.dt.unwrap_or(1e-8), c.damping.unwrap_or(1.5e-6), 4_000),
        nodes,
        springs,
        initial,
        forces: vec![],
        damage: vec![],
        grid: Some(paper_grid()),
        sensors: [
            (125, 100),
            (125, 80),
            (125, 5),
            (100, 125),
            (80, 125),
            (5, 125),
            (100, 100),
            (80, 80),
            (5, 5),
        ]
        .iter()
        .map(|&(i, j)| SensorSpec { i, j, k: None })
        .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sweeps_take_integers_or_real_values_with_a_step() {
        let s = parse_sweep("point=1..12").unwrap();
        assert_eq!(s.key, "point");
        assert_eq!(s.values, (1..=12).map(f64::from).collect::<Vec<_>>());
        // Real values: the decimals written, not their float sums.
        let s = parse_sweep("stretch=0.010..0.020:0.002").unwrap();
        assert_eq!(s.values, vec![0.010, 0.012, 0.014, 0.016, 0.018, 0.020]);
        let s = parse_sweep("damping=0..3e-6:1.5e-6").unwrap();
        assert_eq!(s.values, vec![0.0, 1.5e-6, 3e-6]);
        assert_eq!(parse_sweep("x=2..2").unwrap().values, vec![2.0]);
        for bad in [
            "stretch=0.01..0.02",       // real bounds, no step
            "stretch=0.01..0.02:0.003", // HI not LO + k·STEP
            "point=12..1",              // empty
            "x=0..1:0",                 // step 0
            "x=0..1:-0.1",
            "x=0..1e9:1", // too many runs
            "x=a..b",
            "x=0..nan:1",
            "point",
        ] {
            let e = parse_sweep(bad).unwrap_err().to_string();
            assert!(e.contains(bad), "{bad}: {e}");
        }
        // Several sweeps: every combination, the first varying slowest.
        let g = sweep_grid(&[
            parse_sweep("a=1..2").unwrap(),
            parse_sweep("b=0.5..1.5:0.5").unwrap(),
        ]);
        let flat: Vec<(f64, f64)> = g.iter().map(|r| (r[0].1, r[1].1)).collect();
        assert_eq!(
            flat,
            vec![
                (1.0, 0.5),
                (1.0, 1.0),
                (1.0, 1.5),
                (2.0, 0.5),
                (2.0, 1.0),
                (2.0, 1.5)
            ]
        );
        assert_eq!(sweep_grid(&[]), vec![Vec::<(String, f64)>::new()]);
        // Checked before the combinations are made: a key swept twice, too many runs.
        let s = |t: &str| parse_sweep(t).unwrap();
        assert_eq!(
            check_sweeps(&[s("a=1..100"), s("b=1..100")]).unwrap(),
            10_000
        );
        let e = check_sweeps(&[s("a=1..1000"), s("b=1..1000")]).unwrap_err();
        assert!(e.to_string().contains("runs in all"), "{e}");
        let e = check_sweeps(&[s("a=1..2"), s("a=3..4")]).unwrap_err();
        assert!(e.to_string().contains("swept twice"), "{e}");
    }

    #[test]
    fn a_parameter_no_scenario_reads_is_refused_by_name() {
        let p = |kv: &[(&str, f64)]| Params(kv.iter().map(|(k, v)| (k.to_string(), *v)).collect());
        // Every key the scenarios read is accepted …
        assert!(build(
            "structure2x1-fibre-failure",
            &p(&[("point", 7.0), ("iterations", 10.0)])
        )
        .is_ok());
        assert!(build(
            "mesh3x3-bond-failure",
            &p(&[("kink", 5e-6), ("t2", -1.0), ("grid", 0.0)])
        )
        .is_ok());
        // … a typo is named, with what the scenario does read.
        let e = build("structure2x1-fibre-failure", &p(&[("pint", 7.0)])).unwrap_err();
        let m = e.to_string();
        assert!(
            m.contains("no parameter pint") && m.contains("point"),
            "{m}"
        );
        // A key one scenario reads is still unknown to another.
        let e = build("sho", &p(&[("kink", 1.0)])).unwrap_err();
        assert!(e.to_string().contains("no parameter kink"), "{e}");
        // `split` is the plane structure's: the 3-D one refuses it.
        let e = build("network3d-fibre-failure", &p(&[("split", 2.0)])).unwrap_err();
        assert!(e.to_string().contains("no parameter split"), "{e}");
        let e = build_string(&p(&[("kink", 1.0)])).unwrap_err();
        assert!(e.to_string().contains("no parameter kink"), "{e}");
    }

    /// Each key is read as its type: a value the type refuses names the key, whatever
    /// scenario reads it.
    #[test]
    fn a_value_of_the_wrong_kind_is_refused_naming_its_key() {
        let p = |kv: &[(&str, f64)]| Params(kv.iter().map(|(k, v)| (k.to_string(), *v)).collect());
        for (name, key, v) in [
            ("sho", "grid", 2.0),
            ("sho", "iterations", 1.5),
            ("sho", "solver", 7.0),
            ("paper-fibre", "iterations", -1.0),
            ("structure2x1-fibre-failure", "point", 7.5),
            ("structure2x1-fibre-failure", "split", 0.5),
            ("mesh3x3-damaged-bond-failure", "bond", -1.0),
            ("network3d-bond-failure", "cells", 125.5),
        ] {
            let e = build(name, &p(&[(key, v)])).unwrap_err().to_string();
            assert!(
                e.contains(key) && !e.contains("no parameter"),
                "{name} {key}={v}: {e}"
            );
        }
        let e = build_string(&p(&[("intervals", 2.5)]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("intervals"), "{e}");
        // The common keys reach what was built.
        let m = build(
            "paper-fibre",
            &p(&[
                ("grid", 0.0),
                ("dt", 2e-8),
                ("iterations", 7.0),
                ("solver", 2.0),
            ]),
        )
        .unwrap();
        assert!(m.grid.is_none() && m.sensors.is_empty());
        assert_eq!((m.system.dt, m.system.iterations), (2e-8, 7));
        assert_eq!(m.system.solver, Solver::Verlet);
    }

    /// docs/simulator.md's scenario tables name every key each scenario takes and no other,
    /// and its "every scenario also takes" sentence names the common ones.
    #[test]
    fn the_simulator_page_lists_each_scenarios_keys() {
        let page = std::fs::read_to_string(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/simulator.md"),
        )
        .unwrap();
        let ticked = |text: &str| -> Vec<String> {
            text.split('`')
                .skip(1)
                .step_by(2)
                .map(|w| w.split('=').next().unwrap_or(w).to_string())
                .collect()
        };
        for name in names() {
            let head = format!("| `{name}` |");
            let row = page
                .lines()
                .find(|l| l.starts_with(&head))
                .unwrap_or_else(|| panic!("docs/simulator.md has no row for {name}"));
            let said = ticked(row.rsplit('|').nth(1).unwrap());
            let keys = keys(name).unwrap();
            let own: Vec<&str> = keys
                .iter()
                .copied()
                .filter(|k| name == super::super::string::NAME || !Common::KEYS.contains(k))
                .collect();
            for k in &own {
                assert!(
                    said.iter().any(|s| s == k),
                    "{name}: the page does not name {k}"
                );
            }
            for s in &said {
                assert!(
                    keys.contains(&s.as_str()),
                    "{name}: the page names {s}, not a key"
                );
            }
        }
        let common = page
            .split("Every mass/spring scenario also takes")
            .nth(1)
            .and_then(|t| t.split("\n\n").next())
            .expect("the common keys' sentence");
        let said = ticked(common);
        for k in Common::KEYS {
            assert!(
                said.iter().any(|s| s == k),
                "the common sentence does not name {k}"
            );
        }
    }
}
