//! The paper structures of ch. 4, built from a lattice of Table 4.1's fibres: Fig. 4.8's
//! 3×3 mesh (bond failures) and Fig. 4.19's 2×1 structure (fibre failures). The layered
//! 3-D networks of [`super::network3d`] are made from the same lattice.

use super::model::*;
use super::params::{scenario_params, Common, Params};
use super::parts::{
    eq, node, paper_grid, spring, st, system, FIBRE_E, FIBRE_NU, FIBRE_RHO, FIBRE_T, FIBRE_W,
};
use super::SimError;

/// A lattice of straight 2 mm fibres of 29 masses (spacing a = 2 mm/28) on the points
/// (ix·a, iy·a), ix, iy ∈ −14…14: horizontal fibres at the given iy, vertical at the given
/// ix. Where two cross they share one bond mass of twice the fibre mass. Fibre ends are
/// held by StICs that stretch every fibre by `stretch` (the damage zone's 1 %, ch. 4.3.3).
struct Lattice {
    nodes: Vec<NodeSpec>,
    springs: Vec<SpringSpec>,
    initial: Vec<InitialSpec>,
    index: std::collections::HashMap<(i32, i32), usize>,
    /// Each fibre's nodes in order along it (rows first, then columns).
    fibres: Vec<Vec<usize>>,
    a: f64,
}

fn lattice(rows: &[i32], cols: &[i32], stretch: &dyn Fn(u32) -> f64) -> Lattice {
    lattice_fine(rows, cols, stretch, 1, &|_, _| true)
}

/// [`lattice`] with each fibre's 28 springs cut into `k` (ix, iy ∈ −14k…14k, spacing
/// 2 mm/28k; rows and columns given in those units). Where `bonded` says no, the two
/// fibres cross without a bond: each keeps its own mass there (`index` names the row's).
fn lattice_fine(
    rows: &[i32],
    cols: &[i32],
    stretch: &dyn Fn(u32) -> f64,
    k: i32,
    bonded: &dyn Fn(i32, i32) -> bool,
) -> Lattice {
    let len = 2e-3;
    let a = len / (28 * k) as f64;
    let m = FIBRE_RHO * FIBRE_T * FIBRE_W * a;
    let mut lat = Lattice {
        nodes: vec![],
        springs: vec![],
        initial: vec![],
        index: Default::default(),
        fibres: vec![],
        a,
    };
    let at = |lat: &mut Lattice, ix: i32, iy: i32| -> usize {
        if let Some(&k) = lat.index.get(&(ix, iy)) {
            if bonded(ix, iy) {
                lat.nodes[k].mass += m;
                return k;
            }
        }
        lat.nodes.push(node(ix as f64 * a, iy as f64 * a, m, false));
        lat.index.entry((ix, iy)).or_insert(lat.nodes.len() - 1);
        lat.nodes.len() - 1
    };
    let mut fibre = 0u32;
    let mut lines: Vec<(u32, bool, i32)> = vec![];
    for &iy in rows {
        lines.push((fibre, true, iy));
        fibre += 1;
    }
    for &ix in cols {
        lines.push((fibre, false, ix));
        fibre += 1;
    }
    for &(f, horizontal, off) in &lines {
        let ids: Vec<usize> = (-14 * k..=14 * k)
            .map(|s| {
                if horizontal {
                    at(&mut lat, s, off)
                } else {
                    at(&mut lat, off, s)
                }
            })
            .collect();
        lat.fibres.push(ids.clone());
        for w in ids.windows(2) {
            lat.springs.push(spring(
                w[0], w[1], FIBRE_E, None, FIBRE_T, FIBRE_W, FIBRE_NU, f,
            ));
        }
        let d = stretch(f) * len / 2.0;
        let (first, last) = (ids[0], ids[ids.len() - 1]);
        if horizontal {
            lat.initial.push(st(first, -d, 0.0));
            lat.initial.push(st(last, d, 0.0));
        } else {
            lat.initial.push(st(first, 0.0, -d));
            lat.initial.push(st(last, 0.0, d));
        }
    }
    lat
}

