//! `aepipe trend`: per experiment × channel × column, Pearson r, two-sided p, slope and
//! intercept of y (a per-hit feature, by default the 25 power ratios) against x = AE number
//! (1-based order of the hit in its experiment and channel), thesis ch. 4.5.5, Tables 4.2–4.3.
//!
//! Cut-off (thesis: "the following analysis will focus on the AEs emitted before the load
//! begins to decrease"): by default only the hits up to the peak load when the experiment has
//! a load channel; otherwise all hits, and the table says so.

use super::load::{LoadCheck, LoadVerdict};
use super::stats::{linear_trend, LinearTrend, NoTrend, TrendFit};
use crate::model::columns as cols;
use crate::store::spill::{Dec, Enc, Sorted, Sorter, Span, Spill};
use crate::store::{ColType, ColumnSpec, Table, TableWriter, Value};
use crate::store::{SourceRows, StoreError, TableScan};
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum TrendError {
    #[error("{path}: {message}")]
    Read { path: String, message: String },
    #[error(transparent)]
    Store(#[from] crate::store::StoreError),
    #[error("{0}")]
    Usage(String),
}

impl crate::util::HasKind for TrendError {
    fn kind(&self) -> crate::util::ErrorKind {
        match self {
            TrendError::Read { .. } | TrendError::Usage(_) => crate::util::ErrorKind::Usage,
            TrendError::Store(s) => s.kind(),
        }
    }
}

pub use super::settings::Cutoff;

/// Trend options.
#[derive(Debug, Clone)]
pub struct TrendOptions {
    pub cutoff: Cutoff,
    /// Significance level (thesis: 0.01).
    pub alpha: f64,
    /// Columns to test; empty = every `pr_*` column.
    pub columns: Vec<String>,
    /// Which rows count: with events built, one hit per event (the series of the
    /// experiment's events, channel 0), zone-filtered with `exclude_outside`.
    pub sources: SourceRows,
    /// A load channel spanning less, or within its noise, is no load (`trend.min_load_span_n`).
    pub min_load_span_n: f64,
    /// Fewest hits a trend is stated on (`trend.min_hits`).
    pub min_hits: usize,
}

impl Default for TrendOptions {
    fn default() -> Self {
        TrendOptions {
            cutoff: Cutoff::PeakLoad,
            alpha: 0.01,
            min_load_span_n: 1.0,
            min_hits: super::settings::MIN_TREND_HITS,
            columns: Vec::new(),
            sources: SourceRows::default(),
        }
    }
}

/// One experiment × channel: which hits were used, and why.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Selection {
    pub experiment: String,
    pub channel: i32,
    pub hits_total: usize,
    pub hits_used: usize,
    /// Hit number (AE number) of the last hit used.
    pub last_hit: Option<i64>,
    pub cutoff: String,
    pub peak_load_n: Option<f64>,
    pub peak_load_time_s: Option<f64>,
    pub note: Option<String>,
}

/// One row of `trend.parquet`.
#[derive(Debug, Clone, PartialEq)]
pub struct TrendRow {
    pub experiment: String,
    pub channel: i32,
    pub column: String,
    pub n: usize,
    /// Which hits were used (the selection's description).
    pub cutoff: String,
    pub fit: Option<LinearTrend>,
    pub significant: bool,
    pub note: Option<String>,
}

