//! `[trend]` (ch. 4.5.5) and `[evolution]` (the damage evolution's windows): the analysis
//! room's settings and their checks.

use crate::util::Checked;
use serde::{Deserialize, Serialize};

/// What is wrong with `[trend]` or `[evolution]` (or a `--cutoff`): each variant names the
/// key.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AnalysisSettingsError {
    #[error("cut-off '{0}': expected none, peak-load, time:SECONDS or hits:N")]
    Cutoff(String),
    #[error("trend.alpha must be in (0, 1), got {0}")]
    Alpha(f64),
    #[error("trend.min_load_span_n must be a number of newtons ≥ 0, got {0}")]
    MinLoadSpan(f64),
    #[error(
        "trend.min_hits must be at least 3 (a line through fewer points has no p value), got {0}"
    )]
    MinHits(usize),
    #[error("evolution.window must be at least 10 sources, got {0}")]
    Window(usize),
    #[error("evolution.completeness_db must be finite, got {0}")]
    Completeness(f64),
    #[error("{key} must be > 0, got {value}")]
    NotPositive { key: &'static str, value: f64 },
    #[error("evolution.cycle_drop_fraction must be in (0, 1), got {0}")]
    CycleDrop(f64),
    #[error("evolution.felicity_onset_sources must be at least 1")]
    OnsetSources,
    #[error("evolution.felicity_onset_db must be finite, got {0}")]
    OnsetDb(f64),
}

/// Which hits enter the statistics (in TOML and on the command line: `none`, `peak-load`,
/// `time:SECONDS`, `hits:N`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum Cutoff {
    None,
    /// Hits up to (and including) the one at the highest load.
    PeakLoad,
    /// Hits with `time_s ≤` this.
    Time(f64),
    /// The first N hits.
    Hits(usize),
}

impl std::fmt::Display for Cutoff {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Cutoff::None => f.write_str("none"),
            Cutoff::PeakLoad => f.write_str("peak-load"),
            Cutoff::Time(t) => write!(f, "time:{t}"),
            Cutoff::Hits(n) => write!(f, "hits:{n}"),
        }
    }
}

impl TryFrom<String> for Cutoff {
    type Error = AnalysisSettingsError;
    fn try_from(s: String) -> Result<Cutoff, AnalysisSettingsError> {
        s.parse()
    }
}

impl From<Cutoff> for String {
    fn from(c: Cutoff) -> String {
        c.to_string()
    }
}

impl std::str::FromStr for Cutoff {
    type Err = AnalysisSettingsError;
    fn from_str(s: &str) -> Result<Cutoff, AnalysisSettingsError> {
        let bad = || AnalysisSettingsError::Cutoff(s.to_string());
        match s {
            "none" => Ok(Cutoff::None),
            "peak-load" => Ok(Cutoff::PeakLoad),
            _ => match s.split_once(':') {
                Some(("time", v)) => v.parse().map(Cutoff::Time).map_err(|_| bad()),
                Some(("hits", v)) => v.parse().map(Cutoff::Hits).map_err(|_| bad()),
                _ => Err(bad()),
            },
        }
    }
}

/// The trend stage of `aepipe run` (ch. 4.5.5).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrendConfig {
    pub enabled: bool,
    /// `none`, `peak-load` (ch. 4.5.5: only hits before the load falls), `time:S`, `hits:N`.
    pub cutoff: Cutoff,
    /// Significance level (Table 4.2: 1 %).
    pub alpha: f64,
    /// The smallest span a load channel needs to count as a load, N: a channel spanning
    /// less (or within its own noise, see `analysis::load`) is treated as absent — no
    /// peak-load cut, no profile against load. 1 N is far below any paper strip's breaking
    /// load and above the noise of an unloaded machine's channel; 0 leaves only the noise test.
    pub min_load_span_n: f64,
    /// Fewest hits a trend is stated on: below it a row says `n = 3: too few hits for a
    /// trend` with null r and p. Three points give a p value, but a correlation of a handful
    /// of hits is r = ±1 by chance often enough to mislead (n = 4: |r| > 0.95 in 5 % of
    /// uncorrelated draws); 10 keeps the chance |r| > 0.8 below 1 % (Student t, 8 d.f.).
    pub min_hits: usize,
}

