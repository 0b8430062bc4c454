//! Novelty: whether a hit is like any of the map's references at all.
//!
//! A map gives every input its best-matching unit, however far that node is: hits of a
//! specimen the references never described (pencil-lead breaks on carbon fibre read with a
//! paper map) still get a class. The distance to the BMU — the input's quantisation error,
//! the summand of Eq. 5.4.1 — says how well the map describes the input; a threshold on it
//! says when it does not.
//!
//! **How the threshold is calibrated.** A reference row the map was trained on lies closer
//! to its node than a new hit of the same kind would, so the threshold is not read off the
//! training rows' own distances. Instead the training set's distinct rows are dealt into
//! [`FOLDS`] folds (a seeded shuffle); for each fold a map with the same parameters and seed
//! is trained on the other folds' rows (repeats of a balanced class kept) and measures the
//! held-out fold's distances. Every reference row thus has one distance from a map that
//! never saw it; their distribution is kept in the model. `[som] novelty_quantile` q
//! (default 0.99) picks the threshold by the split-conformal rule (Vovk et al. 2005;
//! Angelopoulos & Bates 2021): with n held-out distances, the ⌈(n + 1)·q⌉-th smallest. For
//! a new hit exchangeable with the references this bounds the chance that it is novel by
//! 1 − q, whatever the distances' distribution; a plain empirical q-quantile of 120
//! distances would be the 2nd-largest and is beyond the 1 − q guarantee. When
//! ⌈(n + 1)·q⌉ > n the strict rule gives no finite threshold; aepipe takes the largest
//! held-out distance (so the bound is then 1/(n + 1) rather than 1 − q), and the model
//! states n. A hit beyond the threshold is *novel*. The map that classifies is the one
//! trained on all rows, which lies at least as close to references as the fold maps.
//!
//! The demo's own hits are references with propagation, noise and sensor added, so they lie
//! farther from the map than unseen clean references: on the default demo (seed 2026, the
//! one this rule was chosen on) an empirical 0.99-quantile marks 5 % of its true bond and
//! fibre hits novel, the conformal rule 0.8 %. Tests check the rule on seeds never used
//! to choose anything.

use super::{Som, SomError, ValidParams};
use ndarray::{Array2, ArrayView2};

/// Folds of the cross-validation (each fold map sees 4/5 of the references).
pub const FOLDS: usize = 5;

/// Fewest distinct reference rows to calibrate on (two per fold); a map trained on fewer
/// has no novelty threshold, and says so.
pub const MIN_ROWS: usize = 2 * FOLDS;

/// Held-out distances kept in `model.json`: all of them up to this many, else this many
/// evenly spaced order statistics (the first the smallest, the last the largest), so a map
/// trained on millions of rows stays a small file.
pub const MAX_KEPT: usize = 4096;

/// The calibration a model carries (`model.json`'s `novelty`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Novelty {
    /// Folds of the cross-validation.
    pub folds: usize,
    /// Distinct reference rows that were held out once each.
    pub rows: usize,
    /// Their distances to the BMU of a map trained without them, ascending (all of them, or
    /// [`MAX_KEPT`] evenly spaced order statistics).
    pub held_out: Vec<f64>,
}

