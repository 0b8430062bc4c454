//! The VisualAE setup file (`.vaex`, XML) beside a `.pridb`: what it says about the event
//! builder and location, for the events step.
//!
//! Read: the first `<LocationProcessor>` that holds sensor positions —
//! * `<Location Velocity="5">`: km/s (= mm/µs). vallenae's location example reads it so
//!   (× 1e3 → m/s), and with that the steel-plate example's event locates on the plate;
//!   `UserUnit="cm"` is the unit VisualAE *displays*, not the stored one.
//! * `<ChannelGroup LocationType="LSetFuzzy2D">` and its `<ChannelPos Chan X Y>`: metres (the
//!   plate's sensors sit at 0.15 and 0.6, a 45 cm square, as vallenae's example uses them).
//! * `<EventBuilder DT1XMax DTNXMax FHCDT AllowDuplicates>`: milliseconds, and its
//!   `<Channel Chan Function>`: 0 unused, 1 normal, 2 guard, 3 combined (vallenae's
//!   `ChannelFunction` numbering, which it says matches VisualAE's dialog).
//!
//! A file larger than [`MAX_VAEX_BYTES`] or not XML is an error for the caller to report;
//! an unknown element or attribute is ignored (a setup holds far more than this).

use crate::model::{ChannelRole, LocationKind};
use quick_xml::events::{BytesStart, Event};
use quick_xml::Reader;
use std::path::Path;

/// Setup files seen are 5–13 kB; a bound well above that, checked before reading.
pub const MAX_VAEX_BYTES: u64 = 16 << 20;

/// The `<EventBuilder>` of a setup, in seconds.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct VaexEventBuilder {
    pub dt1x_max_s: Option<f64>,
    pub dtnx_max_s: Option<f64>,
    pub fhcdt_s: Option<f64>,
    pub allow_duplicates: Option<bool>,
    pub channels: Vec<(u32, ChannelRole)>,
}

/// The `<Location>` of a setup, in SI units.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct VaexLocation {
    pub velocity_m_s: Option<f64>,
    pub kind: Option<LocationKind>,
    /// (channel, x m, y m).
    pub sensors: Vec<(u32, f64, f64)>,
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct VaexSetup {
    pub event_builder: Option<VaexEventBuilder>,
    pub location: Option<VaexLocation>,
}

/// A setup file that cannot be read: too large, unreadable or not XML.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct VaexError(pub String);

/// The `.vaex` beside a Vallen file (same stem), if there is one.
pub fn beside(path: &Path) -> Option<std::path::PathBuf> {
    let p = path.with_extension("vaex");
    p.is_file().then_some(p)
}

fn attr(e: &BytesStart, name: &str) -> Option<String> {
    e.attributes()
        .flatten()
        .find(|a| a.key.as_ref() == name.as_bytes())
        .and_then(|a| a.unescape_value().ok().map(|v| v.trim().to_string()))
}

fn num(e: &BytesStart, name: &str) -> Option<f64> {
    attr(e, name)?.parse::<f64>().ok().filter(|v| v.is_finite())
}

fn role(code: &str) -> Option<ChannelRole> {
    match code {
        "0" => Some(ChannelRole::Unused),
        "1" => Some(ChannelRole::Normal),
        "2" => Some(ChannelRole::Guard),
        "3" => Some(ChannelRole::Combined),
        _ => None,
    }
}

fn kind(location_type: &str) -> Option<LocationKind> {
    let t = location_type.to_ascii_lowercase();
    if t.contains("2d") || t.contains("planar") {
        Some(LocationKind::Planar)
    } else if t.contains("1d") || t.contains("linear") {
        Some(LocationKind::Linear)
    } else {
        None
    }
}

/// Read a `.vaex`.
pub fn read(path: &Path) -> Result<VaexSetup, VaexError> {
    let size = std::fs::metadata(path)
        .map_err(|e| VaexError(e.to_string()))?
        .len();
    if size > MAX_VAEX_BYTES {
        return Err(VaexError(format!(
            "{size} bytes, more than the {MAX_VAEX_BYTES} a setup file may have"
        )));
    }
    let bytes = std::fs::read(path).map_err(|e| VaexError(e.to_string()))?;
    let text = String::from_utf8_lossy(&bytes);
    parse(text.trim_start_matches('\u{feff}'))
}