/// `trend.parquet`: one row per experiment × channel × tested column.
pub fn trend_table() -> Table<TrendRow> {
    let f = |n: &str, u: &str, d: &str| ColumnSpec::new(n, ColType::Float64, u, d).nullable();
    Table::new("trend")
        .col(ColumnSpec::of(cols::EXPERIMENT, "", "experiment id"), |t: &TrendRow| Value::Str(Some(t.experiment.clone())))
        .col(ColumnSpec::of(cols::CHANNEL, "", "sensor channel; 0: the experiment's events (one hit per event, whichever sensor heard it first)"), |t| Value::I32(Some(t.channel)))
        .col(ColumnSpec::new("column", ColType::Utf8, "", "the per-hit feature tested (y), e.g. pr_200_300khz"), |t| Value::Str(Some(t.column.clone())))
        .col(ColumnSpec::new("n", ColType::Int64, "", "hits used (after the cut-off)"), |t| Value::I64(Some(t.n as i64)))
        .col(ColumnSpec::new("cutoff", ColType::Utf8, "", "which hits were used: none, peak-load (up to hit N at L newtons), time ≤ S, first N hits; `none (all hits): …` says why a peak-load cut was not made (no load channel, or one that spans less than trend.min_load_span_n or stays within its noise)"), |t| Value::Str(Some(t.cutoff.clone())))
        .col(f("r", "1", "Pearson's correlation coefficient of y against x = AE number (Eq. 4.5.5); null with a note when undefined"), |t| Value::F64(t.fit.map(|f| f.r)))
        .col(f("p", "1", "two-sided p value of H0: no correlation (Student t, n − 2 degrees of freedom)"), |t| Value::F64(t.fit.map(|f| f.p)))
        .col(f("slope", "1/AE", "m of the least-squares line y = m·x + c (Table 4.3)"), |t| Value::F64(t.fit.map(|f| f.slope)))
        .col(f("intercept", "1", "c of that line: y at x = 0"), |t| Value::F64(t.fit.map(|f| f.intercept)))
        .col(f("slope_stderr", "1/AE", "standard error of the slope"), |t| Value::F64(t.fit.map(|f| f.slope_stderr)))
        .col(ColumnSpec::new("significant", ColType::Bool, "", "p < alpha (default 0.01, as Table 4.2)"), |t| Value::Bool(Some(t.significant)))
        .col(ColumnSpec::new("note", ColType::Utf8, "", "why r and p are null (n below trend.min_hits: `n = 3: too few hits for a trend`; a constant series), or how the cut-off fell back").nullable(), |t| Value::Str(t.note.clone()))
}

/// What a trend folder holds (`aepipe trend --out`, a run's `trend/`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TrendDir(PathBuf);

impl TrendDir {
    pub fn new(p: impl Into<PathBuf>) -> TrendDir {
        TrendDir(p.into())
    }
    pub fn path(&self) -> &Path {
        &self.0
    }
    pub fn table(&self) -> PathBuf {
        self.0.join("trend.parquet")
    }
    pub fn manifest(&self) -> PathBuf {
        self.0.join("trend_manifest.json")
    }
    /// The Fig. 4.18 plot of one experiment × channel (the id made file-safe: an experiment
    /// id read from a table never writes outside the folder).
    pub fn png(&self, experiment: &str, channel: i32) -> PathBuf {
        self.0.join(format!(
            "trend_{}_ch{channel}.png",
            crate::util::file_safe(experiment)
        ))
    }
}

/// The per-hit data of one experiment × channel, in hit order.
#[derive(Debug, Clone, Default)]
pub struct TrendSeries {
    pub experiment: String,
    pub channel: i32,
    pub hit: Vec<i64>,
    pub time_s: Vec<Option<f64>>,
    pub load_n: Vec<Option<f64>>,
    /// One vector per tested column.
    pub values: Vec<Vec<Option<f64>>>,
}

/// Read feature tables through the store's reader: identity, time, load and the tested
/// columns, grouped by experiment × channel and sorted by hit. Returns the column names
/// tested too.
pub fn read_series(
    paths: &[PathBuf],
    wanted: &[String],
    rows: SourceRows,
) -> Result<(Vec<String>, Vec<TrendSeries>), TrendError> {
    let read = |e: StoreError| match e {
        StoreError::Read { path, message } => TrendError::Read { path, message },
        other => TrendError::Store(other),
    };
    let mut columns: Vec<String> = wanted.to_vec();
    let mut groups: std::collections::BTreeMap<(String, i32), TrendSeries> = Default::default();
    for p in paths {
        let t = TableScan::open(p).map_err(read)?.sources(rows);
        t.require(
            &[
                cols::EXPERIMENT.name,
                cols::CHANNEL.name,
                cols::HIT.name,
                cols::TIME_S.name,
                cols::LOAD_N.name,
            ],
            ": not an aepipe features table",
        )
        .map_err(read)?;
        columns = tested_columns(&t, p, &columns)?;
        let df = t.columns(&series_columns(&t, &columns)).map_err(read)?;
        let keys = t.hit_keys(&df).map_err(read)?;
        let first = t.event_first(&df).map_err(read)?;
        let time = t.floats(&df, cols::TIME_S).map_err(read)?;
        let load = t.floats(&df, cols::LOAD_N).map_err(read)?;
        let vals: Vec<Vec<Option<f64>>> = columns
            .iter()
            .map(|c| t.f64s(&df, c))
            .collect::<Result<_, _>>()
            .map_err(read)?;
        for (i, (exp, ch, hit)) in keys.into_iter().enumerate() {
            let ch = crate::store::group_channel(ch, first[i]);
            let s = groups
                .entry((exp.clone(), ch))
                .or_insert_with(|| TrendSeries {
                    experiment: exp,
                    channel: ch,
                    values: vec![Vec::new(); columns.len()],
                    ..Default::default()
                });
            s.hit.push(hit);
            s.time_s.push(time[i]);
            s.load_n.push(load[i]);
            for (k, v) in vals.iter().enumerate() {
                s.values[k].push(v[i]);
            }
        }
    }
    // Hit order inside each group (tables are written in that order; several files may not be).
    for s in groups.values_mut() {
        let mut idx: Vec<usize> = (0..s.hit.len()).collect();
        idx.sort_by_key(|&i| s.hit[i]);
        let pick = |v: &Vec<Option<f64>>| idx.iter().map(|&i| v[i]).collect::<Vec<_>>();
        s.time_s = pick(&s.time_s);
        s.load_n = pick(&s.load_n);
        s.values = s.values.iter().map(pick).collect();
        s.hit = idx.iter().map(|&i| s.hit[i]).collect();
    }
    Ok((columns, groups.into_values().collect()))
}

