//! §6.2's third dimension: the damage structures of ch. 4 as a layered network. A handsheet
//! is fibres laid one on another, so a crossing joins two fibres at different heights; the
//! sensor sits on (or above) the sheet's surface, in a 3-D field ([`super::acoustic3d`]).
//!
//! Layers: each fibre lies one fibre thickness (2.8 µm, Table 4.1) above the one laid before
//! it, horizontal and vertical fibres alternating; a bond mass sits halfway between the two
//! fibres it joins, so the springs next to a bond tilt out of the plane and a bond failure
//! moves the fibres in z as well. The fibres themselves are the plane model's (the lattice
//! of Fig. 4.8 and Fig. 4.19, the same masses, springs and stretch).

use super::model::*;
use super::paper::{lattice, Lattice};
use super::scenario::{eq, system, Params, FIBRE_T};
use super::SimError;

/// The 3-D scenarios (names are contracts).
pub const NAMES: &[&str] = &["network3d-bond-failure", "network3d-fibre-failure"];

/// The 3-D grid: ±4.5 mm × ±4.5 mm around the damage zone, ±2.232 mm about the sheet, in
/// the Appendix-A cell (72 µm: 125 × 125 × 62 cells), Δt 0.1 µs, air, 4th order (Courant
/// number 0.486, under 3-D's 1/2).
pub fn grid3() -> GridSpec {
    let h = 72e-6;
    GridSpec {
        x1: -62.5 * h,
        x2: 62.5 * h,
        y1: -62.5 * h,
        y2: 62.5 * h,
        nx: 125,
        ny: 125,
        dt: 1e-7,
        rho: 1.25,
        c: 350.0,
        order: Order::Fourth,
        dipole_m: None,
        z: Some(ZAxis {
            z1: -31.0 * h,
            z2: 31.0 * h,
            nz: 62,
        }),
    }
}

/// Make a plane model three-dimensional: node k at height `z[k]`, the given 3-D grid (or
/// none). Rest lengths given explicitly stay; those taken from the node distances now
/// include the heights.
pub fn lift(m: &mut ModelFile, z: &[f64], grid: Option<GridSpec>) {
    for (n, &h) in m.nodes.iter_mut().zip(z) {
        n.z = Some(h);
    }
    m.grid = grid;
}

/// Heights of a lattice's nodes: a node on one fibre at that fibre's layer × thickness; a
/// bond halfway between its fibres' layers.
fn heights(lat: &Lattice, layer: &dyn Fn(u32) -> u32) -> Vec<f64> {
    let mut on: Vec<Vec<u32>> = vec![Vec::new(); lat.nodes.len()];
    for s in &lat.springs {
        for n in [s.a, s.b] {
            if !on[n].contains(&s.fibre) {
                on[n].push(s.fibre);
            }
        }
    }
    on.iter()
        .map(|fs| {
            let sum: f64 = fs.iter().map(|&f| layer(f) as f64).sum();
            FIBRE_T * sum / fs.len().max(1) as f64
        })
        .collect()
}

/// The two sensors of a 3-D scenario: on the sheet's surface 1.8 mm from the zone's centre
/// along −y (where the plane model's sensor 1 stands), and 1.8 mm straight above the centre
/// (across the sheet: where a fibre moving through the sheet radiates most).
fn sensors(g: &GridSpec) -> Vec<SensorSpec> {
    let z = g.z.expect("a 3-D grid");
    let h = g.dx();
    let (ic, jc) = g.cell(0.0, 0.0).expect("the centre is inside");
    let (_, j1) = g.cell(0.0, -1.8e-3).expect("inside");
    let above = ((1.8e-3 - z.z1) / h).floor() as usize;
    vec![
        SensorSpec {
            i: ic,
            j: j1,
            k: None,
        },
        SensorSpec {
            i: ic,
            j: jc,
            k: Some(above),
        },
    ]
}

/// Build a 3-D scenario by name (`None`: not one of [`NAMES`]).
pub fn build(name: &str, p: &Params) -> Option<Result<ModelFile, SimError>> {
    match name {
        "network3d-bond-failure" => Some(Ok(bond_failure(p))),
        "network3d-fibre-failure" => Some(fibre_failure(p)),
        _ => None,
    }
}