/// Parse the text of a `.vaex`.
pub fn parse(text: &str) -> Result<VaexSetup, VaexError> {
    let mut r = Reader::from_str(text);
    let mut out = VaexSetup::default();
    // Inside the first LocationProcessor that turns out to have sensor positions.
    let mut depth_in_processor: Option<usize> = None;
    let mut depth = 0usize;
    let mut loc = VaexLocation::default();
    let mut eb: Option<VaexEventBuilder> = None;
    let mut in_eb = false;
    loop {
        let ev = r
            .read_event()
            .map_err(|e| VaexError(format!("not XML at byte {}: {e}", r.buffer_position())))?;
        let (e, empty) = match &ev {
            Event::Start(e) => (Some(e), false),
            Event::Empty(e) => (Some(e), true),
            Event::End(end) => {
                depth = depth.saturating_sub(1);
                let name = end.name();
                if name.as_ref() == b"EventBuilder" {
                    in_eb = false;
                }
                if name.as_ref() == b"LocationProcessor" && depth_in_processor == Some(depth) {
                    depth_in_processor = None;
                    if !loc.sensors.is_empty() && out.location.is_none() {
                        out.location = Some(std::mem::take(&mut loc));
                        out.event_builder = eb.take();
                        break;
                    }
                    if out.event_builder.is_none() {
                        out.event_builder = eb.take();
                    }
                    loc = VaexLocation::default();
                }
                continue;
            }
            Event::Eof => break,
            _ => continue,
        };
        let e = e.expect("start or empty");
        let name = e.name();
        match name.as_ref() {
            b"LocationProcessor" if depth_in_processor.is_none() => {
                depth_in_processor = Some(depth);
            }
            b"Location" if depth_in_processor.is_some() => {
                loc.velocity_m_s = num(e, "Velocity").map(|v| v * 1e3);
            }
            b"ChannelGroup" if depth_in_processor.is_some() => {
                if let Some(t) = attr(e, "LocationType") {
                    loc.kind = loc.kind.or(kind(&t));
                }
            }
            b"ChannelPos" if depth_in_processor.is_some() => {
                if let (Some(c), Some(x)) = (attr(e, "Chan"), num(e, "X")) {
                    if let Ok(c) = c.parse::<u32>() {
                        loc.sensors.push((c, x, num(e, "Y").unwrap_or(0.0)));
                    }
                }
            }
            b"EventBuilder" if depth_in_processor.is_some() => {
                let ms = |k: &str| num(e, k).filter(|v| *v >= 0.0).map(|v| v * 1e-3);
                eb = Some(VaexEventBuilder {
                    dt1x_max_s: ms("DT1XMax"),
                    dtnx_max_s: ms("DTNXMax"),
                    fhcdt_s: ms("FHCDT"),
                    allow_duplicates: attr(e, "AllowDuplicates")
                        .map(|v| v.eq_ignore_ascii_case("true")),
                    channels: Vec::new(),
                });
                in_eb = !empty;
            }
            b"Channel" if in_eb => {
                if let (Some(c), Some(f)) = (attr(e, "Chan"), attr(e, "Function")) {
                    if let (Ok(c), Some(role)) = (c.parse::<u32>(), role(&f)) {
                        if let Some(eb) = eb.as_mut() {
                            eb.channels.push((c, role));
                        }
                    }
                }
            }
            _ => {}
        }
        if !empty {
            depth += 1;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_builder_location_and_roles() {
        let x = r#"<?xml version="1.0"?><Root><Other><Channel Chan="9" Function="2"/></Other>
        <LocationProcessor ID="5"><Location UserUnit="cm" Velocity="3.2">
        <ChannelGroups><ChannelGroup LocationType="LSetFuzzy2D">
        <ChannelPos Chan="1" X="0.6" Y="0.5"/><ChannelPos Chan="2" X="0.1" Y="0.2"/>
        </ChannelGroup></ChannelGroups></Location>
        <EventBuilder DT1XMax="0.5" DTNXMax="0.25" FHCDT="1" AllowDuplicates="True"><Channels>
        <Channel Chan="1" Function="1"/><Channel Chan="2" Function="2"/><Channel Chan="3" Function="0"/>
        </Channels></EventBuilder></LocationProcessor></Root>"#;
        let s = parse(x).unwrap();
        let l = s.location.unwrap();
        assert_eq!(l.velocity_m_s, Some(3200.0));
        assert_eq!(l.kind, Some(LocationKind::Planar));
        assert_eq!(l.sensors, vec![(1, 0.6, 0.5), (2, 0.1, 0.2)]);
        let e = s.event_builder.unwrap();
        assert_eq!(e.dt1x_max_s, Some(0.5e-3));
        assert_eq!(e.dtnx_max_s, Some(0.25e-3));
        assert_eq!(e.fhcdt_s, Some(1e-3));
        assert_eq!(e.allow_duplicates, Some(true));
        // The channel outside the EventBuilder is not one of its roles.
        assert_eq!(
            e.channels,
            vec![
                (1, ChannelRole::Normal),
                (2, ChannelRole::Guard),
                (3, ChannelRole::Unused)
            ]
        );
    }

    #[test]
    fn broken_or_empty_setups() {
        assert!(parse("<a><b></a>").is_err());
        assert_eq!(parse("<Root/>").unwrap(), VaexSetup::default());
    }
}
