//! The damage profile (Fig. 6.1, the thesis's future work): per experiment and channel, the
//! classified hits in time order with the test machine's load and the running count of
//! each class, so that "fibre failures occur before final fracture" can be read off a test.

use super::SomError;
use crate::model::Mechanism;
use crate::store::{ColType, ColumnSpec, HitKey, Table, TableScan, TableWriter, Value};
use polars::prelude::col;
use std::collections::BTreeMap;
use std::path::Path;

/// The classes with a column of their own; any other class (e.g. `unclassified` from a map
/// labelled by criteria) counts in `n_other`.
pub const CLASSES: [Mechanism; 3] = [
    Mechanism::BondFailure,
    Mechanism::FibreFailure,
    Mechanism::Erroneous,
];

/// `damage_profile.parquet`.
pub fn profile_table() -> Table<ProfileRow> {
    let mut t = Table::new("damage_profile")
        .col(
            ColumnSpec::new("experiment", ColType::Utf8, "", "experiment id"),
            |r: &ProfileRow| Value::Str(Some(r.key.0.clone())),
        )
        .col(
            ColumnSpec::new("channel", ColType::Int32, "", "sensor channel; 0: the experiment's events (one hit per event, whichever sensor heard it first)"),
            |r| Value::I32(Some(r.key.1)),
        )
        .col(
            ColumnSpec::new("hit", ColType::Int64, "", "hit number"),
            |r| Value::I64(Some(r.key.2)),
        )
        .col(
            ColumnSpec::new(
                "time_s",
                ColType::Float64,
                "s",
                "hit time (null: the format records none; rows are then in hit order)",
            )
            .nullable(),
            |r| Value::F64(r.time_s),
        )
        .col(
            ColumnSpec::new(
                "load_n",
                ColType::Float64,
                "N",
                "test-machine load at the hit (null: no load channel)",
            )
            .nullable(),
            |r| Value::F64(r.load_n),
        )
        .col(
            ColumnSpec::new(
                "extension_m",
                ColType::Float64,
                "m",
                "test-machine extension at the hit (null: none)",
            )
            .nullable(),
            |r| Value::F64(r.extension_m),
        )
        .col(
            ColumnSpec::new("class", ColType::Utf8, "", "the SOM's class of the hit"),
            |r| Value::Str(Some(r.class.clone())),
        )
        .col(
            ColumnSpec::new(
                "before_peak_load",
                ColType::Bool,
                "",
                "the hit comes before the experiment × channel's largest load (null: no load)",
            )
            .nullable(),
            |r| Value::Bool(r.before_peak_load),
        );
    for (k, c) in CLASSES.iter().enumerate() {
        t = t.col(
            ColumnSpec::new(
                format!("n_{c}"),
                ColType::Int64,
                "hits",
                &format!("{c} hits of this experiment × channel up to and including this one"),
            ),
            move |r: &ProfileRow| Value::I64(Some(r.counts[k] as i64)),
        );
    }
    t.col(
        ColumnSpec::new(
            "n_other",
            ColType::Int64,
            "hits",
            "hits of any other class up to and including this one",
        ),
        |r| Value::I64(Some(r.counts[OTHER] as i64)),
    )
}

/// The slot of "any other class" in [`ProfileRow::counts`].
pub const OTHER: usize = CLASSES.len();

/// One classified hit of the profile.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileRow {
    pub key: HitKey,
    pub time_s: Option<f64>,
    pub load_n: Option<f64>,
    pub extension_m: Option<f64>,
    pub class: String,
    pub before_peak_load: Option<bool>,
    /// Running counts of [`CLASSES`], then "other" (at [`OTHER`]).
    pub counts: [u64; OTHER + 1],
    /// Not columns of the profile; what the damage evolution adds up: the row's peak
    /// amplitude (dB_AE) and energy (eu), and the hits of its source (an event's; 1 for a
    /// hit outside events).
    pub amplitude_db: Option<f64>,
    pub energy_eu: Option<f64>,
    pub source_hits: u64,
    /// The event the row opened (None: a hit outside events).
    pub event: Option<i64>,
}

