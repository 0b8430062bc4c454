//! `aepipe demo`: the README's first command. Until the end-to-end pipeline lands it makes a
//! synthetic notched-paper experiment (Vallen `.pridb`/`.tradb`, labelled), runs the feature
//! pipeline on it through the real ingest path, and summarises what came out.

use crate::config::PipelineConfig;
use crate::inspect;
use crate::pipeline::{run, Job, RunOptions, RunReport};
use crate::synth::Experiment;
use std::path::{Path, PathBuf};

pub struct DemoResult {
    pub data_dir: PathBuf,
    pub out_dir: PathBuf,
    pub inspect: Vec<inspect::Summary>,
    pub report: RunReport,
    pub trend: crate::analysis::trend::TrendReport,
    pub trend_plot: Option<PathBuf>,
    pub seconds: f64,
}

/// The demo's pipeline definition, `pipelines/demo.toml`, embedded in the binary so that
/// `aepipe demo` needs no file beside it.
pub fn demo_config() -> PipelineConfig {
    PipelineConfig::from_toml(include_str!("../pipelines/demo.toml"))
        .expect("pipelines/demo.toml is valid")
}

pub fn run_demo(root: &Path, hits: usize, seed: u64, threads: usize) -> Result<DemoResult, String> {
    let t0 = std::time::Instant::now();
    let data_dir = root.join("data");
    let out_dir = root.join("features");
    let exp = Experiment::new("synthetic_notched_paper", hits, seed);
    exp.write_vallen(&data_dir).map_err(|e| {
        format!(
            "{}: cannot write the synthetic experiment: {e}",
            data_dir.display()
        )
    })?;
    let cfg = demo_config();
    let disc = crate::ingest::discover(std::slice::from_ref(&data_dir), &cfg.ingest);
    let inspect = disc
        .sources
        .iter()
        .map(|s| inspect::summarise(s, &cfg.ingest))
        .collect();
    let report = run(
        Job::Features,
        std::slice::from_ref(&data_dir),
        &out_dir,
        &cfg,
        &RunOptions {
            threads,
            progress: true,
        },
    )
    .map_err(|e| e.to_string())?;
    let trend_dir = root.join("trend");
    let trend = crate::analysis::trend::run_trend(
        std::slice::from_ref(&report.table_path),
        &trend_dir,
        &Default::default(),
    )
    .map_err(|e| e.to_string())?;
    let png = trend_dir.join("trend.png");
    let trend_plot = match crate::plot::trend_png(&png, &trend, &exp.id, 1, 4) {
        Ok(true) => Some(png),
        _ => None,
    };
    Ok(DemoResult {
        data_dir,
        out_dir,
        inspect,
        report,
        trend,
        trend_plot,
        seconds: t0.elapsed().as_secs_f64(),
    })
}
