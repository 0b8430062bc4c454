//! `series.parquet`: a lab's tests side by side, one row per experiment — how many hits,
//! how many have load, the peak load, what the SOM's classes and the clusters say, and the
//! energy exponent — read from the tables the run wrote, a batch at a time.

use super::*;
use crate::model::columns as cols;
use crate::store::{ColType, ColumnSpec, Table, TableScan, TableWriter, Value};

/// The SOM label of a hit like none of the map's references: it has a share, not a column.
const UNLIKE: &str = "unlike_references";

/// One experiment of a run.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SeriesRow {
    pub experiment: String,
    pub hits: u64,
    pub rejects: u64,
    pub hits_with_load: u64,
    pub peak_load_n: Option<f64>,
    pub peak_load_s: Option<f64>,
    /// Hits the SOM classified, and the share of them unlike the map's references.
    pub classified: Option<u64>,
    pub unlike_references_share: Option<f64>,
    /// Hits per SOM class, in the order of [`Series::classes`].
    pub classes: Vec<Option<u64>>,
    /// Distinct clusters among the experiment's hits (`[cluster] enabled`).
    pub clusters: Option<u64>,
    /// Sources with a positive energy, and the energy exponent (null below the power law's
    /// minimum tail, `statistics.parquet`).
    pub energy_n: u64,
    pub alpha: Option<f64>,
    /// Significant trend rows (null: the trend stage did not run), and why a series of the
    /// experiment states none (`n = 3: too few hits for a trend`).
    pub significant_trends: Option<u64>,
    pub trend_note: Option<String>,
}

/// The series table of a run: its rows and the classes that have a column.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Series {
    pub classes: Vec<String>,
    pub clustering: bool,
    pub rows: Vec<SeriesRow>,
    pub path: PathBuf,
}

/// `series.parquet` with one `<class>_hits` column per class and `clusters` when clustering
/// ran.
pub fn series_table(classes: &[String], clustering: bool) -> Table<SeriesRow> {
    let f = |n: &str, u: &str, d: &str| ColumnSpec::new(n, ColType::Float64, u, d).nullable();
    let i = |n: &str, d: &str| ColumnSpec::new(n, ColType::Int64, "", d);
    let mut t = Table::new("series")
        .col(ColumnSpec::of(cols::EXPERIMENT, "", "experiment id"), |r: &SeriesRow| Value::Str(Some(r.experiment.clone())))
        .col(i("hits", "rows of hits.parquet"), |r| Value::I64(Some(r.hits as i64)))
        .col(i("rejects", "reject rows (any record type)"), |r| Value::I64(Some(r.rejects as i64)))
        .col(i("hits_with_load", "hits with a load_n (inside the machine log's or load file's span)"), |r| Value::I64(Some(r.hits_with_load as i64)))
        .col(f("peak_load_n", "N", "the largest load of parametric.parquet (else of the hits); null: no load"), |r| Value::F64(r.peak_load_n))
        .col(f("peak_load_s", "s", "when the peak load was reached, AE clock"), |r| Value::F64(r.peak_load_s))
        .col(i("classified", "hits the SOM classified; null: no SOM stage").nullable(), |r| Value::I64(r.classified.map(|v| v as i64)))
        .col(f("unlike_references_share", "1", "share of the classified hits whose som_label is unlike_references (like none of the map's references); above 0.5 the map's classes do not describe the test"), |r| Value::F64(r.unlike_references_share));
    for (k, c) in classes.iter().enumerate() {
        t = t.col(
            i(
                &format!("{c}_hits"),
                &format!("hits the SOM classified {c}"),
            )
            .nullable(),
            move |r: &SeriesRow| Value::I64(r.classes.get(k).copied().flatten().map(|v| v as i64)),
        );
    }
    if clustering {
        t = t.col(
            i("clusters", "distinct clusters among the experiment's hits").nullable(),
            |r| Value::I64(r.clusters.map(|v| v as i64)),
        );
    }
    t.col(i("energy_n", "sources with a positive energy_eu (statistics.parquet n_energy)"), |r| Value::I64(Some(r.energy_n as i64)))
        .col(f("alpha", "1", "energy exponent of p(E) ∝ E^−α (statistics.parquet energy_alpha); null with fewer than 50 energies, the power law's minimum tail"), |r| Value::F64(r.alpha))
        .col(i("significant_trends", "significant rows of trend.parquet; null: no trend stage").nullable(), |r| Value::I64(r.significant_trends.map(|v| v as i64)))
        .col(ColumnSpec::new("trend_note", ColType::Utf8, "", "why a series of the experiment states no trend (n below trend.min_hits)").nullable(), |r| Value::Str(r.trend_note.clone()))
}

