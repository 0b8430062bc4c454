//! `[detect]`: how a continuous recording is cut into hits (the keys are a contract, issue
//! 40), checked once into [`ValidDetect`].

use serde::{Deserialize, Serialize};

/// Whether streams are cut.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum DetectMode {
    /// Every record is a hit as recorded (the default).
    #[default]
    Off,
    /// Every stream and record is cut.
    On,
    /// Records longer than `auto_min_samples` are cut; shorter ones are hits as recorded.
    Auto,
}

/// `[detect]` as written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DetectConfig {
    pub mode: DetectMode,
    /// With `auto`, a record of more samples than this is a stream.
    pub auto_min_samples: u64,
    /// The fixed threshold, dB_AE (20·log10(V / 1 µV)).
    pub threshold_db: f64,
    /// A floating threshold instead: `floating_factor` × the noise RMS of the previous
    /// `floating_window_s` (its samples outside hits).
    pub floating: bool,
    pub floating_factor: f64,
    pub floating_window_s: f64,
    /// Duration discrimination time: a hit ends this long after its last crossing.
    pub ddt_s: f64,
    /// Rearm time: the detector is blind this long after a hit's end.
    pub rearm_s: f64,
    /// A hit is ended at this duration whatever follows.
    pub max_duration_s: f64,
    /// Peak definition time: the peak is the largest |x| within this of the first crossing
    /// (rise time and counts to peak use it).
    pub pdt_s: f64,
    /// Samples kept before the first crossing and after the last.
    pub pretrigger_s: f64,
    pub posttrigger_s: f64,
    /// A hit with a gap of at least this below the threshold inside it is flagged as two
    /// bursts in one record (Table 5.1's "two signals"); 0: not flagged.
    pub split_gap_s: f64,
    /// Samples read per block (per channel) from a stream file.
    pub block_samples: usize,
}

impl Default for DetectConfig {
    fn default() -> Self {
        DetectConfig {
            mode: DetectMode::Off,
            auto_min_samples: 1_000_000,
            threshold_db: 40.0,
            floating: false,
            floating_factor: 4.0,
            floating_window_s: 10e-3,
            ddt_s: 200e-6,
            rearm_s: 100e-6,
            max_duration_s: 10e-3,
            pdt_s: 50e-6,
            pretrigger_s: 50e-6,
            posttrigger_s: 100e-6,
            split_gap_s: 0.0,
            block_samples: 1 << 20,
        }
    }
}

/// What is wrong with `[detect]`: the key and its value.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DetectSettingsError {
    #[error("detect.{key} must be {want}, got {value}")]
    Bad {
        key: &'static str,
        want: &'static str,
        value: f64,
    },
}

/// `[detect]` checked, its times still in seconds (a stream's rate gives the samples).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ValidDetect(DetectConfig);

impl std::ops::Deref for ValidDetect {
    type Target = DetectConfig;
    fn deref(&self) -> &DetectConfig {
        &self.0
    }
}

impl DetectConfig {
    pub fn check(self) -> Result<ValidDetect, DetectSettingsError> {
        let bad = |key, want, value| Err(DetectSettingsError::Bad { key, want, value });
        for (key, v) in [
            ("ddt_s", self.ddt_s),
            ("rearm_s", self.rearm_s),
            ("pretrigger_s", self.pretrigger_s),
            ("posttrigger_s", self.posttrigger_s),
            ("split_gap_s", self.split_gap_s),
            ("pdt_s", self.pdt_s),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(key, "a time ≥ 0 s", v);
            }
        }
        if !(self.max_duration_s.is_finite() && self.max_duration_s > 0.0) {
            return bad("max_duration_s", "a time > 0 s", self.max_duration_s);
        }
        if !self.threshold_db.is_finite() {
            return bad("threshold_db", "finite", self.threshold_db);
        }
        if self.floating && !(self.floating_factor.is_finite() && self.floating_factor > 0.0) {
            return bad("floating_factor", "> 0", self.floating_factor);
        }
        if self.floating && !(self.floating_window_s.is_finite() && self.floating_window_s > 0.0) {
            return bad("floating_window_s", "a time > 0 s", self.floating_window_s);
        }
        if self.block_samples < 1024 {
            return bad("block_samples", "at least 1024", self.block_samples as f64);
        }
        Ok(ValidDetect(self))
    }
}

impl ValidDetect {
    /// Whether a record of `n` samples is cut.
    pub fn cuts(&self, n: u64) -> bool {
        match self.mode {
            DetectMode::Off => false,
            DetectMode::On => true,
            DetectMode::Auto => n > self.auto_min_samples,
        }
    }

    /// The detector's parameters at a stream's rate.
    pub fn at_rate(&self, rate_hz: f64) -> super::Params {
        let n = |s: f64| (s * rate_hz).round() as u64;
        super::Params {
            threshold_v: if self.floating {
                None
            } else {
                Some(1e-6 * 10f64.powf(self.threshold_db / 20.0))
            },
            floating_factor: self.floating_factor,
            floating_window: n(self.floating_window_s).max(1),
            ddt: n(self.ddt_s),
            rearm: n(self.rearm_s),
            max_duration: n(self.max_duration_s).max(1),
            pdt: n(self.pdt_s),
            pre: n(self.pretrigger_s),
            post: n(self.posttrigger_s),
            split_gap: (self.split_gap_s > 0.0).then(|| n(self.split_gap_s).max(1)),
        }
    }
}
