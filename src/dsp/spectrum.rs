//! Power spectrum features of a record (thesis Eq. 4.5.4, right-hand side).
//!
//! From the record's DFT `X_j` (one FFT, shared with the CWT): power `P_j = |X_j|²` at
//! `f_j = j·fs/N` for `0 ≤ j ≤ N/2`. The power ratio of band i is the power in
//! `[i·Δf, (i+1)·Δf)` divided by the power in `[0, band_max)`, so the ratios sum to 1.
//! Bands entirely above the Nyquist frequency hold 0.

use rustfft::num_complex::Complex32;

/// Scalar spectrum features.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpectrumScalars {
    /// Power in `[0, band_max)`, (V·sample)² (unnormalised DFT units; only ratios matter).
    pub total_power: f64,
    /// Frequency of the largest power bin (DC excluded), Hz.
    pub peak_freq_hz: f64,
    /// Power-weighted mean frequency over `(0, fs/2]`, Hz.
    pub centroid_freq_hz: f64,
}

/// Fill `ratios` (one per band) from the spectrum of an `n`-sample record at `fs`.
/// Returns `None` when the record has no power below `band_max` (a flat record), and for
/// no bands, a band width that is not positive or a negative rate (not inputs the
/// configuration lets through).
pub fn power_ratios(
    spec: &[Complex32],
    n: usize,
    fs: f64,
    band_hz: f64,
    ratios: &mut [f64],
) -> Option<SpectrumScalars> {
    ratios.fill(0.0);
    if ratios.is_empty() || band_hz.is_nan() || band_hz <= 0.0 || fs < 0.0 {
        return None;
    }
    let band_max = band_hz * ratios.len() as f64;
    let df = fs / n as f64;
    let half = n / 2;
    let mut total_all = 0.0;
    let mut moment = 0.0;
    let mut peak = (0usize, -1.0f64);
    // Bins come in frequency order, so each band is one run of bins. The run's ends are
    // found once per band (by the same expression the bins would use, which never falls as
    // j grows), so no bin divides; its sum is kept in a register and stored when the run
    // ends: the same additions in the same order as `ratios[i] += p` bin by bin.
    let last = ratios.len() - 1;
    let band_of = |j: usize| {
        let f = j as f64 * df;
        (f < band_max).then(|| ((f / band_hz) as usize).min(last))
    };
    let bins = spec.len().min(half + 1);
    let mut j = 0;
    while j < bins {
        let band = band_of(j);
        let end = run_end(j, bins, band, band_hz, df, band_of);
        let mut acc = 0.0f64;
        if j == 0 {
            // DC: in band 0's sum, not in the total, the centroid or the peak.
            acc += spec[0].norm_sqr() as f64;
            j = 1;
        }
        for (k, x) in spec[j..end].iter().enumerate() {
            let j = j + k;
            let p = x.norm_sqr() as f64;
            total_all += p;
            moment += p * (j as f64 * df);
            if p > peak.1 {
                peak = (j, p);
            }
            acc += p;
        }
        if let Some(b) = band {
            ratios[b] = acc;
        }
        j = end;
    }
    let total: f64 = ratios.iter().sum();
    if total.is_nan() || total <= 0.0 || !total.is_finite() {
        ratios.fill(0.0);
        return None;
    }
    ratios.iter_mut().for_each(|r| *r /= total);
    Some(SpectrumScalars {
        total_power: total,
        peak_freq_hz: peak.0 as f64 * df,
        centroid_freq_hz: if total_all > 0.0 {
            moment / total_all
        } else {
            0.0
        },
    })
}