/// Fig. 4.8's mesh (three horizontal, three vertical 2 mm fibres, 0.5 mm apart) laid in six
/// layers, horizontal and vertical alternating (h, v, h, v, h, v from the bottom). The
/// middle horizontal fibre is bent across the damage zone *out of the sheet* — its nodes
/// lifted by `kink`·sin²(πξ), the plane model's shape turned into z, as a fibre pressed over
/// another one is — and bond (1) at the centre fails at `t1`: the freed 1 mm length rings
/// through the sheet at its fundamental (~250 kHz). Bond (2), at (+0.5 mm, 0), fails at `t2`
/// (negative: never).
fn bond_failure(p: &Params) -> ModelFile {
    let stretch = p.get("stretch", 0.01);
    let lat = lattice(&[-7, 0, 7], &[-7, 0, 7], &|_| stretch);
    let z = heights(&lat, &|f| if f < 3 { 2 * f } else { 2 * (f - 3) + 1 });
    let kink = p.get("kink", 1e-5);
    let b1 = lat.index[&(0, 0)];
    let b2 = lat.index[&(7, 0)];
    let mut initial = lat.initial.clone();
    for ix in -6..=6 {
        let xi = (ix + 7) as f64 / 14.0;
        let dz = kink * (std::f64::consts::PI * xi).sin().powi(2);
        let mut ic = eq(lat.index[&(ix, 0)], stretch * ix as f64 * lat.a, 0.0);
        ic.dz = dz;
        initial.push(ic);
    }
    // The vertical fibre through bond (1) is carried up with it, as in the plane model.
    for end in [lat.index[&(0, -14)], lat.index[&(0, 14)]] {
        if let Some(ic) = initial.iter_mut().find(|ic| ic.node == end) {
            ic.dz += kink;
        }
    }
    let (t1, t2) = (p.get("t1", 0.0), p.get("t2", -1.0));
    let mut damage = vec![DamageSpec::Bond { node: b1, time: t1 }];
    if t2 >= 0.0 {
        damage.push(DamageSpec::Bond { node: b2, time: t2 });
    }
    let g = grid3();
    let mut m = plane_model(
        "network3d-bond-failure",
        crate::model::Mechanism::BondFailure,
        lat,
        initial,
        damage,
        p,
    );
    m.sensors = sensors(&g);
    lift(&mut m, &z, Some(g));
    m
}

/// Fig. 4.19's structure as layers: fibres 1 and 2 (vertical, x = ∓0.5 mm) at the bottom,
/// fibre 3 (horizontal, y = 0) laid over them; fibre 3 and fibre 2 stretched 1 %, fibre 1
/// 0.2 %. Spring `point` + 1 of fibre 3's 14 between the bonds breaks at `t1` (1 µs): the
/// two ends recoil along the fibre, and the pieces, tilted down to the bonds, swing.
fn fibre_failure(p: &Params) -> Result<ModelFile, SimError> {
    let point = p.get("point", 7.0);
    if !(1.0..=12.0).contains(&point) || point.fract() != 0.0 {
        return Err(SimError::Model(format!(
            "network3d-fibre-failure: point must be 1…12, got {point}"
        )));
    }
    let point = point as i32;
    let (s3, s1) = (p.get("stretch", 0.01), p.get("stretch1", 0.002));
    let lat = lattice(&[0], &[-7, 7], &|f| if f == 1 { s1 } else { s3 });
    let z = heights(&lat, &|f| u32::from(f == 0));
    let (lo, hi) = (lat.index[&(-7 + point, 0)], lat.index[&(-6 + point, 0)]);
    let spring = lat
        .springs
        .iter()
        .position(|s| (s.a == lo && s.b == hi) || (s.a == hi && s.b == lo))
        .expect("fibre 3 has the spring");
    let initial = lat.initial.clone();
    let damage = vec![DamageSpec::Fibre {
        spring,
        time: p.get("t1", 1e-6),
    }];
    let g = grid3();
    let mut m = plane_model(
        &format!("network3d-fibre-failure-p{point}"),
        crate::model::Mechanism::FibreFailure,
        lat,
        initial,
        damage,
        p,
    );
    m.sensors = sensors(&g);
    lift(&mut m, &z, Some(g));
    Ok(m)
}

/// The lattice as a model with the paper scenarios' system (implicit Euler, 10 ns, b =
/// 1.5e-6 kg/s, 4 000 steps), before it is lifted.
fn plane_model(
    name: &str,
    label: crate::model::Mechanism,
    lat: Lattice,
    initial: Vec<InitialSpec>,
    damage: Vec<DamageSpec>,
    p: &Params,
) -> ModelFile {
    ModelFile {
        name: name.into(),
        label: Some(label.as_str().into()),
        system: system(p.get("dt", 1e-8), p.get("damping", 1.5e-6), 4_000),
        nodes: lat.nodes,
        springs: lat.springs,
        initial,
        forces: vec![],
        damage,
        grid: None,
        sensors: vec![],
    }
}
