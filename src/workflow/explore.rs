//! The explorable report's data (issue 41): one point per feature row — at most
//! [`MAX_POINTS`], every k-th row beyond, and the page says so — with the columns a reader
//! plots, its class (SOM, else ch. 4.7), cluster, zone and event location; and the hits
//! whose waveform and CWT the page can open (the gallery's, up to `[report]
//! explorable_hits`, taken across classes in turn).

use super::*;
use crate::model::columns as cols;
use crate::report::explore::{Explorer, PlotColumn};
use std::collections::HashMap;

/// Points embedded at most: ~110 B each in the page, so ≤ ~6 MB of data at any size.
pub const MAX_POINTS: usize = 50_000;

/// The feature columns the reader can put on an axis: (column, label).
const AXES: [(&str, &str); 13] = [
    ("time_s", "time (s)"),
    ("load_n", "load (N)"),
    ("peak_amplitude_db", "amplitude (dB_AE)"),
    ("energy_eu", "energy (eu)"),
    ("duration_s", "duration (s)"),
    ("rise_time_s", "rise time (s)"),
    ("counts", "counts"),
    ("ra_ms_per_v", "RA (ms/V)"),
    ("af_khz", "AF (kHz)"),
    ("peak_freq_hz", "peak frequency (Hz)"),
    ("centroid_freq_hz", "centroid frequency (Hz)"),
    ("extension_m", "extension (m)"),
    ("event", "event"),
];

/// Read the explorer's points from the run's tables.
pub(super) fn explorer(
    s: &RunSummary,
    gallery: &BTreeMap<String, Vec<HitKey>>,
) -> Result<Explorer, WorkflowError> {
    // The events table the feature stage wrote beside its features.
    let events = s.features.table_path.parent().map(|d| {
        crate::pipeline::StreamDir::new(d).table(
            crate::pipeline::PartTable::Events,
            crate::pipeline::StreamJob::Features,
        )
    });
    let tables = ExplorerTables {
        features: &s.features.table_path,
        classification: s.som.as_ref().map(|m| m.classification.as_path()),
        clusters: s.cluster.as_ref().map(|c| c.report.clusters.as_path()),
        events: events.as_deref().filter(|p| p.is_file()),
    };
    let mut e = explorer_of(&tables)?;
    e.embedded = embedded(gallery, s.config.report.explorable_hits);
    e.validity = s.cluster.as_ref().map(|c| validity(&c.report));
    Ok(e)
}

/// The validity indices of the k tried, for the chart.
fn validity(r: &crate::cluster::ClusterReport) -> crate::report::explore::ValidityCurves {
    let v = &r.validity;
    let index = |name: &str, f: fn(&crate::cluster::ValidityRow) -> Option<f64>| {
        (name.to_string(), v.iter().map(f).collect::<Vec<_>>())
    };
    let all = [
        index("Davies–Bouldin", |r| r.davies_bouldin),
        index("silhouette", |r| r.silhouette),
        index("Calinski–Harabasz", |r| r.calinski_harabasz),
        index("BIC", |r| r.bic),
    ];
    crate::report::explore::ValidityCurves {
        k: v.iter().map(|r| r.k as f64).collect(),
        indices: all
            .into_iter()
            .filter(|(_, vals)| vals.iter().any(Option::is_some))
            .collect(),
        chosen: r.k,
    }
}

/// The tables the explorer reads.
pub struct ExplorerTables<'a> {
    pub features: &'a Path,
    pub classification: Option<&'a Path>,
    pub clusters: Option<&'a Path>,
    /// events.parquet: each point placed at its event's source.
    pub events: Option<&'a Path>,
}

