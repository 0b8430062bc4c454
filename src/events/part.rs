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
    // The hits: key, time, status and the link to their transient.
    let hits = HitColumns::read(p.hits)?;
    let n = hits.ch.len();

    // The features: their key and arrival time (null without a picker).
    let feats = match &p.features {
        Some((path, _)) => Some(FeatureColumns::read(path)?),
        None => None,
    };
    // (channel, transient) → features row.
    let feat_row: HashMap<(u32, i64), usize> = feats
        .as_ref()
        .map(FeatureColumns::row_by_key)
        .unwrap_or_default();

    let vaex = read_vaex(p.vaex)?;
    channels.extend(hits.ch.iter().copied());
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

    let input = in_time_order(&hits, &mut summary);
    let (mut events, fates) = builder::build(&input, &s.params).expect("sorted by time above");
    if let (Some((t, c)), Some(e)) = (next_hit, events.last_mut()) {
        e.close_by(t, c, &s.params);
    }

    // Per hit row: event (1-based), whether it opened it, and the zone.
    let mut marks = HitMarks::new(n);
    count_fates(&input, &fates, &mut summary, &mut marks.zone);
    let arrivals = Arrivals {
        use_picker,
        hits: &hits,
        feats: feats.as_ref(),
        feat_row,
    };
    for (k, e) in events.iter().enumerate() {
        let number = events_before as i64 + k as i64 + 1;
        for (j, hh) in e.hits.iter().enumerate() {
            marks.event[hh.index] = Some(number);
            marks.first[hh.index] = Some(j == 0);
        }
        let mut row = event_row(p.experiment, number, e, &hits.hit_no, use_picker);
        if e.hits.len() == 1 {
            summary.single_hit_events += 1;
        }
        if let Some(l) = &s.locator {
            locate_event(l, &s.params, e, &arrivals, &mut row, &mut summary);
            for hh in &e.hits {
                if row.zone.is_some() {
                    marks.zone[hh.index] = row.zone;
                }
            }
        }
        w.push(table.row(row)).map_err(store)?;
    }
    summary.events = events.len() as u64;
    w.finish().map_err(store)?;

    // Fill the hit tables.
    fill_hit_tables(p, cfg.row_group_rows, &hits, feats.as_ref(), marks)?;
    Ok(summary)
}

/// Wrap a store error (every table read and write of this step) as an events error.
fn store(e: crate::store::StoreError) -> EventsError {
    EventsError::Store(Box::new(e))
}

/// The hits' columns the step uses: their key, time, status and the link to their
/// transient (a null channel, hit or status read as 0).
struct HitColumns {
    ch: Vec<u32>,
    hit_no: Vec<i64>,
    time: Vec<Option<f64>>,
    status: Vec<i64>,
    transient: Vec<Option<i64>>,
}

impl HitColumns {
    /// Read the columns from `hits.parquet`, once, for building and filling alike.
    fn read(path: &Path) -> Result<HitColumns, EventsError> {
        let h = TableScan::open(path).map_err(store)?;
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
        Ok(HitColumns {
            ch,
            hit_no,
            time,
            status,
            transient,
        })
    }
}

/// The features' columns the step uses: their key (channel, hit = the hit's transient) and
/// arrival time (null without a picker).
struct FeatureColumns {
    ch: Vec<Option<i32>>,
    hit: Vec<Option<i64>>,
    arrival: Vec<Option<f64>>,
}

impl FeatureColumns {
    /// Read the columns from `features.parquet`, for the picked arrivals and the filling.
    fn read(path: &Path) -> Result<FeatureColumns, EventsError> {
        let f = TableScan::open(path).map_err(store)?;
        let df = f
            .columns(&[cols::CHANNEL.name, cols::HIT.name, cols::ARRIVAL_S.name])
            .map_err(store)?;
        let fch = f.i32s(&df, cols::CHANNEL).map_err(store)?;
        let fhit = f.i64s(&df, cols::HIT).map_err(store)?;
        let arr = f.floats(&df, cols::ARRIVAL_S).map_err(store)?;
        Ok(FeatureColumns {
            ch: fch,
            hit: fhit,
            arrival: arr,
        })
    }

    /// (channel, transient) → features row, to find a hit's picked arrival.
    fn row_by_key(&self) -> HashMap<(u32, i64), usize> {
        self.ch
            .iter()
            .zip(&self.hit)
            .enumerate()
            .filter_map(|(i, (c, hh))| Some(((c.map(|v| v as u32)?, (*hh)?), i)))
            .collect()
    }
}

/// Per hit row: event (1-based), whether it opened it, and the zone: what the hit tables'
/// event columns are filled with.
struct HitMarks {
    event: Vec<Option<i64>>,
    first: Vec<Option<bool>>,
    zone: Vec<Option<&'static str>>,
}

impl HitMarks {
    /// `n` hit rows in no event, none first, in no zone (until the building marks them).
    fn new(n: usize) -> HitMarks {
        HitMarks {
            event: vec![None; n],
            first: vec![Some(false); n],
            zone: vec![None; n],
        }
    }
}

/// Read the Vallen setup file beside the recording, if any, with its path for messages.
fn read_vaex(
    vaex: Option<&Path>,
) -> Result<Option<(String, crate::ingest::vallen::vaex::VaexSetup)>, EventsError> {
    Ok(match vaex {
        Some(path) => match crate::ingest::vallen::vaex::read(path) {
            Ok(v) => Some((path.display().to_string(), v)),
            Err(e) => return Err(EventsError::Vaex(path.display().to_string(), e.0)),
        },
        None => None,
    })
}

