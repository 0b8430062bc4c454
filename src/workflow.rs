//! `aepipe run`: the whole staged method from one pipeline definition — features → trend →
//! SOM (trained on a reference library or on criteria-labelled hits) → classification →
//! accuracy against ground truth when there is one → the HTML report.

use crate::config::PipelineConfig;
use crate::pipeline::{RunOptions, RunReport};
use crate::som::run::Confusion;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What a run produced, for the terminal and the report.
pub struct RunSummary {
    pub out: PathBuf,
    pub inputs: Vec<PathBuf>,
    pub features: RunReport,
    pub trend: Option<crate::analysis::trend::TrendReport>,
    pub trend_plots: Vec<(String, PathBuf)>,
    pub som: Option<SomStage>,
    pub truth: Option<TruthScore>,
    pub config: PipelineConfig,
    pub seconds: Vec<(String, f64)>,
}

pub struct SomStage {
    pub model_dir: PathBuf,
    pub trained_on: String,
    pub training_rows: usize,
    /// Against the criteria labels of the run's hits (Table 5.4 orientation).
    pub confusion: Confusion,
    pub classification: PathBuf,
    pub u_matrix: Option<PathBuf>,
    pub hit_maps: Option<PathBuf>,
    /// SOM class → number of hits.
    pub classes: BTreeMap<String, usize>,
}

/// Classification against the ground truth (`truth.parquet`).
pub struct TruthScore {
    pub path: PathBuf,
    /// (SOM class, true mechanism) → hits.
    pub counts: BTreeMap<(String, String), usize>,
    /// Bond vs fibre failures: hits whose truth is one of the two, and how many the SOM got.
    pub bond_fibre_total: usize,
    pub bond_fibre_correct: usize,
}

impl TruthScore {
    pub fn accuracy(&self) -> Option<f64> {
        (self.bond_fibre_total > 0)
            .then(|| self.bond_fibre_correct as f64 / self.bond_fibre_total as f64)
    }
}

/// Options that are not part of the pipeline definition.
pub struct Job<'a> {
    pub config: &'a PipelineConfig,
    pub inputs: &'a [PathBuf],
    pub out: &'a Path,
    pub truth: Option<&'a Path>,
    pub threads: usize,
    pub progress: bool,
}

/// Run every enabled stage.
pub fn run(job: &Job) -> Result<RunSummary, String> {
    let cfg = job.config;
    let mut seconds = Vec::new();
    let t = std::time::Instant::now();
    let features = crate::pipeline::run(
        crate::pipeline::Job::Features,
        job.inputs,
        &job.out.join("features"),
        cfg,
        &RunOptions {
            threads: job.threads,
            progress: job.progress,
        },
    )
    .map_err(|e| e.to_string())?;
    seconds.push(("features".to_string(), t.elapsed().as_secs_f64()));
    let feats = vec![features.table_path.clone()];

    let (mut trend, mut trend_plots) = (None, Vec::new());
    if cfg.trend.enabled {
        let t = std::time::Instant::now();
        let (rep, plots) = trend_stage(cfg, &feats, &job.out.join("trend"))?;
        trend = Some(rep);
        trend_plots = plots;
        seconds.push(("trend".to_string(), t.elapsed().as_secs_f64()));
    }

    let mut som = None;
    if cfg.som.enabled {
        let t = std::time::Instant::now();
        som = Some(som_stage(job, &feats)?);
        seconds.push(("som".to_string(), t.elapsed().as_secs_f64()));
    }
    let truth = match (job.truth, &som) {
        (Some(p), Some(s)) => Some(score_truth(p, &s.classification)?),
        _ => None,
    };
    let mut summary = RunSummary {
        out: job.out.to_path_buf(),
        inputs: job.inputs.to_vec(),
        features,
        trend,
        trend_plots,
        som,
        truth,
        config: cfg.clone(),
        seconds,
    };
    if cfg.report.enabled {
        let t = std::time::Instant::now();
        crate::report::write(&summary, &job.out.join("report.html"))?;
        summary
            .seconds
            .push(("report".to_string(), t.elapsed().as_secs_f64()));
    }
    write_run_json(&summary)?;
    Ok(summary)
}

/// `RUN_DIR/run.json`: what `aepipe report` needs besides the run's tables.
#[derive(serde::Serialize, serde::Deserialize)]
struct RunFile {
    tool_version: String,
    inputs: Vec<PathBuf>,
    truth: Option<PathBuf>,
    /// The effective pipeline definition (canonical TOML).
    config: String,
    seconds: Vec<(String, f64)>,
    som_trained_on: Option<String>,
    som_training_rows: Option<usize>,
}