impl Novelty {
    /// Calibrate on the training rows: `data` (in the map's scaling, one row per training
    /// row, a balanced class's repeats included), `origin`, each row's index among the
    /// distinct references (equal for repeats), and `group`, each row's source (rows of one
    /// source are held out together). `None` with fewer than [`MIN_ROWS`] distinct
    /// references or fewer sources than folds. The fold maps train in parallel.
    pub fn calibrate(
        params: &ValidParams,
        data: ArrayView2<f64>,
        origin: &[usize],
        group: &[usize],
        seed: u64,
    ) -> Result<Option<Novelty>, SomError> {
        use rayon::prelude::*;
        use std::collections::HashMap;
        if origin.len() != data.nrows() || group.len() != data.nrows() {
            return Err(SomError::Data(format!(
                "{} origins and {} groups for {} rows",
                origin.len(),
                group.len(),
                data.nrows()
            )));
        }
        // Each distinct reference's first row stands for it when held out.
        let mut first: HashMap<usize, usize> = HashMap::new();
        for (r, o) in origin.iter().enumerate() {
            first.entry(*o).or_insert(r);
        }
        let mut groups: Vec<usize> = group.to_vec();
        groups.sort_unstable();
        groups.dedup();
        if first.len() < MIN_ROWS || groups.len() < FOLDS {
            return Ok(None);
        }
        // Seeded Fisher–Yates over the sources, then dealt round-robin into the folds.
        crate::util::Rng::new(seed ^ 0x6e6f_7665_6c74_7921).shuffle(&mut groups);
        let fold_of: HashMap<usize, usize> = groups
            .iter()
            .enumerate()
            .map(|(pos, &g)| (g, pos % FOLDS))
            .collect();
        let mut held_rows: Vec<usize> = first.values().copied().collect();
        held_rows.sort_unstable();
        let per_fold: Vec<Vec<f64>> = (0..FOLDS)
            .into_par_iter()
            .map(|f| -> Result<Vec<f64>, SomError> {
                let train: Vec<usize> = (0..origin.len())
                    .filter(|&r| fold_of[&group[r]] != f)
                    .collect();
                let rows: Array2<f64> = data.select(ndarray::Axis(0), &train);
                let som = Som::fit_with(params, rows.view(), false)?;
                Ok(held_rows
                    .iter()
                    .filter(|&&r| fold_of[&group[r]] == f)
                    .map(|&r| {
                        let x = data.row(r);
                        som.bmu(x.as_slice().expect("standard layout")).1
                    })
                    .collect())
            })
            .collect::<Result<_, _>>()?;
        let mut all: Vec<f64> = per_fold.into_iter().flatten().collect();
        all.sort_by(f64::total_cmp);
        Ok(Some(Novelty {
            folds: FOLDS,
            rows: all.len(),
            held_out: thin(&all, MAX_KEPT),
        }))
    }

    /// The threshold for `novelty_quantile` q: the ⌈(n + 1)·q⌉-th smallest of the n held-out
    /// distances (split-conformal), the largest when that rank exceeds n. q is checked by
    /// `[som]`; it is clamped to [0, 1] here. With thinned distances the rank is read by
    /// linear interpolation between the kept order statistics.
    pub fn threshold(&self, q: f64) -> f64 {
        let n = self.rows.max(1);
        let rank = (((n + 1) as f64) * q.clamp(0.0, 1.0))
            .ceil()
            .clamp(1.0, n as f64);
        if n == 1 {
            return self.held_out[self.held_out.len() - 1];
        }
        quantile(&self.held_out, (rank - 1.0) / (n - 1) as f64)
    }

    /// The kept distances are sorted, finite and non-negative (a model file is checked
    /// before use).
    pub fn check(&self) -> Result<(), SomError> {
        let bad = |m: &str| Err(SomError::Data(format!("model.json's novelty: {m}")));
        if self.held_out.is_empty() {
            return bad("the calibration holds no distances");
        }
        if self.held_out.iter().any(|d| !d.is_finite() || *d < 0.0) {
            return bad("the calibration holds a negative or non-finite distance");
        }
        if self.held_out.windows(2).any(|w| w[1] < w[0]) {
            return bad("the calibration's distances are not ascending");
        }
        Ok(())
    }
}

/// What the novelty test found in one classification (`Confusion::novelty`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct NoveltyReading {
    /// The threshold in force; `None` when the model carries no calibration.
    pub threshold: Option<f64>,
    /// `[som] novelty_quantile`.
    pub quantile: f64,
    /// Held-out references the threshold was calibrated on.
    pub calibrated_on: usize,
    /// Experiment → (novel hits, classified hits).
    pub per_experiment: std::collections::BTreeMap<String, (usize, usize)>,
}

/// Above this share of novel hits, the map's classes do not describe a test.
pub const MOSTLY_UNLIKE: f64 = 0.5;

impl NoveltyReading {
    /// Novel share of one experiment's classified hits (`None`: no calibration or no hits).
    pub fn share(&self, experiment: &str) -> Option<f64> {
        let (n, t) = *self.per_experiment.get(experiment)?;
        (self.threshold.is_some() && t > 0).then(|| n as f64 / t as f64)
    }

