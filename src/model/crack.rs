//! The RA–AF crack-mode split (JCMS-IIIB5706; RILEM TC 212-ACD, Ohtsu 2010): a hit whose
//! waveform rises slowly for its amplitude and rings at a low average frequency comes from
//! a shear crack, a fast-rising high-frequency one from a tensile crack.
//!
//! * RA (rise time over peak amplitude) in ms/V;
//! * AF (average frequency: threshold counts over duration) in kHz;
//! * `tensile` above the line AF = `af_per_ra` × RA, `shear` on or below it.
//!
//! The recommendations fix the two axes and their units but not the slope: it depends on
//! the specimen, sensor and threshold, and should be calibrated (for instance on
//! pencil-lead breaks of known mode). The default, 1 kHz per ms/V, is the diagonal of
//! Ohno & Ohtsu (2010, *Constr. Build. Mater.* 24:2339) in those units; `[crack_mode]
//! af_per_ra` sets another.

use serde::{Deserialize, Serialize};

/// `[crack_mode]` of the pipeline TOML.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CrackModeConfig {
    /// Slope of the dividing line, kHz per ms/V (> 0, finite).
    pub af_per_ra: f64,
}

/// The default slope (see the module's documentation for its source).
pub const AF_PER_RA: f64 = 1.0;

impl Default for CrackModeConfig {
    fn default() -> Self {
        CrackModeConfig {
            af_per_ra: AF_PER_RA,
        }
    }
}

/// What is wrong with `[crack_mode]`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CrackModeError {
    #[error("crack_mode.af_per_ra must be a positive number, not {0}")]
    Slope(f64),
}

impl CrackModeConfig {
    /// The slope is positive and finite.
    pub fn check(&self) -> Result<(), CrackModeError> {
        if self.af_per_ra.is_finite() && self.af_per_ra > 0.0 {
            Ok(())
        } else {
            Err(CrackModeError::Slope(self.af_per_ra))
        }
    }
}

/// A hit's crack mode by the RA–AF line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CrackMode {
    Tensile,
    Shear,
}

impl CrackMode {
    pub fn as_str(self) -> &'static str {
        match self {
            CrackMode::Tensile => "tensile",
            CrackMode::Shear => "shear",
        }
    }
}

/// RA, ms/V: rise time over peak amplitude; `None` without a positive, finite amplitude or
/// a finite, non-negative rise time.
pub fn ra_ms_per_v(rise_time_s: f64, amplitude_v: f64) -> Option<f64> {
    (amplitude_v.is_finite() && amplitude_v > 0.0 && rise_time_s.is_finite() && rise_time_s >= 0.0)
        .then(|| rise_time_s * 1e3 / amplitude_v)
}

/// AF, kHz: threshold counts over duration; `None` without a positive, finite duration.
pub fn af_khz(counts: i64, duration_s: f64) -> Option<f64> {
    (counts >= 0 && duration_s.is_finite() && duration_s > 0.0)
        .then(|| counts as f64 / (duration_s * 1e3))
}

/// The mode of a hit with both RA and AF: tensile when AF > `af_per_ra` × RA, shear
/// otherwise; `None` when either is undefined.
pub fn crack_mode(ra: Option<f64>, af: Option<f64>, af_per_ra: f64) -> Option<CrackMode> {
    let (ra, af) = (ra?, af?);
    Some(if af > af_per_ra * ra {
        CrackMode::Tensile
    } else {
        CrackMode::Shear
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Worked by hand: rise 50 µs at 0.1 V is RA = 0.05 ms / 0.1 V = 0.5 ms/V; 30 counts
    /// over 200 µs is AF = 30 / 0.2 ms = 150 kHz.
    #[test]
    fn ra_af_and_the_mode_by_hand() {
        let ra = ra_ms_per_v(50e-6, 0.1).unwrap();
        let af = af_khz(30, 200e-6).unwrap();
        assert!((ra - 0.5).abs() < 1e-12 && (af - 150.0).abs() < 1e-9);
        // The line at 1 kHz per ms/V: 150 > 0.5 → tensile; at 400: 150 < 200 → shear.
        assert_eq!(
            crack_mode(Some(ra), Some(af), 1.0),
            Some(CrackMode::Tensile)
        );
        assert_eq!(
            crack_mode(Some(ra), Some(af), 400.0),
            Some(CrackMode::Shear)
        );
        // On the line is not above it.
        assert_eq!(
            crack_mode(Some(0.5), Some(150.0), 300.0),
            Some(CrackMode::Shear)
        );
        // Undefined: no amplitude, no duration (the threshold was never crossed).
        assert_eq!(ra_ms_per_v(1e-6, 0.0), None);
        assert_eq!(ra_ms_per_v(f64::NAN, 0.1), None);
        assert_eq!(af_khz(0, 0.0), None);
        assert_eq!(crack_mode(None, Some(1.0), 1.0), None);
        assert_eq!(crack_mode(Some(1.0), None, 1.0), None);
        assert!(CrackModeConfig { af_per_ra: 0.0 }.check().is_err());
        assert!(CrackModeConfig {
            af_per_ra: f64::INFINITY
        }
        .check()
        .is_err());
        assert!(CrackModeConfig::default().check().is_ok());
    }
}