fn write_run_json(s: &RunSummary) -> Result<(), String> {
    let f = RunFile {
        tool_version: env!("CARGO_PKG_VERSION").into(),
        inputs: s.inputs.clone(),
        truth: s.truth.as_ref().map(|t| t.path.clone()),
        config: s.config.to_toml(),
        seconds: s.seconds.clone(),
        som_trained_on: s.som.as_ref().map(|m| m.trained_on.clone()),
        som_training_rows: s.som.as_ref().map(|m| m.training_rows),
    };
    let p = s.out.join("run.json");
    crate::pipeline::write_atomic(
        &p,
        serde_json::to_string_pretty(&f).expect("json").as_bytes(),
    )
    .map_err(|e| format!("{}: {e}", p.display()))
}

/// `aepipe report RUN_DIR`: rebuild the summary of a finished run from its folder (tables,
/// model, `run.json`; the trend and the classification are recomputed, deterministically)
/// and write `RUN_DIR/report.html` again.
pub fn rebuild_report(dir: &Path) -> Result<PathBuf, String> {
    let rp = dir.join("run.json");
    let text = std::fs::read_to_string(&rp)
        .map_err(|e| format!("{}: {e} (not a folder written by aepipe run)", rp.display()))?;
    let f: RunFile = serde_json::from_str(&text).map_err(|e| format!("{}: {e}", rp.display()))?;
    let config =
        PipelineConfig::from_toml(&f.config).map_err(|e| format!("{}: {e}", rp.display()))?;
    let fdir = dir.join("features");
    let mp = fdir.join("manifest.json");
    let m: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(&mp).map_err(|e| format!("{}: {e}", mp.display()))?,
    )
    .map_err(|e| format!("{}: {e}", mp.display()))?;
    let c = &m["counts"];
    let mut stats = crate::pipeline::StreamStats {
        records_read: c["records_read"].as_u64().unwrap_or(0),
        rows: c["rows_written"].as_u64().unwrap_or(0),
        rejects: c["rejects"].as_u64().unwrap_or(0),
        ..Default::default()
    };
    if let Some(o) = c["by_experiment"].as_object() {
        for (k, v) in o {
            stats.by_experiment.insert(
                k.clone(),
                crate::pipeline::Counts {
                    rows: v["rows"].as_u64().unwrap_or(0),
                    rejects: v["rejects"].as_u64().unwrap_or(0),
                },
            );
        }
    }
    let features = RunReport {
        stats,
        table_path: fdir.join("features.parquet"),
        rejects_path: fdir.join("rejects.parquet"),
        manifest_path: mp,
        sources: vec![],
        skipped: vec![],
    };
    let feats = vec![features.table_path.clone()];
    let (mut trend, mut trend_plots) = (None, Vec::new());
    let tdir = dir.join("trend");
    if config.trend.enabled && tdir.is_dir() {
        let (rep, plots) = trend_stage(&config, &feats, &tdir)?;
        trend = Some(rep);
        trend_plots = plots;
    }
    let sdir = dir.join("som");
    let mut som = None;
    if config.som.enabled && sdir.join("model/model.json").is_file() {
        let model = crate::som::run::load_model(&sdir.join("model")).map_err(|e| e.to_string())?;
        let confusion = crate::som::run::classify(&model, &feats, Some("criteria_label"), &sdir)
            .map_err(|e| e.to_string())?;
        let classes = classes_of(&confusion);
        let existing = |p: PathBuf| p.is_file().then_some(p);
        som = Some(SomStage {
            model_dir: sdir.join("model"),
            trained_on: f.som_trained_on.clone().unwrap_or_default(),
            training_rows: f.som_training_rows.unwrap_or(0),
            confusion,
            classification: sdir.join("classification.parquet"),
            u_matrix: existing(sdir.join("u_matrix.png")),
            hit_maps: existing(sdir.join("hit_maps.png")),
            classes,
        });
    }
    let truth = match (&f.truth, &som) {
        (Some(p), Some(s)) => Some(score_truth(p, &s.classification)?),
        _ => None,
    };
    let summary = RunSummary {
        out: dir.to_path_buf(),
        inputs: f.inputs,
        features,
        trend,
        trend_plots,
        som,
        truth,
        config,
        seconds: f.seconds,
    };
    let out = dir.join("report.html");
    crate::report::write(&summary, &out)?;
    Ok(out)
}