/// How many leading hits of a series the cut-off keeps, and the description.
pub fn select(s: &TrendSeries, cutoff: Cutoff, min_load_span_n: f64) -> Selection {
    let rows = (0..s.hit.len()).map(|i| (s.hit[i], s.time_s[i], s.load_n[i]));
    select_from(&s.experiment, s.channel, rows, cutoff, min_load_span_n)
}

/// [`select`] over a series' (hit, time, load) rows in hit order, as they stream by (one
/// pass, a few kilobytes kept). A peak-load cut needs a load: a load channel that spans
/// less than `min_load_span_n` or stays within its noise ([`LoadCheck`]) is treated as
/// absent, and the cut-off says why.
pub fn select_from(
    experiment: &str,
    channel: i32,
    rows: impl Iterator<Item = (i64, Option<f64>, Option<f64>)>,
    cutoff: Cutoff,
    min_load_span_n: f64,
) -> Selection {
    let mut load_check = LoadCheck::new();
    let (mut total, mut last) = (0usize, None);
    // The first largest load (the fold keeps an earlier row on a tie), its row and time.
    let mut peak: Option<(usize, f64, i64, Option<f64>)> = None;
    // Time cut: the leading rows at or before t, and whether any row lacks a time.
    let (mut lead, mut leading, mut no_time) = (0usize, true, false);
    let mut lead_hit = None;
    let mut nth_hit = None;
    for (i, (hit, time, load)) in rows.enumerate() {
        total += 1;
        last = Some(hit);
        if let Some(l) = load {
            load_check.push(l);
            if !matches!(peak, Some((_, ml, _, _)) if ml >= l) {
                peak = Some((i, l, hit, time));
            }
        }
        if let Cutoff::Time(t) = cutoff {
            if leading && time.is_some_and(|x| x <= t) {
                lead += 1;
                lead_hit = Some(hit);
            } else {
                leading = false;
            }
        }
        no_time |= time.is_none();
        if let Cutoff::Hits(n) = cutoff {
            if i + 1 == n {
                nth_hit = Some(hit);
            }
        }
    }
    let mut sel = Selection {
        experiment: experiment.to_string(),
        channel,
        hits_total: total,
        hits_used: total,
        last_hit: last,
        cutoff: "none (all hits)".into(),
        peak_load_n: None,
        peak_load_time_s: None,
        note: None,
    };
    match cutoff {
        Cutoff::None => {}
        Cutoff::PeakLoad => match (peak, load_check.verdict(min_load_span_n)) {
            (Some(_), LoadVerdict::Noise(why)) => {
                sel.cutoff = format!("none (all hits): {why}");
                sel.note = Some(format!(
                    "--cutoff peak-load asked, but {why}: no load, all hits used"
                ));
            }
            (Some((i, l, hit, time)), _) => {
                sel.hits_used = i + 1;
                sel.last_hit = Some(hit);
                sel.peak_load_n = Some(l);
                sel.peak_load_time_s = time;
                sel.cutoff = format!("peak-load: hits up to {hit} at {l:.6} N");
            }
            (None, _) => {
                sel.cutoff = "none (all hits): no load channel".into();
                sel.note = Some("--cutoff peak-load asked, but the experiment has no load channel: all hits used".into());
            }
        },
        Cutoff::Time(t) => {
            sel.hits_used = lead;
            sel.last_hit = lead_hit;
            sel.cutoff = format!("time ≤ {t} s");
            if no_time {
                sel.note =
                    Some("some hits have no time: the cut-off stops at the first of them".into());
            }
        }
        Cutoff::Hits(n) => {
            sel.hits_used = n.min(total);
            if n < total {
                sel.last_hit = nth_hit;
            }
            sel.cutoff = format!("first {n} hits");
        }
    }
    sel
}