impl Default for TrendConfig {
    fn default() -> Self {
        TrendConfig {
            enabled: true,
            cutoff: Cutoff::PeakLoad,
            alpha: 0.01,
            min_load_span_n: 1.0,
            min_hits: MIN_TREND_HITS,
        }
    }
}

/// The default of `[trend] min_hits`.
pub const MIN_TREND_HITS: usize = 10;

impl TrendConfig {
    /// The checks serde cannot express.
    pub fn check(self) -> Result<Checked<TrendConfig>, AnalysisSettingsError> {
        if !(self.alpha > 0.0 && self.alpha < 1.0) {
            return Err(AnalysisSettingsError::Alpha(self.alpha));
        }
        if !(self.min_load_span_n.is_finite() && self.min_load_span_n >= 0.0) {
            return Err(AnalysisSettingsError::MinLoadSpan(self.min_load_span_n));
        }
        if self.min_hits < 3 {
            return Err(AnalysisSettingsError::MinHits(self.min_hits));
        }
        Ok(Checked::new(self))
    }
}

/// `[evolution]`: the damage evolution's sliding windows (`evolution.parquet`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EvolutionConfig {
    /// Sources per window of the b- and Ib-value (the last `window` of a series).
    pub window: usize,
    /// The b-value's completeness threshold, dB_AE: amplitudes below it are left out of the
    /// b-value (M_c = completeness_db / 20).
    pub completeness_db: f64,
    /// Shiotani's α₁ and α₂ of the Ib-value (1 and 1 in his papers).
    pub ib_alpha1: f64,
    pub ib_alpha2: f64,
    /// A drop (and a rise after it) counts as an unloading (a reload) when it exceeds this
    /// share of the load's span (or 5 noise σ, if more): the cycles of a load–unload–reload
    /// test ([`super::cycles`]).
    pub cycle_drop_fraction: f64,
    /// The AE onset of a reload: its `felicity_onset_sources`-th source while loading …
    pub felicity_onset_sources: usize,
    /// … counting only sources at or above this amplitude, dB_AE (0: every source).
    pub felicity_onset_db: f64,
    /// The Kaiser effect holds on a reload whose Felicity ratio is at least this (1 by
    /// the effect's definition).
    pub kaiser_min_ratio: f64,
}

impl Default for EvolutionConfig {
    fn default() -> Self {
        EvolutionConfig {
            window: 50,
            completeness_db: 40.0,
            ib_alpha1: 1.0,
            ib_alpha2: 1.0,
            cycle_drop_fraction: 0.1,
            felicity_onset_sources: 1,
            felicity_onset_db: 0.0,
            kaiser_min_ratio: 1.0,
        }
    }
}

impl EvolutionConfig {
    /// The checks serde cannot express.
    pub fn check(self) -> Result<Checked<EvolutionConfig>, AnalysisSettingsError> {
        if self.window < 10 {
            return Err(AnalysisSettingsError::Window(self.window));
        }
        if !self.completeness_db.is_finite() {
            return Err(AnalysisSettingsError::Completeness(self.completeness_db));
        }
        if !(self.cycle_drop_fraction > 0.0 && self.cycle_drop_fraction < 1.0) {
            return Err(AnalysisSettingsError::CycleDrop(self.cycle_drop_fraction));
        }
        if self.felicity_onset_sources == 0 {
            return Err(AnalysisSettingsError::OnsetSources);
        }
        if !self.felicity_onset_db.is_finite() {
            return Err(AnalysisSettingsError::OnsetDb(self.felicity_onset_db));
        }
        for (key, value) in [
            ("evolution.ib_alpha1", self.ib_alpha1),
            ("evolution.ib_alpha2", self.ib_alpha2),
            ("evolution.kaiser_min_ratio", self.kaiser_min_ratio),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(AnalysisSettingsError::NotPositive { key, value });
            }
        }
        Ok(Checked::new(self))
    }
}
