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
use super::paper::{mesh, structure, Across, Mesh, Structure};
use super::params::{scenario_params, Common, Params, Scenario};
use super::parts::FIBRE_T;
use super::SimError;

/// The 3-D scenarios (names are contracts).
pub(super) const SCENARIOS: &[Scenario] = &[
    Scenario::new(
        "network3d-bond-failure",
        &[Mesh::KEYS, Cells::KEYS],
        bond_failure,
    ),
    Scenario::new(
        "network3d-fibre-failure",
        &[Structure::KEYS, Cells::KEYS],
        fibre_failure,
    ),
];

scenario_params! {
    /// Cells across the 3-D grid in x and y: a whole number from 60 (the sensors' 1.8 mm
    /// fit) to 401 (a grid 7× the default's memory).
    pub struct Cells {
        cells: u32 = CELLS as u32,
    }
}

/// Cells across the default 3-D grid, in x and in y.
pub const CELLS: usize = 125;

/// The 3-D grid: ±4.5 mm × ±4.5 mm around the damage zone, ±2.232 mm about the sheet, in
/// the Appendix-A cell (72 µm: 125 × 125 × 62 cells), Δt 0.1 µs, air, 4th order (Courant
/// number 0.486, under 3-D's 1/2).
pub fn grid3() -> GridSpec {
    grid3_across(CELLS)
}

/// [`grid3`] with `cells` cells across in x and y (the damage zone at the centre): a wider
/// sheet holds sensors as far as the plane library's 4.7 mm one (161 cells: ±5.8 mm), at
/// (cells/125)² the cost.
pub fn grid3_across(cells: usize) -> GridSpec {
    let h = 72e-6;
    let half = cells as f64 / 2.0;
    GridSpec {
        x1: -half * h,
        x2: half * h,
        y1: -half * h,
        y2: half * h,
        nx: cells,
        ny: cells,
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

/// Heights of a model's nodes: a node on one fibre at that fibre's layer × thickness; a
/// bond halfway between its fibres' layers.
fn heights(m: &ModelFile, layer: &dyn Fn(u32) -> u32) -> Vec<f64> {
    let mut on: Vec<Vec<u32>> = vec![Vec::new(); m.nodes.len()];
    for s in &m.springs {
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

/// Lay a plane structure in layers (`layer` of each fibre id), in the 3-D grid `cells`
/// across, with the two 3-D sensors.
fn layered(mut m: ModelFile, layer: &dyn Fn(u32) -> u32, cells: usize) -> ModelFile {
    let z = heights(&m, layer);
    let g = grid3_across(cells);
    m.sensors = sensors(&g);
    lift(&mut m, &z, Some(g));
    m
}

/// The `cells` parameter ([`Cells`]; default [`CELLS`]), checked.
fn cells(p: &Params) -> Result<usize, SimError> {
    let c = Cells::read(p)?.cells;
    if !(60..=401).contains(&c) {
        return Err(SimError::Model(format!(
            "cells must be a whole number from 60 to 401, got {c}"
        )));
    }
    Ok(c as usize)
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

/// Fig. 4.8's mesh (three horizontal, three vertical 2 mm fibres, 0.5 mm apart) laid in six
/// layers, horizontal and vertical alternating (h, v, h, v, h, v from the bottom). The
/// middle horizontal fibre is bent across the damage zone *out of the sheet* — its nodes
/// lifted by `kink`·sin²(πξ), the plane model's shape turned into z, as a fibre pressed over
/// another one is — and bond (1) at the centre fails at `t1`: the freed 1 mm length rings
/// through the sheet at its fundamental (~250 kHz). Bond (2), at (+0.5 mm, 0), fails at `t2`
/// (negative, the default: never).
fn bond_failure(p: &Params, c: &Common) -> Result<ModelFile, SimError> {
    let m = mesh(
        &Mesh::read(p)?,
        c,
        "network3d-bond-failure",
        Across::Sheet,
        -1.0,
    );
    // Fibre ids: the three horizontal fibres 0–2, then the three vertical ones 3–5.
    let layer = |f| if f < 3 { 2 * f } else { 2 * (f - 3) + 1 };
    Ok(layered(m, &layer, cells(p)?))
}

/// Fig. 4.19's structure as layers: fibres 1 and 2 (vertical, x = ∓0.5 mm) at the bottom,
/// fibre 3 (horizontal, y = 0) laid over them; fibre 3 and fibre 2 stretched 1 %, fibre 1
/// 0.2 %. Spring `point` + 1 of fibre 3's 14 between the bonds breaks at `t1` (1 µs): the
/// two ends recoil along the fibre, and the pieces, tilted down to the bonds, swing.
fn fibre_failure(p: &Params, c: &Common) -> Result<ModelFile, SimError> {
    let m = structure(&Structure::read(p)?, 1, c, "network3d-fibre-failure")?;
    // Fibre id 0 is fibre 3.
    Ok(layered(m, &|f| u32::from(f == 0), cells(p)?))
}