/// Per experiment × channel: the class totals and how many came before the peak load.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileSummary {
    pub experiment: String,
    pub channel: i32,
    pub peak_load_n: Option<f64>,
    pub peak_time_s: Option<f64>,
    /// Class → (hits, hits before the peak load).
    pub classes: BTreeMap<String, (u64, u64)>,
    /// Time of the last fibre failure, s.
    pub last_fibre_s: Option<f64>,
    /// Time of the last hit, s (final fracture is at or after it).
    pub last_hit_s: Option<f64>,
}

impl ProfileSummary {
    /// One line for the terminal.
    pub fn line(&self) -> String {
        let mut parts: Vec<String> = Vec::new();
        for (c, (n, before)) in &self.classes {
            parts.push(if self.peak_load_n.is_some() {
                format!("{c} {n} ({before} before the peak load)")
            } else {
                format!("{c} {n}")
            });
        }
        let peak = match (self.peak_load_n, self.peak_time_s) {
            (Some(l), Some(t)) => format!("peak load {l:.1} N at {t:.1} s; "),
            (Some(l), None) => format!("peak load {l:.1} N; "),
            _ => String::new(),
        };
        format!(
            "damage profile {} ch{}: {peak}{}",
            self.experiment,
            self.channel,
            parts.join(", ")
        )
    }
}

fn slot(class: &str) -> usize {
    Mechanism::parse(class)
        .and_then(|m| CLASSES.iter().position(|c| *c == m))
        .unwrap_or(OTHER)
}

