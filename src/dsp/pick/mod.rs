//! Arrival-time pickers: where in a record the AE wave arrives. The four of vallenae 0.14
//! (`vallenae.timepicker`), with its definitions to the bit, so that a pick can be compared
//! index for index:
//!
//! * [`hinkley`] (Hinkley criterion, Molenda 2016; van Rijn 2017): S[i] = Σ_{k≤i} x[k]² −
//!   i·E/(α·n), E = Σx²; the pick is the first index of the minimum.
//! * [`aic`] (Akaike information criterion, Bai et al. 2017): AIC[i] = (i+1)·log10
//!   var(x[0..=i]) plus (n−i−2)·log10 var(x[i+1..]), population variances clamped below at
//!   `f32::MIN_POSITIVE`; the last element is undefined (NaN); the first index of the
//!   minimum over the rest.
//! * [`energy_ratio`] (Han, Wong & Bancroft 2009): ER[i] = Σx[i+1..=i+w]² / Σx[i−w+1..=i]² for
//!   w ≤ i < n−w, 0 elsewhere, stored in float32; the first index of the maximum, a NaN (a
//!   silent left window) winning as numpy's `argmax` lets it.
//! * [`modified_energy_ratio`]: (ER[i]·|x[i]|)⁴ in float32. vallenae raises to the fourth
//!   power (its comment says the third, as the paper does); the pick is the same either way,
//!   and the values here are vallenae's.
//!
//! As in vallenae, squares are taken in the samples' own type (f32 volts) and summed in f64;
//! otherwise the last bits would decide ties differently. Each picker is O(n) with prefix
//! sums, [`pick_all`] shares one pair of prefix sums between the four, and the only memory
//! is the caller's [`PickScratch`], reused from record to record.
//!
//! The AIC needs two logarithms per sample; [`aic`] (its own file) takes few of them
//! while giving the exact pick.

mod aic;

pub use aic::aic;
use aic::{aic_loaded, aic_value};

/// The buffers the pickers work in (owned by the caller, reused).
#[derive(Debug, Default, Clone)]
pub struct PickScratch {
    /// Prefix sums of x² (f32 squares, f64 sums) and of x.
    sq: Vec<f64>,
    sum: Vec<f64>,
    /// Approximate AIC values of one block (see the module doc), and the indices (with
    /// their approximate values) that may hold the minimum.
    approx: Vec<f64>,
    candidates: Vec<(usize, f64)>,
    /// Each AIC block's lower bound (block k starts at k·AIC_BLOCK).
    floors: Vec<f64>,
    /// ER and MER values over the computed range.
    ratios: Vec<[f32; 2]>,
}

impl PickScratch {
    fn load_squares(&mut self, x: &[f32]) {
        self.sq.clear();
        let mut acc = 0.0f64;
        self.sq.extend(x.iter().map(|&v| {
            acc += (v * v) as f64;
            acc
        }));
    }

    /// Both prefix sums in one pass (two independent chains).
    fn load_both(&mut self, x: &[f32]) {
        self.sq.clear();
        self.sum.clear();
        let (mut a, mut b) = (0.0f64, 0.0f64);
        for &v in x {
            a += (v * v) as f64;
            b += v as f64;
            self.sq.push(a);
            self.sum.push(b);
        }
    }
}

/// The four picks of one record: Hinkley, AIC, energy ratio, modified energy ratio.
pub fn pick_all(x: &[f32], alpha: f64, win: usize, s: &mut PickScratch) -> [Option<usize>; 4] {
    s.load_both(x);
    let (er, mer) = ratios_loaded(x, win, &s.sq, &mut s.ratios);
    [
        hinkley_loaded(x.len(), alpha, &s.sq),
        aic_loaded(s),
        er,
        mer,
    ]
}

/// Hinkley criterion with divisor `alpha` (vallenae's default 5). `None` for an empty record.
pub fn hinkley(x: &[f32], alpha: f64, s: &mut PickScratch) -> Option<usize> {
    s.load_squares(x);
    hinkley_loaded(x.len(), alpha, &s.sq)
}

/// Hinkley's trend term: the record's energy over α·n (`sq` the cumulative squares, n > 0).
#[inline]
fn hinkley_trend(n: usize, alpha: f64, sq: &[f64]) -> f64 {
    sq[n - 1] / (alpha * n as f64)
}

/// Hinkley's S[i] from the cumulative energy at i, with the index rounded through f32 as
/// vallenae's float32 arange does.
#[inline]
fn hinkley_value(i: usize, e: f64, trend: f64) -> f64 {
    e - (i as f32) as f64 * trend
}

