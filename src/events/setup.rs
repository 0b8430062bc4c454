//! The effective event-builder and location setup of one experiment: `[events]` and
//! `[location]` of the pipeline TOML first, then a Vallen `.vaex` beside the recording, then
//! the defaults; and whether events are built at all.

use super::builder::Params;
use super::settings::{EventsConfig, LocationConfig, ZoneSpec};
use crate::ingest::vallen::vaex::{VaexEventBuilder, VaexLocation, VaexSetup};
use crate::model::{ChannelRole, LocationKind};
use std::collections::{BTreeMap, BTreeSet};

/// DT1X when neither the TOML, nor a `.vaex`, nor a sensor layout says: 100 µs (a paper
/// strip's sensors are centimetres apart: tens of µs at plate-wave speeds).
pub const DEFAULT_DT1X_S: f64 = 100e-6;

/// Where sources are located.
#[derive(Debug, Clone, PartialEq)]
pub struct Locator {
    pub kind: LocationKind,
    pub velocity_m_s: f64,
    /// (x, y) by channel, m.
    pub sensors: BTreeMap<u32, (f64, f64)>,
    pub zone: Option<ZoneSpec>,
    pub max_iterations: usize,
}

/// The setup, and where each value came from (`toml`, `vaex: FILE`, `default`).
#[derive(Debug, Clone, PartialEq)]
pub struct Setup {
    pub enabled: bool,
    /// Why events are (not) built.
    pub why: String,
    pub params: Params,
    pub locator: Option<Locator>,
    pub provenance: BTreeMap<String, String>,
}

/// Resolve the setup for an experiment whose hits are on `channels`.
pub fn resolve(
    ev: &EventsConfig,
    loc: &LocationConfig,
    vaex: Option<(&str, &VaexSetup)>,
    channels: &BTreeSet<u32>,
) -> Setup {
    let mut prov = BTreeMap::new();
    // Where a value from the .vaex came from (only used when there is one).
    let vaex_src = vaex.map(|(p, _)| format!("vaex: {p}")).unwrap_or_default();
    let veb = vaex.and_then(|(_, v)| v.event_builder.as_ref());
    let vloc = vaex.and_then(|(_, v)| v.location.as_ref());

    let locator = resolve_locator(loc, vloc, &vaex_src, &mut prov);

    // DT1X: TOML, .vaex, the sensor layout, or the fixed default.
    let dt1x_default = default_dt1x(locator.as_ref());
    let mut pick =
        |key: &str, toml, vaex_v, default| choose(&mut prov, key, toml, vaex_v, &vaex_src, default);
    let dt1x = pick(
        "dt1x_max_s",
        ev.dt1x_max_s,
        veb.and_then(|e| e.dt1x_max_s),
        dt1x_default,
    );
    let dtnx = pick(
        "dtnx_max_s",
        ev.dtnx_max_s,
        veb.and_then(|e| e.dtnx_max_s),
        (dt1x, "default: dt1x_max_s".into()),
    );
    let fhcdt = pick(
        "fhcdt_s",
        ev.fhcdt_s,
        veb.and_then(|e| e.fhcdt_s),
        (dt1x, "default: dt1x_max_s".into()),
    );
    let allow_duplicates = choose(
        &mut prov,
        "allow_duplicates",
        ev.allow_duplicates,
        veb.and_then(|e| e.allow_duplicates),
        &vaex_src,
        (false, "default: false".into()),
    );
    let roles = channel_roles(ev, veb, &vaex_src, &mut prov);
    let mut params = Params::new(fhcdt, dt1x, dtnx);
    params.allow_duplicates = allow_duplicates;
    params.roles = roles;

    let used = channels
        .iter()
        .filter(|c| params.role(**c) != ChannelRole::Unused)
        .count();
    let (enabled, why) = match ev.enabled {
        Some(true) => (true, "[events] enabled = true".to_string()),
        Some(false) => (false, "[events] enabled = false".to_string()),
        None if used >= 2 => (true, format!("{used} channels")),
        None => (false, format!("{used} channel(s): events need two or more")),
    };
    Setup {
        enabled,
        why,
        params,
        locator,
        provenance: prov,
    }
}