    /// Novel and classified hits over all experiments.
    pub fn totals(&self) -> (usize, usize) {
        self.per_experiment
            .values()
            .fold((0, 0), |(a, b), (n, t)| (a + n, b + t))
    }

    /// Experiments of which more than half the hits are novel.
    pub fn undescribed(&self) -> Vec<&str> {
        self.per_experiment
            .keys()
            .filter(|e| self.share(e).is_some_and(|s| s > MOSTLY_UNLIKE))
            .map(String::as_str)
            .collect()
    }

    /// One line for the terminal and the report: the threshold and the share unlike the
    /// references, per experiment when there are a few, and what to do when most are.
    pub fn describe(&self) -> String {
        let Some(t) = self.threshold else {
            return "novelty not tested: the map carries no calibration (a map read from a .cod \
                    file, or trained on fewer than 10 distinct references in 5 sources)"
                .into();
        };
        let (n, total) = self.totals();
        let mut s = format!(
            "unlike the references: {n} of {total} hits ({:.1} %) beyond quantisation error {t:.4} (the conformal {} quantile of {} held-out references)",
            100.0 * n as f64 / total.max(1) as f64,
            self.quantile,
            self.calibrated_on
        );
        if self.per_experiment.len() > 1 && self.per_experiment.len() <= 12 {
            let per: Vec<String> = self
                .per_experiment
                .iter()
                .map(|(e, (n, t))| format!("{e} {:.0} %", 100.0 * *n as f64 / (*t).max(1) as f64))
                .collect();
            s += &format!(" ({})", per.join(", "));
        }
        let bad = self.undescribed();
        if !bad.is_empty() {
            s += &format!(
                ". More than half of {} unlike the references: the map's classes do not describe {}; group {} hits by their own features instead (aepipe cluster, or [cluster] enabled = true in the pipeline)",
                if bad.len() == 1 { format!("{} is", bad[0]) } else { format!("each of {} tests is", bad.len()) },
                if bad.len() == 1 { "this test" } else { "these tests" },
                if bad.len() == 1 { "its" } else { "their" }
            );
        }
        s
    }
}

/// The q-quantile of ascending `v` (non-empty), NumPy's default ("linear", type 7).
pub fn quantile(v: &[f64], q: f64) -> f64 {
    let q = q.clamp(0.0, 1.0);
    let h = (v.len() - 1) as f64 * q;
    let (lo, hi) = (h.floor() as usize, h.ceil() as usize);
    v[lo] + (h - lo as f64) * (v[hi] - v[lo])
}