/// The first bin after `j` (at most `bins`) whose band (`band_of`, never falling as the bin
/// grows; `None` above the banded range) is not `band`: from the band's upper edge over the
/// bin spacing, then moved bin by bin until `band_of` itself agrees.
fn run_end(
    j: usize,
    bins: usize,
    band: Option<usize>,
    band_hz: f64,
    df: f64,
    band_of: impl Fn(usize) -> Option<usize>,
) -> usize {
    let Some(b) = band else { return bins };
    let edge = ((b + 1) as f64 * band_hz / df).ceil();
    let mut end = if edge.is_finite() && edge > 0.0 {
        (edge as usize).clamp(j + 1, bins)
    } else {
        bins
    };
    while end > j + 1 && band_of(end - 1) != band {
        end -= 1;
    }
    while end < bins && band_of(end) == band {
        end += 1;
    }
    end
}

/// Column name of band `i`: `pr_200_300khz`.
pub fn band_column(i: usize, band_hz: f64) -> String {
    let lo = i as f64 * band_hz / 1e3;
    let hi = (i + 1) as f64 * band_hz / 1e3;
    if lo.fract() == 0.0 && hi.fract() == 0.0 {
        format!("pr_{}_{}khz", lo as u64, hi as u64)
    } else {
        format!("pr_{lo}_{hi}khz").replace('.', "p")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rustfft::FftPlanner;
    use std::f64::consts::PI;

    fn spectrum(x: &[f64]) -> Vec<Complex32> {
        let mut buf: Vec<Complex32> = x.iter().map(|&v| Complex32::new(v as f32, 0.0)).collect();
        FftPlanner::<f32>::new()
            .plan_fft_forward(x.len())
            .process(&mut buf);
        buf
    }

    #[test]
    fn damped_250_khz_sine_puts_most_power_in_200_300_khz() {
        let fs = 10e6;
        let n = 4096;
        let x: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                if i < 500 {
                    0.0
                } else {
                    let t = t - 500.0 / fs;
                    (-5e4 * t).exp() * (2.0 * PI * 250e3 * t).sin()
                }
            })
            .collect();
        let mut r = vec![0.0; 25];
        let s = power_ratios(&spectrum(&x), n, fs, 100e3, &mut r).unwrap();
        assert!((r.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        assert!(r[2] > 0.8, "200–300 kHz holds {}", r[2]);
        assert!((s.peak_freq_hz - 250e3).abs() < 2.5e3, "{}", s.peak_freq_hz);
    }

    #[test]
    fn bands_above_nyquist_are_zero_and_flat_records_give_none() {
        let fs = 2e6;
        let n = 2048;
        let x: Vec<f64> = (0..n)
            .map(|i| (2.0 * PI * 300e3 * i as f64 / fs).sin())
            .collect();
        let mut r = vec![0.0; 25];
        power_ratios(&spectrum(&x), n, fs, 100e3, &mut r).unwrap();
        // 1 MHz Nyquist: its bin opens band 1000–1100 kHz; every band above is empty.
        assert!(r[11..].iter().all(|&v| v == 0.0));
        assert!((r.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        assert!(power_ratios(&spectrum(&vec![0.0; 64]), 64, fs, 100e3, &mut r).is_none());
    }

    #[test]
    fn centroid_of_two_equal_tones_is_their_mean() {
        let fs = 10e6;
        let n = 10000; // both tones on exact bins (1 kHz resolution)
        let x: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                (2.0 * PI * 200e3 * t).sin() + (2.0 * PI * 600e3 * t).sin()
            })
            .collect();
        let mut r = vec![0.0; 25];
        let s = power_ratios(&spectrum(&x), n, fs, 100e3, &mut r).unwrap();
        assert!(
            (s.centroid_freq_hz - 400e3).abs() < 100.0,
            "{}",
            s.centroid_freq_hz
        );
        assert!((r[2] - 0.5).abs() < 1e-3 && (r[6] - 0.5).abs() < 1e-3);
    }

    #[test]
    fn band_names() {
        assert_eq!(band_column(2, 100e3), "pr_200_300khz");
        assert_eq!(band_column(0, 100e3), "pr_0_100khz");
        assert_eq!(band_column(1, 50e3), "pr_50_100khz");
    }

    /// The bin-by-bin loop the run version replaced (a division per bin), for bit equality.
    fn power_ratios_reference(
        spec: &[Complex32],
        n: usize,
        fs: f64,
        band_hz: f64,
        ratios: &mut [f64],
    ) -> (f64, f64, usize) {
        ratios.fill(0.0);
        let band_max = band_hz * ratios.len() as f64;
        let df = fs / n as f64;
        let (mut total_all, mut moment, mut peak) = (0.0, 0.0, (0usize, -1.0f64));
        for (j, x) in spec.iter().enumerate().take(n / 2 + 1) {
            let p = x.norm_sqr() as f64;
            let f = j as f64 * df;
            if j > 0 {
                total_all += p;
                moment += p * f;
                if p > peak.1 {
                    peak = (j, p);
                }
            }
            if f < band_max {
                let i = ((f / band_hz) as usize).min(ratios.len() - 1);
                ratios[i] += p;
            }
        }
        (total_all, moment, peak.0)
    }

    #[test]
    fn the_runs_give_the_bin_by_bin_sums_to_the_bit() {
        let mut rng = crate::util::Rng::new(5);
        let mut u = || rng.uniform();
        // Lengths odd and even, bands narrower than a bin, band ranges past Nyquist, rates
        // whose bins fall exactly on band edges (10 MHz, n = 10 000: 1 kHz bins).
        let cases = [
            (4096, 10e6, 100e3, 25),
            (10_000, 10e6, 100e3, 25),
            (4097, 5e6, 100e3, 25),
            (3, 10e6, 100e3, 25),
            (2, 1e6, 100e3, 4),
            (220_000, 5e6, 100e3, 25),
            (1000, 10e6, 3e3, 7),
            (2048, 2e6, 100e3, 25),
            (777, 3.3e6, 33_333.3, 60),
            (1, 10e6, 100e3, 25),
            (4096, 10e6, 20e6, 3),
            (4096, 0.0, 100e3, 25),
        ];
        for (n, fs, band_hz, bands) in cases {
            let spec: Vec<Complex32> = (0..n)
                .map(|_| Complex32::new((u() - 0.5) as f32, (u() - 0.5) as f32))
                .collect();
            let (mut a, mut b) = (vec![0.0; bands], vec![0.0; bands]);
            let s = power_ratios(&spec, n, fs, band_hz, &mut a).unwrap();
            let (total_all, moment, peak) = power_ratios_reference(&spec, n, fs, band_hz, &mut b);
            let total: f64 = b.iter().sum();
            b.iter_mut().for_each(|v| *v /= total);
            assert_eq!(a, b, "n {n}, fs {fs}, band {band_hz}");
            assert_eq!(s.total_power.to_bits(), total.to_bits());
            assert_eq!(
                s.peak_freq_hz.to_bits(),
                (peak as f64 * (fs / n as f64)).to_bits()
            );
            let centroid = if total_all > 0.0 {
                moment / total_all
            } else {
                0.0
            };
            assert_eq!(s.centroid_freq_hz.to_bits(), centroid.to_bits());
        }
        // A spectrum shorter than n/2 + 1 bins, a NaN bin, and inputs refused up front.
        let spec = vec![Complex32::new(1.0, 0.5); 100];
        let (mut a, mut b) = (vec![0.0; 25], vec![0.0; 25]);
        power_ratios(&spec, 4096, 10e6, 100e3, &mut a).unwrap();
        power_ratios_reference(&spec, 4096, 10e6, 100e3, &mut b);
        let total: f64 = b.iter().sum();
        assert_eq!(a, b.iter().map(|v| v / total).collect::<Vec<_>>());
        let mut nan = spec.clone();
        nan[7] = Complex32::new(f32::NAN, 0.0);
        assert!(power_ratios(&nan, 200, 10e6, 100e3, &mut a).is_none());
        assert!(power_ratios(&spec, 200, 10e6, 100e3, &mut []).is_none());
        assert!(power_ratios(&spec, 200, 10e6, 0.0, &mut a).is_none());
        assert!(power_ratios(&spec, 200, -10e6, 100e3, &mut a).is_none());
    }
}
