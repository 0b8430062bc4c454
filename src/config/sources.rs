//! `[onset]`, `[events]`, `[location]` and `[evolution]`: from hits to sources — arrival
//! picking, the event builder, source location (the `events` room uses them; `features` uses
//! `[onset]`) and the sources' course over a test (`analysis::evolution`).

use super::{positive, ConfigError};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

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

/// A channel's role in the event builder (VisualAE's channel functions, vallenae's
/// `ChannelFunction`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ChannelRole {
    /// Ignored entirely.
    Unused,
    /// Takes part and may open an event.
    Normal,
    /// Never opens an event; while no event is open its hit restarts the FHCDT timer (so the
    /// same source's later hits at normal sensors open none); joins an open event but is
    /// left out of location.
    Guard,
    /// A guard when it would be the first hit, a normal channel otherwise.
    Combined,
}

/// `[events]`: VisualAE's event builder (vallenae 0.14's `EventBuilder`). A key left out is
/// taken from a Vallen `.vaex` beside the `.pridb` when there is one, else from the defaults
/// stated on each key; the manifest records which.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EventsConfig {
    /// Build events at all. Left out: yes for an experiment with two or more channels.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub enabled: Option<bool>,
    /// First-hit-channel discrimination time, s: the quiet time a hit needs before it to open
    /// an event. Default: `dt1x_max_s`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fhcdt_s: Option<f64>,
    /// Longest time from an event's first hit to any of its hits, s. Default: 2 × the
    /// largest sensor distance / velocity with `[location]` (the travel time, and room for
    /// the later threshold crossing of the weaker sensor), else 100 µs.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dt1x_max_s: Option<f64>,
    /// Longest time between consecutive hits of an event, s. Default: `dt1x_max_s`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dtnx_max_s: Option<f64>,
    /// Keep a second hit of a channel in the event (default false: it closes the event).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub allow_duplicates: Option<bool>,
    /// Channels that guard the gauge section (at the grips): they never open an event.
    pub guard_channels: Vec<u32>,
    /// Channels left out of event building.
    pub unused_channels: Vec<u32>,
    /// Channels that act as guards when first, as normal channels otherwise.
    pub combined_channels: Vec<u32>,
}

/// `[location] kind`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LocationKind {
    /// Along a line between two sensors (a strip): x only.
    Linear,
    /// On a plane from three or more sensors: x and y.
    Planar,
}

/// `[location] zone`: the region whose events count as the specimen's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ZoneSpec {
    /// `[x_min, x_max]`, m (linear location).
    Interval([f64; 2]),
    /// `[[x, y], …]`, m: a polygon, at least three corners (planar location).
    Polygon(Vec<[f64; 2]>),
}

/// `[location]`: where the sources are. Left out: from a Vallen `.vaex` beside the `.pridb`
/// (its `<Location Velocity>` in km/s and `<ChannelPos X Y>` in m), else no location.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LocationConfig {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kind: Option<LocationKind>,
    /// Wave velocity, m/s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub velocity_m_s: Option<f64>,
    /// Sensor positions by channel, m: `{ 1 = [x], 2 = [x] }` or `{ 1 = [x, y], … }`.
    pub sensors: BTreeMap<String, Vec<f64>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub zone: Option<ZoneSpec>,
    /// Leave events outside the zone, and hits a guard sensor suppressed, out of the trend,
    /// the SOM's training and the class counts (they stay in every table).
    pub exclude_outside: bool,
    /// Gauss–Newton iterations of planar location before the fallback search.
    pub max_iterations: usize,
}

impl Default for LocationConfig {
    fn default() -> Self {
        LocationConfig {
            kind: None,
            velocity_m_s: None,
            sensors: BTreeMap::new(),
            zone: None,
            exclude_outside: false,
            max_iterations: 50,
        }
    }
}

impl LocationConfig {
    /// The sensor positions as (channel, x, y) (y = 0 for a one-number position).
    pub fn sensor_positions(&self) -> Vec<(u32, f64, f64)> {
        self.sensors
            .iter()
            .filter_map(|(k, v)| {
                let ch = k.trim().parse::<u32>().ok()?;
                Some((ch, *v.first()?, v.get(1).copied().unwrap_or(0.0)))
            })
            .collect()
    }
}

fn invalid(m: String) -> ConfigError {
    ConfigError::Invalid(m)
}

/// The checks of `[onset]`, `[events]` and `[location]`.
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
}

