//! What a run tells its caller: the terminal's headline lines and the JSON summary.

use super::*;
use crate::model::Mechanism;

/// Series (experiment × channel) the terminal gives a line each; a study of more says how
/// many more and where they are.
const SERIES_LINES: usize = 12;

fn more(l: &mut Vec<String>, n: usize, table: &Path) {
    if n > SERIES_LINES {
        l.push(format!(
            "  … and {} more series (all in {})",
            n - SERIES_LINES,
            table.display()
        ));
    }
}

/// The energy power law of each test (the first few) and the clustering's choice.
fn indices_lines(s: &RunSummary) -> Vec<String> {
    let mut l = Vec::new();
    for r in s.statistics.iter().take(SERIES_LINES) {
        if let Some(f) = &r.fit {
            l.push(format!(
                "energy power law {}: α = {:.3} ± {:.3} above {:.3e} eu ({} of {} sources; KS {:.3})",
                r.experiment, f.alpha, f.alpha_se, f.x_min, f.n_tail, r.n, f.ks_distance
            ));
        }
    }
    // The cycles of the `all` series: the SOM stage's, else the clusters'.
    let reloads = match (&s.som, &s.cluster) {
        (Some(m), _) => Some(&m.reloads),
        (None, Some(c)) => Some(&c.reloads),
        _ => None,
    };
    if let Some(reloads) = reloads {
        let mut by: Vec<(&str, Vec<String>)> = Vec::new();
        for r in reloads {
            match by.last_mut() {
                Some((e, v)) if *e == r.experiment => v.extend(r.reading()),
                _ => by.push((&r.experiment, r.reading().into_iter().collect())),
            }
        }
        for (exp, readings) in by.iter().take(SERIES_LINES) {
            l.push(format!(
                "load cycles {exp}: {}; Felicity ratio per reload {} (som/cycles.parquet)",
                readings.len() + 1,
                readings.join(", ")
            ));
        }
    }
    if let Some(e) = &s.export {
        for f in e.files.iter().take(SERIES_LINES) {
            l.push(format!(
                "export {}: {} rows → {}",
                f.experiment,
                f.rows,
                f.path.display()
            ));
        }
        l.extend(e.notes.iter().map(|n| format!("export note: {n}")));
    }
    if let Some(c) = &s.cluster {
        let r = &c.report;
        l.push(format!(
            "clusters ({}): k = {} by {} of {}..{}; hits per cluster {}",
            r.validity.first().map_or("", |v| v.method.as_str()),
            r.k,
            s.config.cluster.choose.as_str(),
            s.config.cluster.k_min,
            s.config.cluster.k_max,
            r.sizes
                .iter()
                .enumerate()
                .map(|(c, n)| format!("{c}: {n}"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    l
}

/// Terminal lines: the headline numbers.
/// What the tests' numbers rest on (one line each), and the tests side by side.
fn series_part(s: &RunSummary) -> Vec<String> {
    let st = &s.features.stats;
    let mut l = Vec::new();
    // What a test's numbers rest on (a rate implied, hits outside the machine log).
    l.extend(st.said_lines(SERIES_TABLE_TESTS));
    // A series of tests side by side (one test is the rest of this summary).
    if let Some(se) = s.series.as_ref().filter(|se| se.rows.len() > 1) {
        l.extend(crate::analysis::series::series_lines(
            se,
            SERIES_TABLE_TESTS,
        ));
    }
    l
}

/// The terminal prints the series table for up to this many tests.
const SERIES_TABLE_TESTS: usize = 20;

pub fn headline(s: &RunSummary) -> Vec<String> {
    let mut l = Vec::new();
    let st = &s.features.stats;
    l.push(format!(
        "hits: {} read, {} feature rows, {} rejects",
        st.records_read, st.rows, st.rejects
    ));
    l.extend(series_part(s));
    l.extend(trend_part(s));
    l.extend(som_part(s));
    if let Some(sc) = &s.sources {
        l.extend(sc.lines());
    }
    l.extend(indices_lines(s));
    l.extend(truth_part(s));
    if let Some(n) = s.page.as_ref().and_then(|p| p.note()) {
        l.push(n);
    }
    l.push(format!("stages: {}", crate::report::stage_line(s)));
    l
}

/// The trend lines: each series' selection and its significant trends.
fn trend_part(s: &RunSummary) -> Vec<String> {
    let mut l = Vec::new();
    let Some(t) = &s.trend else {
        return l;
    };
    for sel in t.selections.iter().take(SERIES_LINES) {
        l.push(format!(
            "trend {} ch{}: {} of {} hits used ({})",
            sel.experiment, sel.channel, sel.hits_used, sel.hits_total, sel.cutoff
        ));
        if let Some(few) = t.too_few(sel) {
            l.push(format!("  {few}"));
        }
    }
    more(&mut l, t.selections.len(), &t.table_path);
    let shown: std::collections::BTreeSet<(&str, i32)> = t
        .selections
        .iter()
        .take(SERIES_LINES)
        .map(|s| (s.experiment.as_str(), s.channel))
        .collect();
    for r in t
        .significant
        .iter()
        .filter(|r| shown.contains(&(r.experiment.as_str(), r.channel)))
    {
        if let Some(f) = &r.fit {
            l.push(format!(
                "  {:<16} r = {:+.2}  p = {:.1e}  slope {:+.2e}",
                crate::analysis::trend::window_name(&r.column),
                f.r,
                f.p,
                f.slope
            ));
        }
    }
    l
}

/// The SOM lines: what it was trained on, its classes, novelty, the damage profile.
fn som_part(s: &RunSummary) -> Vec<String> {
    let mut l = Vec::new();
    let Some(m) = &s.som else {
        return l;
    };
    l.push(format!(
        "SOM trained on {} ({} training rows)",
        m.trained_on, m.training_rows
    ));
    l.push(format!("SOM classes: {}", crate::util::tally(&m.classes)));
    l.push(m.confusion.novelty.describe());
    l.extend(m.profile.iter().take(SERIES_LINES).map(|p| p.line()));
    more(&mut l, m.profile.len(), &m.profile_table);
    if let Some(a) = m.confusion.accuracy() {
        l.push(format!(
            "agreement with the ch. 4.7 criteria labels: {}/{} = {:.1} %",
            m.confusion.correct,
            m.confusion.total,
            100.0 * a
        ));
    }
    l
}

/// Against the ground truth (a synthetic test): accuracy, recalls, Table 5.4.
fn truth_part(s: &RunSummary) -> Vec<String> {
    let mut l = Vec::new();
    let Some(t) = &s.truth else {
        return l;
    };
    if let Some(a) = t.accuracy() {
        l.push(format!(
            "accuracy against the ground truth, bond vs fibre failures: {}/{} = {:.1} %",
            t.bond_fibre_correct,
            t.bond_fibre_total,
            100.0 * a
        ));
    }
    l.push(format!(
        "recall by true class (→ the same SOM class): {}{}",
        t.recall_line(),
        t.balanced_accuracy().map_or(String::new(), |b| format!(
            "; balanced accuracy (mean of bond and fibre recalls) {:.1} %",
            100.0 * b
        ))
    ));
    let (ek, en) = t.erroneous_recall();
    let (ok, all) = t.thesis_overall();
    let called = t.erroneous_called();
    l.push(format!(
        "erroneous records kept from the mechanisms: {ek}/{en} ({called} called erroneous, {} unlike the references); overall the thesis's way (mechanism, or an erroneous record kept from the mechanisms, over all hits): {ok}/{all} = {:.1} %",
        ek - called,
        100.0 * ok as f64 / all.max(1) as f64
    ));
    let (bn, bt) = t.unlike(&[Mechanism::BondFailure, Mechanism::FibreFailure]);
    let (en, et) = t.unlike(&[Mechanism::Erroneous]);
    let (xn, xt) = t.unlike(&[Mechanism::Both]);
    if s.som
        .as_ref()
        .is_some_and(|m| m.confusion.novelty.threshold.is_some())
    {
        l.push(format!(
            "unlike the references, by truth: bond and fibre failures {bn}/{bt}, erroneous {en}/{et}, both {xn}/{xt}"
        ));
    }
    l.push("Table 5.4 (share of each SOM class's hits):".into());
    l.extend(t.format_table_5_4().lines().map(|x| format!("  {x}")));
    l
}

/// The run's summary as JSON, for callers that are not a terminal (the Python package's
/// `aepipe.run` returns it as a dict): where every output is, the counts, the significant
/// trends, the SOM's classes and the scores against a truth, the timings and the headline.
pub fn summary_json(s: &RunSummary) -> serde_json::Value {
    use serde_json::json;
    let dir = RunDir::new(&s.out);
    let path = |p: &Path| p.display().to_string();
    let existing = |p: PathBuf| p.is_file().then(|| path(&p));
    let st = &s.features.stats;
    let tables = tables_json(s, &dir);
    let trend = s.trend.as_ref().map(|t| {
        t.significant
            .iter()
            .map(|r| {
                json!({
                    "experiment": r.experiment, "channel": r.channel, "column": r.column,
                    "n": r.n, "cutoff": r.cutoff,
                    "r": r.fit.map(|f| f.r), "p": r.fit.map(|f| f.p),
                    "slope": r.fit.map(|f| f.slope), "intercept": r.fit.map(|f| f.intercept),
                })
            })
            .collect::<Vec<_>>()
    });
    let som = s.som.as_ref().map(som_json);
    let truth = s.truth.as_ref().map(truth_json);
    let report = existing(dir.report_html());
    json!({
        "out": path(&s.out),
        "report": report,
        "run_json": existing(dir.run_json()),
        "inputs": s.inputs.iter().map(|p| path(p)).collect::<Vec<_>>(),
        "tables": tables,
        "counts": {
            "records_read": st.records_read, "hits": st.hits, "feature_rows": st.rows,
            "rejects": st.rejects, "parametric": st.parametric, "markers": st.markers,
        },
        "trend_significant": trend,
        "som": som,
        "truth": truth,
        "cluster": s.cluster.as_ref().map(|c| json!({
            "k": c.report.k,
            "method": c.report.validity.first().map(|v| v.method.as_str()),
            "sizes": c.report.sizes,
            "clusters": path(&c.report.clusters),
            "validity": path(&c.report.validity_table),
        })),
        "seconds": s.seconds.iter().map(|(k, v)| (k.clone(), json!(v))).collect::<serde_json::Map<_, _>>(),
        "peak_rss_bytes": s.peak_rss.iter().map(|(k, v)| (k.clone(), json!(v))).collect::<serde_json::Map<_, _>>(),
        "headline": headline(s),
    })
}

/// The run's tables that exist, by name, for `summary.json`.
fn tables_json(s: &RunSummary, dir: &RunDir) -> serde_json::Map<String, serde_json::Value> {
    let path = |p: &Path| p.display().to_string();
    let existing = |p: PathBuf| p.is_file().then(|| path(&p));
    let mut tables = serde_json::Map::new();
    let f = &s.features;
    for (name, p) in [
        ("features", &f.table_path),
        ("hits", &f.hits_path),
        ("rejects", &f.rejects_path),
        ("parametric", &f.parametric_path),
        ("markers", &f.markers_path),
        ("events", &f.events_path),
    ] {
        if let Some(p) = existing(p.clone()) {
            tables.insert(name.into(), p.into());
        }
    }
    if let Some(t) = &s.trend {
        tables.insert("trend".into(), path(&t.table_path).into());
    }
    if let Some(m) = &s.som {
        tables.insert("classification".into(), path(&m.classification).into());
        tables.insert("damage_profile".into(), path(&m.profile_table).into());
        if let Some(p) = existing(dir.som().evolution()) {
            tables.insert("evolution".into(), p.into());
        }
        if let Some(p) = existing(dir.som().cycles()) {
            tables.insert("cycles".into(), p.into());
        }
    }
    tables
}

/// The SOM stage for `summary.json`: the map, its classes, its agreement with the criteria,
/// novelty and the reloads' Felicity ratios.
fn som_json(m: &SomStage) -> serde_json::Value {
    use serde_json::json;
    let path = |p: &Path| p.display().to_string();
    json!({
        "model": path(&m.model_dir),
        "trained_on": m.trained_on,
        "training_rows": m.training_rows,
        "classes": m.classes,
        "agreement_with_criteria": {"correct": m.confusion.correct, "total": m.confusion.total},
        "reading": m.confusion.reading.describe(),
        "novelty": {
            "threshold": m.confusion.novelty.threshold,
            "quantile": m.confusion.novelty.quantile,
            "calibrated_on": m.confusion.novelty.calibrated_on,
            "per_experiment": m.confusion.novelty.per_experiment.iter()
                .map(|(e, (n, t))| (e.clone(), json!({"novel": n, "classified": t})))
                .collect::<serde_json::Map<_, _>>(),
            "undescribed": m.confusion.novelty.undescribed(),
        },
        "reloads": m.reloads.iter().filter(|r| r.kaiser.is_some()).map(|r| json!({
            "experiment": r.experiment, "cycle": r.cycle.index,
            "previous_max_n": r.cycle.previous_max_n, "onset_load_n": r.onset_load_n,
            "felicity_ratio": r.felicity_ratio, "kaiser": r.kaiser,
        })).collect::<Vec<_>>(),
    })
}

/// The truth table's counts for `summary.json`.
fn truth_json(t: &TruthScore) -> serde_json::Value {
    use serde_json::json;
    let path = |p: &Path| p.display().to_string();
    let (ek, en) = t.erroneous_recall();
    let (ok, all) = t.thesis_overall();
    json!({
        "path": path(&t.path),
        "bond_vs_fibre": {"correct": t.bond_fibre_correct, "total": t.bond_fibre_total},
        "erroneous_recognised": {"correct": ek, "total": en, "called_erroneous": t.erroneous_called(), "novel": ek - t.erroneous_called()},
        "thesis_overall": {"correct": ok, "total": all},
        "recall": Mechanism::ALL.iter().filter_map(|&m| {
            let (k, n) = t.recall(m);
            (n > 0).then(|| (m.as_str().to_string(), json!({"correct": k, "total": n})))
        }).collect::<serde_json::Map<_, _>>(),
        "balanced_accuracy": t.balanced_accuracy(),
    })
}