/// Fig. 4.8: a Cartesian mesh of 2 mm fibres (three horizontal, three vertical, 0.5 mm
/// apart, so the middle square is the 1 mm damage zone) with 9 bonds. Before the failure the
/// middle horizontal fibre is bent across the damage zone, its two 0.5 mm halves meeting at
/// bond (1) (Fig. 4.13b). The mass/spring model has no bending stiffness, so a kink would
/// hold every harmonic with equal acceleration; the bent shape is the smooth
/// `kink`·sin²(πξ) over the zone (ξ = 0…1): its fundamental and a third harmonic of 20 %
/// amplitude, the mix of the first harmonics the thesis describes. It leaves bonds (2) at
/// the zone's edges tangentially, so they are in equilibrium at the release. (The earlier
/// shape, sin πξ + sin 3πξ / 9, met them at a slope: its tension jerked the crossing
/// fibres along their length and rang their ~1.2 MHz longitudinal resonance, a flash at
/// the onset that made the criteria read every bond failure heard from below as "both".)
/// At `t1` (0) it is released and bond (1), the centre, fails: the fibre rings at the 1 mm
/// free length's fundamental (~250 kHz) and third harmonic (~750 kHz).
/// Bond (2), at (+0.5 mm, 0), fails at `t2` (20 µs; negative: never), lengthening the free
/// fibre to 1.5 mm.
pub(super) fn mesh3x3(p: &Params, c: &Common) -> Result<ModelFile, SimError> {
    let mut m = mesh(
        &Mesh::read(p)?,
        c,
        "mesh3x3-bond-failure",
        Across::Plane,
        20e-6,
    );
    m.grid = Some(paper_grid());
    m.sensors = below_and_beside();
    Ok(m)
}

scenario_params! {
    /// Fig. 4.8's mesh: the fibres' stretch (strain), the bent fibre's kink (m), when bond
    /// (1) fails (`t1`, s) and bond (2) (`t2`, s; negative: never; each scenario its own
    /// default).
    pub struct Mesh {
        stretch: f64 = 0.01,
        kink: f64 = 1e-5,
        t1: f64 = 0.0,
        t2: Option<f64> = None,
    }
}

scenario_params! {
    /// [`damaged_mesh`]'s keys: the bonds already `broken` (a mask of bits 0…8), the `bond`
    /// (0…8) that fails at `t1`, the fibre `along` it (0 the row, 1 the column), the stretch
    /// and the kink.
    pub struct DamagedMesh {
        broken: u32 = 0,
        bond: u32 = 4,
        along: u32 = 0,
        stretch: f64 = 0.01,
        kink: f64 = 1e-5,
        t1: f64 = 0.0,
    }
}

scenario_params! {
    /// Fig. 4.19's structure: the break `point` (1…12), fibres 3 and 2's stretch, fibre 1's
    /// (`stretch1`), when the fibre breaks (`t1`, s).
    pub struct Structure {
        point: u32 = 7,
        stretch: f64 = 0.01,
        stretch1: f64 = 0.002,
        t1: f64 = 1e-6,
    }
}

scenario_params! {
    /// The plane structure's springs each cut in `split` (1…8).
    pub struct Split {
        split: u32 = 1,
    }
}

/// The crossing of bond k (0…8) of Fig. 4.8's mesh, (ix, iy) in lattice steps: k = 3·row +
/// column, rows and columns counted from −0.5 mm (so 4 is the centre, bond (1)).
pub fn mesh_bond(k: u32) -> (i32, i32) {
    ((k % 3) as i32 * 7 - 7, (k / 3) as i32 * 7 - 7)
}