/// The trend statistics of the feature tables into `dir`, with a Fig. 4.18 plot per
/// experiment × channel that has significant windows.
fn trend_stage(
    cfg: &PipelineConfig,
    feats: &[PathBuf],
    dir: &Path,
) -> Result<(crate::analysis::trend::TrendReport, Vec<(String, PathBuf)>), String> {
    let opts = crate::analysis::trend::TrendOptions {
        cutoff: cfg
            .trend
            .cutoff
            .parse()
            .map_err(|e: String| format!("trend.cutoff: {e}"))?,
        alpha: cfg.trend.alpha,
        columns: vec![],
    };
    let rep = crate::analysis::trend::run_trend(feats, dir, &opts).map_err(|e| e.to_string())?;
    let mut plots = Vec::new();
    for sel in &rep.selections {
        let png = dir.join(format!("trend_{}_ch{}.png", sel.experiment, sel.channel));
        if let Ok(true) = crate::plot::trend_png(&png, &rep, &sel.experiment, sel.channel, 4) {
            plots.push((format!("{} ch{}", sel.experiment, sel.channel), png));
        }
    }
    Ok((rep, plots))
}

/// Hits per SOM class.
fn classes_of(c: &Confusion) -> BTreeMap<String, usize> {
    let mut classes = BTreeMap::new();
    for ((s, _), n) in &c.counts {
        *classes.entry(s.clone()).or_insert(0) += n;
    }
    classes
}

fn som_stage(job: &Job, feats: &[PathBuf]) -> Result<SomStage, String> {
    use crate::som::run::{classify, train, TrainOptions, TrainingSet};
    let cfg = job.config;
    let som_dir = job.out.join("som");
    let (train_paths, label, fraction, trained_on) = if cfg.som.train_on == "reference" {
        let lib = if cfg.som.reference_library.is_empty() {
            let f = crate::sim::reference::ReferenceFile::default_library();
            let dir = job.out.join("reference");
            crate::sim::reference::build_library(&f.reference, &dir, job.progress)
                .map_err(|e| e.to_string())?;
            dir.join("waveforms.parquet")
        } else {
            PathBuf::from(&cfg.som.reference_library)
        };
        // The library's features, with the run's own settings.
        let rep = crate::pipeline::run(
            crate::pipeline::Job::Features,
            std::slice::from_ref(&lib),
            &job.out.join("reference-features"),
            cfg,
            &RunOptions {
                threads: job.threads,
                progress: false,
            },
        )
        .map_err(|e| e.to_string())?;
        (
            vec![rep.table_path],
            "label".to_string(),
            1.0,
            format!("reference library {} (simulated labels)", lib.display()),
        )
    } else {
        (
            feats.to_vec(),
            "criteria_label".to_string(),
            cfg.som.fraction,
            format!(
                "{:.0} % of the run's hits, criteria labels (ch. 5.4)",
                100.0 * cfg.som.fraction
            ),
        )
    };
    let o = TrainOptions {
        label,
        rows: cfg.som.rows,
        cols: cfg.som.cols,
        seed: cfg.som.seed,
        training: TrainingSet {
            fraction,
            seed: cfg.som.seed,
            ..Default::default()
        },
        ..Default::default()
    };
    let model_dir = som_dir.join("model");
    let model = train(&train_paths, &model_dir, &o).map_err(|e| e.to_string())?;
    let confusion =
        classify(&model, feats, Some("criteria_label"), &som_dir).map_err(|e| e.to_string())?;
    let u = som_dir.join("u_matrix.png");
    let u_matrix = crate::plot::u_matrix_png(&u, &model.som).ok().map(|_| u);
    let hm = som_dir.join("hit_maps.png");
    let hit_maps = crate::plot::hit_maps_png(&hm, &model.som, &confusion.hits)
        .ok()
        .map(|_| hm);
    let classes = classes_of(&confusion);
    Ok(SomStage {
        model_dir,
        trained_on,
        training_rows: model.composition.values().map(|(_, r)| r).sum(),
        confusion,
        classification: som_dir.join("classification.parquet"),
        u_matrix,
        hit_maps,
        classes,
    })
}

/// A hit's key in every table: (experiment, channel, hit).
pub type HitKey = (String, i32, i64);

/// Draw the CWT of the chosen hits (one pass over the inputs) into `dir`; returns the PNG
/// of each hit drawn.
pub fn draw_gallery(
    inputs: &[PathBuf],
    cfg: &PipelineConfig,
    chosen: &BTreeMap<String, Vec<(String, i32, i64)>>,
    dir: &Path,
) -> BTreeMap<(String, i32, i64), PathBuf> {
    let want: std::collections::BTreeSet<&(String, i32, i64)> = chosen.values().flatten().collect();
    let mut out = BTreeMap::new();
    if want.is_empty() || std::fs::create_dir_all(dir).is_err() {
        return out;
    }
    let mut ex = crate::features::FeatureExtractor::new(cfg);
    let d = crate::ingest::discover(inputs, &cfg.ingest);
    for src in &d.sources {
        for it in crate::ingest::open(src, &cfg.ingest) {
            let crate::model::Item::Record(r) = it else {
                continue;
            };
            let key = (r.experiment.clone(), r.channel as i32, r.hit as i64);
            if !want.contains(&key) || crate::features::validate(&r, cfg).is_err() {
                continue;
            }
            let a = ex.analyse(&r);
            let (freqs, power) = ex.full_cwt(&r);
            let png = dir.join(format!("{}_ch{}_hit{}.png", key.0, key.1, key.2));
            if crate::plot::cwt_png(
                &png,
                &r,
                &freqs,
                &power,
                &format!("{} — {}", r.id(), a.label),
            )
            .is_ok()
            {
                out.insert(key, png);
            }
        }
    }
    out
}

