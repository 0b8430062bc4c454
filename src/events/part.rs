//! The events step of one experiment's part: read its hits (and the features' arrival
//! times), build the events, locate them, write `events.parquet`, and fill `event`,
//! `event_first` and `zone` of `hits.parquet` and `features.parquet`.

use super::builder::{self, Fate, HitIn};
use super::locate::{self, Arrival, Status};
use super::settings::EventsSettings;
use super::setup::{self, Setup};
use super::table::{events_table, EventRow};
use super::{EventsError, EventsSummary};
use crate::dsp::settings::Picker;
use crate::model::columns as cols;
use crate::model::ChannelRole;
use crate::store::{TableScan, TableSchema, TableWriter};
use arrow::array::{ArrayRef, BooleanArray, Int64Array, StringArray};
use std::collections::{BTreeSet, HashMap};
use std::path::Path;
use std::sync::Arc;

/// Where one part's tables are.
pub struct PartTables<'a> {
    pub experiment: &'a str,
    pub hits: &'a Path,
    /// With its schema (the features table's depends on the configuration); None for a
    /// waveforms job.
    pub features: Option<(&'a Path, TableSchema)>,
    pub events: &'a Path,
    /// The Vallen setup file beside the recording, if any.
    pub vaex: Option<&'a Path>,
}

/// Run the events step on one part.
pub fn run_part(p: &PartTables, cfg: &EventsSettings) -> Result<EventsSummary, EventsError> {
    run_part_after(p, cfg, 0, &mut BTreeSet::new(), None)
}

