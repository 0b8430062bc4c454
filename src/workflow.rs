//! `aepipe run`: the whole staged method from one pipeline definition — features → trend →
//! SOM (trained on a reference library or on criteria-labelled hits) → classification →
//! accuracy against ground truth when there is one → the HTML report. Also the commands
//! that read inputs to draw (`aepipe cwt`) and rebuild a report from a run folder.

use crate::analysis::trend::{TrendError, TrendReport};
use crate::config::{ConfigError, PipelineConfig};
use crate::pipeline::{PipelineError, RunReport, StreamOptions};
use crate::report::{Gallery, Gathered};
pub use crate::report::{RunSummary, SomStage, TruthScore};
use crate::som::tables::Confusion;
use crate::som::SomError;
use crate::store::{HitKey, StoreError, TableScan};
use crate::util::IoAt;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Why a run (or a report rebuild, or a drawing) failed; each stage's own error inside.
#[derive(Debug, thiserror::Error)]
pub enum WorkflowError {
    #[error(transparent)]
    Config(#[from] ConfigError),
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    #[error(transparent)]
    Merge(#[from] crate::pipeline::MergeError),
    #[error(transparent)]
    Trend(#[from] TrendError),
    #[error(transparent)]
    Som(#[from] SomError),
    #[error(transparent)]
    Sim(#[from] crate::sim::SimError),
    #[error(transparent)]
    Synth(#[from] crate::synth::SynthError),
    #[error(transparent)]
    Store(#[from] StoreError),
    #[error(transparent)]
    Report(#[from] crate::report::ReportError),
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
    #[error(transparent)]
    Write(#[from] IoAt),
    /// A folder or file given to a command is not what it should be (e.g. not a run folder).
    #[error("{path}: {message}")]
    Input { path: String, message: String },
    /// The hit asked for is not in the inputs, or cannot be analysed.
    #[error("{0}")]
    NoHit(String),
}

/// What `aepipe run` is given besides the pipeline definition.
pub struct RunJob<'a> {
    pub config: &'a PipelineConfig,
    pub inputs: &'a [PathBuf],
    pub out: &'a Path,
    pub truth: Option<&'a Path>,
    pub threads: usize,
    pub progress: bool,
    /// Reuse the finished, unchanged per-experiment parts of an earlier run in `out`.
    pub resume: bool,
    /// Only this shard's experiments, features only, as a Hive-partitioned dataset in `out`
    /// (`aepipe merge` runs the whole-batch stages).
    pub shard: Option<crate::util::Shard>,
}

/// What a sharded `aepipe run` did: its part of the features, nothing else.
pub enum RunOutcome {
    Whole(Box<RunSummary>),
    Shard(Box<crate::pipeline::RunReport>),
}

/// Run every enabled stage (or, with a shard, its features).
pub fn run_or_shard(job: &RunJob) -> Result<RunOutcome, WorkflowError> {
    match job.shard {
        None => Ok(RunOutcome::Whole(Box::new(run(job)?))),
        Some(sh) => Ok(RunOutcome::Shard(Box::new(crate::pipeline::run(
            crate::pipeline::StreamJob::Features,
            job.inputs,
            job.out,
            job.config,
            &StreamOptions {
                threads: job.threads,
                progress: job.progress,
                resume: job.resume,
                shard: Some(sh),
            },
        )?))),
    }
}

/// `aepipe merge DIR`: check the N shards of a sharded run, assemble the whole-batch tables
/// into `OUT/features/` and run the whole-batch stages (trend, SOM, classification, report)
/// exactly as an unsharded `aepipe run` does.
pub fn merge(
    dir: &Path,
    out: &Path,
    truth: Option<&Path>,
    threads: usize,
    progress: bool,
) -> Result<RunSummary, WorkflowError> {
    for sub in ["", "trend", "som"] {
        crate::store::clean_stale_tmp(&out.join(sub));
    }
    let t = std::time::Instant::now();
    let (features, first) = crate::pipeline::merge(
        dir,
        &out.join("features"),
        threads,
        Some(crate::pipeline::StreamJob::Features),
    )?;
    let cfg = PipelineConfig::from_toml(&first.config)?;
    let job = RunJob {
        config: &cfg,
        inputs: &first.inputs,
        out,
        truth,
        threads,
        progress,
        resume: false,
        shard: None,
    };
    stages(
        &job,
        features,
        vec![("merge".to_string(), t.elapsed().as_secs_f64())],
    )
}

/// Run every enabled stage.
pub fn run(job: &RunJob) -> Result<RunSummary, WorkflowError> {
    let cfg = job.config;
    // Temporary files of a killed earlier run (every output is written under a temporary
    // name, then renamed): never read, removed here.
    for sub in ["", "trend", "som"] {
        crate::store::clean_stale_tmp(&job.out.join(sub));
    }
    let mut seconds = Vec::new();
    let t = std::time::Instant::now();
    let features = crate::pipeline::run(
        crate::pipeline::StreamJob::Features,
        job.inputs,
        &job.out.join("features"),
        cfg,
        &StreamOptions {
            threads: job.threads,
            progress: job.progress,
            resume: job.resume,
            shard: None,
        },
    )?;
    seconds.push(("features".to_string(), t.elapsed().as_secs_f64()));
    stages(job, features, seconds)
}

/// The whole-batch stages after the features: trend, SOM, truth, report, run.json.
fn stages(
    job: &RunJob,
    features: crate::pipeline::RunReport,
    mut seconds: Vec<(String, f64)>,
) -> Result<RunSummary, WorkflowError> {
    let cfg = job.config;
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
        let g = gather(&summary)?;
        crate::report::write(&summary, &g, &job.out.join("report.html"))?;
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

fn write_run_json(s: &RunSummary) -> Result<(), WorkflowError> {
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
    crate::util::write_atomic(
        &p,
        serde_json::to_string_pretty(&f).expect("json").as_bytes(),
    )?;
    Ok(())
}

fn input_err(p: &Path, m: impl std::fmt::Display) -> WorkflowError {
    WorkflowError::Input {
        path: p.display().to_string(),
        message: m.to_string(),
    }
}

/// `aepipe report RUN_DIR`: rebuild the summary of a finished run from its folder (tables,
/// model, `run.json`; the trend and the classification are recomputed, deterministically)
/// and write `RUN_DIR/report.html` again.
pub fn rebuild_report(dir: &Path) -> Result<PathBuf, WorkflowError> {
    let rp = dir.join("run.json");
    let text = std::fs::read_to_string(&rp)
        .map_err(|e| input_err(&rp, format!("{e} (not a folder written by aepipe run)")))?;
    let f: RunFile = serde_json::from_str(&text).map_err(|e| input_err(&rp, e))?;
    let config = PipelineConfig::from_toml(&f.config).map_err(|e| input_err(&rp, e))?;
    let fdir = dir.join("features");
    let mp = fdir.join("manifest.json");
    let m = crate::pipeline::Manifest::read(&mp).map_err(|e| input_err(&mp, e))?;
    let features = RunReport {
        stats: m.stats(),
        table_path: fdir.join("features.parquet"),
        hits_path: fdir.join("hits.parquet"),
        rejects_path: fdir.join("rejects.parquet"),
        parametric_path: fdir.join("parametric.parquet"),
        markers_path: fdir.join("markers.parquet"),
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
        let model = crate::som::tables::load_model(&sdir.join("model"))?;
        let confusion =
            crate::som::tables::classify_tables(&model, &feats, Some(&config.som.label), &sdir)?;
        let classes = classes_of(&confusion);
        let existing = |p: PathBuf| p.is_file().then_some(p);
        let (profile, profile_plots) = profile_stage(&config, &feats[0], &sdir)?;
        som = Some(SomStage {
            profile_table: sdir.join("damage_profile.parquet"),
            profile,
            profile_plots,
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
    let g = gather(&summary)?;
    crate::report::write(&summary, &g, &out)?;
    Ok(out)
}

/// Read what the report shows besides the summary (the label columns, the manifest) and draw
/// the CWT gallery (one pass over the inputs).
fn gather(s: &RunSummary) -> Result<Gathered, WorkflowError> {
    let criteria: BTreeMap<HitKey, String> = TableScan::open(&s.features.table_path)?
        .keyed_strings("criteria_label")?
        .into_iter()
        .collect();
    let som: BTreeMap<HitKey, String> = match &s.som {
        Some(m) => TableScan::open(&m.classification)?
            .keyed_strings("som_label")?
            .into_iter()
            .collect(),
        None => BTreeMap::new(),
    };
    let per = s.config.report.gallery_per_class;
    let (by, labels) = if som.is_empty() {
        ("criteria", &criteria)
    } else {
        ("SOM", &som)
    };
    let chosen = crate::report::choose_gallery(labels, per);
    let pics = draw_gallery(&s.inputs, &s.config, &chosen, &s.out.join("gallery"));
    let gallery = Gallery {
        by,
        classes: chosen
            .into_iter()
            .map(|(c, keys)| {
                let v = keys
                    .into_iter()
                    .map(|k| {
                        let p = pics.get(&k).cloned();
                        (k, p)
                    })
                    .collect();
                (c, v)
            })
            .collect(),
    };
    let manifest = std::fs::read_to_string(&s.features.manifest_path)
        .map_err(|e| input_err(&s.features.manifest_path, e))?;
    Ok(Gathered {
        criteria,
        som,
        gallery,
        manifest,
    })
}

/// The trend statistics of the feature tables into `dir`, with a Fig. 4.18 plot per
/// experiment × channel that has significant windows.
fn trend_stage(
    cfg: &PipelineConfig,
    feats: &[PathBuf],
    dir: &Path,
) -> Result<(TrendReport, Vec<(String, PathBuf)>), WorkflowError> {
    let opts = crate::analysis::trend::TrendOptions {
        cutoff: cfg.trend.cutoff.parse()?,
        alpha: cfg.trend.alpha,
        columns: vec![],
    };
    let rep = crate::analysis::trend::run_trend(feats, dir, &opts)?;
    let mut plots = Vec::new();
    for sel in &rep.selections {
        let png = trend_png_path(dir, &sel.experiment, sel.channel);
        // A picture that cannot be written fails the stage (exit 3), it is not skipped quietly.
        if crate::plot::trend_png(&png, &rep, &sel.experiment, sel.channel, 4)? {
            plots.push((format!("{} ch{}", sel.experiment, sel.channel), png));
        }
    }
    Ok((rep, plots))
}

/// Where the Fig. 4.18 plot of one experiment × channel goes (the id made file-safe: an
/// experiment id read from a table never writes outside `dir`).
pub fn trend_png_path(dir: &Path, experiment: &str, channel: i32) -> PathBuf {
    dir.join(format!(
        "trend_{}_ch{channel}.png",
        crate::util::file_safe(experiment)
    ))
}

/// Hits per SOM class.
fn classes_of(c: &Confusion) -> BTreeMap<String, usize> {
    let mut classes = BTreeMap::new();
    for ((s, _), n) in &c.counts {
        *classes.entry(s.clone()).or_insert(0) += n;
    }
    classes
}

fn som_stage(job: &RunJob, feats: &[PathBuf]) -> Result<SomStage, WorkflowError> {
    use crate::som::tables::{classify_tables, train, TrainOptions, TrainingSet};
    let cfg = job.config;
    let som_dir = job.out.join("som");
    let (train_paths, label, fraction, trained_on) = if cfg.som.train_on == "reference" {
        let lib = if cfg.som.reference_library.is_empty() {
            let f = crate::sim::reference::ReferenceFile::default_library();
            let dir = job.out.join("reference");
            crate::sim::reference::build_library(&f.reference, &dir, job.progress)?;
            dir.join("waveforms.parquet")
        } else {
            PathBuf::from(&cfg.som.reference_library)
        };
        // The library's features, with the run's own settings.
        let rep = crate::pipeline::run(
            crate::pipeline::StreamJob::Features,
            std::slice::from_ref(&lib),
            &job.out.join("reference-features"),
            cfg,
            &StreamOptions {
                threads: job.threads,
                progress: false,
                resume: false,
                shard: None,
            },
        )?;
        (
            vec![rep.table_path],
            "label".to_string(),
            1.0,
            format!("reference library {} (simulated labels)", lib.display()),
        )
    } else {
        (
            feats.to_vec(),
            cfg.som.label.clone(),
            cfg.som.fraction,
            if cfg.som.label == "criteria_label" {
                format!(
                    "{:.0} % of the run's hits, criteria labels (ch. 5.4)",
                    100.0 * cfg.som.fraction
                )
            } else {
                format!(
                    "{:.0} % of the run's hits, labels of column {}",
                    100.0 * cfg.som.fraction,
                    cfg.som.label
                )
            },
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
    let model = train(&train_paths, &model_dir, &o)?;
    let confusion = classify_tables(&model, feats, Some(&cfg.som.label), &som_dir)?;
    let u = som_dir.join("u_matrix.png");
    crate::plot::u_matrix_png(&u, &model.som)?;
    let hm = som_dir.join("hit_maps.png");
    crate::plot::hit_maps_png(&hm, &model.som, &confusion.hits)?;
    let (u_matrix, hit_maps) = (Some(u), Some(hm));
    let classes = classes_of(&confusion);
    let (profile, profile_plots) = profile_stage(cfg, &feats[0], &som_dir)?;
    Ok(SomStage {
        profile_table: som_dir.join("damage_profile.parquet"),
        profile,
        profile_plots,
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

/// The damage profile of a classified run into `som_dir`: `damage_profile.parquet` and a
/// Fig. 6.1 picture per experiment × channel.
type Profile = (
    Vec<crate::som::profile::ProfileSummary>,
    Vec<(String, PathBuf)>,
);

fn profile_stage(
    cfg: &PipelineConfig,
    features: &Path,
    som_dir: &Path,
) -> Result<Profile, WorkflowError> {
    let (rows, summaries) =
        crate::som::profile::build(features, &som_dir.join("classification.parquet"))?;
    crate::som::profile::write(&som_dir.join("damage_profile.parquet"), &rows, &cfg.hash())?;
    let mut plots = Vec::new();
    for s in &summaries {
        let group: Vec<&crate::som::profile::ProfileRow> = rows
            .iter()
            .filter(|r| r.key.0 == s.experiment && r.key.1 == s.channel)
            .collect();
        let png = som_dir.join(format!(
            "damage_profile_{}_ch{}.png",
            crate::util::file_safe(&s.experiment),
            s.channel
        ));
        crate::plot::damage_profile_png(&png, &group, s)?;
        plots.push((format!("{} ch{}", s.experiment, s.channel), png));
    }
    Ok((summaries, plots))
}

/// Draw the CWT of the chosen hits (one pass over the inputs) into `dir`; returns the PNG
/// of each hit drawn (a hit that cannot be read or drawn is left out, and the report says
/// "not drawn").
fn draw_gallery(
    inputs: &[PathBuf],
    cfg: &PipelineConfig,
    chosen: &BTreeMap<String, Vec<HitKey>>,
    dir: &Path,
) -> BTreeMap<HitKey, PathBuf> {
    let want: std::collections::BTreeSet<&HitKey> = chosen.values().flatten().collect();
    let mut out = BTreeMap::new();
    if want.is_empty() || std::fs::create_dir_all(dir).is_err() {
        return out;
    }
    let mut ex = crate::features::FeatureExtractor::new(cfg);
    let d = crate::ingest::discover(inputs, &cfg.ingest);
    for src in &d.sources {
        for it in crate::ingest::open(src, cfg) {
            let crate::model::Item::Record(r) = it else {
                continue;
            };
            let key = (r.experiment.clone(), r.channel as i32, r.hit as i64);
            if !want.contains(&key) || crate::features::validate(&r, cfg).is_err() {
                continue;
            }
            let a = ex.analyse(&r);
            let (freqs, power) = ex.full_cwt(&r);
            let png = dir.join(format!(
                "{}_ch{}_hit{}.png",
                crate::util::file_safe(&key.0),
                key.1,
                key.2
            ));
            if crate::plot::cwt_png(
                &png,
                &r,
                &freqs,
                power.view(),
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

/// Find a hit in the inputs, analyse it and draw it: the `aepipe cwt` command. Returns a
/// one-line summary (label, dominant frequency).
pub fn cwt_of_hit(
    inputs: &[std::path::PathBuf],
    cfg: &crate::config::PipelineConfig,
    experiment: Option<&str>,
    channel: Option<u32>,
    hit: u64,
    png: &Path,
) -> Result<String, WorkflowError> {
    let d = crate::ingest::discover(inputs, &cfg.ingest);
    let found = d
        .sources
        .iter()
        .filter(|s| {
            experiment.is_none_or(|e| s.id == e || s.format == crate::ingest::Format::Parquet)
        })
        .flat_map(|s| crate::ingest::open(s, cfg))
        .find_map(|it| match it {
            crate::model::Item::Record(r)
                if r.hit == hit
                    && channel.is_none_or(|c| r.channel == c)
                    && experiment.is_none_or(|e| r.experiment == e) =>
            {
                Some(r)
            }
            _ => None,
        });
    let Some(rec) = found else {
        return Err(WorkflowError::NoHit(format!(
            "no hit {hit}{}{} in {}",
            channel
                .map(|c| format!(" on channel {c}"))
                .unwrap_or_default(),
            experiment.map(|e| format!(" of {e}")).unwrap_or_default(),
            inputs
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )));
    };
    crate::features::validate(&rec, cfg)
        .map_err(|e| WorkflowError::NoHit(format!("{}: {e}", rec.id())))?;
    let mut ex = crate::features::FeatureExtractor::new(cfg);
    let a = ex.analyse(&rec);
    let (freqs, power) = ex.full_cwt(&rec);
    let summary = format!(
        "{}: {} ({}), dominant {} kHz, peak {:.1} dB_AE",
        rec.id(),
        a.label,
        a.reason,
        a.components
            .dominant
            .map(|d| format!("{:.0}", d.freq_hz / 1e3))
            .unwrap_or_else(|| "–".into()),
        a.hit.amplitude_db
    );
    crate::plot::cwt_png(
        png,
        &rec,
        &freqs,
        power.view(),
        &format!("{} — {}", rec.id(), a.label),
    )?;
    Ok(summary)
}

/// Compare the SOM classes with `truth.parquet`.
pub fn score_truth(truth: &Path, classification: &Path) -> Result<TruthScore, WorkflowError> {
    let t: BTreeMap<_, _> = TableScan::open(truth)?
        .keyed_strings("mechanism")?
        .into_iter()
        .collect();
    let mut s = TruthScore {
        path: truth.to_path_buf(),
        counts: BTreeMap::new(),
        bond_fibre_total: 0,
        bond_fibre_correct: 0,
    };
    for (key, class) in TableScan::open(classification)?.keyed_strings("som_label")? {
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

/// The tables whose columns `aepipe schema` prints.
pub const TABLES: &[&str] = &[
    "features",
    "waveforms",
    "rejects",
    "hits",
    "parametric",
    "markers",
    "trend",
    "classification",
    "damage_profile",
    "sim_waveforms",
    "sim_trajectories",
    "truth",
];

/// The schema of a written table by name (one of [`TABLES`]).
pub fn table_schema(name: &str, cfg: &PipelineConfig) -> Option<crate::store::TableSchema> {
    Some(match name {
        "features" => crate::features::features_table(cfg),
        "waveforms" => crate::store::waveforms_table(),
        "rejects" => crate::store::rejects_table(),
        "hits" => crate::store::hits_table(),
        "parametric" => crate::store::parametric_table().schema(),
        "markers" => crate::store::markers_table().schema(),
        "trend" => crate::analysis::trend::trend_table(),
        "classification" => crate::som::tables::classification_table(),
        "damage_profile" => crate::som::profile::profile_table(),
        "sim_waveforms" => crate::sim::output::sim_waveforms_table(),
        "sim_trajectories" => crate::sim::output::trajectory_table(),
        "truth" => crate::synth::truth_table(),
        _ => return None,
    })
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
        l.extend(m.profile.iter().map(|p| p.line()));
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
        let (ek, en) = t.erroneous_recall();
        let (ok, all) = t.thesis_overall();
        l.push(format!(
            "erroneous records recognised: {ek}/{en}; overall the thesis's way (mechanism or erroneous, over all hits): {ok}/{all} = {:.1} %",
            100.0 * ok as f64 / all.max(1) as f64
        ));
        l.push("Table 5.4 (share of each SOM class's hits):".into());
        l.extend(t.format_table_5_4().lines().map(|x| format!("  {x}")));
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