/// A bond failure in Fig. 4.8's mesh after others have failed (§4.5.5: "as damage occurs
/// … the number of fibre/fibre bonds in the damage zone decreases"). `broken` (a mask of
/// bits k, default 0) names the bonds already failed: there the two fibres cross unbonded.
/// Bond `bond` (default 4) fails at `t1` (0); the fibre `along` it (0 the row, default; 1
/// the column) is bent between its nearest intact bonds, or its held ends, on either side —
/// the free length the failure releases, 1 mm in the intact mesh, up to 2 mm. The shape is
/// [`mesh3x3`]'s, peaked at the failing bond: kink·sin²(π/2·s/S) on each side, s from the
/// span's end, S from that end to the bond (for a centred bond exactly mesh3x3's
/// sin²(πξ)); the crossing fibre's held ends are shifted by the kink, as there.
pub(super) fn damaged_mesh(p: &Params, c: &Common) -> Result<ModelFile, SimError> {
    let name = "mesh3x3-damaged-bond-failure";
    let d = DamagedMesh::read(p)?;
    let at_most = |key: &str, v: u32, hi: u32| -> Result<u32, SimError> {
        if v <= hi {
            Ok(v)
        } else {
            Err(SimError::Model(format!(
                "{name}: {key} must be a whole number 0…{hi}, got {v}"
            )))
        }
    };
    let broken = at_most("broken", d.broken, 511)?;
    let bond = at_most("bond", d.bond, 8)?;
    let along = at_most("along", d.along, 1)?;
    if broken >> bond & 1 == 1 {
        return Err(SimError::Model(format!(
            "{name}: bond {bond} is among the broken ({broken:#b}); a bond fails once"
        )));
    }
    let bonded = |ix: i32, iy: i32| intact(broken, (ix, iy));
    let (stretch, kink) = (d.stretch, d.kink);
    let mut lat = lattice_fine(&[-7, 0, 7], &[-7, 0, 7], &|_| stretch, 1, &bonded);
    let (bx, by) = mesh_bond(bond);
    // Fibres: rows 0…2 (iy −7, 0, 7), then columns 3…5 (ix −7, 0, 7); position s along a
    // fibre is its node's lattice coordinate, −14…14.
    let (bent, cross) = if along == 0 {
        ((by / 7 + 1) as usize, (bx / 7 + 4) as usize)
    } else {
        ((bx / 7 + 4) as usize, (by / 7 + 1) as usize)
    };
    let (at, lo, hi) = span(broken, bond, along);
    let half_pi = std::f64::consts::FRAC_PI_2;
    for s in lo + 1..hi {
        let d = if s <= at {
            kink * (half_pi * (s - lo) as f64 / (at - lo) as f64).sin().powi(2)
        } else {
            kink * (half_pi * (hi - s) as f64 / (hi - at) as f64).sin().powi(2)
        };
        let n = lat.fibres[bent][(s + 14) as usize];
        let l = stretch * s as f64 * lat.a;
        lat.initial
            .push(if along == 0 { eq(n, l, d) } else { eq(n, d, l) });
    }
    let ends = [lat.fibres[cross][0], lat.fibres[cross][28]];
    for ic in lat.initial.iter_mut().filter(|ic| ends.contains(&ic.node)) {
        if along == 0 {
            ic.dy += kink;
        } else {
            ic.dx += kink;
        }
    }
    let node = lat.fibres[bent][(at + 14) as usize];
    let damage = vec![DamageSpec::Bond { node, time: d.t1 }];
    let mut m = lattice_model(
        format!("{name}-b{bond}"),
        crate::model::Mechanism::BondFailure,
        lat,
        damage,
        c.damping.unwrap_or(1.5e-6),
        c,
    );
    m.grid = Some(paper_grid());
    m.sensors = below_and_beside();
    Ok(m)
}

/// The free length (m) a [`damaged_mesh`] failure releases: between the nearest intact
/// bonds or held ends on either side of `bond` along the bent fibre.
pub fn damaged_span(broken: u32, bond: u32, along: u32) -> f64 {
    let (_, lo, hi) = span(broken, bond, along);
    (hi - lo) as f64 * 2e-3 / 28.0
}

