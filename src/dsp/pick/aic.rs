//! The Akaike information criterion picker (Bai et al. 2017, vallenae's arithmetic to the
//! bit): AIC[i] = (i+1)·log10 var(x[0..=i]) + (n−i−2)·log10 var(x[i+1..]).
//!
//! It needs two logarithms per sample, which cost more than the rest of a record's picking
//! together. [`aic`] therefore never takes them all with the library's `log10`:
//!
//! 1. **Blocks that cannot hold the minimum are skipped whole.** The sum of squared
//!    deviations of x[0..=i] never falls as i grows, nor that of x[i+1..] as i falls, so
//!    over a block a..=b each is at least its value where its part is shortest (at a for
//!    the left part, at b for the right), and each of the two terms, concave in its length,
//!    is least at one of
//!    the block's ends: four logarithms bound the whole block from below. The bound carries
//!    a margin for every rounding between the true sums of squares and the values vallenae's
//!    arithmetic computes (f32 squares, f64 prefix sums, the cancelling subtraction), so it
//!    holds for the computed values, not only the ideal ones. The block with the lowest
//!    bound goes first, so the running minimum is near the final one at once.
//! 2. **The other blocks are evaluated with a polynomial logarithm** whose error is bounded
//!    (below 1e-8 in log10), keeping every index that could still be the minimum given that
//!    bound.
//! 3. **Those few indices are evaluated exactly**, with the library's `log10`, in index
//!    order: the pick is the exact one (the first index of the minimum), only the work is
//!    less.

use super::{lane_min, lowest_first, PickScratch};

/// Akaike information criterion. `None` for fewer than 2 samples (vallenae raises).
pub fn aic(x: &[f32], s: &mut PickScratch) -> Option<usize> {
    s.load_both(x);
    aic_loaded(s)
}

/// One AIC value, vallenae's arithmetic, with the logarithm `log10` given.
#[inline(always)]
pub(super) fn aic_value(
    i: usize,
    n: usize,
    sum: &[f64],
    sq: &[f64],
    log10: impl Fn(f64) -> f64,
) -> f64 {
    let eps = f32::MIN_POSITIVE as f64;
    // numpy's maximum propagates NaN.
    let clamp = |v: f64| if v.is_nan() { v } else { v.max(eps) };
    let (l_var, r_var) = variances(i, n, sum, sq);
    (i as f64 + 1.0) * log10(clamp(l_var)) + (n as f64 - i as f64 - 2.0) * log10(clamp(r_var))
}

/// The population variances of x[..=i] and x[i+1..] from the prefix sums, in vallenae's
/// arithmetic (unclamped; they may cancel below zero).
#[inline(always)]
fn variances(i: usize, n: usize, sum: &[f64], sq: &[f64]) -> (f64, f64) {
    let (total, total_sq) = (sum[n - 1], sq[n - 1]);
    let (l_len, r_len) = ((i + 1) as f64, (n - i - 1) as f64);
    let (l_sum, l_sq) = (sum[i], sq[i]);
    let (r_sum, r_sq) = (total - l_sum, total_sq - l_sq);
    let (l_mean, r_mean) = ((1.0 / l_len) * l_sum, (1.0 / r_len) * r_sum);
    let l_var = (1.0 / l_len) * l_sq - l_mean * l_mean;
    let r_var = (1.0 / r_len) * r_sq - r_mean * r_mean;
    (l_var, r_var)
}

/// The first index of the smallest exact AIC value among `candidates` (NaN never wins).
fn exact_first_min(
    candidates: impl Iterator<Item = usize>,
    n: usize,
    sum: &[f64],
    sq: &[f64],
) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for i in candidates {
        let v = aic_value(i, n, sum, sq, f64::log10);
        if !v.is_nan() && best.is_none_or(|(_, b)| v < b) {
            best = Some((i, v));
        }
    }
    best.map(|b| b.0)
}

/// Bound on |fast_log10(v) − log10(v)| for every positive normal v (the tests check it).
const FAST_LOG10_ERR: f64 = 1e-8;

/// ln(1+t) on t ∈ [√½−1, √2−1]: a degree-9 polynomial (a least-squares Chebyshev fit, in
/// powers of t, highest last), within 1.5e-8 of ln on that interval. Degree 13 (3e-12) cost
/// a third more per sample and pruned no better: the candidates within the bound are the
/// few samples about the minimum either way.
const LN1P: [f64; 10] = [
    2.644224492143188e-10,
    0.9999999061054841,
    -0.5000000283219791,
    0.3333473061429857,
    -0.250012522864788,
    0.19944783534031452,
    -0.1657576840854324,
    0.15056337689992272,
    -0.14296445004740982,
    0.0838341074215048,
];

