//! Eq. 4.5.6 (§4.5.5, Tables 4.2–4.3, Fig. 4.18): as bonds fail, "the statistical
//! frequency of the 700 - 800 kHz signals is inversely proportional to the amount of damage
//! … and [that] of recording the 200 - 300 kHz signals is proportional to [it]". The thesis
//! infers this from one paper test's power ratios against AE number; no paper test is at
//! hand, and a synthetic test would only read back the law it was drawn from. So the entry
//! asks the thesis's own model instead: Fig. 4.8's mesh is broken bond by bond, each failure
//! simulated in the structure the earlier ones left (`mesh3x3-damaged-bond-failure`), so
//! the free length each failure releases — the only cause the thesis names — grows as the
//! model says it does. Nothing is drawn but the order of the failures and the fibre each
//! one bends. Each AE is heard by the sensor facing its fibre's motion (the other sits on
//! the fibre's silent axis, where a bond's coupling is ill-defined: docs/fidelity.md). By
//! the mesh's diagonal symmetry a column bent and heard at sensor 2 is its mirror, a row
//! bent and heard at sensor 1, which is what is simulated. Then Eq. 4.5.4's 25 power ratios, and per window
//! Pearson's r (Eq. 4.5.5) and the regression of Table 4.3 against AE number.

use super::ThesisError;
use crate::analysis::stats::linear_trend;
use crate::sim::paper::damaged_span;
use crate::sim::scenario::{build, Params};
use crate::sim::{simulate, SimError, SimOptions};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::Path;

/// Damage sequences: random orders of the mesh's nine bonds (seeds 1…SEQUENCES).
pub const SEQUENCES: u64 = 8;
/// Eq. 4.5.4's windows.
const BANDS: usize = crate::sim::output::POWER_BANDS;

/// One failure of a sequence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Failure {
    pub sequence: u64,
    /// 1…9 within its sequence: the damage before it is `ae_number` − 1 failed bonds.
    pub ae_number: u32,
    /// The bond (0…8) and the fibre bent (0 its row, 1 its column).
    pub bond: u32,
    pub along: u32,
    /// The bonds failed before (bit k: bond k).
    pub broken: u32,
}

/// The mirror of bond k in the mesh's diagonal (rows ↔ columns).
fn mirror(k: u32) -> u32 {
    3 * (k % 3) + k / 3
}

fn mirror_mask(m: u32) -> u32 {
    (0..9)
        .filter(|k| m >> k & 1 == 1)
        .fold(0, |a, k| a | 1 << mirror(k))
}

impl Failure {
    /// The row-bent configuration simulated for it: itself, or its mirror.
    pub fn simulated(&self) -> (u32, u32) {
        if self.along == 0 {
            (self.broken, self.bond)
        } else {
            (mirror_mask(self.broken), mirror(self.bond))
        }
    }
}

/// The failures of `sequences` random damage sequences, in order.
pub fn sequences(sequences: u64) -> Vec<Failure> {
    let mut out = vec![];
    for sequence in 1..=sequences {
        let mut rng = crate::util::Rng::new(sequence);
        let mut order: Vec<u32> = (0..9).collect();
        rng.shuffle(&mut order);
        let mut broken = 0u32;
        for (i, &bond) in order.iter().enumerate() {
            let along = (rng.next_u64() & 1) as u32;
            out.push(Failure {
                sequence,
                ae_number: i as u32 + 1,
                bond,
                along,
                broken,
            });
            broken |= 1 << bond;
        }
    }
    out
}

/// What one simulated failure sounds like at the sensor facing it.
#[derive(Debug, Clone)]
pub struct Heard {
    pub dominant_hz: f64,
    pub ratios: [f64; BANDS],
}

