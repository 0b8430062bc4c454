//! Rows of the full-resolution CWT interpolated across frequency.
//!
//! At a fixed time, W(t, f) is the signal's spectrum smoothed by a Gaussian of width σ_f(f):
//! it changes on the scale of σ_f, which at high frequencies spans many grid steps (25 steps of
//! 10 kHz at 1.5 MHz for Morlet ω0 = 6). There the frequencies that no shorter transform can
//! hold (see `banded`) are computed exactly at *anchors* no more than σ_f / [`ANCHORS_PER_SIGMA`]
//! apart, and every row between them is the 6-point Lagrange interpolation of the anchors'
//! complex W (then |·|²): one linear combination per sample instead of a full-length inverse
//! FFT. The error this leaves is measured with the banded path's (tests, `aepipe bench cwt`).

/// Rows whose band decimates by at most this much are taken across frequency (a shorter
/// transform plus interpolation along time costs more than an anchor shared by several rows).
pub(super) const MAX_DECIMATION: usize = 2;
/// Points of the interpolator in frequency.
pub(super) const TAPS: usize = 6;
/// Anchors per σ_f of the Gaussian filter (at the lower anchor's frequency): 5 keeps the
/// interpolation ~2e-5 of a row's peak on the peers' signals; 4 would save a few transforms at
/// ~3× the error.
pub(super) const ANCHORS_PER_SIGMA: f64 = 5.0;

/// The anchors of a run of rows with ascending frequencies `f` (indices into `f`): the first
/// and last row, and between them each next anchor as far as σ_f(f_a) / ANCHORS_PER_SIGMA
/// allows (at least the next row). `sigma_f` gives σ_f of a frequency.
pub(super) fn anchors(f: &[f64], sigma_f: impl Fn(f64) -> f64) -> Vec<usize> {
    let mut out = Vec::new();
    if f.is_empty() {
        return out;
    }
    let mut a = 0;
    out.push(a);
    while a + 1 < f.len() {
        let reach = f[a] + sigma_f(f[a]) / ANCHORS_PER_SIGMA;
        let mut next = a + 1;
        while next + 1 < f.len() && f[next + 1] <= reach {
            next += 1;
        }
        a = next;
        out.push(a);
    }
    out
}

/// The first of the TAPS anchors (indices into `anchors`) whose interpolation gives row `i`:
/// centred on the anchors around `i`, kept inside the run.
pub(super) fn stencil_start(anchors: &[usize], i: usize) -> usize {
    let right = anchors.partition_point(|&a| a <= i);
    right
        .saturating_sub(TAPS / 2)
        .min(anchors.len().saturating_sub(TAPS))
}

/// Lagrange weights at frequency `x` of the nodes `nodes`.
pub(super) fn weights(nodes: &[f64; TAPS], x: f64) -> [f32; TAPS] {
    std::array::from_fn(|i| {
        (0..TAPS)
            .filter(|&k| k != i)
            .map(|k| (x - nodes[k]) / (nodes[i] - nodes[k]))
            .product::<f64>() as f32
    })
}

/// `out[j] = |Σ_k w[k]·W_k[j]|²`, each `W_k` complex as `2·out.len()` floats: the real
/// parts, then the imaginary parts (so that the loop runs over `j` in plain SIMD lanes). In AVX with fused multiply-adds where the CPU has them.
pub(super) fn interpolate_power(rows: [&[f32]; TAPS], w: &[f32; TAPS], out: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx") && std::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports AVX and FMA (checked just above).
        return unsafe { interpolate_power_avx(rows, w, out) };
    }
    interpolate_power_generic::<false>(rows, w, out)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,fma")]
unsafe fn interpolate_power_avx(rows: [&[f32]; TAPS], w: &[f32; TAPS], out: &mut [f32]) {
    interpolate_power_generic::<true>(rows, w, out)
}

#[inline(always)]
fn interpolate_power_generic<const FMA: bool>(
    rows: [&[f32]; TAPS],
    w: &[f32; TAPS],
    out: &mut [f32],
) {
    let n = out.len();
    let re: [&[f32]; TAPS] = std::array::from_fn(|k| &rows[k][..n]);
    let im: [&[f32]; TAPS] = std::array::from_fn(|k| &rows[k][n..2 * n]);
    for (j, o) in out.iter_mut().enumerate() {
        let (mut a, mut b) = (0.0f32, 0.0f32);
        for k in 0..TAPS {
            if FMA {
                a = w[k].mul_add(re[k][j], a);
                b = w[k].mul_add(im[k][j], b);
            } else {
                a += w[k] * re[k][j];
                b += w[k] * im[k][j];
            }
        }
        *o = a * a + b * b;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn anchors_are_at_most_a_fifth_of_sigma_apart_and_include_both_ends() {
        let f: Vec<f64> = (0..100).map(|k| 1e6 + 1e4 * k as f64).collect();
        let sigma = |x: f64| x / 6.0;
        let a = anchors(&f, sigma);
        assert_eq!((a[0], *a.last().unwrap()), (0, 99));
        for p in a.windows(2) {
            assert!(p[1] > p[0]);
            // Each gap is as long as allowed: one row more would pass σ/5.
            assert!(f[p[1]] - f[p[0]] <= sigma(f[p[0]]) / 5.0 + 1e-6 || p[1] == p[0] + 1);
            if p[1] < 99 {
                assert!(f[p[1] + 1] - f[p[0]] > sigma(f[p[0]]) / 5.0);
            }
        }
        // At 1 MHz σ/5 = 33 kHz: three 10 kHz steps.
        assert_eq!(a[1], 3);
    }

    #[test]
    fn stencils_stay_inside_the_run_and_surround_their_row() {
        let a: Vec<usize> = (0..10).map(|k| 3 * k).collect();
        for i in 0..=27 {
            let s = stencil_start(&a, i);
            assert!(s + TAPS <= a.len());
            if i >= a[2] && i <= a[7] {
                // Inside: two or three anchors on either side.
                assert!(a[s] <= i && a[s + TAPS - 1] >= i, "{i}: {s}");
                assert!(a[s + 1] <= i && a[s + TAPS - 2] >= i, "{i}: {s}");
            }
        }
    }

    #[test]
    fn weights_reproduce_polynomials_of_degree_five_on_uneven_nodes() {
        let nodes = [1.0, 1.3, 2.0, 2.2, 3.1, 4.0];
        for x in [1.1, 2.1, 2.9, 3.7] {
            let w = weights(&nodes, x);
            for deg in 0..TAPS as i32 {
                let got: f64 = (0..TAPS).map(|i| w[i] as f64 * nodes[i].powi(deg)).sum();
                assert!(
                    (got - x.powi(deg)).abs() < 1e-5 * 4f64.powi(deg),
                    "{x} x^{deg}"
                );
            }
        }
    }
}
