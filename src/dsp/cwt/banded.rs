//! Full-resolution |W|² of one frequency from a shorter inverse transform.
//!
//! A frequency's filter is non-zero on a band of bins only (its Gaussian out to ±5σ_f). Shifted
//! so that its peak bin `c` sits at zero, the band fits in an `m = n/d`-point grid, and the
//! `m`-point inverse FFT gives `z[j]` with `|z[j]| = |W(j·d)|` **exactly** (the shift is a phase
//! factor of modulus one). The samples in between are interpolated from `z`, which is a
//! band-limited, oversampled signal centred on zero: a 10-point Lagrange interpolator (maximally
//! flat at zero frequency, where the Gaussian holds its weight) on `z`'s real and imaginary
//! parts, then |·|². `d` is the largest power of two dividing the padded length for which the
//! grid holds at least [`OVERSAMPLE`] times the band; where none does (or `d = 2`, where an
//! anchor shared across frequency is cheaper: see `across`), the row is computed otherwise. The
//! error this leaves against the full-length transform is measured in the tests (< 1e-4 of each
//! row's peak on broadband signals, < 5e-5 of the scalogram's on pure tones too) and by
//! `aepipe bench cwt` on the peers' signals (3.8e-5 of a row's peak).

use rustfft::num_complex::Complex32;

/// Points of the interpolator: z[j − BEFORE] … z[j + TAPS − 1 − BEFORE] around j + μ.
pub(super) const TAPS: usize = 10;
const BEFORE: usize = TAPS / 2 - 1;
/// The decimated grid holds at least this many times the band (bins either side of the peak,
/// the wider side doubled). With 10 points, 2 keeps the interpolation error at 3.8e-5 of a
/// row's peak on the peers' signals; 8 points would be 10 % faster at 1.4e-4, 12 points at 1.5
/// gave 8.6e-5 for more time (measured on W1 while choosing these).
pub(super) const OVERSAMPLE: f64 = 2.0;
/// Shortest decimated grid (the interpolator needs its TAPS points, the FFT a few more).
const MIN_POINTS: usize = 16;

/// Lagrange weights of the points at offsets −BEFORE … TAPS − 1 − BEFORE for position μ ∈ [0, 1).
fn lagrange(mu: f64) -> [f32; TAPS] {
    std::array::from_fn(|i| {
        let xi = i as f64 - BEFORE as f64;
        (0..TAPS)
            .filter(|&k| k != i)
            .map(|k| {
                let xk = k as f64 - BEFORE as f64;
                (mu - xk) / (xi - xk)
            })
            .product::<f64>() as f32
    })
}

/// The interpolator's weights for decimation `d`: phase `r` (outputs `j·d + r`) at μ = r/d.
pub(super) fn phases(d: usize) -> Vec<[f32; TAPS]> {
    (0..d).map(|r| lagrange(r as f64 / d as f64)).collect()
}

/// The peak bin of a filter at `f` on a grid of bin width `df`, inside its band `k0..k0+len`.
pub(super) fn centre(f: f64, df: f64, k0: usize, len: usize) -> usize {
    ((f / df).round().max(0.0) as usize).clamp(k0, k0 + len - 1)
}

/// The decimation for a band `k0..k0+len` with peak bin `c` on a padded grid of `n` points:
/// the largest power of two `d` dividing `n` with `n/d ≥ OVERSAMPLE·(2h + 1)` and
/// `n/d ≥ MIN_POINTS`, `h` the band's wider side; 1 when there is none.
pub(super) fn decimation(n: usize, k0: usize, len: usize, c: usize) -> usize {
    let h = (c - k0).max(k0 + len - 1 - c);
    let need = (OVERSAMPLE * (2 * h + 1) as f64).ceil() as usize;
    let mut d = 1;
    while n.is_multiple_of(2 * d) && n / (2 * d) >= need.max(MIN_POINTS) {
        d *= 2;
    }
    d
}

/// Scratch of [`interpolate_power`], owned by the engine and reused.
#[derive(Debug, Default)]
pub(super) struct Scratch {
    re: Vec<f32>,
    im: Vec<f32>,
    phase_rows: Vec<f32>,
}

/// `out[s] = |z(s/d)|²` for `s < out.len() ≤ d·z.len()`, with `z` circular: exact at
/// `s = j·d`, interpolated between. In 8-lane AVX with fused multiply-adds where the CPU
/// has them (the build targets baseline x86-64: 4-lane SSE); the last bits of the
/// interpolated samples then differ between the two, well inside the stated error.
pub(super) fn interpolate_power(
    z: &[Complex32],
    d: usize,
    weights: &[[f32; TAPS]],
    scratch: &mut Scratch,
    out: &mut [f32],
) {
    #[cfg(target_arch = "x86_64")]
    if std::is_x86_feature_detected!("avx") && std::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU supports AVX and FMA (checked just above).
        return unsafe { interpolate_power_avx(z, d, weights, scratch, out) };
    }
    interpolate_power_generic::<false>(z, d, weights, scratch, out)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,fma")]
unsafe fn interpolate_power_avx(
    z: &[Complex32],
    d: usize,
    weights: &[[f32; TAPS]],
    scratch: &mut Scratch,
    out: &mut [f32],
) {
    interpolate_power_generic::<true>(z, d, weights, scratch, out)
}