/// Whether the crossing (ix, iy) still holds its bond: not one of the `broken` mask's.
fn intact(broken: u32, crossing: (i32, i32)) -> bool {
    (0..9).all(|k| broken >> k & 1 == 0 || mesh_bond(k) != crossing)
}

/// The failing bond's position `at` along the bent fibre and the span (lo, hi) it is bent
/// over, in lattice steps.
fn span(broken: u32, bond: u32, along: u32) -> (i32, i32, i32) {
    let (bx, by) = mesh_bond(bond);
    let (at, line) = if along == 0 { (bx, by) } else { (by, bx) };
    let bonded = |s: i32| {
        let c = if along == 0 { (s, line) } else { (line, s) };
        s != at && intact(broken, c)
    };
    let lo = [-7, 0, 7]
        .into_iter()
        .filter(|&s| s < at && bonded(s))
        .max();
    let hi = [-7, 0, 7]
        .into_iter()
        .filter(|&s| s > at && bonded(s))
        .min();
    (at, lo.unwrap_or(-14), hi.unwrap_or(14))
}

/// Which way a structure is bent before it is let go: across its fibre in the sheet's plane
/// (y, the thesis's plane model) or through the sheet (z, the layered network of §6.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Across {
    Plane,
    Sheet,
}

impl Across {
    fn add(self, ic: &mut InitialSpec, d: f64) {
        match self {
            Across::Plane => ic.dy += d,
            Across::Sheet => ic.dz += d,
        }
    }
}

/// [`mesh3x3`]'s fibres, kink and bond failures, bent `across`, bond (2) failing at `t2`
/// unless given (negative: never); no grid and no sensors yet.
pub(super) fn mesh(p: &Mesh, c: &Common, name: &str, across: Across, t2_default: f64) -> ModelFile {
    let (stretch, kink) = (p.stretch, p.kink);
    let mut lat = lattice(&[-7, 0, 7], &[-7, 0, 7], &|_| stretch);
    let b1 = lat.index[&(0, 0)];
    let b2 = lat.index[&(7, 0)];
    for ix in -6..=6 {
        let xi = (ix + 7) as f64 / 14.0;
        let pi = std::f64::consts::PI;
        let d = kink * (pi * xi).sin().powi(2);
        // The fibre is already stretched 1 %: its nodes sit at the stretched spacing.
        let mut ic = eq(lat.index[&(ix, 0)], stretch * ix as f64 * lat.a, 0.0);
        across.add(&mut ic, d);
        lat.initial.push(ic);
    }
    // The vertical fibre through bond (1) carries the bond's displacement as a whole (its
    // held ends shifted alike), so it holds no extra longitudinal strain: when the bond
    // fails it stays put instead of recoiling along its length at its ~1.2 MHz
    // longitudinal resonance, which would drown the horizontal fibre's ring.
    for end in [lat.index[&(0, -14)], lat.index[&(0, 14)]] {
        if let Some(ic) = lat.initial.iter_mut().find(|ic| ic.node == end) {
            across.add(ic, kink);
        }
    }
    let (t1, t2) = (p.t1, p.t2.unwrap_or(t2_default));
    let mut damage = vec![DamageSpec::Bond { node: b1, time: t1 }];
    if t2 >= 0.0 {
        damage.push(DamageSpec::Bond { node: b2, time: t2 });
    }
    lattice_model(
        name.into(),
        crate::model::Mechanism::BondFailure,
        lat,
        damage,
        c.damping.unwrap_or(1.5e-6),
        c,
    )
}

/// The plane structures' two sensors: 1.8 mm below the damage zone's centre and 1.8 mm to
/// its left, in the Appendix-A grid's cells.
fn below_and_beside() -> Vec<SensorSpec> {
    [(125, 100), (100, 125)]
        .iter()
        .map(|&(i, j)| SensorSpec { i, j, k: None })
        .collect()
}