impl Default for EvolutionConfig {
    fn default() -> Self {
        EvolutionConfig {
            window: 50,
            completeness_db: 40.0,
            ib_alpha1: 1.0,
            ib_alpha2: 1.0,
        }
    }
}

pub(super) fn check_evolution(v: &EvolutionConfig) -> Result<(), ConfigError> {
    if v.window < 10 {
        return Err(invalid(format!(
            "evolution.window must be at least 10 sources, got {}",
            v.window
        )));
    }
    if !v.completeness_db.is_finite() {
        return Err(invalid(format!(
            "evolution.completeness_db must be finite, got {}",
            v.completeness_db
        )));
    }
    positive(v.ib_alpha1, "evolution.ib_alpha1")?;
    positive(v.ib_alpha2, "evolution.ib_alpha2")
}

pub(super) fn check(
    o: &OnsetConfig,
    e: &EventsConfig,
    l: &LocationConfig,
) -> Result<(), ConfigError> {
    positive(o.alpha, "onset.alpha")?;
    if o.win == 0 {
        return Err(invalid("onset.win must be ≥ 1 sample".into()));
    }
    match (o.window_before_s, o.window_after_s) {
        (None, None) => {}
        (Some(b), Some(a)) if b.is_finite() && a.is_finite() && b >= 0.0 && a > 0.0 => {}
        _ => {
            return Err(invalid(
                "onset.window_before_s and window_after_s: both ≥ 0 (after > 0), or neither".into(),
            ))
        }
    }
    for (name, v) in [
        ("fhcdt_s", e.fhcdt_s),
        ("dt1x_max_s", e.dt1x_max_s),
        ("dtnx_max_s", e.dtnx_max_s),
    ] {
        if let Some(v) = v {
            if !(v.is_finite() && v >= 0.0) {
                return Err(invalid(format!("events.{name} must be ≥ 0 s, got {v}")));
            }
        }
    }
    let lists = [
        ("guard_channels", &e.guard_channels),
        ("unused_channels", &e.unused_channels),
        ("combined_channels", &e.combined_channels),
    ];
    for (i, (a, la)) in lists.iter().enumerate() {
        for (b, lb) in &lists[i + 1..] {
            if let Some(c) = la.iter().find(|c| lb.contains(c)) {
                return Err(invalid(format!(
                    "events: channel {c} is in both {a} and {b}"
                )));
            }
        }
    }
    if let Some(v) = l.velocity_m_s {
        positive(v, "location.velocity_m_s")?;
    }
    for (k, v) in &l.sensors {
        let ok_key = k.trim().parse::<u32>().is_ok();
        let ok_val = (1..=2).contains(&v.len()) && v.iter().all(|x| x.is_finite());
        if !ok_key || !ok_val {
            return Err(invalid(format!(
                "location.sensors: {k:?} = {v:?}: keys are channel numbers, values [x] or [x, y] in m"
            )));
        }
    }
    let kind = l.kind;
    match &l.zone {
        None => {}
        Some(ZoneSpec::Interval([a, b])) => {
            if !(a.is_finite() && b.is_finite() && a < b) {
                return Err(invalid(format!(
                    "location.zone = [{a}, {b}]: need x_min < x_max"
                )));
            }
            if kind == Some(LocationKind::Planar) {
                return Err(invalid(
                    "location.zone: planar location needs a polygon [[x, y], …]".into(),
                ));
            }
        }
        Some(ZoneSpec::Polygon(p)) => {
            if p.len() < 3 || p.iter().flatten().any(|v| !v.is_finite()) {
                return Err(invalid(
                    "location.zone: a polygon needs at least three finite corners".into(),
                ));
            }
            if kind == Some(LocationKind::Linear) {
                return Err(invalid(
                    "location.zone: linear location needs an interval [x_min, x_max]".into(),
                ));
            }
        }
    }
    if kind.is_some() || !l.sensors.is_empty() {
        let n = l.sensors.len();
        let need = match kind {
            Some(LocationKind::Planar) => 3,
            _ => 2,
        };
        if n < need || l.velocity_m_s.is_none() || kind.is_none() {
            return Err(invalid(format!(
                "location: kind, velocity_m_s and at least {need} sensors go together (got kind {kind:?}, {n} sensors, velocity {:?})",
                l.velocity_m_s
            )));
        }
    }
    if l.max_iterations == 0 {
        return Err(invalid("location.max_iterations must be ≥ 1".into()));
    }
    Ok(())
}
