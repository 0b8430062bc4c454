//! `[criteria]` (the ch. 4.7 labels) and `[validate]` (what makes a record a reject before
//! its features): the features room's settings and their checks.

use crate::dsp::settings::{DspConfig, OnsetConfig};
use crate::util::Checked;
use serde::{Deserialize, Serialize};

/// What the per-record transform reads of a checked pipeline: the DSP, the criteria, the
/// arrival pickers and the validation.
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureSettings {
    pub dsp: DspConfig,
    pub criteria: CriteriaConfig,
    pub crack_mode: crate::model::crack::CrackModeConfig,
    pub onset: OnsetConfig,
    pub validate: ValidateConfig,
}

/// What is wrong with `[criteria]` or `[validate]`: each variant names the key.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FeatureSettingsError {
    #[error("criteria.clip_min_steps must be a number ≥ 0, got {0}")]
    ClipMinSteps(f64),
}

/// The ch. 4.7 criteria that label a hit from its CWT (every threshold here).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CriteriaConfig {
    /// The two bond-failure frequencies, Hz (≈250 and ≈750 kHz).
    pub bond_low_hz: f64,
    pub bond_high_hz: f64,
    /// How far a dominant frequency may be from them, Hz (Fig. 4.7: ±10 % of the material
    /// properties moves a fibre's frequency by less than ±150 kHz).
    pub bond_tolerance_hz: f64,
    /// A fibre failure's dominant frequency is above this, Hz (800 kHz).
    pub fibre_min_hz: f64,
    /// …lasts less than this above half power, s (5 µs).
    pub fibre_max_duration_s: f64,
    /// …and arrives within this time of the trigger, s.
    pub fibre_max_arrival_s: f64,
    /// A component counts as present when its peak power is at least this share of the
    /// dominant component's (0.05 in power ≈ 0.22 in amplitude: clearly visible in a CWT).
    pub component_min_ratio: f64,
    /// "both": a bond-like component peaking at least this long after the fibre pulse, s.
    pub both_min_delay_s: f64,
    /// "both": the pulse's peak power is at least this share of the dominant component's
    /// (ch. 5.4: the pulse is "comparable" to the wave; 0.25 in power = 0.5 in amplitude).
    /// A weaker flash at the onset of a wave is the onset, not a fibre failure.
    pub both_min_ratio: f64,
    /// Triggered early: the signal already exceeds the threshold this long before the
    /// trigger, s.
    pub early_trigger_s: f64,
    /// Triggered before the front (ch. 5.4, Fig. 5.8c): the signal first reaches the
    /// threshold this long after the trigger, s (an AE system's own trigger is the first
    /// crossing, so a record whose front comes later was triggered by something else).
    pub late_front_s: f64,
    /// Two bursts: the envelope falls below `burst_quiet_ratio` of the peak for at least
    /// `burst_gap_s`, then rises above `burst_level_ratio` of the peak again.
    pub burst_gap_s: f64,
    pub burst_quiet_ratio: f64,
    pub burst_level_ratio: f64,
    /// Clipped: this many consecutive samples at the record's extreme value…
    pub clip_run: usize,
    /// …or this many samples at it in all (0: off; issue 24: a 250 kHz wave at 10 MHz
    /// clipped at 90 % of its peak sits at the rail 2–3 samples a half-cycle, so the run
    /// alone missed it)…
    pub clip_count: usize,
    /// …when the extreme is at least this many quantisation steps (the smallest gap between
    /// the record's distinct values): a weak record spanning a few ADC codes repeats its top
    /// code without being clipped.
    pub clip_min_steps: f64,
}

impl Default for CriteriaConfig {
    fn default() -> Self {
        CriteriaConfig {
            bond_low_hz: 250e3,
            bond_high_hz: 750e3,
            bond_tolerance_hz: 150e3,
            fibre_min_hz: 800e3,
            fibre_max_duration_s: 5e-6,
            fibre_max_arrival_s: 5e-6,
            component_min_ratio: 0.05,
            both_min_delay_s: 2e-6,
            both_min_ratio: 0.25,
            early_trigger_s: 10e-6,
            late_front_s: 5e-6,
            burst_gap_s: 5e-6,
            burst_quiet_ratio: 0.25,
            burst_level_ratio: 0.5,
            clip_run: 3,
            clip_count: 8,
            clip_min_steps: 100.0,
        }
    }
}

impl CriteriaConfig {
    /// The checks serde cannot express.
    pub fn check(self) -> Result<Checked<CriteriaConfig>, FeatureSettingsError> {
        let m = self.clip_min_steps;
        if !(m.is_finite() && m >= 0.0) {
            return Err(FeatureSettingsError::ClipMinSteps(m));
        }
        Ok(Checked::new(self))
    }
}

/// Checks that turn a hit into a reject row instead of a feature row.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ValidateConfig {
    /// Fewer samples than this is a reject ("too short").
    pub min_samples: usize,
}

impl Default for ValidateConfig {
    fn default() -> Self {
        ValidateConfig { min_samples: 16 }
    }
}