/// The explorer's points of any features table (and its classification and clusters):
/// what the report embeds, without the gallery's pictures (`aepipe bench report` measures
/// it alone).
pub fn explorer_of(tables: &ExplorerTables) -> Result<Explorer, WorkflowError> {
    let t = TableScan::open(tables.features)?;
    let total = t.file_rows();
    let stride = total.div_ceil(MAX_POINTS).max(1);
    let have = t.column_names();
    let has = |c: &str| have.iter().any(|h| h == c);
    let present: Vec<(&str, &str)> = AXES.into_iter().filter(|(c, _)| has(c)).collect();
    let mut names = vec![
        cols::EXPERIMENT.name,
        cols::CHANNEL.name,
        cols::HIT.name,
        cols::CRITERIA_LABEL.name,
    ];
    names.extend(present.iter().map(|(c, _)| *c));
    if has(cols::ZONE.name) {
        names.push(cols::ZONE.name);
    }
    let mut e = Explorer {
        total,
        stride,
        columns: present
            .iter()
            .map(|(c, l)| PlotColumn {
                name: c.to_string(),
                label: l.to_string(),
                values: Vec::new(),
            })
            .collect(),
        ..Default::default()
    };
    let mut index: HashMap<HitKey, usize> = HashMap::new();
    let mut criteria = Vec::new();
    let mut zone = Vec::new();
    let mut row = 0usize;
    for batch in t.batches(&names) {
        let (_, df) = batch?;
        let keys = t.hit_keys(&df)?;
        let crit = t.texts(&df, cols::CRITERIA_LABEL)?;
        let zones = match names.contains(&cols::ZONE.name) {
            true => t.texts(&df, cols::ZONE)?,
            false => vec![None; df.height()],
        };
        let vals: Vec<Vec<Option<f64>>> = present
            .iter()
            .map(|(c, _)| t.f64s(&df, c))
            .collect::<Result<_, _>>()?;
        for (i, k) in keys.into_iter().enumerate() {
            row += 1;
            if !(row - 1).is_multiple_of(stride) {
                continue;
            }
            index.insert(k.clone(), e.keys.len());
            e.keys.push(k);
            criteria.push(crit[i].clone());
            zone.push(zones[i].clone());
            for (c, v) in e.columns.iter_mut().zip(&vals) {
                c.values.push(v[i]);
            }
        }
    }
    e.add_coloring("ch. 4.7 label", criteria);
    if let Some(p) = tables.classification {
        e.add_coloring("SOM class", keyed_texts(p, cols::SOM_LABEL.name, &index)?);
    }
    if let Some(p) = tables.clusters {
        e.add_coloring("cluster", keyed_texts(p, "cluster", &index)?);
    }
    if zone.iter().any(Option::is_some) {
        e.add_coloring("zone", zone);
    }
    e.location = match tables.events {
        Some(p) => event_places(p, &e)?,
        None => None,
    };
    Ok(e)
}

/// A keyed table's `column` (as text) for the points, in point order.
fn keyed_texts(
    path: &Path,
    column: &str,
    index: &HashMap<HitKey, usize>,
) -> Result<Vec<Option<String>>, WorkflowError> {
    let t = TableScan::open(path)?;
    let mut out = vec![None; index.len()];
    let names = [
        cols::EXPERIMENT.name,
        cols::CHANNEL.name,
        cols::HIT.name,
        column,
    ];
    for batch in t.batches(&names) {
        let (_, df) = batch?;
        let keys = t.hit_keys(&df)?;
        let v = t.as_strings(&df, column)?;
        for (k, v) in keys.iter().zip(v) {
            if let Some(&i) = index.get(k) {
                out[i] = v;
            }
        }
    }
    Ok(out)
}

/// The event's source position (x, y in m) of each point in an event, when events were
/// located.
fn event_places(path: &Path, e: &Explorer) -> Result<Option<[Vec<Option<f64>>; 2]>, WorkflowError> {
    let Some(events) = e.column("event") else {
        return Ok(None);
    };
    let at = crate::events::table::read_places(path)?;
    let mut out = [vec![None; e.keys.len()], vec![None; e.keys.len()]];
    for (i, k) in e.keys.iter().enumerate() {
        let Some(n) = events[i] else { continue };
        if let Some((x, y)) = at.get(&(k.0.clone(), n as i64)) {
            (out[0][i], out[1][i]) = (*x, *y);
        }
    }
    Ok(out[0].iter().any(Option::is_some).then_some(out))
}

/// The gallery's hits the page opens: across classes in turn, at most `max`.
fn embedded(gallery: &BTreeMap<String, Vec<HitKey>>, max: usize) -> Vec<HitKey> {
    let mut out = Vec::new();
    let deepest = gallery.values().map(Vec::len).max().unwrap_or(0);
    for j in 0..deepest {
        for keys in gallery.values() {
            if let Some(k) = keys.get(j) {
                if out.len() < max && !out.contains(k) {
                    out.push(k.clone());
                }
            }
        }
    }
    out
}