/// a·b + c, fused where the caller's target has FMA (`F`), else two roundings.
#[inline(always)]
fn madd<const F: bool>(a: f64, b: f64, c: f64) -> f64 {
    if F {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// log10 of a positive normal `v`: exponent, and the mantissa m ∈ [√½, √2) by [`LN1P`]
/// (Estrin's scheme: a short dependency chain). Branch- and division-free so that the loop
/// around it vectorises; only for inputs known to be positive and normal.
#[inline(always)]
fn fast_log10<const F: bool>(v: f64) -> f64 {
    let bits = v.to_bits();
    let e = ((bits >> 52) & 0x7ff) as i64 - 1023;
    let m = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000);
    let high = m > std::f64::consts::SQRT_2;
    let m = if high { m * 0.5 } else { m };
    let e = if high { e + 1 } else { e };
    let t = m - 1.0;
    let c = &LN1P;
    let t2 = t * t;
    let t4 = t2 * t2;
    let t8 = t4 * t4;
    let p = |k: usize| madd::<F>(c[k + 1], t, c[k]);
    let q0 = madd::<F>(p(2), t2, p(0));
    let q1 = madd::<F>(p(6), t2, p(4));
    let lo = madd::<F>(q1, t4, q0);
    let ln = madd::<F>(p(8), t8, lo);
    madd::<F>(e as f64, std::f64::consts::LN_2, ln) * std::f64::consts::LOG10_E
}

/// Pass 1 of the AIC: `out[i]` within the bound of the exact value for i < n−1. The
/// variances are computed exactly as [`aic_value`] does (they may cancel, so only the
/// logarithm may differ); after the clamp they lie in [f32::MIN_POSITIVE, ~f32::MAX] (a
/// mean of finite f32 squares, up to rounding), positive and normal, as [`fast_log10`]
/// needs (the sum of squares is finite, checked).
#[inline(always)]
fn aic_approx_generic<const F: bool>(i0: usize, sum: &[f64], sq: &[f64], out: &mut [f64]) {
    let n = sq.len();
    let eps = f32::MIN_POSITIVE as f64;
    for (i, o) in (i0..n - 1).zip(out.iter_mut()) {
        let (l_len, r_len) = ((i + 1) as f64, (n - i - 1) as f64);
        let (l_var, r_var) = variances(i, n, sum, sq);
        let l_var = if l_var > eps { l_var } else { eps };
        let r_var = if r_var > eps { r_var } else { eps };
        *o = l_len * fast_log10::<F>(l_var) + (r_len - 1.0) * fast_log10::<F>(r_var);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn aic_approx_avx2(i0: usize, sum: &[f64], sq: &[f64], out: &mut [f64]) {
    aic_approx_generic::<true>(i0, sum, sq, out)
}

/// Pass 1 for i in `i0 .. i0 + out.len()`, four lanes at a time where the CPU has AVX2.
fn aic_approx(i0: usize, sum: &[f64], sq: &[f64], out: &mut [f64]) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports AVX2 and FMA (checked just above).
        return unsafe { aic_approx_avx2(i0, sum, sq, out) };
    }
    aic_approx_generic::<false>(i0, sum, sq, out)
}

/// Pass 1 runs over blocks of this many samples, each first bounded from below (step 1 of
/// the module doc) and, unless the bound rules it out, evaluated in a buffer that stays in
/// the L1 cache (a whole-record buffer made the long records of a LinWave test wait on
/// memory). Shorter blocks bound tighter; longer ones cost fewer logarithms per sample.
const AIC_BLOCK: usize = 256;

/// Relative rounding, per unit of energy, between the ideal sums of squared deviations and
/// the variances computed from the prefix sums of a record of `n` samples: the f32 squares
/// (2⁻²⁴), the f64 prefix sums and the cancelling subtraction (≤ (4n + 16)·ε of the energy,
/// √n more for the suffix's squared sum through Cauchy–Schwarz), times 4 for slack.
///
/// Only the squares of the block's own samples matter (those of the shared prefix or
/// suffix are in the bound and the values alike). A subnormal f32 square is off by up to
/// 2⁻¹⁵⁰ absolute rather than 2⁻²⁴ relative, and that is covered too: the bound can only
/// exceed the value at a length ℓ if the part's squared deviations exceed ℓ·2⁻¹²⁶ (below
/// that the clamp at `f32::MIN_POSITIVE` already puts the value above the bound), so the
/// margin is then over 2⁻¹⁴⁸·ℓ, more than the ≤ ℓ block samples can be off by.
fn rounding_per_energy(n: usize, suffix: bool) -> f64 {
    let nf = n as f64;
    let sums = (4.0 * nf + 16.0) * f64::EPSILON * if suffix { nf.sqrt() } else { 1.0 };
    4.0 * (f32::EPSILON as f64 * 0.5 + sums)
}

/// min over the lengths ℓ ∈ {lo, hi} of (ℓ − shift)·(log10 s − log10 ℓ): a lower bound of
/// (ℓ − shift)·log10 max(ε, v) over lo ≤ ℓ ≤ hi when every v ≥ s/ℓ, as the function is
/// concave in ℓ. `s ≤ 0` (nothing known about the variance) bounds with the clamp ε.
fn term_bound(s: f64, lo: f64, hi: f64, shift: f64) -> f64 {
    let eps = f32::MIN_POSITIVE as f64;
    if s > 0.0 {
        let at = |l: f64| (l - shift) * (s.log10() - l.log10());
        at(lo).min(at(hi))
    } else {
        // log10 ε < 0: the longest length gives the least.
        (hi - shift) * eps.log10()
    }
}

/// A lower bound on every computed AIC value (exact log10) at i ∈ a..=b (b ≤ n − 2), from
/// the prefix sums alone (step 1 of the module doc).
fn block_bound(a: usize, b: usize, sum: &[f64], sq: &[f64]) -> f64 {
    let n = sq.len();
    let (total, total_sq) = (sum[n - 1], sq[n - 1]);
    // Left part: the squared deviations of x[..=i] are at least those of x[..=a].
    let la = (a + 1) as f64;
    let left = sq[a] - sum[a] * sum[a] / la - rounding_per_energy(n, false) * sq[b];
    // Right part: those of x[i+1..] are at least those of x[b+1..].
    let rb = (n - b - 1) as f64;
    let (r_sum, r_sq) = (total - sum[b], total_sq - sq[b]);
    let right = r_sq - r_sum * r_sum / rb - rounding_per_energy(n, true) * total_sq;
    term_bound(left, la, (b + 1) as f64, 0.0) + term_bound(right, rb, (n - a - 1) as f64, 1.0)
}

pub(super) fn aic_loaded(s: &mut PickScratch) -> Option<usize> {
    let n = s.sq.len();
    if n < 2 {
        return None;
    }
    let (sum, sq) = (&s.sum, &s.sq);
    // A sum of squares (non-negative terms) is finite exactly when every square is: no
    // NaN or infinite sample, none whose f32 square overflows. Else (not a record the
    // feature path lets through) the direct way, as numpy would.
    if !sq[n - 1].is_finite() {
        return exact_first_min(0..n, n, sum, sq);
    }
    // |approx − exact| ≤ (i+1)·δ + |n−i−2|·δ + the rounding of products and sum, whose
    // terms are at most n·|log10 v| ≤ n·39 < n·80 (v between f32::MIN_POSITIVE and f32::MAX);
    // twice that separates the indices that can hold the exact minimum from those that
    // cannot.
    let nf = n as f64 + 2.0;
    let bound = 2.0 * (nf * FAST_LOG10_ERR + 8.0 * nf * 80.0 * f64::EPSILON);
    // Step 1: each block's lower bound; the lowest goes first. A block whose bound, less
    // the approximation's error and the rounding of the bound itself (one `bound` each,
    // generously), is above the running minimum plus `bound` holds no candidate.
    s.floors.clear();
    s.floors.extend((0..n - 1).step_by(AIC_BLOCK).map(|i0| {
        let i1 = (i0 + AIC_BLOCK).min(n - 1);
        block_bound(i0, i1 - 1, sum, sq)
    }));
    // Step 2, block by block: every defined value to within `bound` of the exact one, the
    // running minimum `low`, and each index whose value is within `bound` of it then (a
    // superset of those within `bound` of the final minimum, as the minimum only falls).
    // The last element is undefined (NaN) and never a candidate.
    let mut low = f64::INFINITY;
    let mut prune_at = 64;
    s.candidates.clear();
    s.approx.resize(AIC_BLOCK.min(n - 1), 0.0);
    let floors = &s.floors;
    for k in lowest_first(floors.len(), |k| floors[k]) {
        let i0 = k * AIC_BLOCK;
        if floors[k] - 2.0 * bound > low + bound {
            continue; // the bound rules the whole block out
        }
        let out = &mut s.approx[..AIC_BLOCK.min(n - 1 - i0)];
        aic_approx(i0, sum, sq, out);
        let m = lane_min(out.iter().copied());
        if m > low + bound {
            continue; // nothing here comes within the bound of the minimum
        }
        low = low.min(m);
        let cut = low + bound;
        s.candidates.extend(
            out.iter()
                .enumerate()
                .filter(|&(_, &v)| v <= cut)
                .map(|(k, &v)| (i0 + k, v)),
        );
        if s.candidates.len() >= prune_at {
            s.candidates.retain(|c| c.1 <= cut);
            prune_at = 2 * s.candidates.len() + 64;
        }
    }
    // Step 3: the exact values of the candidates, in index order (the first minimum wins;
    // the first block may have come out of turn).
    let cut = low + bound;
    s.candidates.retain(|c| c.1 <= cut);
    s.candidates.sort_unstable_by_key(|c| c.0);
    exact_first_min(s.candidates.iter().map(|c| c.0), n, sum, sq)
}

#[cfg(test)]
mod tests {
    use super::super::tests::burst;
    use super::*;

    /// vallenae's AIC computed the direct way: every value with the library's log10.
    fn aic_reference(x: &[f32]) -> Option<usize> {
        let mut s = PickScratch::default();
        s.load_both(x);
        let n = x.len();
        let mut best: Option<(usize, f64)> = None;
        for i in 0..n {
            let v = aic_value(i, n, &s.sum, &s.sq, f64::log10);
            if !v.is_nan() && best.is_none_or(|(_, b)| v < b) {
                best = Some((i, v));
            }
        }
        best.map(|b| b.0)
    }

    #[test]
    fn the_fast_logarithm_keeps_its_bound() {
        // Across many octaves and both halves of the mantissa range, and at the edges.
        let mut worst = 0.0f64;
        let mut v = f32::MIN_POSITIVE as f64;
        while v < 1e80 {
            for k in 0..64 {
                let x = v * (1.0 + k as f64 / 64.0);
                worst = worst.max((fast_log10::<false>(x) - x.log10()).abs());
                worst = worst.max((fast_log10::<true>(x) - x.log10()).abs());
            }
            v *= 1.37;
        }
        assert!(worst < FAST_LOG10_ERR, "worst error {worst:e}");
    }

    #[test]
    fn the_pruned_aic_is_the_exact_aic() {
        let mut s = PickScratch::default();
        // Bursts of many lengths and onsets, flat and near-flat records (ties everywhere),
        // a step, and records of two and three samples.
        let mut cases: Vec<Vec<f32>> = (0..40)
            .map(|k| burst(200 + 97 * k, 50 + 31 * k, 7 + k as u64))
            .collect();
        cases.push(vec![0.0; 500]);
        cases.push(vec![1e-3; 500]);
        cases.push((0..500).map(|i| if i < 250 { 0.0 } else { 1.0 }).collect());
        cases.push(vec![1.0, 2.0]);
        cases.push(vec![1.0, 2.0, 1.0]);
        cases.push(burst(220_000, 100_000, 99));
        // Slow growth: the minimum keeps falling block after block (the candidate list is
        // pruned as it goes), and a record of exactly one block and one more.
        cases.push((0..9000).map(|i| (i as f32 * 1e-3).exp() * 1e-3).collect());
        cases.push(
            (0..7000)
                .map(|i| ((i as f32) * 0.01).sin() * i as f32)
                .collect(),
        );
        cases.push(burst(AIC_BLOCK + 1, 600, 5));
        cases.push(burst(AIC_BLOCK + 2, 600, 6));
        for x in &cases {
            assert_eq!(aic(x, &mut s), aic_reference(x), "n = {}", x.len());
        }
    }

    /// Records meant to strain the block bound: a large DC offset (the sums of squares
    /// cancel), a burst at the very end, steps up and down, near-silence, a burst riding a
    /// slow ramp, white noise alone.
    fn hard_cases() -> Vec<Vec<f32>> {
        let mut cases = Vec::new();
        for (k, &dc) in [0.0f32, 1.0, 1e3, -3e4].iter().enumerate() {
            cases.push(
                burst(3000, 1200, 40 + k as u64)
                    .iter()
                    .map(|v| v + dc)
                    .collect(),
            );
        }
        cases.push(burst(5000, 4990, 3));
        cases.push(burst(5000, 3, 4));
        cases.push(
            (0..4000)
                .map(|i| if (1000..2500).contains(&i) { 1.0 } else { 1e-6 })
                .collect(),
        );
        cases.push(burst(6000, 2000, 8).iter().map(|v| v * 1e-30).collect());
        // Squares in f32's subnormal range (|x| ~ 1e-22 to 1e-19): rounded absolutely.
        for (k, &scale) in [1e-19f32, 3e-21, 1e-22].iter().enumerate() {
            cases.push(
                burst(3000, 900, 60 + k as u64)
                    .iter()
                    .map(|v| v * scale)
                    .collect(),
            );
        }
        cases.push(
            burst(6000, 2500, 9)
                .iter()
                .enumerate()
                .map(|(i, v)| v + i as f32 * 1e-3)
                .collect(),
        );
        let mut rng = crate::util::Rng::new(11);
        cases.push((0..5000).map(|_| rng.uniform() as f32 - 0.5).collect());
        cases
    }

    #[test]
    fn a_blocks_bound_is_below_every_value_in_it() {
        let mut s = PickScratch::default();
        let mut tight = 0;
        for x in hard_cases() {
            s.load_both(&x);
            let n = x.len();
            for (a, len) in [
                (0, 1),
                (0, 256),
                (1, 7),
                (300, 256),
                (1000, 1000),
                (n - 300, 298),
            ] {
                let b = a + len - 1;
                let floor = block_bound(a, b, &s.sum, &s.sq);
                let least = (a..=b)
                    .map(|i| aic_value(i, n, &s.sum, &s.sq, f64::log10))
                    .fold(f64::INFINITY, f64::min);
                assert!(floor <= least, "n {n}, block {a}..={b}: {floor} > {least}");
                // Not vacuous: most bounds are within a few hundred of the block's least.
                tight += usize::from(least - floor < 0.5 * least.abs().max(1.0));
            }
        }
        assert!(tight >= 30, "only {tight} useful bounds");
    }

    #[test]
    fn the_aic_is_exact_on_records_that_strain_the_bound() {
        let mut s = PickScratch::default();
        for x in hard_cases() {
            assert_eq!(aic(&x, &mut s), aic_reference(&x), "n = {}", x.len());
        }
    }

    #[test]
    fn random_records_keep_the_bound_and_the_pick() {
        // Offsets up to 1e4 on signals down to 1e-10 (the sums cancel to their last bits),
        // onsets anywhere, blocks of any length: the bound holds and the pick is exact.
        let mut s = PickScratch::default();
        let mut rng = crate::util::Rng::new(99);
        let mut u = || rng.uniform();
        for case in 0..300 {
            let n = 3 + (u() * 3000.0) as usize;
            let sign = if u() < 0.5 { -1.0 } else { 1.0 };
            let dc = if u() < 0.5 {
                0.0
            } else {
                sign * 10f64.powf(u() * 8.0 - 4.0)
            };
            let scale = 10f64.powf(u() * 12.0 - 10.0);
            let at = (u() * n as f64) as usize;
            let decay = 50.0 + 500.0 * u();
            let x: Vec<f32> = (0..n)
                .map(|i| {
                    let t = i.saturating_sub(at) as f64;
                    let burst = (t * 0.3).sin() * (-t / decay).exp() * 100.0;
                    let burst = if i >= at { burst } else { 0.0 };
                    (dc + ((u() - 0.5) + burst) * scale) as f32
                })
                .collect();
            s.load_both(&x);
            for _ in 0..8 {
                let a = (u() * (n - 1) as f64) as usize;
                let b = (a + (u() * 400.0) as usize).min(n - 2);
                let floor = block_bound(a, b, &s.sum, &s.sq);
                let least = (a..=b)
                    .map(|i| aic_value(i, n, &s.sum, &s.sq, f64::log10))
                    .fold(f64::INFINITY, f64::min);
                assert!(floor <= least, "case {case}, {a}..={b}: {floor} > {least}");
            }
            assert_eq!(aic(&x, &mut s), aic_reference(&x), "case {case}");
        }
    }
}