/// Read a string column and the (experiment, channel, hit) key of every row.
pub fn keyed_column(path: &Path, column: &str) -> Result<Vec<(HitKey, String)>, String> {
    use arrow::array::{Array, AsArray};
    use arrow::datatypes::{Int32Type, Int64Type};
    let (_, _, batches) = crate::store::read_parquet(path).map_err(|e| e.to_string())?;
    let mut out = Vec::new();
    for b in batches {
        let get = |n: &str| {
            b.column_by_name(n)
                .ok_or_else(|| format!("{}: no column {n}", path.display()))
        };
        let e = get("experiment")?
            .as_string_opt::<i32>()
            .ok_or("experiment: not a string")?
            .clone();
        let c = get("channel")?
            .as_primitive_opt::<Int32Type>()
            .ok_or("channel: not int32")?
            .clone();
        let h = get("hit")?
            .as_primitive_opt::<Int64Type>()
            .ok_or("hit: not int64")?
            .clone();
        let v = get(column)?
            .as_string_opt::<i32>()
            .ok_or(format!("{column}: not a string"))?
            .clone();
        for i in 0..b.num_rows() {
            let val = if v.is_null(i) {
                String::new()
            } else {
                v.value(i).to_string()
            };
            out.push(((e.value(i).to_string(), c.value(i), h.value(i)), val));
        }
    }
    Ok(out)
}

/// Compare the SOM classes with `truth.parquet`.
pub fn score_truth(truth: &Path, classification: &Path) -> Result<TruthScore, String> {
    let t: BTreeMap<_, _> = keyed_column(truth, "mechanism")?.into_iter().collect();
    let mut s = TruthScore {
        path: truth.to_path_buf(),
        counts: BTreeMap::new(),
        bond_fibre_total: 0,
        bond_fibre_correct: 0,
    };
    for (key, class) in keyed_column(classification, "som_label")? {
        let Some(m) = t.get(&key) else { continue };
        *s.counts.entry((class.clone(), m.clone())).or_insert(0) += 1;
        if m == "bond_failure" || m == "fibre_failure" {
            s.bond_fibre_total += 1;
            if &class == m {
                s.bond_fibre_correct += 1;
            }
        }
    }
    Ok(s)
}

/// Terminal lines: the headline numbers.
pub fn headline(s: &RunSummary) -> Vec<String> {
    let mut l = Vec::new();
    let st = &s.features.stats;
    l.push(format!(
        "hits: {} read, {} feature rows, {} rejects",
        st.records_read, st.rows, st.rejects
    ));
    if let Some(t) = &s.trend {
        for sel in &t.selections {
            l.push(format!(
                "trend {} ch{}: {} of {} hits used ({})",
                sel.experiment, sel.channel, sel.hits_used, sel.hits_total, sel.cutoff
            ));
        }
        for r in t.rows.iter().filter(|r| r.significant) {
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
    }
    if let Some(m) = &s.som {
        l.push(format!(
            "SOM trained on {} ({} training rows)",
            m.trained_on, m.training_rows
        ));
        l.push(format!(
            "SOM classes: {}",
            m.classes
                .iter()
                .map(|(k, v)| format!("{k} {v}"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
        if let Some(a) = m.confusion.accuracy() {
            l.push(format!(
                "agreement with the ch. 4.7 criteria labels: {}/{} = {:.1} %",
                m.confusion.correct,
                m.confusion.total,
                100.0 * a
            ));
        }
    }
    if let Some(t) = &s.truth {
        if let Some(a) = t.accuracy() {
            l.push(format!(
                "accuracy against the ground truth, bond vs fibre failures: {}/{} = {:.1} %",
                t.bond_fibre_correct,
                t.bond_fibre_total,
                100.0 * a
            ));
        }
    }
    l.push(format!(
        "stages: {}",
        s.seconds
            .iter()
            .map(|(k, v)| format!("{k} {v:.1} s"))
            .collect::<Vec<_>>()
            .join(", ")
    ));
    l
}
