//! `[events]` (the event builder) and `[location]` (sensors, velocity, zone): the events
//! room's settings and their checks. A key left out is taken from a Vallen `.vaex` beside
//! the recording when there is one (see [`super::setup`]).

use crate::dsp::settings::Picker;
use crate::model::LocationKind;
use crate::util::Checked;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// What the events step reads of a checked pipeline: the builder, the location, which
/// picker gives the arrival times, and the tables' row-group size.
#[derive(Debug, Clone, PartialEq)]
pub struct EventsSettings {
    pub events: EventsConfig,
    pub location: LocationConfig,
    pub picker: Picker,
    pub row_group_rows: usize,
}

/// What is wrong with `[events]` or `[location]`: each variant names the key.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EventsSettingsError {
    #[error("events.{key} must be ≥ 0 s, got {value}")]
    Time { key: &'static str, value: f64 },
    #[error("events: channel {channel} is in both {a} and {b}")]
    ChannelTwice {
        channel: u32,
        a: &'static str,
        b: &'static str,
    },
    #[error("location.velocity_m_s must be > 0, got {0}")]
    Velocity(f64),
    #[error("location.sensors: {key:?} = {value:?}: keys are channel numbers, values [x] or [x, y] in m")]
    Sensor { key: String, value: Vec<f64> },
    #[error("location.zone = [{0}, {1}]: need x_min < x_max")]
    Interval(f64, f64),
    #[error("location.zone: planar location needs a polygon [[x, y], …]")]
    PlanarInterval,
    #[error("location.zone: a polygon needs at least three finite corners")]
    Polygon,
    #[error("location.zone: linear location needs an interval [x_min, x_max]")]
    LinearPolygon,
    #[error("location: kind, velocity_m_s and at least {need} sensors go together (got kind {kind:?}, {sensors} sensors, velocity {velocity:?})")]
    Incomplete {
        need: usize,
        kind: Option<LocationKind>,
        sensors: usize,
        velocity: Option<f64>,
    },
    #[error("location.max_iterations must be ≥ 1")]
    Iterations,
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

impl EventsConfig {
    /// The checks serde cannot express.
    pub fn check(self) -> Result<Checked<EventsConfig>, EventsSettingsError> {
        for (key, v) in [
            ("fhcdt_s", self.fhcdt_s),
            ("dt1x_max_s", self.dt1x_max_s),
            ("dtnx_max_s", self.dtnx_max_s),
        ] {
            if let Some(value) = v {
                if !(value.is_finite() && value >= 0.0) {
                    return Err(EventsSettingsError::Time { key, value });
                }
            }
        }
        let lists = [
            ("guard_channels", &self.guard_channels),
            ("unused_channels", &self.unused_channels),
            ("combined_channels", &self.combined_channels),
        ];
        for (i, (a, la)) in lists.iter().enumerate() {
            for (b, lb) in &lists[i + 1..] {
                if let Some(c) = la.iter().find(|c| lb.contains(c)) {
                    return Err(EventsSettingsError::ChannelTwice { channel: *c, a, b });
                }
            }
        }
        Ok(Checked::new(self))
    }
}

impl LocationConfig {
    /// The checks serde cannot express.
    pub fn check(self) -> Result<Checked<LocationConfig>, EventsSettingsError> {
        if let Some(v) = self.velocity_m_s {
            if !(v.is_finite() && v > 0.0) {
                return Err(EventsSettingsError::Velocity(v));
            }
        }
        for (k, v) in &self.sensors {
            let ok_key = k.trim().parse::<u32>().is_ok();
            let ok_val = (1..=2).contains(&v.len()) && v.iter().all(|x| x.is_finite());
            if !ok_key || !ok_val {
                return Err(EventsSettingsError::Sensor {
                    key: k.clone(),
                    value: v.clone(),
                });
            }
        }
        let kind = self.kind;
        match &self.zone {
            None => {}
            Some(ZoneSpec::Interval([a, b])) => {
                if !(a.is_finite() && b.is_finite() && a < b) {
                    return Err(EventsSettingsError::Interval(*a, *b));
                }
                if kind == Some(LocationKind::Planar) {
                    return Err(EventsSettingsError::PlanarInterval);
                }
            }
            Some(ZoneSpec::Polygon(p)) => {
                if p.len() < 3 || p.iter().flatten().any(|v| !v.is_finite()) {
                    return Err(EventsSettingsError::Polygon);
                }
                if kind == Some(LocationKind::Linear) {
                    return Err(EventsSettingsError::LinearPolygon);
                }
            }
        }
        if kind.is_some() || !self.sensors.is_empty() {
            let n = self.sensors.len();
            let need = match kind {
                Some(LocationKind::Planar) => 3,
                _ => 2,
            };
            if n < need || self.velocity_m_s.is_none() || kind.is_none() {
                return Err(EventsSettingsError::Incomplete {
                    need,
                    kind,
                    sensors: n,
                    velocity: self.velocity_m_s,
                });
            }
        }
        if self.max_iterations == 0 {
            return Err(EventsSettingsError::Iterations);
        }
        Ok(Checked::new(self))
    }
}