/// Run the events step on one part of an experiment read in parts (`aepipe watch`), cut
/// where no event can span the cut: its events are numbered on from `events_before`, and
/// the setup (whether events are built at all) counts the channels of the parts before
/// (`channels`, which this part's are added to); `next_hit` (time, channel), the hit after
/// the part if one is known, closes its last event as it will in the whole experiment.
pub fn run_part_after(
    p: &PartTables,
    cfg: &EventsSettings,
    events_before: u64,
    channels: &mut BTreeSet<u32>,
    next_hit: Option<(f64, u32)>,
) -> Result<EventsSummary, EventsError> {
    let store = |e| EventsError::Store(Box::new(e));
    // The hits: key, time, status and the link to their transient.
    let h = TableScan::open(p.hits).map_err(store)?;
    let df = h
        .columns(&[
            cols::CHANNEL.name,
            cols::HIT.name,
            cols::TIME_S.name,
            cols::STATUS.name,
            cols::TRANSIENT.name,
        ])
        .map_err(store)?;
    let ch: Vec<u32> = h
        .i32s(&df, cols::CHANNEL)
        .map_err(store)?
        .into_iter()
        .map(|v| v.unwrap_or(0) as u32)
        .collect();
    let hit_no: Vec<i64> = h
        .i64s(&df, cols::HIT)
        .map_err(store)?
        .into_iter()
        .map(|v| v.unwrap_or(0))
        .collect();
    let time = h.floats(&df, cols::TIME_S).map_err(store)?;
    let status: Vec<i64> = h
        .i64s(&df, cols::STATUS)
        .map_err(store)?
        .into_iter()
        .map(|v| v.unwrap_or(0))
        .collect();
    let transient: Vec<Option<i64>> = h.i64s(&df, cols::TRANSIENT).map_err(store)?;
    let n = ch.len();

    // The features: their key and arrival time (null without a picker).
    let feats = match &p.features {
        Some((path, _)) => {
            let f = TableScan::open(path).map_err(store)?;
            let df = f
                .columns(&[cols::CHANNEL.name, cols::HIT.name, cols::ARRIVAL_S.name])
                .map_err(store)?;
            let fch = f.i32s(&df, cols::CHANNEL).map_err(store)?;
            let fhit = f.i64s(&df, cols::HIT).map_err(store)?;
            let arr = f.floats(&df, cols::ARRIVAL_S).map_err(store)?;
            Some((fch, fhit, arr))
        }
        None => None,
    };
    // (channel, transient) → features row.
    let feat_row: HashMap<(u32, i64), usize> = feats
        .as_ref()
        .map(|(c, hh, _)| {
            c.iter()
                .zip(hh)
                .enumerate()
                .filter_map(|(i, (c, hh))| Some(((c.map(|v| v as u32)?, (*hh)?), i)))
                .collect()
        })
        .unwrap_or_default();

    let vaex = match p.vaex {
        Some(path) => match crate::ingest::vallen::vaex::read(path) {
            Ok(v) => Some((path.display().to_string(), v)),
            Err(e) => return Err(EventsError::Vaex(path.display().to_string(), e.0)),
        },
        None => None,
    };
    channels.extend(ch.iter().copied());
    let s: Setup = setup::resolve(
        &cfg.events,
        &cfg.location,
        vaex.as_ref().map(|(p, v)| (p.as_str(), v)),
        channels,
    );
    let use_picker = cfg.picker != Picker::None && feats.is_some();
    let mut summary = EventsSummary::new(p.experiment, &s, use_picker, n as u64);

    let table = events_table();
    let mut w =
        TableWriter::create(p.events, table.schema(), &[], cfg.row_group_rows).map_err(store)?;
    if !s.enabled {
        w.finish().map_err(store)?;
        return Ok(summary);
    }

    // Hits in time order (stable: equal times keep the table's order); no time, no event.
    let mut order: Vec<usize> = (0..n)
        .filter(|&i| time[i].is_some_and(f64::is_finite))
        .collect();
    summary.no_time = (n - order.len()) as u64;
    order.sort_by(|&a, &b| {
        time[a]
            .unwrap()
            .total_cmp(&time[b].unwrap())
            .then(a.cmp(&b))
    });
    let input: Vec<HitIn> = order
        .iter()
        .map(|&i| HitIn {
            index: i,
            time_s: time[i].unwrap(),
            channel: ch[i],
            status: status[i],
        })
        .collect();
    let (mut events, fates) = builder::build(&input, &s.params).expect("sorted by time above");
    if let (Some((t, c)), Some(e)) = (next_hit, events.last_mut()) {
        e.close_by(t, c, &s.params);
    }

    // Per hit row: event (1-based), whether it opened it, and the zone.
    let mut ev_of: Vec<Option<i64>> = vec![None; n];
    let mut first: Vec<Option<bool>> = vec![Some(false); n];
    let mut zone: Vec<Option<&'static str>> = vec![None; n];
    for (h, f) in input.iter().zip(&fates) {
        match f {
            Fate::InEvent(_) => summary.hits_in_events += 1,
            Fate::Unused => summary.unused += 1,
            Fate::Duplicate => summary.duplicates += 1,
            Fate::NotStarted { by_guard: false } => summary.not_started += 1,
            Fate::Guard | Fate::NotStarted { by_guard: true } => {
                summary.guard_suppressed += 1;
                zone[h.index] = Some("guard");
            }
        }
    }
    let arrival_of = |i: usize| -> f64 {
        if use_picker {
            if let (Some(t), Some((_, _, arr))) = (transient[i], feats.as_ref()) {
                if let Some(&r) = feat_row.get(&(ch[i], t)) {
                    if let Some(a) = arr[r].filter(|a| a.is_finite()) {
                        return a;
                    }
                }
            }
        }
        time[i].unwrap_or(f64::NAN)
    };
    for (k, e) in events.iter().enumerate() {
        let number = events_before as i64 + k as i64 + 1;
        let t0 = e.time_s();
        for (j, hh) in e.hits.iter().enumerate() {
            ev_of[hh.index] = Some(number);
            first[hh.index] = Some(j == 0);
        }
        let mut row = EventRow {
            experiment: p.experiment.to_string(),
            event: number as u64,
            time_s: t0,
            first_hit_channel: e.first_hit_channel(),
            channels: e.hits.iter().map(|h| h.channel as i32).collect(),
            hits: e.hits.iter().map(|h| hit_no[h.index]).collect(),
            dt_to_first_s: e.hits[1..].iter().map(|h| h.time_s - t0).collect(),
            close_reason: e.close.as_str(),
            arrival: if use_picker { "arrival_s" } else { "hit_time" },
            ..Default::default()
        };
        if e.hits.len() == 1 {
            summary.single_hit_events += 1;
        }
        if let Some(l) = &s.locator {
            // Guard hits are left out of location; a combined channel joined as normal.
            let mut a: Vec<Arrival> = e
                .hits
                .iter()
                .filter(|h| s.params.role(h.channel) != ChannelRole::Guard)
                .filter_map(|h| {
                    let &(x, y) = l.sensors.get(&h.channel)?;
                    let t = arrival_of(h.index);
                    t.is_finite().then_some(Arrival { x, y, t })
                })
                .collect();
            a.sort_by(|p, q| p.t.total_cmp(&q.t));
            match locate::locate(l.kind, &a, l.velocity_m_s, l.max_iterations) {
                Some(loc) => {
                    let located = loc.status != Status::TooFewHits;
                    row.location_status = Some(loc.status.as_str());
                    row.location_iterations = Some(loc.iterations as i32);
                    if located {
                        row.x_m = Some(loc.x);
                        row.y_m = loc.y;
                        row.lucy_m = Some(loc.lucy);
                        summary.located += 1;
                        if loc.status == Status::BeyondSensor {
                            summary.beyond_sensor += 1;
                        }
                        if let Some(z) = &l.zone {
                            let inside = locate::in_zone(z, loc.x, loc.y.unwrap_or(0.0));
                            row.zone = Some(if inside { "inside" } else { "outside" });
                            if inside {
                                summary.inside += 1;
                            } else {
                                summary.outside += 1;
                            }
                        }
                    } else {
                        summary.not_located += 1;
                    }
                }
                None => {
                    row.location_status = Some(Status::TooFewHits.as_str());
                    summary.not_located += 1;
                }
            }
            for hh in &e.hits {
                if row.zone.is_some() {
                    zone[hh.index] = row.zone;
                }
            }
        }
        w.push(table.row(row)).map_err(store)?;
    }
    summary.events = events.len() as u64;
    w.finish().map_err(store)?;

    // Fill the hit tables.
    let rg = cfg.row_group_rows;
    let columns = |ev: Vec<Option<i64>>,
                   fi: Vec<Option<bool>>,
                   zo: Vec<Option<&str>>|
     -> [(&'static str, ArrayRef); 3] {
        let [e, f, z] = crate::store::table::EVENT_COLUMNS;
        [
            (e, Arc::new(Int64Array::from(ev)) as ArrayRef),
            (f, Arc::new(BooleanArray::from(fi)) as ArrayRef),
            (z, Arc::new(StringArray::from(zo)) as ArrayRef),
        ]
    };
    if let (Some((path, schema)), Some((fch, fhit, _))) = (&p.features, &feats) {
        // Each features row takes its hit's values (through hits.transient).
        let hit_row: HashMap<(u32, i64), usize> = (0..n)
            .filter_map(|i| Some(((ch[i], transient[i]?), i)))
            .collect();
        let m = fch.len();
        let (mut fe, mut ff, mut fz) = (vec![None; m], vec![Some(false); m], vec![None; m]);
        for r in 0..m {
            let key = fch[r].zip(fhit[r]).map(|(c, hh)| (c as u32, hh));
            if let Some(&i) = key.and_then(|k| hit_row.get(&k)) {
                fe[r] = ev_of[i];
                ff[r] = first[i];
                fz[r] = zone[i];
            }
        }
        crate::store::rewrite::replace_columns(path, schema, &columns(fe, ff, fz), rg)
            .map_err(store)?;
    }
    // The hits' own columns last, moved rather than copied.
    crate::store::rewrite::replace_columns(
        p.hits,
        &crate::store::hits_table().schema(),
        &columns(ev_of, first, zone),
        rg,
    )
    .map_err(store)?;
    Ok(summary)
}