/// Where sources are located: the TOML's geometry, else the .vaex's; its origin into `prov`.
fn resolve_locator(
    loc: &LocationConfig,
    vloc: Option<&VaexLocation>,
    vaex_src: &str,
    prov: &mut BTreeMap<String, String>,
) -> Option<Locator> {
    // Location: the TOML's when it names a kind, else the .vaex's.
    let geometry = if let (Some(kind), Some(v)) = (loc.kind, loc.velocity_m_s) {
        let sensors = loc
            .sensor_positions()
            .into_iter()
            .map(|(c, x, y)| (c, (x, y)));
        Some((kind, v, sensors.collect(), "toml".to_string()))
    } else {
        vloc.and_then(|l| {
            let v = l.velocity_m_s?;
            if l.sensors.len() < 2 {
                return None;
            }
            let kind = l.kind.unwrap_or(if l.sensors.len() >= 3 {
                LocationKind::Planar
            } else {
                LocationKind::Linear
            });
            let sensors = l.sensors.iter().map(|&(c, x, y)| (c, (x, y)));
            Some((kind, v, sensors.collect(), vaex_src.to_string()))
        })
    };
    geometry.map(|(kind, velocity_m_s, sensors, src)| {
        prov.insert("location".into(), src);
        Locator {
            kind,
            velocity_m_s,
            sensors,
            zone: loc.zone.clone(),
            max_iterations: loc.max_iterations,
        }
    })
}

/// DT1X's default and why: 2 × the sensors' span / velocity, else [`DEFAULT_DT1X_S`].
fn default_dt1x(locator: Option<&Locator>) -> (f64, String) {
    let span = locator.map(|l| {
        let p: Vec<(f64, f64)> = l.sensors.values().copied().collect();
        let mut d = 0.0f64;
        for (i, a) in p.iter().enumerate() {
            for b in &p[i + 1..] {
                d = d.max((a.0 - b.0).hypot(a.1 - b.1));
            }
        }
        (d, l.velocity_m_s)
    });
    match span {
        Some((d, v)) if d > 0.0 => (
            2.0 * d / v,
            "default: 2 × largest sensor distance / velocity".to_string(),
        ),
        _ => (
            DEFAULT_DT1X_S,
            format!("default: {} µs", DEFAULT_DT1X_S * 1e6),
        ),
    }
}

/// The channels' roles from the TOML's lists, else the .vaex's; their origin into `prov`.
fn channel_roles(
    ev: &EventsConfig,
    veb: Option<&VaexEventBuilder>,
    vaex_src: &str,
    prov: &mut BTreeMap<String, String>,
) -> BTreeMap<u32, ChannelRole> {
    // Roles: the TOML's lists when any is given, else the .vaex's channel functions.
    let mut roles = BTreeMap::new();
    let toml_roles = !(ev.guard_channels.is_empty()
        && ev.unused_channels.is_empty()
        && ev.combined_channels.is_empty());
    if toml_roles {
        for (list, role) in [
            (&ev.guard_channels, ChannelRole::Guard),
            (&ev.unused_channels, ChannelRole::Unused),
            (&ev.combined_channels, ChannelRole::Combined),
        ] {
            for c in list {
                roles.insert(*c, role);
            }
        }
        prov.insert("channel_roles".into(), "toml".into());
    } else if let Some(e) = veb.filter(|e| !e.channels.is_empty()) {
        for &(c, r) in &e.channels {
            roles.insert(c, r);
        }
        prov.insert("channel_roles".into(), vaex_src.to_string());
    } else {
        prov.insert(
            "channel_roles".into(),
            "default: every channel normal".into(),
        );
    }
    roles
}

/// The TOML's value, else the .vaex's, else the default; where it came from goes into `prov`
/// under `key`.
fn choose<T>(
    prov: &mut BTreeMap<String, String>,
    key: &str,
    toml: Option<T>,
    vaex: Option<T>,
    vaex_src: &str,
    default: (T, String),
) -> T {
    let (v, src) = match (toml, vaex) {
        (Some(v), _) => (v, "toml".to_string()),
        (None, Some(v)) => (v, vaex_src.to_string()),
        (None, None) => default,
    };
    prov.insert(key.into(), src);
    v
}
