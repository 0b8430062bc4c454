//! Signal processing: power spectrum and band power ratios (Eq. 4.5.4), the continuous
//! wavelet transform (Gabor/Morlet, frequency domain), and the standard hit features.
//!
//! Plans, filters and scratch buffers live in the structs here and are reused from record to
//! record (RustFFT style: a planner hands out plans, callers own scratch); the per-record
//! work allocates nothing once the caches are warm.

pub mod cwt;
pub mod filter;
pub mod hit;
pub mod pick;
pub mod settings;
pub mod spectrum;

/// The smallest length ≥ `n` of the form 2^a·3^b: RustFFT's fastest sizes (measured here:
/// 432 points 0.34 µs, 450 points 0.94 µs, 500 points 1.27 µs; factors of 5 cost).
pub fn next_fast_len(n: usize) -> usize {
    let mut m = n.max(1);
    loop {
        let mut k = m;
        for p in [2, 3] {
            while k.is_multiple_of(p) {
                k /= p;
            }
        }
        if k == 1 {
            return m;
        }
        m += 1;
    }
}

/// The smallest length ≥ `n` of the form 2^a·3^b with a ≥ 3 (a multiple of 8): RustFFT's
/// AVX transforms of lengths with few factors of two are markedly slower per point (measured
/// here, inverse f32: 486 = 2·3⁵ points 0.47 µs against 512 points 0.35 µs; 729 0.99 µs
/// against 768 0.62 µs; 972 1.10 µs against 1 024 0.85 µs; 1 458 1.84 µs against 1 536 1.56 µs).
/// For the CWT's short segments, whose length is free.
pub fn next_fast_segment_len(n: usize) -> usize {
    let mut m = next_fast_len(n);
    while !m.is_multiple_of(8) {
        m = next_fast_len(m + 1);
    }
    m
}

/// Remove the DC offset, measured as the mean of the pretrigger (the only part of a record
/// known to hold no signal), and convert to f32 volts, into `out` (reused). Without a
/// pretrigger nothing is subtracted: the mean of a record that holds a burst is not its
/// baseline (and acquisition systems such as Vallen's AMSY are AC-coupled anyway).
/// Returns the offset removed.
pub fn condition(samples: &[f32], pretrigger: usize, out: &mut Vec<f32>) -> f64 {
    let pre = pretrigger.min(samples.len());
    let dc = if pre > 0 {
        samples[..pre].iter().map(|&s| s as f64).sum::<f64>() / pre as f64
    } else {
        0.0
    };
    out.clear();
    out.extend(samples.iter().map(|&s| (s as f64 - dc) as f32));
    dc
}

/// The largest `f(v)` over `x`, from 0 (0 for an empty slice or one without a positive
/// value), skipping NaN as `f32::max` does. A maximum does not depend on the order it is
/// taken in, so eight lanes take it at once: the plain fold is one long compare chain and
/// ran at its latency.
#[inline]
pub fn max_from_zero(x: &[f32], f: impl Fn(f32) -> f32) -> f32 {
    let mut m = [0.0f32; 8];
    let chunks = x.chunks_exact(8);
    let tail = chunks.remainder();
    for c in chunks {
        for (lane, &v) in m.iter_mut().zip(c) {
            let v = f(v);
            *lane = if v > *lane { v } else { *lane };
        }
    }
    let top = m.iter().fold(0.0f32, |a, &b| if b > a { b } else { a });
    tail.iter()
        .map(|&v| f(v))
        .fold(top, |a, b| if b > a { b } else { a })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lane_maximum_is_the_plain_fold() {
        let mut r = crate::util::Rng::new(5);
        for n in [0usize, 1, 7, 8, 9, 63, 64, 65, 1000] {
            let mut x: Vec<f32> = (0..n).map(|_| (r.uniform() - 0.7) as f32).collect();
            if n > 3 {
                x[n / 2] = f32::NAN;
            }
            let plain = x.iter().fold(0.0f32, |m, v| m.max(v.abs()));
            assert_eq!(
                max_from_zero(&x, f32::abs).to_bits(),
                plain.to_bits(),
                "n = {n}"
            );
            let plain = x.iter().fold(0.0f32, |m, &v| m.max(v));
            assert_eq!(
                max_from_zero(&x, |v| v).to_bits(),
                plain.to_bits(),
                "n = {n}"
            );
        }
    }

    #[test]
    fn fast_lengths() {
        assert_eq!(next_fast_len(1), 1);
        assert_eq!(next_fast_len(7), 8);
        assert_eq!(next_fast_len(401), 432);
        assert_eq!(next_fast_len(4096), 4096);
        assert_eq!(next_fast_len(4097), 4374);
    }

    #[test]
    fn conditioning_removes_the_pretrigger_mean() {
        let mut out = Vec::new();
        let dc = condition(&[1.0, 3.0, 10.0, 2.0], 2, &mut out);
        assert_eq!(dc, 2.0);
        assert_eq!(out, vec![-1.0, 1.0, 8.0, 0.0]);
        // No pretrigger, no known baseline: nothing is subtracted.
        assert_eq!(condition(&[1.0, 3.0], 0, &mut out), 0.0);
        assert_eq!(out, vec![1.0, 3.0]);
    }
}