fn hinkley_loaded(n: usize, alpha: f64, sq: &[f64]) -> Option<usize> {
    if n == 0 {
        return None;
    }
    let trend = hinkley_trend(n, alpha, sq);
    let value = |i: usize, e: f64| hinkley_value(i, e, trend);
    if !trend.is_finite() || trend < 0.0 {
        // Not a record (or an α) the feature path lets through: numpy's argmin the plain
        // way.
        let (mut best, mut best_v) = (0, f64::INFINITY);
        for (i, &e) in sq.iter().enumerate() {
            let v = value(i, e);
            if v < best_v {
                (best, best_v) = (i, v);
            }
        }
        return Some(best);
    }
    // The first index of the minimum (numpy's argmin; no NaN in finite input): the minimum
    // first, block by block in four lanes (it does not depend on the order), then the
    // first index holding it, each value computed the same way both times. A block's
    // values are at least `value(its last index, its first energy)`: the energy never
    // falls, the index term never falls (trend ≥ 0), and rounding keeps both orders, so
    // that one value is an exact lower bound, and a block whose bound is above the running
    // minimum holds neither the minimum nor, later, its first index.
    let block = |k: usize| k * HINKLEY_BLOCK..((k + 1) * HINKLEY_BLOCK).min(n);
    let blocks = n.div_ceil(HINKLEY_BLOCK);
    let floor = |k: usize| {
        let r = block(k);
        value(r.end - 1, sq[r.start])
    };
    let mut lowest = f64::INFINITY;
    for k in lowest_first(blocks, floor) {
        if floor(k) > lowest {
            continue;
        }
        let r = block(k);
        let low = lane_min(sq[r.clone()].iter().zip(r).map(|(&e, i)| value(i, e)));
        lowest = lowest.min(low);
    }
    (0..blocks)
        .filter(|&k| floor(k) <= lowest)
        .find_map(|k| {
            let r = block(k);
            sq[r.clone()]
                .iter()
                .zip(r)
                .find(|&(&e, i)| value(i, e) <= lowest)
                .map(|(_, i)| i)
        })
        .or(Some(0))
}

/// Hinkley's pass runs over blocks of this many samples, each bounded below first.
const HINKLEY_BLOCK: usize = 256;

/// Block indices `0..blocks` in the order the block-bounded pickers visit them: the block
/// with the lowest `floor` first (so the running minimum is near the final one at once),
/// then the others in index order.
fn lowest_first(blocks: usize, floor: impl Fn(usize) -> f64) -> impl Iterator<Item = usize> {
    let first = (0..blocks)
        .min_by(|&p, &q| floor(p).total_cmp(&floor(q)))
        .unwrap_or(0);
    std::iter::once(first)
        .chain((0..blocks).filter(move |&k| k != first))
        .take(blocks)
}

/// The smallest of NaN-free values, from +∞, in four independent lanes.
#[inline(always)]
fn lane_min(mut values: impl ExactSizeIterator<Item = f64>) -> f64 {
    let mut m = [f64::INFINITY; 4];
    let n = values.len();
    for _ in 0..n / 4 {
        for lane in &mut m {
            let v = values.next().unwrap_or(f64::INFINITY);
            *lane = if v < *lane { v } else { *lane };
        }
    }
    let mut low = m
        .iter()
        .fold(f64::INFINITY, |a, &b| if b < a { b } else { a });
    for v in values {
        low = if v < low { v } else { low };
    }
    low
}

/// Energy ratio with windows of `win` samples (vallenae's default 100). `None` when the
/// record holds no full pair of windows (n ≤ 2·win; vallenae returns 0 there) or `win` is 0.
pub fn energy_ratio(x: &[f32], win: usize, s: &mut PickScratch) -> Option<usize> {
    s.load_squares(x);
    ratios_loaded(x, win, &s.sq, &mut s.ratios).0
}

/// Modified energy ratio, (ER·|x|)⁴ in float32 as vallenae computes it.
pub fn modified_energy_ratio(x: &[f32], win: usize, s: &mut PickScratch) -> Option<usize> {
    s.load_squares(x);
    ratios_loaded(x, win, &s.sq, &mut s.ratios).1
}

