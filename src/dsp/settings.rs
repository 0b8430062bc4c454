//! `[dsp]` (spectrum bands, CWT, bins, hit features) and `[onset]` (arrival picking): the
//! signal-processing room's settings and their checks.

use crate::util::Checked;
use serde::{Deserialize, Serialize};

/// What is wrong with `[dsp]` or `[onset]`: each variant names the key.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DspSettingsError {
    #[error("{key} must be > 0, got {value}")]
    NotPositive { key: &'static str, value: f64 },
    #[error("dsp.cwt: need f_max_hz ≥ f_min_hz and n_freqs ≥ 1")]
    CwtGrid,
    /// The feature path sums at most 64 windows (a fixed edge table): more would leave the
    /// later bins silently zero.
    #[error("dsp.bins.n_windows must be 1 to 64, got {0}")]
    Windows(usize),
    #[error("dsp.band_max_hz / dsp.band_hz must be a whole number of bands (≤ 1000), got {0}")]
    Bands(f64),
    #[error("dsp.band_max_hz / dsp.bins.band_hz must be a whole number, got {0}")]
    BinBands(f64),
    #[error("onset.win must be ≥ 1 sample")]
    OnsetWindow,
    #[error("onset.window_before_s and window_after_s: both ≥ 0 (after > 0), or neither")]
    OnsetSpan,
}

/// Signal processing (thesis ch. 4.5.5, 5.2; DESIGN §4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DspConfig {
    /// Width of one power-ratio band, Hz (Eq. 4.5.4: Δf = 100 kHz).
    pub band_hz: f64,
    /// Upper end of the power-ratio range, Hz (Eq. 4.5.4: 2500 kHz → 25 bands).
    pub band_max_hz: f64,
    pub cwt: CwtConfig,
    pub bins: BinsConfig,
    pub hit: HitConfig,
}

/// The continuous wavelet transform: complex Gabor (Morlet) wavelet on a linear grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CwtConfig {
    pub f_min_hz: f64,
    pub f_max_hz: f64,
    pub n_freqs: usize,
    /// Full width at half maximum of the Gaussian envelope, in periods of the centre
    /// frequency (AGU-Vallen style Gabor wavelet; 2 periods → Δf/f ≈ 0.44). Morlet with
    /// ω0 = 6 is 2.2487 periods.
    pub fwhm_periods: f64,
}

/// The time/frequency bins of ch. 5.2 (Fig. 5.2): normalised |W|² summed over windows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BinsConfig {
    /// Window length in time, s (thesis: 5 µs).
    pub window_s: f64,
    /// Number of time windows from the trigger (8 × 5 µs = 40 µs).
    pub n_windows: usize,
    /// Frequency band of one bin, Hz (thesis: 100 kHz); bands cover 0..dsp.band_max_hz.
    pub band_hz: f64,
}

/// Standard hit features (vallenae / ASTM E1316 conventions).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HitConfig {
    /// Detection threshold, dB_AE, used when the recording does not carry its own
    /// (Vallen records do; they are used unless `use_record_threshold = false`).
    pub threshold_db: f64,
    pub use_record_threshold: bool,
}

impl Default for DspConfig {
    fn default() -> Self {
        DspConfig {
            band_hz: 100e3,
            band_max_hz: 2500e3,
            cwt: CwtConfig::default(),
            bins: BinsConfig::default(),
            hit: HitConfig::default(),
        }
    }
}

impl Default for CwtConfig {
    fn default() -> Self {
        CwtConfig {
            f_min_hz: 10e3,
            f_max_hz: 2500e3,
            n_freqs: 250,
            fwhm_periods: 2.0,
        }
    }
}

impl Default for BinsConfig {
    fn default() -> Self {
        BinsConfig {
            window_s: 5e-6,
            n_windows: 8,
            band_hz: 100e3,
        }
    }
}

impl Default for HitConfig {
    fn default() -> Self {
        HitConfig {
            threshold_db: 40.0,
            use_record_threshold: true,
        }
    }
}

fn positive(v: f64, key: &'static str) -> Result<(), DspSettingsError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(DspSettingsError::NotPositive { key, value: v })
    }
}

impl DspConfig {
    /// The checks serde cannot express.
    pub fn check(self) -> Result<Checked<DspConfig>, DspSettingsError> {
        positive(self.band_hz, "dsp.band_hz")?;
        positive(self.band_max_hz, "dsp.band_max_hz")?;
        positive(self.cwt.f_min_hz, "dsp.cwt.f_min_hz")?;
        positive(self.cwt.fwhm_periods, "dsp.cwt.fwhm_periods")?;
        positive(self.bins.window_s, "dsp.bins.window_s")?;
        positive(self.bins.band_hz, "dsp.bins.band_hz")?;
        if self.cwt.f_max_hz < self.cwt.f_min_hz || self.cwt.n_freqs == 0 {
            return Err(DspSettingsError::CwtGrid);
        }
        if self.bins.n_windows == 0 || self.bins.n_windows > 64 {
            return Err(DspSettingsError::Windows(self.bins.n_windows));
        }
        let bands = self.band_max_hz / self.band_hz;
        if (bands - bands.round()).abs() > 1e-9 || bands.round() > 1000.0 || bands.round() < 1.0 {
            return Err(DspSettingsError::Bands(bands));
        }
        let bin_bands = self.band_max_hz / self.bins.band_hz;
        if (bin_bands - bin_bands.round()).abs() > 1e-9 || bin_bands.round() < 1.0 {
            return Err(DspSettingsError::BinBands(bin_bands));
        }
        Ok(Checked::new(self))
    }

    /// The number of power-ratio bands (Eq. 4.5.4: 25).
    pub fn n_ratio_bands(&self) -> usize {
        (self.band_max_hz / self.band_hz).round() as usize
    }
}

/// Which picker gives a hit's arrival time (`arrival_s`, and the events' and location's
/// times).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Picker {
    /// None: `arrival_s` is null, and events and location use the hit time (the
    /// acquisition's own threshold crossing).
    #[default]
    None,
    /// The first sample at or above the record's threshold.
    Threshold,
    Aic,
    Hinkley,
    Er,
    Mer,
}

/// `[onset]`: the four pickers of vallenae run on every record (`onset_*` columns); `picker`
/// chooses the one that gives `arrival_s`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OnsetConfig {
    pub picker: Picker,
    /// Hinkley's divisor α (vallenae: 5).
    pub alpha: f64,
    /// The energy ratios' window, samples (vallenae: 100).
    pub win: usize,
    /// Pick inside a window around the trigger instead of the whole record: this long before
    /// and after it, s (both set, or neither).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub window_before_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub window_after_s: Option<f64>,
}

impl Default for OnsetConfig {
    fn default() -> Self {
        OnsetConfig {
            picker: Picker::None,
            alpha: 5.0,
            win: 100,
            window_before_s: None,
            window_after_s: None,
        }
    }
}

impl OnsetConfig {
    /// The checks serde cannot express.
    pub fn check(self) -> Result<Checked<OnsetConfig>, DspSettingsError> {
        positive(self.alpha, "onset.alpha")?;
        if self.win == 0 {
            return Err(DspSettingsError::OnsetWindow);
        }
        match (self.window_before_s, self.window_after_s) {
            (None, None) => {}
            (Some(b), Some(a)) if b.is_finite() && a.is_finite() && b >= 0.0 && a > 0.0 => {}
            _ => return Err(DspSettingsError::OnsetSpan),
        }
        Ok(Checked::new(self))
    }
}