/// Statistics of every tested column of one series.
pub fn trends(
    s: &TrendSeries,
    columns: &[String],
    sel: &Selection,
    alpha: f64,
    min_hits: usize,
) -> Vec<TrendRow> {
    let k = sel.hits_used;
    columns
        .iter()
        .enumerate()
        .map(|(ci, name)| {
            // x = AE number (1-based position in the experiment); hits whose value is null
            // (a flat record) are left out of the fit but keep their AE numbers.
            let (x, y): (Vec<f64>, Vec<f64>) = s.values[ci][..k]
                .iter()
                .enumerate()
                .filter_map(|(i, v)| v.map(|v| ((i + 1) as f64, v)))
                .unzip();
            let (fit, note) = match linear_trend(&x, &y) {
                _ if x.len() < min_hits => (None, Some(too_few(x.len(), min_hits))),
                Err(why) => (None, Some(why.to_string())),
                Ok(f) => (Some(f), sel.note.clone()),
            };
            TrendRow {
                experiment: s.experiment.clone(),
                channel: s.channel,
                column: name.clone(),
                n: x.len(),
                cutoff: sel.cutoff.clone(),
                significant: fit.is_some_and(|f| f.p < alpha),
                fit,
                note,
            }
        })
        .collect()
}

/// What `aepipe trend` produced. Every row is in `trend.parquet`; only the significant ones
/// are kept here (what the terminal, the report and the summary show): a study of thousands
/// of series holds a few hundred bytes per series, not its whole table.
pub struct TrendReport {
    /// The significant rows, in the series' order.
    pub significant: Vec<TrendRow>,
    pub selections: Vec<Selection>,
    pub columns: Vec<String>,
    pub table_path: PathBuf,
    /// `trend.min_hits`: a series with fewer hits used states no trend.
    pub min_hits: usize,
}

impl TrendReport {
    /// `n = 3: too few hits for a trend …` for a series below `min_hits`.
    pub fn too_few(&self, sel: &Selection) -> Option<String> {
        (sel.hits_used < self.min_hits).then(|| too_few(sel.hits_used, self.min_hits))
    }
}

/// One row of a trend series as it is sorted: the group, the hit, its position in the input
/// (ties keep input order, as the in-memory sort did), time, load and the tested values.
#[derive(Debug, Clone, PartialEq)]
struct SeriesRow {
    experiment: String,
    channel: i32,
    hit: i64,
    seq: u64,
    time_s: Option<f64>,
    load_n: Option<f64>,
    values: Vec<Option<f64>>,
}

impl SeriesRow {
    fn key(&self) -> (&str, i32, i64, u64) {
        (&self.experiment, self.channel, self.hit, self.seq)
    }
}

impl Eq for SeriesRow {}
impl PartialOrd for SeriesRow {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for SeriesRow {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        self.key().cmp(&o.key())
    }
}

impl Spill for SeriesRow {
    fn encode(&self, out: &mut Vec<u8>) {
        let mut e = Enc(out);
        e.str(&self.experiment)
            .i32(self.channel)
            .i64(self.hit)
            .u64(self.seq)
            .opt_f64(self.time_s)
            .opt_f64(self.load_n)
            .u32(self.values.len() as u32);
        for v in &self.values {
            e.opt_f64(*v);
        }
    }
    fn decode(b: &mut Dec<'_>) -> Option<Self> {
        let (experiment, channel, hit, seq) = (b.str()?, b.i32()?, b.i64()?, b.u64()?);
        let (time_s, load_n) = (b.opt_f64()?, b.opt_f64()?);
        let n = b.u32()? as usize;
        let values = (0..n).map(|_| b.opt_f64()).collect::<Option<Vec<_>>>()?;
        Some(SeriesRow {
            experiment,
            channel,
            hit,
            seq,
            time_s,
            load_n,
            values,
        })
    }
    fn mem_bytes(&self) -> usize {
        std::mem::size_of::<Self>()
            + self.experiment.len()
            + self.values.len() * std::mem::size_of::<Option<f64>>()
    }
}