/// The builder's input: the hits in time order (stable: equal times keep the table's
/// order); no time, no event (counted in `summary.no_time`).
fn in_time_order(hits: &HitColumns, summary: &mut EventsSummary) -> Vec<HitIn> {
    let (n, time) = (hits.ch.len(), &hits.time);
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
    order
        .iter()
        .map(|&i| HitIn {
            index: i,
            time_s: time[i].unwrap(),
            channel: hits.ch[i],
            status: hits.status[i],
        })
        .collect()
}

/// Count what became of each hit in the summary, and mark the guard hits' zone.
fn count_fates(
    input: &[HitIn],
    fates: &[Fate],
    summary: &mut EventsSummary,
    zone: &mut [Option<&'static str>],
) {
    for (h, f) in input.iter().zip(fates) {
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
}

/// The row of event `number` before location: its time, hits and how it closed.
fn event_row(
    experiment: &str,
    number: i64,
    e: &builder::Event,
    hit_no: &[i64],
    use_picker: bool,
) -> EventRow {
    let t0 = e.time_s();
    EventRow {
        experiment: experiment.to_string(),
        event: number as u64,
        time_s: t0,
        first_hit_channel: e.first_hit_channel(),
        channels: e.hits.iter().map(|h| h.channel as i32).collect(),
        hits: e.hits.iter().map(|h| hit_no[h.index]).collect(),
        dt_to_first_s: e.hits[1..].iter().map(|h| h.time_s - t0).collect(),
        close_reason: e.close.as_str(),
        arrival: if use_picker { "arrival_s" } else { "hit_time" },
        ..Default::default()
    }
}

/// Where location takes a hit's arrival time from: with the picker, the finite `arrival_s`
/// of its features row (found through hits.transient); else, or failing that, its hit time.
struct Arrivals<'a> {
    use_picker: bool,
    hits: &'a HitColumns,
    feats: Option<&'a FeatureColumns>,
    /// (channel, transient) → features row.
    feat_row: HashMap<(u32, i64), usize>,
}

impl Arrivals<'_> {
    /// The arrival time of hit row `i` (NaN without a time).
    fn of(&self, i: usize) -> f64 {
        let (hits, use_picker) = (self.hits, self.use_picker);
        if use_picker {
            if let (Some(t), Some(f)) = (hits.transient[i], self.feats) {
                if let Some(&r) = self.feat_row.get(&(hits.ch[i], t)) {
                    if let Some(a) = f.arrival[r].filter(|a| a.is_finite()) {
                        return a;
                    }
                }
            }
        }
        hits.time[i].unwrap_or(f64::NAN)
    }
}

/// Locate one event from its hits' arrivals, recording its position, status and zone in
/// its row and the outcome in the summary's counts.
fn locate_event(
    l: &setup::Locator,
    params: &builder::Params,
    e: &builder::Event,
    arrivals: &Arrivals,
    row: &mut EventRow,
    summary: &mut EventsSummary,
) {
    // Guard hits are left out of location; a combined channel joined as normal.
    let mut a: Vec<Arrival> = e
        .hits
        .iter()
        .filter(|h| params.role(h.channel) != ChannelRole::Guard)
        .filter_map(|h| {
            let &(x, y) = l.sensors.get(&h.channel)?;
            let t = arrivals.of(h.index);
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
}

/// The hit tables' event columns (`event`, `event_first`, `zone`) as arrays.
fn event_columns(
    ev: Vec<Option<i64>>,
    fi: Vec<Option<bool>>,
    zo: Vec<Option<&str>>,
) -> [(&'static str, ArrayRef); 3] {
    let [e, f, z] = crate::store::table::EVENT_COLUMNS;
    [
        (e, Arc::new(Int64Array::from(ev)) as ArrayRef),
        (f, Arc::new(BooleanArray::from(fi)) as ArrayRef),
        (z, Arc::new(StringArray::from(zo)) as ArrayRef),
    ]
}

/// Fill the hit tables' event columns: the features' first (each row takes its hit's
/// values), then the hits' own.
fn fill_hit_tables(
    p: &PartTables,
    rg: usize,
    hits: &HitColumns,
    feats: Option<&FeatureColumns>,
    marks: HitMarks,
) -> Result<(), EventsError> {
    let HitMarks {
        event: ev_of,
        first,
        zone,
    } = marks;
    let n = hits.ch.len();
    if let (Some((path, schema)), Some(f)) = (&p.features, feats) {
        let (fch, fhit) = (&f.ch, &f.hit);
        // Each features row takes its hit's values (through hits.transient).
        let hit_row: HashMap<(u32, i64), usize> = (0..n)
            .filter_map(|i| Some(((hits.ch[i], hits.transient[i]?), i)))
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
        crate::store::rewrite::replace_columns(path, schema, &event_columns(fe, ff, fz), rg)
            .map_err(store)?;
    }
    // The hits' own columns last, moved rather than copied.
    crate::store::rewrite::replace_columns(
        p.hits,
        &crate::store::hits_table(Default::default()).schema(),
        &event_columns(ev_of, first, zone),
        rg,
    )
    .map_err(store)?;
    Ok(())
}
