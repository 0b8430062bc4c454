//! The whole-batch stages after the features: trend, SOM (training, classification,
//! damage profile).

use super::*;
use crate::analysis::trend::TrendDir;
use crate::config::{MapSource, TrainOn};
use crate::model::columns as cols;
use crate::som::layout::ClassifyDir;

/// The trend statistics of the feature tables into `dir`, with a Fig. 4.18 plot per
/// experiment × channel that has significant windows.
pub(super) fn trend_stage(
    cfg: &ValidConfig,
    feats: &[PathBuf],
    dir: &TrendDir,
) -> Result<(TrendReport, Vec<(String, PathBuf)>), WorkflowError> {
    let opts = crate::analysis::trend::TrendOptions {
        cutoff: cfg.trend.cutoff,
        alpha: cfg.trend.alpha,
        min_load_span_n: cfg.trend.min_load_span_n,
        min_hits: cfg.trend.min_hits,
        columns: vec![],
        sources: cfg.source_rows(),
    };
    let mut plots = Vec::new();
    let figures = cfg.report.series_figures;
    let rep =
        crate::analysis::trend::run_trend_with(feats, dir.path(), &opts, 4, figures, |pic| {
            let sel = pic.selection;
            let png = dir.png(&sel.experiment, sel.channel);
            // A picture that cannot be written fails the stage (exit 3), it is not skipped quietly.
            crate::plot::trend_png(&png, pic)?;
            plots.push((format!("{} ch{}", sel.experiment, sel.channel), png));
            Ok::<(), WorkflowError>(())
        })?;
    Ok((rep, plots))
}

/// Hits per SOM class.
pub(super) fn classes_of(c: &Confusion) -> BTreeMap<String, usize> {
    let mut classes = BTreeMap::new();
    for ((s, _), n) in &c.counts {
        *classes.entry(s.clone()).or_insert(0) += n;
    }
    classes
}

pub(super) fn som_stage(
    job: &RunJob,
    feats: &[PathBuf],
    written: &crate::pipeline::RunReport,
    log: &mut StageLog,
) -> Result<SomStage, WorkflowError> {
    use crate::som::classify::classify_tables;
    let cfg = job.config;
    let run = job.dir();
    let som_dir = run.som();
    let model_dir = run.som_model();
    let mut map_cache = None;
    let (model, trained_on) = match cfg.som.map_source() {
        // A given map: copied into the run (its model folder), so the run stays whole.
        MapSource::Given(given) => log.time("som model", || -> Result<_, WorkflowError> {
            let m = crate::som::tables::load_model(given)?;
            crate::som::tables::save_model(&m, model_dir.path(), None)?;
            Ok((m, format!("the given map {}", given.display())))
        })?,
        MapSource::Reference(_) | MapSource::Criteria => {
            let (m, on, cached) = log.time("som training", || train_stage(job, feats))?;
            map_cache = cached;
            (m, on)
        }
    };
    let confusion = log.time("classification", || -> Result<_, WorkflowError> {
        let confusion = classify_tables(
            &model,
            feats,
            Some(&cfg.som.label),
            som_dir.path(),
            cfg.source_rows(),
            crate::som::classify::ClassifyRules::of(&cfg.som),
        )?;
        crate::plot::u_matrix_png(&som_dir.u_matrix(), &model.som)?;
        crate::plot::hit_maps_png(&som_dir.hit_maps(), &model.som, &confusion.hits)?;
        Ok(confusion)
    })?;
    let trained = Trained {
        model_dir: model_dir.path().to_path_buf(),
        trained_on,
        map_cache,
        training_rows: model.composition.values().map(|(_, r)| r).sum(),
        u_matrix: Some(som_dir.u_matrix()),
        hit_maps: Some(som_dir.hit_maps()),
    };
    log.time("damage profile", || {
        classified_stage(cfg, confusion, &feats[0], written, &som_dir, trained)
    })
}