/// What a trend series reads of a features table: the hit's key, time and load, the tested
/// columns, and whether it is its event's first hit when the table says.
fn series_columns<'a>(t: &TableScan, columns: &'a [String]) -> Vec<&'a str> {
    let mut sel = vec![
        cols::EXPERIMENT.name,
        cols::CHANNEL.name,
        cols::HIT.name,
        cols::TIME_S.name,
        cols::LOAD_N.name,
    ];
    sel.extend(columns.iter().map(String::as_str));
    sel.extend(t.event_first_col());
    sel
}

/// The tested columns of the tables, checked (every `pr_*` column of the first table when
/// none are named).
fn tested_columns(t: &TableScan, p: &Path, wanted: &[String]) -> Result<Vec<String>, TrendError> {
    let mut columns = wanted.to_vec();
    if columns.is_empty() {
        columns = t
            .column_names()
            .into_iter()
            .filter(|n| n.starts_with("pr_"))
            .collect();
        if columns.is_empty() {
            return Err(TrendError::Read {
                path: p.display().to_string(),
                message: "no pr_* power-ratio columns; name the columns to test with --columns"
                    .into(),
            });
        }
    }
    for c in &columns {
        match t.dtype(c) {
            None => {
                return Err(TrendError::Read {
                    path: p.display().to_string(),
                    message: format!("no column {c}"),
                })
            }
            Some(dt) if !dt.is_primitive_numeric() => {
                return Err(TrendError::Read {
                    path: p.display().to_string(),
                    message: format!("column {c} is {dt}, not a number"),
                })
            }
            _ => {}
        }
    }
    Ok(columns)
}

/// Every series row of the tables, sorted by experiment, group channel and hit, in bounded
/// memory (read a batch at a time; sorted runs spill under `spill_dir`).
fn sorted_series(
    paths: &[PathBuf],
    wanted: &[String],
    rows: SourceRows,
    spill_dir: &Path,
) -> Result<(Vec<String>, Sorted<SeriesRow>), TrendError> {
    let read = |e: StoreError| match e {
        StoreError::Read { path, message } => TrendError::Read { path, message },
        other => TrendError::Store(other),
    };
    let mut columns: Vec<String> = wanted.to_vec();
    let mut sorter = Sorter::new(spill_dir);
    let mut seq = 0u64;
    for p in paths {
        let t = TableScan::open(p).map_err(read)?.sources(rows);
        t.require(
            &[
                cols::EXPERIMENT.name,
                cols::CHANNEL.name,
                cols::HIT.name,
                cols::TIME_S.name,
                cols::LOAD_N.name,
            ],
            ": not an aepipe features table",
        )
        .map_err(read)?;
        columns = tested_columns(&t, p, &columns)?;
        let sel = series_columns(&t, &columns);
        for batch in t.batches(&sel) {
            let (_, df) = batch.map_err(read)?;
            let keys = t.hit_keys(&df).map_err(read)?;
            let first = t.event_first(&df).map_err(read)?;
            let time = t.floats(&df, cols::TIME_S).map_err(read)?;
            let load = t.floats(&df, cols::LOAD_N).map_err(read)?;
            let vals: Vec<Vec<Option<f64>>> = columns
                .iter()
                .map(|c| t.f64s(&df, c))
                .collect::<Result<_, _>>()
                .map_err(read)?;
            for (i, (exp, ch, hit)) in keys.into_iter().enumerate() {
                sorter.push(SeriesRow {
                    experiment: exp,
                    channel: crate::store::group_channel(ch, first[i]),
                    hit,
                    seq,
                    time_s: time[i],
                    load_n: load[i],
                    values: vals.iter().map(|v| v[i]).collect(),
                })?;
                seq += 1;
            }
        }
    }
    Ok((columns, sorter.finish()?))
}

