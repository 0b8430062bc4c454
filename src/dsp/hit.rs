//! Standard AE hit features with vallenae's definitions (vallenae.features), on the
//! conditioned (DC-free) record:
//!
//! * peak amplitude `max|x|`, in V and dB_AE (re 1 µV);
//! * first threshold crossing: first sample with `|x| ≥ thr`;
//! * rise time: first crossing → peak amplitude, s (0 if the threshold is never reached);
//! * duration: first → last sample with `|x| ≥ thr`, s (ASTM E1316; vallenae has none);
//! * counts: positive-going crossings of `+thr`;
//! * energy: `Σx²/fs` in eu (1 eu = 1e-14 V²s); signal strength `Σ|x|/fs` in nVs;
//!   RMS `sqrt(mean x²)` — over the whole record, as vallenae computes them.

use crate::model::db_ae;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HitFeatures {
    pub amplitude_v: f64,
    pub amplitude_db: f64,
    pub threshold_v: f64,
    /// Index of the first threshold crossing (None: the threshold is never reached).
    pub first_crossing: Option<usize>,
    pub last_crossing: Option<usize>,
    pub peak_index: usize,
    pub rise_time_s: f64,
    pub duration_s: f64,
    pub counts: i64,
    pub energy_eu: f64,
    pub signal_strength_nvs: f64,
    pub rms_v: f64,
}

/// Relative slack of the threshold comparisons. ADC samples and thresholds are multiples of
/// the ADC step, so a sample often lies exactly on the threshold; whether float rounding
/// puts it an ulp below or above must not decide a crossing (vallenae compares in float32,
/// aepipe scales in float64). 1e-6 is far below one ADC step (≈3 % of a typical threshold).
const THRESHOLD_SLACK: f64 = 1e-6;

pub fn hit_features(x: &[f32], fs: f64, threshold_v: f64) -> HitFeatures {
    let thr = (threshold_v * (1.0 - THRESHOLD_SLACK)) as f32;
    let mut peak = (0usize, 0.0f32);
    let mut first = None;
    let mut last = None;
    let mut counts = 0i64;
    let mut sq = 0.0f64;
    let mut abs = 0.0f64;
    let mut prev_above = true; // vallenae counts rising edges from the second sample on
    for (i, &v) in x.iter().enumerate() {
        let a = v.abs();
        if a > peak.1 {
            peak = (i, a);
        }
        if a >= thr {
            if first.is_none() {
                first = Some(i);
            }
            last = Some(i);
        }
        let above = v >= thr;
        if i > 0 && above && !prev_above {
            counts += 1;
        }
        prev_above = above;
        sq += (v as f64) * (v as f64);
        abs += a as f64;
    }
    let amp = peak.1 as f64;
    HitFeatures {
        amplitude_v: amp,
        amplitude_db: if amp > 0.0 {
            db_ae(amp)
        } else {
            f64::NEG_INFINITY
        },
        threshold_v,
        first_crossing: first,
        last_crossing: last,
        peak_index: peak.0,
        rise_time_s: first
            .map(|f| (peak.0 as f64 - f as f64) / fs)
            .unwrap_or(0.0),
        duration_s: match (first, last) {
            (Some(f), Some(l)) => (l - f) as f64 / fs,
            _ => 0.0,
        },
        counts,
        energy_eu: sq / fs * 1e14,
        signal_strength_nvs: abs / fs * 1e9,
        rms_v: if x.is_empty() {
            0.0
        } else {
            (sq / x.len() as f64).sqrt()
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn features_of_a_hand_made_burst() {
        // fs = 1 MHz; threshold 0.5 V.
        let x = [0.0f32, 0.1, 0.6, -0.7, 0.9, -0.2, 0.55, 0.1, -0.6, 0.0];
        let h = hit_features(&x, 1e6, 0.5);
        assert_eq!(h.first_crossing, Some(2));
        assert_eq!(h.last_crossing, Some(8));
        assert_eq!(h.peak_index, 4);
        assert!((h.amplitude_v - 0.9).abs() < 1e-7);
        assert!((h.rise_time_s - 2e-6).abs() < 1e-12);
        assert!((h.duration_s - 6e-6).abs() < 1e-12);
        // Rising edges through +0.5: at 2 (0.1→0.6), 4 (-0.7→0.9), 6 (-0.2→0.55).
        assert_eq!(h.counts, 3);
        let sq: f64 = x.iter().map(|v| (*v as f64).powi(2)).sum();
        assert!((h.energy_eu - sq / 1e6 * 1e14).abs() / h.energy_eu < 1e-12);
        let ab: f64 = x.iter().map(|v| v.abs() as f64).sum();
        assert!((h.signal_strength_nvs - ab / 1e6 * 1e9).abs() < 1e-6);
        assert!((h.rms_v - (sq / 10.0).sqrt()).abs() < 1e-9);
    }

    #[test]
    fn below_threshold_gives_zero_times() {
        let h = hit_features(&[0.1, -0.2, 0.1], 1e6, 0.5);
        assert_eq!(h.first_crossing, None);
        assert_eq!((h.rise_time_s, h.duration_s, h.counts), (0.0, 0.0, 0));
    }
}