/// The run's map as `[som] train_on` says, and its cache entry: a reference map from the
/// cache when the job has one and the key matches ([`super::mapcache`]), else trained and
/// kept there; a map of the run's own hits is never cached.
pub(super) fn train_stage(
    job: &RunJob,
    feats: &[PathBuf],
) -> Result<(crate::som::tables::Model, String, Option<super::MapCache>), WorkflowError> {
    use super::mapcache;
    let cache = match (&job.cache, job.config.som.train_on) {
        (Some(c), TrainOn::Reference) => Some((c, mapcache::map_key(job)?)),
        _ => None,
    };
    let model_dir = job.dir().som_model();
    if let Some((root, key)) = &cache {
        if mapcache::reuse(root, key, model_dir.path())? {
            let m = crate::som::tables::load_model(model_dir.path())?;
            let on = library_name(job.config.som.reference_library.as_deref());
            let c = super::MapCache {
                key: key.clone(),
                reused: true,
            };
            return Ok((m, format!("{on}; {c}"), Some(c)));
        }
    }
    let (m, on) = train_new(job, feats)?;
    match cache {
        Some((root, key)) => {
            mapcache::keep(root, &key, model_dir.path())?;
            let c = super::MapCache { key, reused: false };
            Ok((m, format!("{on}; {c}"), Some(c)))
        }
        None => Ok((m, on, None)),
    }
}

/// What a reference map was trained on, the same whether it was trained now or reused.
fn library_name(named: Option<&Path>) -> String {
    match named {
        Some(l) => format!("reference library {} (simulated labels)", l.display()),
        None => {
            "the embedded reference library (pipelines/reference-library.toml, simulated labels)"
                .to_string()
        }
    }
}

