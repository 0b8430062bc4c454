//! From hits to sources: events, location and zones.
//!
//! A source in a specimen with two or more sensors is heard once per sensor. This room
//! groups the hits of one source into an event (VisualAE's event builder, as vallenae 0.14
//! implements it: [`builder`]), locates the source from the arrival differences (linear on a
//! strip, planar on a sheet: [`locate`]) and tells the gauge section's events from the
//! grips' (the `[location] zone`, guard channels). It runs per experiment after the stream,
//! on the part's tables ([`part::run_part`]), with the setup of the pipeline TOML or of a
//! Vallen `.vaex` ([`setup`]), and writes `events.parquet` ([`table`]).
//!
//! Analysis downstream counts sources, not hits, through `store::SourceRows`: with events
//! built, one hit per event (the one that opened it), and with `[location] exclude_outside`,
//! only the events inside the zone.

pub mod builder;
pub mod locate;
pub mod part;
pub mod settings;
pub mod setup;
pub mod table;

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

pub use part::{run_part, run_part_after, PartTables};
pub use table::{events_table, EventRow};

#[derive(Debug, thiserror::Error)]
pub enum EventsError {
    #[error(transparent)]
    Store(Box<crate::store::StoreError>),
    #[error("{0}: the VisualAE setup is unreadable: {1}")]
    Vaex(String, String),
}

impl crate::util::HasKind for EventsError {
    fn kind(&self) -> crate::util::ErrorKind {
        match self {
            EventsError::Store(e) => e.kind(),
            EventsError::Vaex(..) => crate::util::ErrorKind::Usage,
        }
    }
}

/// What the events step did for one experiment: the setup it used (and where each value
/// came from) and what became of the hits. In `part.json` and `manifest.json`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct EventsSummary {
    pub experiment: String,
    pub enabled: bool,
    /// Why events were (not) built.
    pub why: String,
    pub fhcdt_s: f64,
    pub dt1x_max_s: f64,
    pub dtnx_max_s: f64,
    pub allow_duplicates: bool,
    /// Channels that are not normal, by role.
    pub channel_roles: BTreeMap<String, String>,
    /// `linear, 2500 m/s, 2 sensors`, or null.
    pub location: Option<String>,
    /// Each parameter's source: `toml`, `vaex: FILE` or `default: …`.
    pub sources: BTreeMap<String, String>,
    /// `arrival_s` (the [onset] picker) or `hit_time`.
    pub arrival: String,
    pub hits: u64,
    pub events: u64,
    pub single_hit_events: u64,
    pub hits_in_events: u64,
    /// Hits that could not open an event (within FHCDT, after-timeout flag), not by a guard.
    pub not_started: u64,
    /// Guard hits with no event open, and hits a guard kept from opening one.
    pub guard_suppressed: u64,
    pub duplicates: u64,
    pub unused: u64,
    /// Hits without a time.
    pub no_time: u64,
    pub located: u64,
    pub beyond_sensor: u64,
    pub not_located: u64,
    pub inside: u64,
    pub outside: u64,
}

impl EventsSummary {
    fn new(experiment: &str, s: &setup::Setup, picker: bool, hits: u64) -> EventsSummary {
        let p = &s.params;
        EventsSummary {
            experiment: experiment.to_string(),
            enabled: s.enabled,
            why: s.why.clone(),
            fhcdt_s: p.fhcdt_s,
            dt1x_max_s: p.dt1x_max_s,
            dtnx_max_s: p.dtnx_max_s,
            allow_duplicates: p.allow_duplicates,
            channel_roles: p
                .roles
                .iter()
                .filter(|(_, r)| **r != crate::model::ChannelRole::Normal)
                .map(|(c, r)| (c.to_string(), format!("{r:?}").to_lowercase()))
                .collect(),
            location: s.locator.as_ref().map(|l| {
                format!(
                    "{}, {} m/s, {} sensors",
                    match l.kind {
                        crate::model::LocationKind::Linear => "linear",
                        crate::model::LocationKind::Planar => "planar",
                    },
                    l.velocity_m_s,
                    l.sensors.len()
                )
            }),
            sources: s.provenance.clone(),
            arrival: if picker { "arrival_s" } else { "hit_time" }.into(),
            hits,
            ..Default::default()
        }
    }
}