/// Simulate a row-bent configuration (broken mask, bond) and hear it at sensor 1.
pub fn hear(broken: u32, bond: u32) -> Result<Heard, SimError> {
    let m = build(
        "mesh3x3-damaged-bond-failure",
        &Params(vec![
            ("broken".into(), broken as f64),
            ("bond".into(), bond as f64),
        ]),
    )?;
    let out = simulate(&m, &SimOptions::default())?;
    let g = m.grid.as_ref().expect("the mesh has a grid");
    let x = crate::sim::output::band_limited(&out.sensors[0], g);
    let fs = out.sample_rate_hz;
    let ratios = crate::sim::output::power_ratios(&x, fs)
        .ok_or_else(|| SimError::Model(format!("bond {bond} after {broken:#b}: a silent AE")))?;
    Ok(Heard {
        dominant_hz: crate::sim::dominant_frequency(&x, fs),
        ratios,
    })
}

/// The entry: writes `aes.parquet` (a row per failure), `trends.parquet` (Tables 4.2–4.3:
/// r, p, m, c per window), `probability.parquet` (the share of AEs whose dominant frequency
/// lies in 700–800 and 200–300 kHz, per AE number) and `trend.png` (Fig. 4.18); returns r of
/// the 200–300 kHz window's power ratio against AE number (Eq. 4.5.6b).
pub fn eq_4_5_6(dir: &Path) -> Result<f64, ThesisError> {
    let fails = sequences(SEQUENCES);
    let configs: Vec<(u32, u32)> = fails
        .iter()
        .map(Failure::simulated)
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect();
    let heard: BTreeMap<(u32, u32), Heard> = configs
        .par_iter()
        .map(|&(m, b)| hear(m, b).map(|h| ((m, b), h)))
        .collect::<Result<_, _>>()?;
    let at = |f: &Failure| &heard[&f.simulated()];
    super::write_floats(
        &dir.join("aes.parquet"),
        "thesis_eq_4_5_6_aes",
        [
            ("sequence", "", "the damage sequence (its seed)"),
            ("ae_number", "", "the failure's place in its sequence, 1…9"),
            (
                "bond",
                "",
                "the bond failing, 0…8 (3·row + column; 4 the centre)",
            ),
            ("along", "", "the fibre bent: 0 its row, 1 its column"),
            (
                "free_length_mm",
                "mm",
                "the free length the failure releases",
            ),
            (
                "dominant_frequency_khz",
                "kHz",
                "the AE's dominant frequency",
            ),
            ("w_200_300", "", "Eq. 4.5.4's power ratio of 200–300 kHz"),
            ("w_700_800", "", "Eq. 4.5.4's power ratio of 700–800 kHz"),
        ],
        fails.iter().map(|f| {
            let h = at(f);
            [
                f.sequence as f64,
                f.ae_number as f64,
                f.bond as f64,
                f.along as f64,
                damaged_span(f.broken, f.bond, f.along) * 1e3,
                h.dominant_hz / 1e3,
                h.ratios[2],
                h.ratios[7],
            ]
        }),
    )?;
    let x: Vec<f64> = fails.iter().map(|f| f.ae_number as f64).collect();
    let mut fits = vec![];
    for w in 0..BANDS {
        let y: Vec<f64> = fails.iter().map(|f| at(f).ratios[w]).collect();
        fits.push(linear_trend(&x, &y).ok());
    }
    super::write_floats(
        &dir.join("trends.parquet"),
        "thesis_eq_4_5_6_trends",
        [
            (
                "window_lo_khz",
                "kHz",
                "the window's lower edge (100 kHz wide)",
            ),
            (
                "r",
                "",
                "Pearson's r of its power ratio against AE number (Eq. 4.5.5)",
            ),
            ("p", "", "r's two-sided p value"),
            ("m", "1/AE", "the regression's gradient (Table 4.3)"),
            ("c", "", "the regression's value at AE number 0"),
        ],
        fits.iter()
            .enumerate()
            .filter_map(|(w, f)| f.map(|f| [w as f64 * 100.0, f.r, f.p, f.slope, f.intercept])),
    )?;
    write_probability(dir, &fails, &heard)?;
    let (Some(hi), Some(lo)) = (fits[7], fits[2]) else {
        return Err(ThesisError::Measure {
            id: "eq-4.5.6",
            message: "the 200–300 or 700–800 kHz power ratio is constant over the AEs".into(),
        });
    };
    let line = |f: crate::analysis::stats::LinearTrend| {
        vec![
            (1.0, f.intercept + f.slope),
            (9.0, f.intercept + 9.0 * f.slope),
        ]
    };
    crate::plot::sim::curves_png(
        &dir.join("trend.png"),
        &format!(
            "Eq. 4.5.6 / Fig. 4.18: {SEQUENCES} sequences of bond failures in Fig. 4.8's mesh (r = {:.2} and {:.2})",
            lo.r, hi.r
        ),
        "AE number (bonds failed + 1)",
        "power ratio",
        &[
            (
                "200–300 kHz, each AE",
                fails.iter().map(|f| (f.ae_number as f64, at(f).ratios[2])).collect(),
            ),
            ("200–300 kHz, fitted", line(lo)),
            ("700–800 kHz, fitted", line(hi)),
        ],
    )?;
    Ok(lo.r)
}

