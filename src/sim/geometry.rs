//! What the acoustic coupling sees of the fibres: per mass, one *strand* for each fibre
//! passing through it.
//!
//! A mass on one fibre is a piece of that fibre: it displaces fluid across the fibre's
//! direction with the length it stands for. A bond is a mass two fibres share, and it is a
//! piece of each of them: it radiates as the two fibres do, each across its own direction
//! with its own length. Summing the two fibres' directions into one tangent instead (what
//! the coupling did before) gives a bond of two crossing fibres a diagonal whose sign turns
//! on a dot product that is zero up to round-off — a 10⁻⁶ change of a kink then moved a
//! quiet sensor by 76 % of its peak (docs/fidelity.md). Grouping by the springs' fibre id
//! makes every strand's direction the sum of springs that continue one another, so it is
//! well conditioned.

use super::mech::{Mech, Spring};

/// One fibre's piece at one mass.
#[derive(Debug, Clone, Copy)]
pub struct Strand<const D: usize> {
    pub node: usize,
    pub fibre: u32,
    /// The fibre length the mass stands for on this fibre: half its intact springs' rest
    /// lengths.
    pub length: f64,
    /// Unit tangent of the fibre at the mass; for a free end (count 1) it points from the
    /// end into the fibre.
    pub tangent: [f64; D],
    /// The fibre's intact springs at the mass (1: a free fibre end).
    pub count: usize,
    /// The fibre's cross-section: width (in the sheet's plane) and thickness, m.
    pub width: f64,
    pub thickness: f64,
}

/// Every mass's strands, in mass order and, at a mass, in the order its fibres' first
/// intact springs appear. A mass on one fibre has one strand, built from the same sums in
/// the same order as the one tangent of the coupling before strands, so a model without
/// bonds couples bit for bit as before.
pub fn strands<const D: usize>(mech: &Mech<D>) -> Vec<Strand<D>> {
    const NONE: usize = usize::MAX;
    // Strands as they are met, with a per-mass list (head, next) to find a fibre's strand.
    let mut head = vec![NONE; mech.len()];
    let mut next: Vec<usize> = Vec::new();
    let mut found: Vec<Strand<D>> = Vec::new();
    for s in mech.springs.iter().filter(|s| !s.broken) {
        let d = sub(mech.r[s.b], mech.r[s.a]);
        let l = dotv(d, d).sqrt().max(1e-300);
        let tv: [f64; D] = std::array::from_fn(|c| d[c] / l);
        for (node, sign) in [(s.a, 1.0), (s.b, -1.0)] {
            let k = strand_of(&mut head, &mut next, &mut found, node, s);
            let e = &mut found[k];
            e.length += 0.5 * s.l0;
            // Orient the springs alike (a fibre passing through has one direction).
            let dot = dotv(e.tangent, tv);
            let sg = if e.count == 0 {
                sign
            } else if dot < 0.0 {
                -1.0
            } else {
                1.0
            };
            for (t, v) in e.tangent.iter_mut().zip(tv) {
                *t += sg * v;
            }
            e.count += 1;
            e.width = s.w;
            e.thickness = s.t;
        }
    }
    let mut out = Vec::with_capacity(found.len());
    for &first in &head {
        let mut k = first;
        // The list runs newest first: collect and reverse so a mass's strands keep the
        // order of their first springs.
        let start = out.len();
        while k != NONE {
            out.push(found[k]);
            k = next[k];
        }
        out[start..].reverse();
    }
    for e in &mut out {
        let l = dotv(e.tangent, e.tangent).sqrt();
        if l > 0.0 {
            e.tangent = std::array::from_fn(|c| e.tangent[c] / l);
        }
    }
    out
}

/// The index of `node`'s strand on spring `s`'s fibre, made when it is the first.
fn strand_of<const D: usize>(
    head: &mut [usize],
    next: &mut Vec<usize>,
    found: &mut Vec<Strand<D>>,
    node: usize,
    s: &Spring,
) -> usize {
    let mut k = head[node];
    while k != usize::MAX {
        if found[k].fibre == s.fibre {
            return k;
        }
        k = next[k];
    }
    found.push(Strand {
        node,
        fibre: s.fibre,
        length: 0.0,
        tangent: [0.0; D],
        count: 0,
        width: 0.0,
        thickness: 0.0,
    });
    next.push(head[node]);
    head[node] = found.len() - 1;
    found.len() - 1
}

