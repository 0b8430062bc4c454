//! Gathers `series.parquet` ([`crate::analysis::series`]) from the tables a run wrote, a
//! batch at a time: hits with a load, the peak load, the SOM's classes, the clusters, the
//! energy exponent and the trends of each experiment.

use super::*;
use crate::analysis::series::series_table;
pub use crate::analysis::series::{Series, SeriesRow};
use crate::model::columns as cols;
use crate::model::UNLIKE_REFERENCES as UNLIKE;
use crate::store::{TableScan, TableWriter};

fn scan_err(e: crate::store::StoreError) -> WorkflowError {
    e.into()
}

/// Hits with a load, and the largest load with its time (s, N).
type WithLoad = (u64, Option<(f64, f64)>);

/// Per experiment: hits with a load, and the largest load with its time (of the hits).
fn hits_load(path: &Path) -> Result<BTreeMap<String, WithLoad>, WorkflowError> {
    let mut out: BTreeMap<String, WithLoad> = BTreeMap::new();
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

/// Hits per (experiment, SOM label) of a classification table.
fn som_counts(path: &Path) -> Result<BTreeMap<(String, String), u64>, WorkflowError> {
    let mut som = BTreeMap::new();
    TableScan::open(path)
        .map_err(scan_err)?
        .for_each_keyed_string(cols::SOM_LABEL.name, |k, l| {
            *som.entry((k.0, l)).or_insert(0) += 1;
            Ok::<(), WorkflowError>(())
        })?;
    Ok(som)
}

/// The distinct clusters of each experiment in a clusters table.
fn cluster_counts(
    path: &Path,
) -> Result<BTreeMap<String, std::collections::BTreeSet<i64>>, WorkflowError> {
    let mut clusters: BTreeMap<String, std::collections::BTreeSet<i64>> = BTreeMap::new();
    let scan = TableScan::open(path).map_err(scan_err)?;
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
    Ok(clusters)
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
    let som = match &s.som {
        Some(m) => som_counts(&m.classification)?,
        None => BTreeMap::new(),
    };
    let classes: Vec<String> = match &s.som {
        Some(m) => m.classes.keys().filter(|c| *c != UNLIKE).cloned().collect(),
        None => Vec::new(),
    };
    let clusters = match &s.cluster {
        Some(c) => cluster_counts(&c.report.clusters)?,
        None => BTreeMap::new(),
    };
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