/// The classes the default reference map labels (the schema page's example columns).
pub fn default_classes() -> Vec<String> {
    crate::model::Mechanism::ALL
        .iter()
        .filter(|m| **m != crate::model::Mechanism::Unclassified)
        .map(|m| m.as_str().to_string())
        .collect()
}

fn scan_err(e: crate::store::StoreError) -> WorkflowError {
    e.into()
}

/// Per experiment: hits with a load, and the largest load with its time (of the hits).
fn hits_load(path: &Path) -> Result<BTreeMap<String, (u64, Option<(f64, f64)>)>, WorkflowError> {
    let mut out: BTreeMap<String, (u64, Option<(f64, f64)>)> = BTreeMap::new();
    peak_loads(path, |e, t, l| {
        let v = out.entry(e).or_default();
        if let Some(l) = l {
            v.0 += 1;
            peak(&mut v.1, t, l);
        }
    })?;
    Ok(out)
}

fn peak(p: &mut Option<(f64, f64)>, t: Option<f64>, l: f64) {
    if l.is_finite() && p.is_none_or(|(_, b)| l > b) {
        *p = Some((t.unwrap_or(f64::NAN), l));
    }
}

/// Each row's experiment, time and load, a batch at a time.
fn peak_loads(
    path: &Path,
    mut f: impl FnMut(String, Option<f64>, Option<f64>),
) -> Result<(), WorkflowError> {
    if !path.is_file() {
        return Ok(());
    }
    let scan = TableScan::open(path).map_err(scan_err)?;
    let sel = [cols::EXPERIMENT.name, cols::TIME_S.name, cols::LOAD_N.name];
    scan.require(&sel, "").map_err(scan_err)?;
    for b in scan.batches(&sel) {
        let (_, df) = b.map_err(scan_err)?;
        let e = scan.strings(&df, cols::EXPERIMENT.name).map_err(scan_err)?;
        let t = scan.f64s(&df, cols::TIME_S.name).map_err(scan_err)?;
        let l = scan.f64s(&df, cols::LOAD_N.name).map_err(scan_err)?;
        for ((e, t), l) in e.into_iter().zip(t).zip(l) {
            f(e.unwrap_or_default(), t, l);
        }
    }
    Ok(())
}