/// The fits of every tested column of one series, from its sorted rows: three passes over
/// the first `k` rows (the cut-off's), exactly [`trends`]'s arithmetic.
fn trends_sorted(
    sorted: &Sorted<SeriesRow>,
    span: Span,
    columns: &[String],
    sel: &Selection,
    alpha: f64,
    min_hits: usize,
) -> Result<Vec<TrendRow>, StoreError> {
    let k = sel.hits_used;
    let mut fits = vec![TrendFit::default(); columns.len()];
    let mut failed: Vec<Option<NoTrend>> = vec![None; columns.len()];
    // x = AE number (1-based position in the series); a row whose value is null (a flat
    // record) is left out of the fit but keeps its AE number.
    let pass = |f: &mut dyn FnMut(usize, f64, f64)| -> Result<(), StoreError> {
        for (i, r) in sorted.span_iter(span).take(k).enumerate() {
            let r = r?;
            for (ci, v) in r.values.iter().enumerate() {
                if let Some(v) = v {
                    f(ci, (i + 1) as f64, *v);
                }
            }
        }
        Ok(())
    };
    pass(&mut |ci, x, y| fits[ci].pass1(x, y))?;
    for (ci, f) in fits.iter_mut().enumerate() {
        failed[ci] = f.end1().err();
    }
    pass(&mut |ci, x, y| {
        if failed[ci].is_none() {
            fits[ci].pass2(x, y)
        }
    })?;
    for (ci, f) in fits.iter_mut().enumerate() {
        if failed[ci].is_none() {
            failed[ci] = f.end2().err();
        }
    }
    pass(&mut |ci, x, y| {
        if failed[ci].is_none() {
            fits[ci].pass3(x, y)
        }
    })?;
    Ok(columns
        .iter()
        .enumerate()
        .map(|(ci, name)| {
            let (fit, note) = match &failed[ci] {
                _ if fits[ci].points() < min_hits => {
                    (None, Some(too_few(fits[ci].points(), min_hits)))
                }
                Some(why) => (None, Some(why.to_string())),
                None => (Some(fits[ci].finish()), sel.note.clone()),
            };
            TrendRow {
                experiment: sel.experiment.clone(),
                channel: sel.channel,
                column: name.clone(),
                n: fits[ci].points(),
                cutoff: sel.cutoff.clone(),
                significant: fit.is_some_and(|f| f.p < alpha),
                fit,
                note,
            }
        })
        .collect())
}

/// The points a Fig. 4.18 picture draws: the steepest significant columns of one series
/// (at most `max_lines`), each (AE number, value) up to the cut-off, at most
/// [`MAX_PLOT_POINTS`] each (every m-th point when more: said on the picture).
pub struct TrendPicture<'a> {
    pub selection: &'a Selection,
    pub lines: Vec<(&'a TrendRow, Vec<(f64, f64)>)>,
    /// The largest value of the drawn columns (all points, drawn or not).
    pub ymax: f64,
    /// Every m-th point drawn (1: all).
    pub every: usize,
}

/// Points drawn per line of a trend picture, at most.
pub const MAX_PLOT_POINTS: usize = 20_000;

/// The stride that keeps `n` points within [`MAX_PLOT_POINTS`] (every m-th one drawn).
pub fn thin_every(n: usize) -> usize {
    n.div_ceil(MAX_PLOT_POINTS).max(1)
}

/// The steepest significant rows of one series, at most `max_lines`, steepest first.
pub fn drawn_rows(rows: &[TrendRow], max_lines: usize) -> Vec<&TrendRow> {
    let mut sig: Vec<&TrendRow> = rows.iter().filter(|r| r.significant).collect();
    sig.sort_by(|a, b| {
        b.fit
            .map(|f| f.slope.abs())
            .unwrap_or(0.0)
            .total_cmp(&a.fit.map(|f| f.slope.abs()).unwrap_or(0.0))
    });
    sig.truncate(max_lines);
    sig
}

fn picture<'a>(
    sorted: &Sorted<SeriesRow>,
    span: Span,
    columns: &[String],
    sel: &'a Selection,
    rows: &'a [TrendRow],
    max_lines: usize,
) -> Result<Option<TrendPicture<'a>>, StoreError> {
    let drawn = drawn_rows(rows, max_lines);
    if drawn.is_empty() {
        return Ok(None);
    }
    let k = sel.hits_used;
    let every = thin_every(k);
    let ci: Vec<usize> = drawn
        .iter()
        .map(|r| columns.iter().position(|c| c == &r.column).expect("tested"))
        .collect();
    let mut lines: Vec<(&TrendRow, Vec<(f64, f64)>)> =
        drawn.iter().map(|r| (*r, Vec::new())).collect();
    let mut ymax = 0.0f64;
    for (j, r) in sorted.span_iter(span).take(k).enumerate() {
        let r = r?;
        for (l, &c) in ci.iter().enumerate() {
            if let Some(v) = r.values[c] {
                ymax = ymax.max(v);
                if j.is_multiple_of(every) {
                    lines[l].1.push(((j + 1) as f64, v));
                }
            }
        }
    }
    Ok(Some(TrendPicture {
        selection: sel,
        lines,
        ymax,
        every,
    }))
}