/// Build the profile from a feature table (time, load, extension) and the classification
/// table (`som_label`) of the same run; hits missing from either are left out.
pub fn build(
    features: &Path,
    classification: &Path,
) -> Result<(Vec<ProfileRow>, Vec<ProfileSummary>), SomError> {
    let serr = |e: crate::store::StoreError| SomError::Data(e.to_string());
    let classes: BTreeMap<HitKey, String> = TableScan::open(classification)
        .map_err(serr)?
        .keyed_strings("som_label")
        .map_err(serr)?
        .into_iter()
        .collect();
    let t = TableScan::open(features).map_err(serr)?;
    t.require(
        &[
            "experiment",
            "channel",
            "hit",
            "time_s",
            "load_n",
            "extension_m",
        ],
        "for the damage profile",
    )
    .map_err(serr)?;
    let mut sel = vec![
        col("experiment"),
        col("channel"),
        col("hit"),
        col("time_s"),
        col("load_n"),
        col("extension_m"),
    ];
    sel.extend(t.event_first_col());
    let has = |c: &str| t.dtype(c).is_some();
    let optional = ["peak_amplitude_db", "energy_eu", "event"];
    for c in optional {
        if has(c) {
            sel.push(col(c));
        }
    }
    let df = t.select(sel).map_err(serr)?;
    let keys = t.hit_keys(&df).map_err(serr)?;
    let first = t.event_first(&df).map_err(serr)?;
    let opt = |c: &str| -> Result<Vec<Option<f64>>, SomError> {
        if has(c) {
            t.f64s(&df, c).map_err(serr)
        } else {
            Ok(vec![None; df.height()])
        }
    };
    let (amp, energy, event) = (opt("peak_amplitude_db")?, opt("energy_eu")?, opt("event")?);
    // Hits per event, over every row (all sensors, classified or not).
    let mut event_hits: BTreeMap<(&str, i64), u64> = BTreeMap::new();
    for (k, e) in keys.iter().zip(&event) {
        if let Some(e) = e {
            *event_hits.entry((k.0.as_str(), *e as i64)).or_default() += 1;
        }
    }
    let time = t.f64s(&df, "time_s").map_err(serr)?;
    let load = t.f64s(&df, "load_n").map_err(serr)?;
    let ext = t.f64s(&df, "extension_m").map_err(serr)?;
    // Per experiment × channel, in time order (hit order where there is no time).
    let mut groups: BTreeMap<(String, i32), Vec<usize>> = BTreeMap::new();
    // With events built, an experiment's events form one series (channel 0), whichever
    // sensor heard each first.
    let group = |i: usize| crate::store::group_channel(keys[i].1, first[i]);
    for (i, k) in keys.iter().enumerate() {
        if classes.contains_key(k) {
            groups.entry((k.0.clone(), group(i))).or_default().push(i);
        }
    }
    let mut rows = Vec::new();
    let mut summaries = Vec::new();
    for ((experiment, channel), mut idx) in groups {
        idx.sort_by(|&a, &b| {
            let ta = time[a].unwrap_or(f64::NAN);
            let tb = time[b].unwrap_or(f64::NAN);
            ta.total_cmp(&tb).then(keys[a].2.cmp(&keys[b].2))
        });
        let peak = idx
            .iter()
            .filter_map(|&i| load[i].filter(|l| l.is_finite()).map(|l| (i, l)))
            .fold(None, |m: Option<(usize, f64)>, (i, l)| match m {
                Some((_, ml)) if ml >= l => m,
                _ => Some((i, l)),
            });
        let peak_pos = peak.and_then(|(pi, _)| idx.iter().position(|&i| i == pi));
        let mut counts = [0u64; OTHER + 1];
        let mut summary = ProfileSummary {
            experiment: experiment.clone(),
            channel,
            peak_load_n: peak.map(|p| p.1),
            peak_time_s: peak.and_then(|p| time[p.0]),
            classes: BTreeMap::new(),
            last_fibre_s: None,
            last_hit_s: None,
        };
        for (pos, &i) in idx.iter().enumerate() {
            let class = classes[&keys[i]].clone();
            let k = slot(&class);
            counts[k] += 1;
            let before = peak_pos.map(|p| pos < p);
            let e = summary.classes.entry(class.clone()).or_insert((0, 0));
            e.0 += 1;
            if before == Some(true) {
                e.1 += 1;
            }
            if CLASSES.get(k) == Some(&Mechanism::FibreFailure) {
                summary.last_fibre_s = time[i].or(summary.last_fibre_s);
            }
            summary.last_hit_s = time[i].or(summary.last_hit_s);
            rows.push(ProfileRow {
                key: (keys[i].0.clone(), group(i), keys[i].2),
                time_s: time[i],
                load_n: load[i],
                extension_m: ext[i],
                class,
                before_peak_load: before,
                counts,
                amplitude_db: amp[i],
                energy_eu: energy[i],
                source_hits: match (first[i], event[i]) {
                    (Some(true), Some(e)) => event_hits[&(keys[i].0.as_str(), e as i64)],
                    _ => 1,
                },
                event: match (first[i], event[i]) {
                    (Some(true), Some(e)) => Some(e as i64),
                    _ => None,
                },
            });
        }
        summaries.push(summary);
    }
    Ok((rows, summaries))
}

/// Write `DIR/damage_profile.parquet`, with the run's configuration hash as every table's.
pub fn write(path: &Path, rows: &[ProfileRow], config_sha256: &str) -> Result<u64, SomError> {
    let werr = |e: crate::store::StoreError| SomError::Write {
        path: path.display().to_string(),
        message: e.to_string(),
    };
    let meta = [(
        "aepipe.config_sha256".to_string(),
        config_sha256.to_string(),
    )];
    let table = profile_table();
    let mut w = TableWriter::create(path, table.schema(), &meta, 65_536).map_err(werr)?;
    for r in rows {
        w.push(table.row(r.clone())).map_err(werr)?;
    }
    w.finish().map_err(werr)
}
