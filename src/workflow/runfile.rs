//! `run.json` and `aepipe report`: rebuild the summary of a finished run from its folder.

use super::stages::{classified_stage, trend_stage, Trained};
use super::*;

/// `RUN_DIR/run.json`: what `aepipe report` needs besides the run's tables.
#[derive(serde::Serialize, serde::Deserialize)]
struct RunFile {
    tool_version: String,
    inputs: Vec<PathBuf>,
    truth: Option<PathBuf>,
    /// The effective pipeline definition (canonical TOML).
    config: String,
    seconds: Vec<(String, f64)>,
    /// Each stage's peak resident memory, bytes (absent in older run folders).
    #[serde(default)]
    peak_rss: Vec<(String, u64)>,
    som_trained_on: Option<String>,
    som_training_rows: Option<usize>,
    /// The map's cache key and whether the run reused it (absent in older run folders).
    #[serde(default)]
    som_map_cache: Option<crate::som::layout::MapCache>,
}

pub(super) fn write_run_json(s: &RunSummary) -> Result<(), WorkflowError> {
    let f = RunFile {
        tool_version: env!("CARGO_PKG_VERSION").into(),
        inputs: s.inputs.clone(),
        truth: s.truth.as_ref().map(|t| t.path.clone()),
        config: s.config.to_toml(),
        seconds: s.seconds.clone(),
        peak_rss: s.peak_rss.clone(),
        som_trained_on: s.som.as_ref().map(|m| m.trained_on.clone()),
        som_training_rows: s.som.as_ref().map(|m| m.training_rows),
        som_map_cache: s.som.as_ref().and_then(|m| m.map_cache.clone()),
    };
    let p = RunDir::new(&s.out).run_json();
    crate::util::write_atomic(
        &p,
        serde_json::to_string_pretty(&f).expect("json").as_bytes(),
    )?;
    Ok(())
}

/// `aepipe report RUN_DIR`: rebuild the summary of a finished run from its folder (tables,
/// model, `run.json`; the trend and the classification are recomputed, deterministically)
/// and write `RUN_DIR/report.html` again.
pub fn rebuild_report(dir: &Path) -> Result<(PathBuf, crate::report::PageFit), WorkflowError> {
    let run = RunDir::new(dir);
    let rp = run.run_json();
    let text = std::fs::read_to_string(&rp)
        .map_err(|e| input_err(&rp, format!("{e} (not a folder written by aepipe run)")))?;
    let f: RunFile = serde_json::from_str(&text).map_err(|e| input_err(&rp, e))?;
    let config = PipelineConfig::from_toml(&f.config).map_err(|e| input_err(&rp, e))?;
    let fdir = run.features();
    let mp = fdir.manifest();
    let m = crate::pipeline::Manifest::read(&mp).map_err(|e| input_err(&mp, e))?;
    let job = crate::pipeline::StreamJob::Features;
    let features = RunReport::of_tables(&fdir, job, m.stats());
    let feats = vec![features.table_path.clone()];
    let (mut trend, mut trend_plots) = (None, Vec::new());
    if config.trend.enabled && run.trend().path().is_dir() {
        let (rep, plots) = trend_stage(&config, &feats, &run.trend())?;
        trend = Some(rep);
        trend_plots = plots;
    }
    let mut som = None;
    if config.som.enabled && run.som_model().json().is_file() {
        let sdir = run.som();
        let model = crate::som::tables::load_model(run.som_model().path())?;
        let confusion = crate::som::classify::classify_tables(
            &model,
            &feats,
            Some(&config.som.label),
            sdir.path(),
            config.source_rows(),
            crate::som::classify::ClassifyRules::of(&config.som),
        )?;
        let existing = |p: PathBuf| p.is_file().then_some(p);
        let trained = Trained {
            model_dir: run.som_model().path().to_path_buf(),
            trained_on: f.som_trained_on.clone().unwrap_or_default(),
            map_cache: f.som_map_cache.clone(),
            training_rows: f.som_training_rows.unwrap_or(0),
            u_matrix: existing(sdir.u_matrix()),
            hit_maps: existing(sdir.hit_maps()),
        };
        som = Some(classified_stage(
            &config, confusion, &feats[0], &features, &sdir, trained,
        )?);
    }
    // The clustering is deterministic (its seed is in the config): redone.
    let cluster = if config.cluster.enabled && run.cluster().is_dir() {
        Some(super::cluster::cluster_stage(
            &config,
            &feats,
            &features,
            &run.cluster(),
            som.as_ref(),
        )?)
    } else {
        None
    };
    let statistics = crate::analysis::powerlaw::run_statistics(
        &feats,
        &run.statistics(),
        config.source_rows(),
        &config.hash(),
    )?;
    let (truth, sources) =
        super::truth::scores(f.truth.as_deref(), som.as_ref(), &features, &config)?;
    let mut summary = RunSummary {
        out: dir.to_path_buf(),
        inputs: f.inputs,
        features,
        trend,
        trend_plots,
        som,
        cluster,
        export: None,
        statistics,
        truth,
        sources,
        config,
        seconds: f.seconds,
        peak_rss: f.peak_rss,
        series: None,
        page: None,
    };
    summary.series = Some(super::series::series_stage(&summary, &run.series())?);
    let out = run.report_html();
    let g = gather(&summary)?;
    let fit = crate::report::write(&summary, &g, &out)?;
    Ok((out, fit))
}