/// Read, select, fit and write `DIR/trend.parquet` and `DIR/trend_manifest.json`.
pub fn run_trend(
    inputs: &[PathBuf],
    out_dir: &Path,
    opts: &TrendOptions,
) -> Result<TrendReport, TrendError> {
    run_trend_with(inputs, out_dir, opts, 0, 0, |_| Ok::<(), TrendError>(()))
}

/// [`run_trend`], calling `picture` with the Fig. 4.18 data (the steepest `max_lines`
/// significant columns) of the first `pictures` series that have significant columns,
/// while each is at hand: the stage streams, so the points are not kept for later. The
/// rows are read a batch at a time and sorted in bounded memory; the fits take three
/// passes over each series.
pub fn run_trend_with<E: From<TrendError> + From<StoreError>>(
    inputs: &[PathBuf],
    out_dir: &Path,
    opts: &TrendOptions,
    max_lines: usize,
    pictures: usize,
    mut picture_of: impl FnMut(&TrendPicture) -> Result<(), E>,
) -> Result<TrendReport, E> {
    if !(opts.alpha > 0.0 && opts.alpha < 1.0) {
        return Err(
            TrendError::Usage(format!("alpha must be in (0, 1), got {}", opts.alpha)).into(),
        );
    }
    std::fs::create_dir_all(out_dir).map_err(|source| crate::store::StoreError::Io {
        path: out_dir.display().to_string(),
        source,
    })?;
    crate::store::clean_stale_tmp(out_dir);
    let (columns, sorted) = sorted_series(inputs, &opts.columns, opts.sources, out_dir)?;
    let dir = TrendDir::new(out_dir);
    let table_path = dir.table();
    let meta = vec![
        ("aepipe.alpha".to_string(), opts.alpha.to_string()),
        (
            "aepipe.x".to_string(),
            "AE number: 1-based order of the hit in its experiment and channel".to_string(),
        ),
    ];
    let table = trend_table();
    let mut w = TableWriter::create(&table_path, table.schema(), &meta, 4096)?;
    let mut rows = Vec::new();
    let mut selections = Vec::new();
    let mut drawn = 0usize;
    for ((experiment, channel), span) in sorted.groups(|r| (r.experiment.clone(), r.channel))? {
        let sel = select_from(
            &experiment,
            channel,
            sorted
                .span_iter(span)
                .map_while(Result::ok)
                .map(|r| (r.hit, r.time_s, r.load_n)),
            opts.cutoff,
            opts.min_load_span_n,
        );
        if sel.hits_total as u64 != span.len {
            // A record that did not read back (map_while stopped): say which file.
            sorted.span_iter(span).collect::<Result<Vec<_>, _>>()?;
        }
        let group = trends_sorted(&sorted, span, &columns, &sel, opts.alpha, opts.min_hits)?;
        if max_lines > 0 && drawn < pictures {
            if let Some(p) = picture(&sorted, span, &columns, &sel, &group, max_lines)? {
                picture_of(&p)?;
                drawn += 1;
            }
        }
        for t in &group {
            w.push(table.row(t.clone()))?;
        }
        rows.extend(group.into_iter().filter(|r| r.significant));
        selections.push(sel);
    }
    w.finish()?;
    let manifest = serde_json::json!({
        "tool": {"name": "aepipe", "version": env!("CARGO_PKG_VERSION")},
        "job": "trend",
        "finished_utc": crate::util::utc_now(),
        "inputs": inputs.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
        "alpha": opts.alpha,
        "min_hits": opts.min_hits,
        "columns": columns,
        "selections": selections,
    });
    crate::util::write_atomic(
        &dir.manifest(),
        serde_json::to_string_pretty(&manifest)
            .expect("json")
            .as_bytes(),
    )
    .map_err(|e| TrendError::Usage(e.to_string()))?;
    Ok(TrendReport {
        significant: rows,
        selections,
        columns,
        table_path,
        min_hits: opts.min_hits,
    })
}

