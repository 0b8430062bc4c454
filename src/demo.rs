//! `aepipe demo`: the README's first command. It builds a reference library with the
//! simulator, a synthetic notched-paper experiment from it (Vallen `.pridb`/`.tradb` + ground
//! truth), and runs the whole pipeline on it through the real ingest path: features, trend,
//! SOM, classification against the truth, and the HTML report.

use crate::inspect;
use crate::report::TruthScore;
use crate::workflow::WorkflowError;
use std::path::{Path, PathBuf};

pub struct DemoResult {
    pub data_dir: PathBuf,
    pub inspect: Vec<inspect::Summary>,
    pub synth: String,
    pub run: crate::workflow::RunSummary,
    /// The classes on another model (`None`: `--no-cross-model`).
    pub cross: Option<CrossModel>,
    pub seconds: f64,
}

/// The demo's classes asked about another model's signals (issue 51 item 5): every other
/// figure of the demo is measured on a test made by the plane model that made the map's
/// references. The other model is the 3-D layered network
/// (`pipelines/reference-library-3d.toml`), at one material draw per grid point to keep the
/// demo short (docs/fidelity.md's cross table uses the full library).
pub struct CrossModel {
    /// The 3-D library: how it was simulated, and whether it came from the cache.
    pub library: crate::workflow::mapcache::Library,
    /// The demo's map (plane references) on a test made from the 3-D library.
    pub plane_map_on_3d: TruthScore,
    /// A map trained on the 3-D library on the demo's own (plane) test.
    pub map_3d_on_plane: TruthScore,
    pub seconds: f64,
}

/// Material draws per grid point of the demo's 3-D library (the file's 4 cost ~135 s here).
pub const CROSS_MODEL_VARIANTS: usize = 1;

pub use crate::synth::demo_config;

/// The whole method on data it makes itself: a synthetic notched-paper experiment built from
/// a reference library simulated with the demo's seed (`root/data`, `root/truth.parquet`),
/// then `aepipe run` with `pipelines/demo.toml`: features, trend, a SOM trained on the
/// embedded reference library (other material draws), classification scored against the
/// truth, and `root/run/report.html`.
/// What `aepipe demo` is asked.
pub struct DemoJob<'a> {
    pub root: &'a Path,
    pub hits: usize,
    pub seed: u64,
    pub threads: usize,
    /// Ask the classes about another model ([`CrossModel`]).
    pub cross_model: bool,
    /// Write `root/run/report.html` (`false`: `--no-report`; nothing else changes).
    pub report: bool,
    /// The reference maps' cache root (`None`: made anew).
    pub cache: Option<PathBuf>,
}

pub fn run_demo(job: &DemoJob) -> Result<DemoResult, WorkflowError> {
    let (root, hits, seed, threads) = (job.root, job.hits, job.seed, job.threads);
    let t0 = std::time::Instant::now();
    let id = "synthetic_notched_paper";
    let synth = crate::synth::synth_experiment(root, id, hits, seed, None, true)?;
    let data_dir = root.join("data");
    let cfg = if job.report {
        demo_config()
    } else {
        let mut c = demo_config().into_inner();
        c.report.enabled = false;
        c.check()?
    };
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
        cache: job.cache.clone(),
        ..crate::workflow::RunJob::new(
            &cfg,
            std::slice::from_ref(&data_dir),
            &root.join("run"),
            threads,
        )
    })?;
    let cross = match job.cross_model {
        true => Some(cross_model_check(job, &run)?),
        false => None,
    };
    Ok(DemoResult {
        data_dir,
        inspect,
        synth,
        run,
        cross,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// [`CrossModel`] in `root/cross/`: the 3-D library (`library-3d/`), a test made from it
/// with the demo's seed and size (`test-3d/`), the demo's map on that test
/// (`plane-map-on-3d/`), and a map trained on the 3-D library on the demo's test
/// (`3d-map-on-plane/`). Neither map is asked about the signals it was trained on.
fn cross_model_check(
    job: &DemoJob,
    demo: &crate::workflow::RunSummary,
) -> Result<CrossModel, WorkflowError> {
    let (root, hits, seed, threads) = (job.root, job.hits, job.seed, job.threads);
    let t0 = std::time::Instant::now();
    let dir = root.join("cross");
    let mut lib = crate::sim::reference::ReferenceFile::library_3d().reference;
    lib.variants = CROSS_MODEL_VARIANTS;
    let lib_dir = crate::sim::reference::LibraryDir::new(dir.join("library-3d"));
    let library = crate::workflow::mapcache::library(job.cache.as_deref(), &lib, &lib_dir, true)?;
    let test = dir.join("test-3d");
    crate::synth::synth_test(
        &test,
        "synthetic_notched_paper_3d",
        hits,
        seed,
        crate::synth::Shape::default(),
        Some(&lib_dir.waveforms()),
        true,
    )?;
    let score = |data: &Path, truth: &Path, library: &Path, out: &str| {
        let mut cfg = demo.config.clone().into_inner();
        cfg.som.reference_library = Some(library.to_path_buf());
        let cfg = cfg.check()?;
        let run = crate::workflow::run(&crate::workflow::RunJob {
            truth: Some(truth),
            progress: false,
            cache: job.cache.clone(),
            ..crate::workflow::RunJob::new(
                &cfg,
                std::slice::from_ref(&data.to_path_buf()),
                &dir.join(out),
                threads,
            )
        })?;
        run.truth.ok_or_else(|| WorkflowError::Input {
            path: truth.display().to_string(),
            message: "the run scored no hit against the truth".into(),
        })
    };
    // The plane library the demo's map was trained on; a map from the cache left none in
    // the run: then it is simulated here (the same embedded definition and seed).
    let mut plane_library = crate::workflow::RunDir::new(&demo.out)
        .reference()
        .waveforms();
    if !plane_library.is_file() {
        let f = crate::sim::reference::ReferenceFile::default_library();
        let d = crate::sim::reference::LibraryDir::new(dir.join("library-plane"));
        crate::workflow::mapcache::library(job.cache.as_deref(), &f.reference, &d, true)?;
        plane_library = d.waveforms();
    }
    let plane_map_on_3d = score(
        &test.join("data"),
        &test.join("truth.parquet"),
        &plane_library,
        "plane-map-on-3d",
    )?;
    let map_3d_on_plane = score(
        &root.join("data"),
        &root.join("truth.parquet"),
        &lib_dir.waveforms(),
        "3d-map-on-plane",
    )?;
    Ok(CrossModel {
        library,
        plane_map_on_3d,
        map_3d_on_plane,
        seconds: t0.elapsed().as_secs_f64(),
    })
}