/// A lattice as a model with the paper scenarios' system (implicit Euler, 10 ns unless
/// `dt` is given, the given damping, 4 000 steps), its own initial conditions, no grid and
/// no sensors.
fn lattice_model(
    name: String,
    label: crate::model::Mechanism,
    lat: Lattice,
    damage: Vec<DamageSpec>,
    damping: f64,
    c: &Common,
) -> ModelFile {
    ModelFile {
        name,
        label: Some(label.as_str().into()),
        system: system(c.dt.unwrap_or(1e-8), damping, 4_000),
        nodes: lat.nodes,
        springs: lat.springs,
        initial: lat.initial,
        forces: vec![],
        damage,
        grid: None,
        sensors: vec![],
    }
}

/// Fig. 4.19: fibre 3 (horizontal, y = 0) bonded to fibre 1 (vertical, x = −0.5 mm) and
/// fibre 2 (vertical, x = +0.5 mm). Fibre 3 and fibre 2 are stretched 1 %, fibre 1 only
/// 0.2 % (so fibre 2 is under the higher tension, Fig. 4.22). Fibre 3's 14 springs between
/// the bonds are the candidate break points; `point` p = 1…12 removes the (p+1)-th of them
/// at `t1` (1 µs), leaving p springs on fibre 1's side and 13 − p on fibre 2's: points p and
/// 13 − p mirror each other, as (1) and (12) do in the thesis.
pub(super) fn structure2x1(p: &Params, c: &Common) -> Result<ModelFile, SimError> {
    let s = Structure::read(p)?;
    let mut m = structure(&s, Split::read(p)?.split, c, "structure2x1-fibre-failure")?;
    m.grid = Some(paper_grid());
    m.sensors = below_and_beside();
    Ok(m)
}

/// [`structure2x1`]'s fibres and failure, each spring cut in `split`, its name
/// `prefix`-p`point`, no grid and no sensors yet.
pub(super) fn structure(
    p: &Structure,
    split: u32,
    c: &Common,
    prefix: &str,
) -> Result<ModelFile, SimError> {
    if !(1..=12).contains(&p.point) {
        return Err(SimError::Model(format!(
            "{prefix}: point must be 1…12, got {}",
            p.point
        )));
    }
    let point = p.point as i32;
    let (s3, s1) = (p.stretch, p.stretch1);
    if !(1..=8).contains(&split) {
        return Err(SimError::Model(format!(
            "{prefix}: split must be 1…8 springs per spring, got {split}"
        )));
    }
    let k = split as i32;
    // Fibre ids: 0 = fibre 3 (horizontal), 1 = fibre 1, 2 = fibre 2.
    let lat = lattice_fine(
        &[0],
        &[-7 * k, 7 * k],
        &|f| match f {
            0 => s3,
            1 => s1,
            _ => s3,
        },
        k,
        &|_, _| true,
    );
    // The break: the first of the k springs that make up spring `point` + 1 of the 14. A
    // split fibre's masses are 1/k of the plain one's: the default damping b is divided by k
    // so that every mode still decays at b/2m.
    let at = (-7 + point) * k;
    let (lo, hi) = (lat.index[&(at, 0)], lat.index[&(at + 1, 0)]);
    let spring = lat
        .springs
        .iter()
        .position(|s| (s.a == lo && s.b == hi) || (s.a == hi && s.b == lo))
        .expect("fibre 3 has the spring");
    let damage = vec![DamageSpec::Fibre { spring, time: p.t1 }];
    let damping = c.damping.unwrap_or(1.5e-6 / k as f64);
    Ok(lattice_model(
        format!("{prefix}-p{point}"),
        crate::model::Mechanism::FibreFailure,
        lat,
        damage,
        damping,
        c,
    ))
}