/// The terminal table of the significant rows, like Table 4.3 (window, m, c, r, p).
pub fn format_table(rep: &TrendReport) -> String {
    let mut s = String::new();
    let mut next = 0;
    for sel in &rep.selections {
        s.push_str(&format!(
            "{} ch{}: {} of {} hits used ({}){}\n",
            sel.experiment,
            sel.channel,
            sel.hits_used,
            sel.hits_total,
            sel.cutoff,
            sel.note
                .as_ref()
                .map(|n| format!("\n  note: {n}"))
                .unwrap_or_default()
        ));
        // The significant rows are in the selections' order: this series' are the next ones.
        let mut sig: Vec<&TrendRow> = Vec::new();
        while let Some(r) = rep.significant.get(next) {
            if (r.experiment.as_str(), r.channel) != (sel.experiment.as_str(), sel.channel) {
                break;
            }
            sig.push(r);
            next += 1;
        }
        if let Some(few) = rep.too_few(sel) {
            s.push_str(&format!("  {few}\n\n"));
            continue;
        }
        if sig.is_empty() {
            s.push_str("  no significant trend\n\n");
            continue;
        }
        s.push_str(&format!(
            "  {:<22} {:>11} {:>9} {:>7} {:>10}\n",
            "frequency window", "m", "c", "r", "p"
        ));
        for r in sig {
            let f = r.fit.expect("significant rows have a fit");
            s.push_str(&format!(
                "  {:<22} {:>11.2e} {:>9.3} {:>7.2} {:>10.2e}\n",
                window_name(&r.column),
                f.slope,
                f.intercept,
                f.r,
                f.p
            ));
        }
        s.push('\n');
    }
    s
}

/// Why a series holds no trend though its statistics could be computed: too few hits.
pub fn too_few(n: usize, min_hits: usize) -> String {
    format!("n = {n}: too few hits for a trend (trend.min_hits = {min_hits})")
}

/// `pr_200_300khz` → `200 - 300 kHz`; other names unchanged.
pub fn window_name(column: &str) -> String {
    column
        .strip_prefix("pr_")
        .and_then(|r| r.strip_suffix("khz"))
        .and_then(|r| r.split_once('_'))
        .map(|(a, b)| format!("{a} - {b} kHz"))
        .unwrap_or_else(|| column.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series(loads: &[Option<f64>]) -> TrendSeries {
        TrendSeries {
            experiment: "e".into(),
            channel: 1,
            hit: (1..=loads.len() as i64).collect(),
            time_s: (0..loads.len()).map(|i| Some(i as f64)).collect(),
            load_n: loads.to_vec(),
            values: vec![(0..loads.len()).map(|i| Some(i as f64 * 0.1)).collect()],
        }
    }

    #[test]
    fn cutoffs() {
        let s = series(&[Some(1.0), Some(3.0), Some(5.0), Some(4.0), Some(2.0)]);
        let sel = select(&s, Cutoff::PeakLoad, 1.0);
        assert_eq!(
            (sel.hits_used, sel.last_hit, sel.peak_load_n),
            (3, Some(3), Some(5.0))
        );
        assert_eq!(select(&s, Cutoff::Time(1.5), 1.0).hits_used, 2);
        assert_eq!(select(&s, Cutoff::Hits(4), 1.0).hits_used, 4);
        assert_eq!(select(&s, Cutoff::Hits(40), 1.0).hits_used, 5);
        let none = select(&series(&[None, None, None]), Cutoff::PeakLoad, 1.0);
        assert_eq!(none.hits_used, 3);
        assert!(none.note.unwrap().contains("no load channel"));
        assert_eq!("time:2.5".parse::<Cutoff>().unwrap(), Cutoff::Time(2.5));
        assert!("peak".parse::<Cutoff>().is_err());
    }

    #[test]
    fn too_few_hits_is_a_null_with_a_reason() {
        let s = series(&[Some(1.0), Some(3.0), Some(5.0), Some(4.0)]);
        let sel = select(&s, Cutoff::Hits(2), 1.0);
        let t = &trends(&s, &["pr_x".into()], &sel, 0.01, 0)[0];
        assert!(t.fit.is_none() && !t.significant);
        assert!(t.note.as_ref().unwrap().contains("n = 2 < 3"));
        // Below trend.min_hits: computable, but not stated.
        let sel = select(&s, Cutoff::Hits(4), 1.0);
        assert!(trends(&s, &["pr_x".into()], &sel, 0.01, 4)[0].fit.is_some());
        let t = &trends(&s, &["pr_x".into()], &sel, 0.01, 5)[0];
        assert!(t.fit.is_none() && !t.significant);
        assert_eq!(
            t.note.as_deref(),
            Some("n = 4: too few hits for a trend (trend.min_hits = 5)")
        );
    }

    #[test]
    fn window_names() {
        assert_eq!(window_name("pr_200_300khz"), "200 - 300 kHz");
        assert_eq!(window_name("peak_freq_hz"), "peak_freq_hz");
    }
}
