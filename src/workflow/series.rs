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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::powerlaw::{PowerLawFit, StatRow};
    use crate::analysis::trend::{Selection, TrendReport, TrendRow};
    use crate::model::{HitRow, ParametricRow};
    use crate::pipeline::{Counts, StreamStats};
    use crate::report::ClusterStage;
    use crate::store::{ColType, ColumnSpec, Table, Value};

    /// Experiment, channel, hit, and a label or a cluster.
    type Keyed<T> = (&'static str, i32, i64, T);

    fn keyed<T: Clone + 'static>(
        name: &str,
        spec: ColumnSpec,
        get: fn(&T) -> Value,
    ) -> Table<Keyed<T>> {
        Table::new(name)
            .col(ColumnSpec::of(cols::EXPERIMENT, "", ""), |r: &Keyed<T>| {
                Value::Str(Some(r.0.to_string()))
            })
            .col(ColumnSpec::of(cols::CHANNEL, "", ""), |r| {
                Value::I32(Some(r.1))
            })
            .col(ColumnSpec::of(cols::HIT, "", ""), |r| Value::I64(Some(r.2)))
            .col(spec, move |r| get(&r.3))
    }

    fn stat(experiment: &str, n: usize, alpha: Option<f64>) -> StatRow {
        StatRow {
            experiment: experiment.into(),
            n,
            fit: alpha.map(|alpha| PowerLawFit {
                x_min: 1.0,
                alpha,
                alpha_se: 0.1,
                ks_distance: 0.05,
                n_tail: n,
            }),
        }
    }

    fn selection(experiment: &str, channel: i32, used: usize) -> Selection {
        Selection {
            experiment: experiment.into(),
            channel,
            hits_total: used,
            hits_used: used,
            last_hit: None,
            cutoff: "none (all hits)".into(),
            peak_load_n: None,
            peak_load_time_s: None,
            note: None,
        }
    }

    fn significant(experiment: &str, column: &str) -> TrendRow {
        TrendRow {
            experiment: experiment.into(),
            channel: 1,
            column: column.into(),
            n: 12,
            cutoff: "none (all hits)".into(),
            fit: None,
            significant: true,
            note: None,
        }
    }

    /// Hits (experiment, time s, load N), in the order of hits.parquet.
    const HITS: [(&str, f64, Option<f64>); 8] = [
        ("A", 1.0, Some(10.0)),
        ("A", 2.0, Some(30.0)),
        ("A", 3.0, None),
        ("A", 4.0, Some(20.0)),
        ("B", 1.0, None),
        ("B", 2.0, None),
        ("C", 1.0, Some(8.0)),
        ("C", 2.0, Some(9.0)),
    ];

    /// A run of three tests written by hand into `dir`: A's machine log peaks above its
    /// hits' loads, B has a log and no hit with a load, C only hits with loads; the SOM
    /// classified A's four hits (one unlike the references) and none of B's or C's; A's
    /// hits fall in two clusters (one hit in none), B's in one; A and B have energies (A
    /// enough for an exponent); A has two significant trends, B two series below
    /// `min_hits`. `clusters` is the clusters table's rows.
    fn summary(dir: &Path, clusters: &[Keyed<Option<i64>>]) -> RunSummary {
        std::fs::create_dir_all(dir).unwrap();
        let feats = RunReport::of_tables(
            &crate::pipeline::StreamDir::new(dir),
            crate::pipeline::StreamJob::Features,
            StreamStats::default(),
        );
        let hits = HITS.iter().enumerate().map(|(k, (e, t, l))| HitRow {
            experiment: e.to_string(),
            channel: 1,
            hit: k as u64 + 1,
            time_s: Some(*t),
            load_n: *l,
            ..Default::default()
        });
        crate::store::hits_table(Default::default())
            .write_all(&feats.hits_path, &[], 4, hits)
            .unwrap();
        let log = [
            ("A", 0.5, 25.0),
            ("A", 2.5, 40.0),
            ("B", 0.5, 5.0),
            ("B", 1.5, 7.0),
        ];
        let log = log.iter().map(|(e, t, l)| ParametricRow {
            experiment: e.to_string(),
            time_s: Some(*t),
            load_n: Some(*l),
            ..Default::default()
        });
        crate::store::parametric_table()
            .write_all(&feats.parametric_path, &[], 4, log)
            .unwrap();
        let label = ColumnSpec::of(cols::SOM_LABEL, "", "");
        let labels: [Keyed<&str>; 4] = [
            ("A", 1, 1, "fibre_failure"),
            ("A", 1, 2, "fibre_failure"),
            ("A", 1, 3, UNLIKE),
            ("A", 1, 4, "bond_failure"),
        ];
        let classification = dir.join("classification.parquet");
        keyed("classification", label, |l: &&str| {
            Value::Str(Some(l.to_string()))
        })
        .write_all(&classification, &[], 4, labels)
        .unwrap();
        let cluster = ColumnSpec::new("cluster", ColType::Int64, "", "").nullable();
        let cluster_path = dir.join("clusters.parquet");
        keyed("clusters", cluster, |c: &Option<i64>| Value::I64(*c))
            .write_all(&cluster_path, &[], 4, clusters.to_vec())
            .unwrap();
        let mut stats = StreamStats::default();
        for (e, hits, rejects) in [("A", 4, 1), ("B", 2, 0), ("C", 2, 0), ("", 0, 3)] {
            let c = Counts {
                hits,
                rejects,
                ..Default::default()
            };
            stats.by_experiment.insert(e.to_string(), c);
        }
        let features = RunReport { stats, ..feats };
        let classes: BTreeMap<String, usize> =
            [("bond_failure", 1), ("fibre_failure", 2), (UNLIKE, 1)]
                .map(|(c, n)| (c.to_string(), n))
                .into();
        RunSummary {
            out: dir.to_path_buf(),
            inputs: vec![],
            features,
            trend: Some(TrendReport {
                significant: vec![significant("A", "pr_x"), significant("A", "pr_y")],
                selections: vec![
                    selection("A", 1, 12),
                    selection("B", 1, 2),
                    selection("B", 2, 3),
                ],
                columns: vec!["pr_x".into(), "pr_y".into()],
                table_path: dir.join("trend.parquet"),
                min_hits: 10,
            }),
            trend_plots: vec![],
            som: Some(crate::report::SomStage {
                model_dir: dir.to_path_buf(),
                trained_on: "reference".into(),
                map_cache: None,
                training_rows: 0,
                confusion: Default::default(),
                classification,
                u_matrix: None,
                hit_maps: None,
                ra_af_plot: None,
                classes,
                profile_table: dir.join("p.parquet"),
                profile: vec![],
                profile_plots: vec![],
                evolution_table: dir.join("e.parquet"),
                evolution_plots: vec![],
                reloads: vec![],
                location_plots: vec![],
            }),
            cluster: Some(ClusterStage {
                report: crate::cluster::ClusterReport {
                    columns: vec![],
                    rows: clusters.len(),
                    skipped: 0,
                    fit_rows: clusters.len(),
                    validity: vec![],
                    k: 3,
                    sizes: vec![],
                    clusters: cluster_path,
                    validity_table: dir.join("v.parquet"),
                    model: dir.join("model.json"),
                },
                validity_png: dir.join("v.png"),
                ra_af_pngs: vec![],
                cumulative_pngs: vec![],
                distributions_png: None,
                location_pngs: vec![],
                pictured: vec![],
                evolution_pngs: vec![],
                reloads: vec![],
            }),
            export: None,
            statistics: vec![stat("A", 60, Some(1.7)), stat("B", 3, None)],
            truth: None,
            sources: None,
            config: Default::default(),
            seconds: vec![],
            peak_rss: vec![],
            series: None,
            page: None,
        }
    }

    const CLUSTERS: [Keyed<Option<i64>>; 5] = [
        ("A", 1, 1, Some(0)),
        ("A", 1, 2, Some(1)),
        ("A", 1, 3, Some(1)),
        ("A", 1, 4, None),
        ("B", 1, 5, Some(2)),
    ];

    /// The rows worked out by hand from [`summary`]'s tables.
    fn expected() -> Vec<SeriesRow> {
        let too_few = |n: usize| format!("n = {n}: too few hits for a trend (trend.min_hits = 10)");
        vec![
            SeriesRow {
                experiment: "A".into(),
                hits: 4,
                rejects: 1,
                hits_with_load: 3,
                peak_load_n: Some(40.0),
                peak_load_s: Some(2.5),
                classified: Some(4),
                unlike_references_share: Some(0.25),
                classes: vec![Some(1), Some(2)],
                clusters: Some(2),
                energy_n: 60,
                alpha: Some(1.7),
                significant_trends: Some(2),
                trend_note: None,
            },
            SeriesRow {
                experiment: "B".into(),
                hits: 2,
                peak_load_n: Some(7.0),
                peak_load_s: Some(1.5),
                classified: Some(0),
                classes: vec![Some(0), Some(0)],
                clusters: Some(1),
                energy_n: 3,
                significant_trends: Some(0),
                trend_note: Some(format!("ch1: {}; ch2: {}", too_few(2), too_few(3))),
                ..Default::default()
            },
            SeriesRow {
                experiment: "C".into(),
                hits: 2,
                hits_with_load: 2,
                peak_load_n: Some(9.0),
                peak_load_s: Some(2.0),
                classified: Some(0),
                classes: vec![Some(0), Some(0)],
                clusters: Some(0),
                significant_trends: Some(0),
                ..Default::default()
            },
        ]
    }

    /// Each row of a hand-built run is the one worked out from its tables: hits with a
    /// load, the machine log's peak (else the hits'), the classes and the share unlike the
    /// references, distinct clusters (a hit in none not counted), energies, significant
    /// trends and the series below `min_hits`; the experiment-less rejects make no row; the
    /// file holds the rows. Plant: the same run with A's cluster-less hit put in a third
    /// cluster gives A 3 clusters, and the check fails.
    #[test]
    fn each_row_is_counted_from_the_runs_tables() {
        let dir = std::env::temp_dir().join(format!("aepipe-series-{}", std::process::id()));
        let s = summary(&dir, &CLUSTERS);
        let got = series_stage(&s, &dir.join("series.parquet")).unwrap();
        assert_eq!(got.classes, ["bond_failure", "fibre_failure"]);
        assert!(got.clustering);
        assert_eq!(got.rows, expected());
        let (schema, _, batches) = crate::store::read_parquet(&got.path).unwrap();
        assert_eq!(batches.iter().map(|b| b.num_rows()).sum::<usize>(), 3);
        let names: Vec<&str> = schema.fields().iter().map(|f| f.name().as_str()).collect();
        assert!(names.contains(&"fibre_failure_hits") && names.contains(&"clusters"));
        let mut planted = CLUSTERS;
        planted[3].3 = Some(2);
        let s = summary(&dir.join("plant"), &planted);
        let got = series_stage(&s, &dir.join("plant/series.parquet")).unwrap();
        assert_ne!(got.rows, expected());
        assert_eq!(got.rows[0].clusters, Some(3));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