/// a − b.
fn sub<const D: usize>(a: [f64; D], b: [f64; D]) -> [f64; D] {
    std::array::from_fn(|c| a[c] - b[c])
}

/// a·b, summed from the first component on (as the mechanics sums it).
fn dotv<const D: usize>(a: [f64; D], b: [f64; D]) -> f64 {
    let mut s = a[0] * b[0];
    for c in 1..D {
        s += a[c] * b[c];
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::scenario::{build, Params};

    fn mech(name: &str) -> Mech<2> {
        let m = build(name, &Params::default()).unwrap();
        Mech::<2>::new(&m)
    }

    #[test]
    fn a_bond_is_a_strand_of_each_of_its_fibres_and_a_plain_mass_one_strand() {
        let m = mech("mesh3x3-bond-failure");
        let st = strands(&m);
        // Every mass with an intact spring has a strand per fibre of its springs.
        for i in 0..m.len() {
            let mut fibres: Vec<u32> = m
                .springs
                .iter()
                .filter(|s| !s.broken && (s.a == i || s.b == i))
                .map(|s| s.fibre)
                .collect();
            fibres.sort();
            fibres.dedup();
            let mut got: Vec<u32> = st.iter().filter(|s| s.node == i).map(|s| s.fibre).collect();
            got.sort();
            assert_eq!(got, fibres, "mass {i}");
        }
        // The mesh's crossings: two strands at right angles, each along its own fibre.
        let mut bonds = 0;
        for i in 0..m.len() {
            let here: Vec<_> = st.iter().filter(|s| s.node == i).collect();
            if here.len() == 2 {
                bonds += 1;
                let d = dotv(here[0].tangent, here[1].tangent);
                assert!(d.abs() < 1e-3, "mass {i}: tangents {:?}", here);
                for s in &here {
                    assert!((dotv(s.tangent, s.tangent) - 1.0).abs() < 1e-12);
                }
            }
        }
        assert_eq!(bonds, 9, "Fig. 4.8's mesh has 9 bonds");
    }

    /// The coupling before strands (one tangent per mass, the sum of all its springs'
    /// directions), kept here as the reference a model without bonds must match bit for bit.
    fn one_tangent_per_mass(m: &Mech<2>) -> Vec<(f64, [f64; 2], usize)> {
        let mut g = vec![(0.0, [0.0; 2], 0usize); m.len()];
        for s in m.springs.iter().filter(|s| !s.broken) {
            let d = sub(m.r[s.b], m.r[s.a]);
            let l = dotv(d, d).sqrt().max(1e-300);
            let tv: [f64; 2] = std::array::from_fn(|c| d[c] / l);
            for (node, sign) in [(s.a, 1.0), (s.b, -1.0)] {
                let e = &mut g[node];
                e.0 += 0.5 * s.l0;
                let sg = if e.2 == 0 {
                    sign
                } else if dotv(e.1, tv) < 0.0 {
                    -1.0
                } else {
                    1.0
                };
                for (t, v) in e.1.iter_mut().zip(tv) {
                    *t += sg * v;
                }
                e.2 += 1;
            }
        }
        for e in &mut g {
            let l = dotv(e.1, e.1).sqrt();
            if l > 0.0 {
                e.1 = std::array::from_fn(|c| e.1[c] / l);
            }
        }
        g
    }

    #[test]
    fn without_bonds_every_mass_couples_bit_for_bit_as_before() {
        for name in [
            "sho",
            "five-mass-fibre",
            "fibre-single-constraint",
            "fibre-multiple-constraints",
            "rubber-band",
            "paper-fibre",
        ] {
            let m = mech(name);
            let before = one_tangent_per_mass(&m);
            let st = strands(&m);
            let with_springs: Vec<usize> = (0..m.len()).filter(|&i| before[i].2 > 0).collect();
            assert_eq!(
                st.iter().map(|s| s.node).collect::<Vec<_>>(),
                with_springs,
                "{name}: one strand per mass with springs, in mass order"
            );
            for s in &st {
                let (length, tangent, count) = before[s.node];
                assert_eq!(
                    s.length.to_bits(),
                    length.to_bits(),
                    "{name} mass {}",
                    s.node
                );
                assert_eq!(s.tangent.map(f64::to_bits), tangent.map(f64::to_bits));
                assert_eq!(s.count, count);
            }
        }
    }
}