/// `n` evenly spaced order statistics of ascending `v` (all of `v` when it is no longer),
/// the first and last kept, so quantiles of the result approximate those of `v`.
fn thin(v: &[f64], n: usize) -> Vec<f64> {
    if v.len() <= n {
        return v.to_vec();
    }
    (0..n)
        .map(|k| quantile(v, k as f64 / (n - 1) as f64))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::som::SomParams;

    #[test]
    fn quantile_is_numpys_linear_interpolation() {
        // numpy.quantile([1, 2, 4, 8], [0, 0.5, 0.9, 1]) = [1, 3, 6.8, 8]
        let v = [1.0, 2.0, 4.0, 8.0];
        for (q, want) in [(0.0, 1.0), (0.5, 3.0), (0.9, 6.8), (1.0, 8.0)] {
            assert!((quantile(&v, q) - want).abs() < 1e-12, "q {q}");
        }
        // Thinning keeps the ends and the quantiles of an evenly spaced series.
        let long: Vec<f64> = (0..10_001).map(f64::from).collect();
        let t = thin(&long, 101);
        assert_eq!(t.len(), 101);
        assert_eq!((t[0], t[100], t[50]), (0.0, 10_000.0, 5_000.0));
    }

    /// The conformal rank: ⌈(n + 1)·q⌉-th smallest, the largest beyond n; thinned
    /// distances give the same rank's value.
    #[test]
    fn threshold_is_the_conformal_rank() {
        let nov = |v: Vec<f64>, rows: usize| Novelty {
            folds: FOLDS,
            rows,
            held_out: v,
        };
        let four = nov(vec![1.0, 2.0, 4.0, 8.0], 4);
        // ⌈5·0.5⌉ = 3rd, ⌈5·0.3⌉ = 2nd, ⌈5·0.9⌉ = 5 > 4: the largest; q = 0: the smallest.
        for (q, want) in [(0.5, 4.0), (0.3, 2.0), (0.9, 8.0), (1.0, 8.0), (0.0, 1.0)] {
            assert_eq!(four.threshold(q), want, "q {q}");
        }
        // 10 001 distances 0..=10 000 thinned to 101: rank ⌈10 002·0.99⌉ = 9 902, value 9 901.
        let long: Vec<f64> = (0..10_001).map(f64::from).collect();
        let thinned = nov(thin(&long, 101), 10_001);
        assert!((thinned.threshold(0.99) - 9_901.0).abs() < 1e-9);
        assert_eq!(nov(long, 10_001).threshold(0.99), 9_901.0);
    }

    /// Two Gaussian clouds as references: a held-out point of a cloud is within the
    /// threshold about q of the time, a point of a third cloud far away never is, and the
    /// threshold of an unseen reference lies above the training rows' own distances.
    #[test]
    fn unseen_references_pass_and_a_distant_cloud_does_not() {
        let mut rng = crate::util::Rng::new(7);
        let mut gauss = || rng.normal();
        let dim = 4;
        let cloud = |c: f64, n: usize, g: &mut dyn FnMut() -> f64| {
            Array2::from_shape_fn((n, dim), |(_, k)| if k == 0 { c } else { 0.0 } + 0.3 * g())
        };
        let a = cloud(0.0, 150, &mut gauss);
        let b = cloud(3.0, 150, &mut gauss);
        let train = ndarray::concatenate![ndarray::Axis(0), a, b];
        let params = SomParams {
            rows: 5,
            cols: 5,
            ..SomParams::default()
        }
        .check()
        .unwrap();
        let origin: Vec<usize> = (0..train.nrows()).collect();
        let nov = Novelty::calibrate(&params, train.view(), &origin, &origin, 1)
            .unwrap()
            .unwrap();
        assert_eq!((nov.folds, nov.rows, nov.held_out.len()), (5, 300, 300));
        nov.check().unwrap();
        let t = nov.threshold(0.99);
        let som = Som::fit(&params, train.view()).unwrap();
        let own = som.quantisation_error(train.view());
        assert!(
            t > own,
            "threshold {t} vs the training rows' mean distance {own}"
        );
        // Fresh draws of the references: about 1 % beyond the threshold.
        let fresh = ndarray::concatenate![
            ndarray::Axis(0),
            cloud(0.0, 1000, &mut gauss),
            cloud(3.0, 1000, &mut gauss)
        ];
        let novel = |m: &Array2<f64>| {
            m.rows()
                .into_iter()
                .filter(|x| som.bmu(x.as_slice().unwrap()).1 > t)
                .count()
        };
        let n = novel(&fresh);
        assert!(n <= 60, "{n} of 2000 fresh references novel (expected ~20)");
        // A cloud the references never held: all of it novel.
        let far = cloud(-4.0, 200, &mut gauss);
        assert_eq!(novel(&far), 200);
        // Too few references: no calibration.
        let few = train.slice(ndarray::s![..9, ..]).to_owned();
        let o: Vec<usize> = (0..9).collect();
        assert!(Novelty::calibrate(&params, few.view(), &o, &o, 1)
            .unwrap()
            .is_none());
        // Repeats are one reference: 9 distinct rows repeated are still too few.
        let rep = ndarray::concatenate![ndarray::Axis(0), few, few];
        let o: Vec<usize> = (0..18).map(|i| i % 9).collect();
        assert!(Novelty::calibrate(&params, rep.view(), &o, &o, 1)
            .unwrap()
            .is_none());
        // Fewer sources than folds: none either.
        let g = vec![0; 300];
        assert!(Novelty::calibrate(&params, train.view(), &origin, &g, 1)
            .unwrap()
            .is_none());
    }
}
