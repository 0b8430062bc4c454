//! `aepipe demo`: the README's first command. It builds a reference library with the
//! simulator, a synthetic notched-paper experiment from it (Vallen `.pridb`/`.tradb` + ground
//! truth), and runs the whole pipeline on it through the real ingest path: features, trend,
//! SOM, classification against the truth, and the HTML report.

use crate::inspect;
use std::path::{Path, PathBuf};

pub struct DemoResult {
    pub data_dir: PathBuf,
    pub inspect: Vec<inspect::Summary>,
    pub synth: String,
    pub run: crate::workflow::RunSummary,
    pub seconds: f64,
}

pub use crate::synth::demo_config;

/// The whole method on data it makes itself: a synthetic notched-paper experiment built from
/// a reference library simulated with the demo's seed (`root/data`, `root/truth.parquet`),
/// then `aepipe run` with `pipelines/demo.toml`: features, trend, a SOM trained on the
/// embedded reference library (other material draws), classification scored against the
/// truth, and `root/run/report.html`.
pub fn run_demo(
    root: &Path,
    hits: usize,
    seed: u64,
    threads: usize,
) -> Result<DemoResult, crate::workflow::WorkflowError> {
    let t0 = std::time::Instant::now();
    let id = "synthetic_notched_paper";
    let synth = crate::synth::synth_experiment(root, id, hits, seed, None, true)?;
    let data_dir = root.join("data");
    let cfg = demo_config();
    let disc = crate::ingest::discover(std::slice::from_ref(&data_dir), &cfg.ingest);
    let inspect = disc
        .sources
        .iter()
        .map(|s| inspect::summarise(s, &cfg))
        .collect();
    let truth = root.join("truth.parquet");
    let run = crate::workflow::run(&crate::workflow::RunJob {
        truth: Some(&truth),
        progress: true,
        ..crate::workflow::RunJob::new(
            &cfg,
            std::slice::from_ref(&data_dir),
            &root.join("run"),
            threads,
        )
    })?;
    Ok(DemoResult {
        data_dir,
        inspect,
        synth,
        run,
        seconds: t0.elapsed().as_secs_f64(),
    })
}