/// `probability.parquet`: per AE number, the share of the sequences' AEs whose dominant
/// frequency lies in 700–800 and in 200–300 kHz.
fn write_probability(
    dir: &Path,
    fails: &[Failure],
    heard: &BTreeMap<(u32, u32), Heard>,
) -> Result<(), ThesisError> {
    let at = |f: &Failure| &heard[&f.simulated()];
    let share = |n: u32, lo: f64, hi: f64| {
        let at_n: Vec<&Failure> = fails.iter().filter(|f| f.ae_number == n).collect();
        let inside = at_n
            .iter()
            .filter(|f| (lo..hi).contains(&at(f).dominant_hz))
            .count();
        inside as f64 / at_n.len() as f64
    };
    super::write_floats(
        &dir.join("probability.parquet"),
        "thesis_eq_4_5_6_probability",
        [
            ("ae_number", "", "AE number, 1…9"),
            (
                "p_700_800",
                "",
                "share of the sequences' AEs at this number dominant in 700–800 kHz",
            ),
            ("p_200_300", "", "share dominant in 200–300 kHz"),
        ],
        (1..=9).map(|n| [n as f64, share(n, 700e3, 800e3), share(n, 200e3, 300e3)]),
    )?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sequence_fails_every_bond_once_and_mirrors_stay_in_the_mesh() {
        let f = sequences(3);
        assert_eq!(f.len(), 27);
        for s in 1..=3 {
            let mut seen = 0u32;
            for x in f.iter().filter(|x| x.sequence == s) {
                assert_eq!(x.broken, seen, "the bonds failed before");
                assert_eq!(seen >> x.bond & 1, 0, "a bond fails once");
                seen |= 1 << x.bond;
            }
            assert_eq!(seen, 511);
        }
        // The mirror swaps rows and columns: corner 2 (row 0, column 2) ↔ corner 6.
        assert_eq!((mirror(2), mirror(6), mirror(4), mirror(1)), (6, 2, 4, 3));
        for k in 0..9 {
            assert_eq!(mirror_mask(1 << k), 1 << mirror(k));
            assert_eq!(mirror(mirror(k)), k);
        }
        for m in 0..512 {
            assert_eq!(mirror_mask(mirror_mask(m)), m);
            // A column bent is its mirror's row bent: the same free length released.
            for k in (0..9).filter(|k| m >> k & 1 == 0) {
                let f = Failure {
                    sequence: 0,
                    ae_number: 1,
                    bond: k,
                    along: 1,
                    broken: m,
                };
                let (mm, mk) = f.simulated();
                assert_eq!(damaged_span(m, k, 1), damaged_span(mm, mk, 0), "{m:#b} {k}");
            }
        }
    }
}