/// Train the run's map as `[som] train_on` says: on a reference library (built from the
/// embedded definition unless one is named) or on the run's own labelled hits.
fn train_new(
    job: &RunJob,
    feats: &[PathBuf],
) -> Result<(crate::som::tables::Model, String), WorkflowError> {
    use crate::som::tables::{train, TrainOptions, TrainingSet};
    let cfg = job.config;
    let run = job.dir();
    let library = match cfg.som.train_on {
        TrainOn::Reference => Some(cfg.som.reference_library.as_deref()),
        TrainOn::Criteria => None,
    };
    let (train_paths, label, fraction, trained_on) = if let Some(named) = library {
        let lib = match named {
            Some(lib) => lib.to_path_buf(),
            None => {
                let f = crate::sim::reference::ReferenceFile::default_library();
                let dir = run.reference();
                super::mapcache::library(job.cache.as_deref(), &f.reference, &dir, job.progress)?;
                dir.waveforms()
            }
        };
        // The library's features, with the run's own settings; its sensors record one
        // simulated source each, not a test: no events, and its records are hits already
        // (`[detect]` would cut them and lose their labels).
        let lib_cfg = cfg.clone().with(|c| {
            c.events.enabled = Some(false);
            c.detect.mode = crate::detect::DetectMode::Off;
        })?;
        let rep = crate::pipeline::run(
            crate::pipeline::StreamJob::Features,
            std::slice::from_ref(&lib),
            run.reference_features().path(),
            &lib_cfg,
            &StreamOptions {
                control: job.control.clone(),
                ..StreamOptions::with_threads(job.threads)
            },
        )?;
        (
            vec![rep.table_path],
            cols::LABEL.name.to_string(),
            1.0,
            library_name(named),
        )
    } else {
        (
            feats.to_vec(),
            cfg.som.label.clone(),
            cfg.som.fraction,
            if cfg.som.label == cols::CRITERIA_LABEL.name {
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
        sources: cfg.source_rows(),
        ..Default::default()
    };
    let model = train(&train_paths, run.som_model().path(), &o)?;
    Ok((model, trained_on))
}

/// Each stage's wall time and peak resident memory, in the order the stages ran: the
/// terminal's "stages:" line, the report's footer, `run.json`, and `aepipe bench analysis`.
#[derive(Debug, Clone, Default)]
pub struct StageLog {
    pub seconds: Vec<(String, f64)>,
    /// Peak RSS during the stage, bytes (the kernel's mark reset at its start; absent off
    /// Linux).
    pub peak_rss: Vec<(String, u64)>,
}

impl StageLog {
    /// Run one stage and record it.
    pub fn time<T>(&mut self, name: &str, f: impl FnOnce() -> T) -> T {
        crate::util::release_freed_memory();
        crate::util::reset_peak_rss();
        let t = std::time::Instant::now();
        let out = f();
        self.seconds
            .push((name.to_string(), t.elapsed().as_secs_f64()));
        if let Some(b) = crate::util::peak_rss_bytes() {
            self.peak_rss.push((name.to_string(), b));
        }
        out
    }
}

/// What is known of a trained map when its classification is summed up.
pub(super) struct Trained {
    pub model_dir: PathBuf,
    pub trained_on: String,
    pub map_cache: Option<MapCache>,
    pub training_rows: usize,
    pub u_matrix: Option<PathBuf>,
    pub hit_maps: Option<PathBuf>,
}

/// After a map classified the feature tables into `som_dir`: the class counts, the damage
/// profile, the evolution and the location pictures, as a [`SomStage`] (`aepipe run` after
/// training; `aepipe report` from a run folder).
pub(super) fn classified_stage(
    cfg: &ValidConfig,
    confusion: Confusion,
    features: &Path,
    written: &crate::pipeline::RunReport,
    som_dir: &ClassifyDir,
    t: Trained,
) -> Result<SomStage, WorkflowError> {
    let classes = classes_of(&confusion);
    let pr = profile_stage(cfg, features, written, som_dir)?;
    let png = som_dir.path().join("ra_af_som_label.png");
    let ra_af = super::cluster::ra_af_picture(
        features,
        &som_dir.classification(),
        cols::SOM_LABEL.name,
        "SOM class",
        &png,
        cfg.crack_mode.af_per_ra,
    )?;
    Ok(SomStage {
        ra_af_plot: ra_af.then_some(png),
        profile_table: som_dir.damage_profile(),
        profile: pr.summaries,
        profile_plots: pr.plots,
        evolution_table: pr.evolution.table,
        evolution_plots: pr.evolution.plots,
        reloads: pr.evolution.reloads,
        location_plots: pr.location_plots,
        model_dir: t.model_dir,
        trained_on: t.trained_on,
        map_cache: t.map_cache,
        training_rows: t.training_rows,
        confusion,
        classification: som_dir.classification(),
        u_matrix: t.u_matrix,
        hit_maps: t.hit_maps,
        classes,
    })
}

/// The damage profile of a classified run into `som_dir`: `damage_profile.parquet` and a
/// Fig. 6.1 picture per experiment × channel (the first `[report] series_figures`); then
/// the damage evolution and the location pictures (`super::sources`). Streams: the profile
/// is sorted on disk, each series emitted in order, and what the evolution and the location
/// need is sorted as it passes.
pub(super) struct Profile {
    pub summaries: Vec<crate::som::profile::ProfileSummary>,
    pub plots: Vec<(String, PathBuf)>,
    pub evolution: super::sources::Evolution,
    pub location_plots: Vec<(String, PathBuf)>,
}

pub(super) fn profile_stage(
    cfg: &ValidConfig,
    features: &Path,
    written: &crate::pipeline::RunReport,
    som_dir: &ClassifyDir,
) -> Result<Profile, WorkflowError> {
    use crate::som::profile::ProfileRow;
    let prof = crate::som::profile::open(features, &som_dir.classification(), som_dir.path())?;
    let table = crate::som::profile::profile_table();
    let path = som_dir.damage_profile();
    let meta = [("aepipe.config_sha256".to_string(), cfg.hash())];
    let mut w = crate::store::TableWriter::create(&path, table.schema(), &meta, 65_536)?;
    let mut evolution = super::sources::EvolutionInput::new(som_dir.path());
    let mut classes = super::sources::EventClasses::new(som_dir.path());
    let mut plots = Vec::new();
    let mut summaries = Vec::new();
    let figures = cfg.report.series_figures;
    let series: Vec<(String, i32)> = prof.series().cloned().collect();
    for (g, (experiment, channel)) in series.iter().enumerate() {
        let n = prof.len(g) as usize;
        let draw = g < figures;
        let every = crate::analysis::trend::thin_every(n);
        let mut drawn: Vec<(usize, ProfileRow)> = Vec::new();
        let mut i = 0usize;
        let summary = prof.emit(g, cfg.trend.min_load_span_n, |r| {
            w.push(table.row(r.clone()))?;
            evolution.push(r)?;
            classes.push(r)?;
            if draw && (i.is_multiple_of(every) || i + 1 == n) {
                drawn.push((i, r.clone()));
            }
            i += 1;
            Ok::<(), WorkflowError>(())
        })?;
        if draw {
            let png = som_dir.damage_profile_png(experiment, *channel);
            crate::plot::damage_profile_png(&png, &drawn, &summary, every)?;
            plots.push((format!("{experiment} ch{channel}"), png));
        }
        summaries.push(summary);
    }
    w.finish()?;
    drop(prof);
    let evolution = super::sources::evolution_stage(
        cfg,
        evolution,
        &summaries,
        &written.parametric_path,
        som_dir,
    )?;
    let to = super::sources::LocationPictures {
        dir: som_dir.path(),
        png: &|e: &str| som_dir.location_png(e),
        by: "SOM class",
    };
    let location_plots = super::sources::location_stage(cfg, classes, &written.events_path, &to)?;
    Ok(Profile {
        summaries,
        plots,
        evolution,
        location_plots,
    })
}