/// numpy's `argmax` of `values(k)` for k in 0..len, values outside the range being 0 (so
/// index 0 holds a 0 to start from): the first NaN wins, else the first maximum. In two
/// passes, as the plain loop decides it: whether there is a NaN and the largest value (order
/// free, eight lanes), then the first index holding it. Returns k, or `None` for index 0.
#[inline(always)]
fn numpy_argmax(len: usize, values: impl Fn(usize) -> f32) -> Option<usize> {
    let mut m = [0.0f32; 8];
    let mut nan = false;
    for c in 0..len / 8 {
        for (k, lane) in m.iter_mut().enumerate() {
            let v = values(c * 8 + k);
            nan |= v.is_nan();
            *lane = if v > *lane { v } else { *lane };
        }
    }
    let mut top = m.iter().fold(0.0f32, |a, &b| if b > a { b } else { a });
    for k in len / 8 * 8..len {
        let v = values(k);
        nan |= v.is_nan();
        top = if v > top { v } else { top };
    }
    if nan {
        return (0..len).position(|k| values(k).is_nan());
    }
    if top > 0.0 {
        (0..len).position(|k| values(k) >= top)
    } else {
        None
    }
}

/// ER and MER values for i in win..n−win (vallenae's arithmetic), branch-free.
#[inline(always)]
fn ratios_generic(x: &[f32], win: usize, sq: &[f64], out: &mut [[f32; 2]]) {
    for (k, o) in out.iter_mut().enumerate() {
        let i = k + win;
        let l = sq[i] - sq[i - win];
        let r = sq[i + win] - sq[i];
        let v = (r / l) as f32;
        let mut m = v * x[i].abs();
        m *= m;
        m *= m;
        *o = [v, m];
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn ratios_avx2(x: &[f32], win: usize, sq: &[f64], out: &mut [[f32; 2]]) {
    ratios_generic(x, win, sq, out)
}

/// ER and MER of samples win..n−win into `buf` (one pass, AVX2 where the CPU has it);
/// `false` (and `buf` untouched) when the record is too short for the window.
fn fill_ratios(x: &[f32], win: usize, sq: &[f64], buf: &mut Vec<[f32; 2]>) -> bool {
    let n = x.len();
    if win == 0 || n <= 2 * win {
        return false;
    }
    buf.clear();
    buf.resize(n - 2 * win, [0.0; 2]);
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        unsafe { ratios_avx2(x, win, sq, buf) };
    } else {
        ratios_generic(x, win, sq, buf);
    }
    #[cfg(not(target_arch = "x86_64"))]
    ratios_generic(x, win, sq, buf);
    true
}

/// ER and MER picks: the values in a vectorised pass, then numpy's argmax of each.
fn ratios_loaded(
    x: &[f32],
    win: usize,
    sq: &[f64],
    buf: &mut Vec<[f32; 2]>,
) -> (Option<usize>, Option<usize>) {
    if !fill_ratios(x, win, sq, buf) {
        return (None, None);
    }
    let at = |k: Option<usize>| Some(k.map_or(0, |k| k + win));
    (
        at(numpy_argmax(buf.len(), |k| buf[k][0])),
        at(numpy_argmax(buf.len(), |k| buf[k][1])),
    )
}

/// The detection functions themselves, each as vallenae returns it beside its pick (the
/// first element of its tuple), for callers who plot or post-process them (the Python
/// package's `aepipe.pickers`). The pick is the matching picker's, so it is the index
/// vallenae gives; these only add the values, which the feature path never needs.
pub mod function {
    use super::*;

    /// Hinkley's S[i] (float64 in vallenae). Empty for an empty record.
    pub fn hinkley(x: &[f32], alpha: f64, s: &mut PickScratch, out: &mut Vec<f64>) {
        s.load_squares(x);
        out.clear();
        let n = x.len();
        if n == 0 {
            return;
        }
        let trend = hinkley_trend(n, alpha, &s.sq);
        out.extend(
            s.sq.iter()
                .enumerate()
                .map(|(i, &e)| hinkley_value(i, e, trend)),
        );
    }

    /// AIC[i] (float64 in vallenae); the last element is NaN.
    pub fn aic(x: &[f32], s: &mut PickScratch, out: &mut Vec<f64>) {
        s.load_both(x);
        out.clear();
        let n = x.len();
        out.extend((0..n).map(|i| aic_value(i, n, &s.sum, &s.sq, f64::log10)));
    }

    /// ER[i] and MER[i] (float32 in vallenae), 0 outside win..n−win.
    pub fn ratios(
        x: &[f32],
        win: usize,
        s: &mut PickScratch,
        er: &mut Vec<f32>,
        mer: &mut Vec<f32>,
    ) {
        let n = x.len();
        er.clear();
        mer.clear();
        er.resize(n, 0.0);
        mer.resize(n, 0.0);
        if win == 0 || n <= 2 * win {
            return;
        }
        s.load_squares(x);
        fill_ratios(x, win, &s.sq, &mut s.ratios);
        for (k, [v, m]) in s.ratios.iter().enumerate() {
            er[k + win] = *v;
            mer[k + win] = *m;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Noise, then a burst from sample `at`.
    pub(super) fn burst(n: usize, at: usize, seed: u64) -> Vec<f32> {
        let mut r = seed;
        (0..n)
            .map(|i| {
                r = r
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let noise = ((r >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 1e-3;
                let s = if i >= at {
                    let t = (i - at) as f32;
                    (t * 0.3).sin() * (-t / 400.0).exp()
                } else {
                    0.0
                };
                noise + s
            })
            .collect()
    }

    /// numpy's argmin / argmax the plain way, for the two-pass versions to equal.
    fn hinkley_reference(x: &[f32], alpha: f64) -> Option<usize> {
        let mut s = PickScratch::default();
        s.load_squares(x);
        let n = x.len();
        let trend = s.sq.last()? / (alpha * n as f64);
        let (mut best, mut best_v) = (0, f64::INFINITY);
        for (i, &e) in s.sq.iter().enumerate() {
            let v = e - (i as f32) as f64 * trend;
            if v < best_v {
                (best, best_v) = (i, v);
            }
        }
        Some(best)
    }

    // Written as vallenae's formula reads, index by index.
    #[allow(clippy::needless_range_loop)]
    fn ratios_reference(x: &[f32], win: usize) -> [Option<usize>; 2] {
        let n = x.len();
        if win == 0 || n <= 2 * win {
            return [None, None];
        }
        let mut s = PickScratch::default();
        s.load_squares(x);
        let mut out = [None; 2];
        for (j, o) in out.iter_mut().enumerate() {
            let (mut best, mut value, mut nan) = (0, 0.0f32, None);
            for i in win..n - win {
                let l = s.sq[i] - s.sq[i - win];
                let r = s.sq[i + win] - s.sq[i];
                let v = (r / l) as f32;
                let m = (v * x[i].abs()).powi(2).powi(2);
                let v = if j == 0 { v } else { m };
                if v.is_nan() {
                    nan.get_or_insert(i);
                } else if v > value {
                    (best, value) = (i, v);
                }
            }
            *o = Some(nan.unwrap_or(best));
        }
        out
    }

    #[test]
    fn the_two_pass_picks_are_the_plain_loops() {
        let mut s = PickScratch::default();
        let mut cases: Vec<Vec<f32>> = (0..40)
            .map(|k| burst(203 + 97 * k, 50 + 31 * k, 70 + k as u64))
            .collect();
        cases.push(vec![0.0; 500]);
        cases.push(vec![1e-3; 501]);
        cases.push((0..509).map(|i| if i < 250 { 0.0 } else { 1.0 }).collect());
        cases.push((0..509).map(|i| (i % 7) as f32).collect());
        let mut x = vec![0.0f32; 403];
        x[250] = 1.0;
        cases.push(x);
        cases.push(vec![1.0]);
        cases.push(burst(220_001, 100_000, 99));
        // Hinkley's blocks: the minimum in the last block or the first sample, a level
        // offset, silence over several blocks then a step, sparse spikes.
        cases.push(burst(5000, 4990, 3));
        cases.push(burst(5000, 0, 4));
        cases.push(burst(3000, 1200, 5).iter().map(|v| v + 1e3).collect());
        cases.push(
            (0..3000)
                .map(|i| if i < 1500 { 0.0 } else { 0.5 })
                .collect(),
        );
        cases.push(
            (0..2000)
                .map(|i| if i % 512 == 0 { 1.0 } else { 0.0 })
                .collect(),
        );
        // Ties across blocks (exact in binary): spikes every 256 samples, α = 1, put S = 1/256
        // at the end of every block; with spikes of 0.5 at 423 and 615 and α = 0.5, S ties at
        // 422 and 614 while the lowest block bound is the third block's, which goes first.
        let ties: Vec<f32> = (0..1024)
            .map(|i| if i % 256 == 0 { 1.0 } else { 0.0 })
            .collect();
        assert_eq!(hinkley(&ties, 1.0, &mut s), Some(255));
        assert_eq!(hinkley_reference(&ties, 1.0), Some(255));
        let mut late = vec![0.0f32; 768];
        (late[423], late[615]) = (0.5, 0.5);
        assert_eq!(hinkley(&late, 0.5, &mut s), Some(422));
        assert_eq!(hinkley_reference(&late, 0.5), Some(422));
        // α outside the configuration's range: the plain loop (trend < 0, infinite, zero).
        let onset = burst(3000, 1200, 5);
        for alpha in [-2.0, 0.0, f64::INFINITY] {
            for x in [&onset, &late] {
                assert_eq!(hinkley(x, alpha, &mut s), hinkley_reference(x, alpha));
            }
        }
        for x in &cases {
            assert_eq!(
                hinkley(x, 5.0, &mut s),
                hinkley_reference(x, 5.0),
                "n = {}",
                x.len()
            );
            let [er, mer] = ratios_reference(x, 100);
            assert_eq!(energy_ratio(x, 100, &mut s), er, "n = {}", x.len());
            assert_eq!(
                modified_energy_ratio(x, 100, &mut s),
                mer,
                "n = {}",
                x.len()
            );
        }
    }

    #[test]
    fn every_picker_finds_a_clear_onset() {
        let x = burst(4000, 1500, 12345);
        let mut s = PickScratch::default();
        let all = pick_all(&x, 5.0, 100, &mut s);
        for (k, (name, p)) in [
            ("hinkley", hinkley(&x, 5.0, &mut s)),
            ("aic", aic(&x, &mut s)),
            ("er", energy_ratio(&x, 100, &mut s)),
            ("mer", modified_energy_ratio(&x, 100, &mut s)),
        ]
        .into_iter()
        .enumerate()
        {
            let p = p.unwrap();
            assert!((1440..=1560).contains(&p), "{name}: {p}");
            assert_eq!(all[k], Some(p), "{name}: pick_all differs");
        }
    }

    #[test]
    fn edges_as_vallenae_defines_them() {
        let mut s = PickScratch::default();
        assert_eq!(hinkley(&[], 5.0, &mut s), None);
        assert_eq!(aic(&[1.0], &mut s), None);
        // Two samples: the last AIC element is undefined, the pick is 0.
        assert_eq!(aic(&[1.0, 2.0], &mut s), Some(0));
        assert_eq!(energy_ratio(&[1.0; 200], 100, &mut s), None);
        // A silent left window: inf or NaN, the first NaN (0/0 at sample 100) wins, as
        // numpy's argmax lets it, over the inf that the burst gives later.
        let mut x = vec![0.0f32; 400];
        x[250] = 1.0;
        assert_eq!(energy_ratio(&x, 100, &mut s), Some(100));
        // MER: inf·|0| is NaN too, so it also picks the first NaN.
        assert_eq!(modified_energy_ratio(&x, 100, &mut s), Some(100));
    }

    #[test]
    fn the_detection_functions_hold_the_picks() {
        // numpy's argmin/argmax over each function is the picker's index (the Python
        // package returns both; vallenae's pairs agree the same way).
        let mut s = PickScratch::default();
        let (mut h, mut a, mut er, mut mer) = (vec![], vec![], vec![], vec![]);
        let first_min = |v: &[f64]| {
            let m = v
                .iter()
                .copied()
                .filter(|x| !x.is_nan())
                .fold(f64::INFINITY, f64::min);
            v.iter().position(|&x| x == m)
        };
        let first_max = |v: &[f32]| {
            let m = v.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            v.iter().position(|&x| x == m)
        };
        for seed in 0..12 {
            let x = burst(900 + 173 * seed as usize, 300 + 40 * seed as usize, seed);
            function::hinkley(&x, 5.0, &mut s, &mut h);
            assert_eq!(first_min(&h), hinkley(&x, 5.0, &mut s));
            function::aic(&x, &mut s, &mut a);
            assert!(a[x.len() - 1].is_nan());
            assert_eq!(first_min(&a), aic(&x, &mut s));
            function::ratios(&x, 100, &mut s, &mut er, &mut mer);
            assert_eq!((er.len(), mer.len()), (x.len(), x.len()));
            assert!(er[..100]
                .iter()
                .chain(&er[x.len() - 100..])
                .all(|&v| v == 0.0));
            assert_eq!(first_max(&er), energy_ratio(&x, 100, &mut s));
            assert_eq!(first_max(&mer), modified_energy_ratio(&x, 100, &mut s));
        }
        function::hinkley(&[], 5.0, &mut s, &mut h);
        assert!(h.is_empty());
        function::ratios(&[1.0; 150], 100, &mut s, &mut er, &mut mer);
        assert!(er.iter().chain(&mer).all(|&v| v == 0.0));
    }
}