/// The body; `FMA`: fused multiply-adds (only where the CPU has them: elsewhere `mul_add` is
/// a slow library call).
#[inline(always)]
fn interpolate_power_generic<const FMA: bool>(
    z: &[Complex32],
    d: usize,
    weights: &[[f32; TAPS]],
    scratch: &mut Scratch,
    out: &mut [f32],
) {
    let m = z.len();
    debug_assert!(m >= MIN_POINTS && weights.len() == d && out.len() <= d * m);
    // Real and imaginary parts, wrapped: re[i] = z[(i − BEFORE) mod m].re, i < m + TAPS − 1.
    let Scratch { re, im, phase_rows } = scratch;
    re.resize(m + TAPS - 1, 0.0);
    im.resize(m + TAPS - 1, 0.0);
    // Three plain loops (a chained iterator would not vectorise).
    let (head, tail) = (&z[m - BEFORE..], &z[..TAPS - 1 - BEFORE]);
    for (at, part) in [(0, head), (BEFORE, z), (BEFORE + m, tail)] {
        let len = part.len();
        for ((r, i), v) in re[at..at + len]
            .iter_mut()
            .zip(&mut im[at..at + len])
            .zip(part)
        {
            *r = v.re;
            *i = v.im;
        }
    }
    phase_rows.resize(d * m, 0.0);
    for (r, row) in phase_rows.chunks_exact_mut(m).enumerate() {
        if r == 0 {
            for ((o, a), b) in row.iter_mut().zip(&re[BEFORE..]).zip(&im[BEFORE..]) {
                *o = a * a + b * b;
            }
        } else {
            phase_row::<FMA>(re, im, &weights[r], row);
        }
    }
    match d {
        2 => interleave::<2>(phase_rows, m, out),
        4 => interleave::<4>(phase_rows, m, out),
        8 => interleave::<8>(phase_rows, m, out),
        16 => interleave::<16>(phase_rows, m, out),
        _ => {
            for (j, o) in out.chunks_mut(d).enumerate() {
                for (r, v) in o.iter_mut().enumerate() {
                    *v = phase_rows[r * m + j];
                }
            }
        }
    }
}

/// One phase: `row[j] = |Σ w[o]·z[j − BEFORE + o]|²`, eight shifted slices so that the loop
/// runs over `j` in SIMD lanes.
#[inline(always)]
fn phase_row<const FMA: bool>(re: &[f32], im: &[f32], w: &[f32; TAPS], row: &mut [f32]) {
    let m = row.len();
    let r: [&[f32]; TAPS] = std::array::from_fn(|o| &re[o..o + m]);
    let i: [&[f32]; TAPS] = std::array::from_fn(|o| &im[o..o + m]);
    for (j, out) in row.iter_mut().enumerate() {
        let mut a = 0.0f32;
        let mut b = 0.0f32;
        for o in 0..TAPS {
            if FMA {
                a = w[o].mul_add(r[o][j], a);
                b = w[o].mul_add(i[o][j], b);
            } else {
                a += w[o] * r[o][j];
                b += w[o] * i[o][j];
            }
        }
        *out = a * a + b * b;
    }
}

/// `out[j·D + r] = rows[r·m + j]`: the phase rows back in time order.
#[inline(always)]
fn interleave<const D: usize>(rows: &[f32], m: usize, out: &mut [f32]) {
    let p: [&[f32]; D] = std::array::from_fn(|r| &rows[r * m..(r + 1) * m]);
    let whole = out.len() / D;
    for (j, o) in out[..whole * D].chunks_exact_mut(D).enumerate() {
        for r in 0..D {
            o[r] = p[r][j];
        }
    }
    for s in whole * D..out.len() {
        out[s] = p[s % D][s / D];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lagrange_weights_reproduce_polynomials_up_to_their_degree() {
        for mu in [0.0, 0.125, 0.3, 0.5, 0.875] {
            let w = lagrange(mu);
            for deg in 0..TAPS as i32 {
                let got: f64 = (0..TAPS)
                    .map(|i| w[i] as f64 * (i as f64 - BEFORE as f64).powi(deg))
                    .sum();
                let want = mu.powi(deg);
                assert!(
                    (got - want).abs() < 2e-5 * 5f64.powi(deg),
                    "μ={mu} x^{deg}: {got} vs {want}"
                );
            }
        }
        let mut unit = [0.0; TAPS];
        unit[BEFORE] = 1.0;
        assert_eq!(lagrange(0.0), unit);
    }

    #[test]
    fn decimation_keeps_the_band_oversampled_and_divides_the_grid() {
        // 4 096 points, a band of ±40 bins: 81·2 = 162 ≤ 256 = 4096/16, 4096/32 = 128 < 162.
        assert_eq!(decimation(4096, 100, 81, 140), 16);
        // A band as wide as half the grid: no decimation.
        assert_eq!(decimation(4096, 1, 2047, 1024), 1);
        // A narrow band: down to the shortest grid (3 072 / 128 = 24 ≥ 16 points).
        assert_eq!(decimation(3072, 10, 3, 11), 128);
        // 17 496 = 8·3⁷: powers of two up to 8 only.
        assert_eq!(decimation(17_496, 10, 3, 11), 8);
    }
}