/// The series table of a run's summary, written to `path`.
pub(super) fn series_stage(s: &RunSummary, path: &Path) -> Result<Series, WorkflowError> {
    let st = &s.features.stats;
    let with_load = hits_load(&s.features.hits_path)?;
    let mut machine: BTreeMap<String, Option<(f64, f64)>> = BTreeMap::new();
    peak_loads(&s.features.parametric_path, |e, t, l| {
        if let Some(l) = l {
            peak(machine.entry(e).or_default(), t, l);
        }
    })?;
    // SOM classes per experiment.
    let mut som: BTreeMap<(String, String), u64> = BTreeMap::new();
    if let Some(m) = &s.som {
        TableScan::open(&m.classification)
            .map_err(scan_err)?
            .for_each_keyed_string(cols::SOM_LABEL.name, |k, l| {
                *som.entry((k.0, l)).or_insert(0) += 1;
                Ok::<(), WorkflowError>(())
            })?;
    }
    let classes: Vec<String> = match &s.som {
        Some(m) => m.classes.keys().filter(|c| *c != UNLIKE).cloned().collect(),
        None => Vec::new(),
    };
    // Distinct clusters per experiment.
    let mut clusters: BTreeMap<String, std::collections::BTreeSet<i64>> = BTreeMap::new();
    if let Some(c) = &s.cluster {
        let scan = TableScan::open(&c.report.clusters).map_err(scan_err)?;
        let sel = [cols::EXPERIMENT.name, "cluster"];
        scan.require(&sel, "").map_err(scan_err)?;
        for b in scan.batches(&sel) {
            let (_, df) = b.map_err(scan_err)?;
            let e = scan.strings(&df, cols::EXPERIMENT.name).map_err(scan_err)?;
            let k = scan.f64s(&df, "cluster").map_err(scan_err)?;
            for (e, k) in e.into_iter().zip(k) {
                if let Some(k) = k {
                    clusters
                        .entry(e.unwrap_or_default())
                        .or_default()
                        .insert(k as i64);
                }
            }
        }
    }
    let mut rows = Vec::new();
    // Rejects of files no experiment could be told for have an empty id: not a test.
    for (e, c) in st.by_experiment.iter().filter(|(e, _)| !e.is_empty()) {
        let stat = s.statistics.iter().find(|r| &r.experiment == e);
        let (hits_with_load, hit_peak) = with_load.get(e).copied().unwrap_or_default();
        let pk = machine.get(e).copied().flatten().or(hit_peak);
        let classified: Option<u64> = s.som.as_ref().map(|_| {
            som.iter()
                .filter(|((x, _), _)| x == e)
                .map(|(_, n)| *n)
                .sum()
        });
        let count = |c: &str| som.get(&(e.clone(), c.to_string())).copied();
        let trend = s.trend.as_ref();
        rows.push(SeriesRow {
            experiment: e.clone(),
            hits: c.hits,
            rejects: c.rejects,
            hits_with_load,
            peak_load_n: pk.map(|p| p.1),
            peak_load_s: pk.map(|p| p.0).filter(|t| t.is_finite()),
            unlike_references_share: classified
                .filter(|n| *n > 0)
                .map(|n| count(UNLIKE).unwrap_or(0) as f64 / n as f64),
            classified,
            classes: classes
                .iter()
                .map(|k| classified.map(|_| count(k).unwrap_or(0)))
                .collect(),
            clusters: s
                .cluster
                .as_ref()
                .map(|_| clusters.get(e).map_or(0, |s| s.len() as u64)),
            energy_n: stat.map_or(0, |r| r.n as u64),
            alpha: stat.and_then(|r| r.fit.map(|f| f.alpha)),
            significant_trends: trend
                .map(|t| t.significant.iter().filter(|r| &r.experiment == e).count() as u64),
            trend_note: trend.and_then(|t| {
                let notes: Vec<String> = t
                    .selections
                    .iter()
                    .filter(|sel| &sel.experiment == e)
                    .filter_map(|sel| Some(format!("ch{}: {}", sel.channel, t.too_few(sel)?)))
                    .collect();
                (!notes.is_empty()).then(|| notes.join("; "))
            }),
        });
    }
    let clustering = s.cluster.is_some();
    let t = series_table(&classes, clustering);
    let meta = [(
        "aepipe.config_sha256".to_string(),
        s.config.hash().to_string(),
    )];
    let mut w = TableWriter::create(path, t.schema(), &meta, 1024).map_err(scan_err)?;
    for r in &rows {
        w.push(t.row(r.clone())).map_err(scan_err)?;
    }
    w.finish().map_err(scan_err)?;
    Ok(Series {
        classes,
        clustering,
        rows,
        path: path.to_path_buf(),
    })
}

/// The terminal's table of the series, for up to `max` tests.
pub fn series_lines(s: &Series, max: usize) -> Vec<String> {
    if s.rows.len() > max {
        return vec![format!(
            "series: {} tests, side by side in {}",
            s.rows.len(),
            s.path.display()
        )];
    }
    let opt = |v: Option<f64>, d: usize| v.map_or("–".to_string(), |v| format!("{v:.d$}"));
    let mut head = format!(
        "{:<16} {:>6} {:>6} {:>10} {:>8} {:>7}",
        "series", "hits", "load", "peak N", "at s", "unlike"
    );
    for c in &s.classes {
        head += &format!(" {:>9}", short(c));
    }
    if s.clustering {
        head += &format!(" {:>8}", "clusters");
    }
    head += &format!(" {:>6}", "alpha");
    let mut l = vec![head];
    for r in &s.rows {
        let mut line = format!(
            "{:<16} {:>6} {:>6} {:>10} {:>8} {:>7}",
            r.experiment,
            r.hits,
            r.hits_with_load,
            opt(r.peak_load_n, 1),
            opt(r.peak_load_s, 1),
            r.unlike_references_share
                .map_or("–".to_string(), |v| format!("{:.0} %", 100.0 * v))
        );
        for v in &r.classes {
            line += &format!(" {:>9}", v.map_or("–".to_string(), |v| v.to_string()));
        }
        if s.clustering {
            line += &format!(
                " {:>8}",
                r.clusters.map_or("–".to_string(), |v| v.to_string())
            );
        }
        line += &format!(" {:>6}", opt(r.alpha, 2));
        l.push(line);
    }
    l
}

/// A class name cut to a column's width.
fn short(c: &str) -> String {
    c.chars().take(9).collect()
}
