//! `aepipe bench report`: the report's explorable charts at growing numbers of feature
//! rows — the page's size, the time to build it and, in headless Chromium (the browser test's
//! own DevTools driver), its time to first contentful paint and to the load event.
//!
//! The rows are a synthetic test's feature rows repeated with their hit numbers moved on
//! (so every row is a distinct hit): the explorer reads only the table, so what it embeds at
//! N rows is what it embeds for any test of N rows. The rest of a report (gallery, pictures)
//! is bounded by the classes and `[report] series_figures`, not by the rows.
//!
//! With `--whole`, the whole report: a synthetic run (`aepipe run` with clusters and linear
//! location) whose features table is replaced by N repeated rows, and `aepipe report` run on
//! it as a child process — trend, SOM classification, clustering and power law redone on the
//! N rows, the pictures drawn from them, the page written and opened in Chromium.

use super::BenchError;
use arrow::array::{Array, AsArray, Int64Array};
use arrow::datatypes::Int64Type;
use arrow::record_batch::RecordBatch;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// One size measured.
#[derive(Debug, Clone)]
pub struct ReportRow {
    pub rows: usize,
    pub points: usize,
    pub bytes: u64,
    pub build_s: f64,
    /// From the browser (none without a Python that has websocket-client and Chromium).
    pub first_paint_ms: Option<f64>,
    pub load_s: Option<f64>,
    pub errors: Option<usize>,
}

impl ReportRow {
    /// A size measured without the browser (its times filled by [`browse`]).
    fn measured(rows: usize, points: usize, bytes: usize, build_s: f64) -> ReportRow {
        ReportRow {
            rows,
            points,
            bytes: bytes as u64,
            build_s,
            first_paint_ms: None,
            load_s: None,
            errors: None,
        }
    }
}

/// Measure the explorer's page at each of `rows`, in `dir`; with `python`, the DevTools
/// `script` opens each page in Chromium.
pub fn bench_report(
    rows: &[usize],
    dir: &Path,
    python: Option<&Path>,
    script: &Path,
) -> Result<Vec<ReportRow>, BenchError> {
    std::fs::create_dir_all(dir).map_err(BenchError::run)?;
    let seed = seed_features(dir)?;
    let mut out = Vec::new();
    for &n in rows {
        let table = dir.join(format!("features_{n}.parquet"));
        repeat_rows(&seed, &table, n)?;
        let t0 = std::time::Instant::now();
        let tables = crate::workflow::explore::ExplorerTables {
            features: &table,
            classification: None,
            clusters: None,
            events: None,
        };
        let e = crate::workflow::explore::explorer_of(&tables).map_err(BenchError::run)?;
        let mut page = String::from(
            "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>aepipe bench \
             report</title></head><body>",
        );
        crate::report::explore::section(&mut page, &e);
        page.push_str("</body></html>");
        let html = dir.join(format!("explore_{n}.html"));
        std::fs::write(&html, &page).map_err(BenchError::run)?;
        let build_s = t0.elapsed().as_secs_f64();
        let mut row = ReportRow::measured(n, e.keys.len(), page.len(), build_s);
        if let Some(py) = python {
            browse(py, script, &html, &mut row)?;
        }
        let _ = std::fs::remove_file(&table);
        out.push(row);
    }
    Ok(out)
}

/// The run the whole-report sizes start from: clusters, linear location, the default gallery.
const WHOLE_PIPELINE: &str = "[cluster]\nenabled = true\nk_min = 2\nk_max = 4\n\n\
[location]\nkind = \"linear\"\nvelocity_m_s = 700\nsensors = { 1 = [-0.020], 2 = [0.020] }\n\
zone = [-0.015, 0.015]\n";

/// The whole report at each of `rows`: `exe run` once on a 2 000-hit synthetic test, then
/// per size its features table replaced by that many rows and `exe report` timed (wall,
/// as a child process); with `python`, each page opened in Chromium.
pub fn bench_whole_report(
    exe: &Path,
    rows: &[usize],
    dir: &Path,
    python: Option<&Path>,
    script: &Path,
) -> Result<Vec<ReportRow>, BenchError> {
    std::fs::create_dir_all(dir).map_err(BenchError::run)?;
    let synth = dir.join("whole-synth");
    let run = dir.join("whole-run");
    let cfg = dir.join("whole.toml");
    std::fs::write(&cfg, WHOLE_PIPELINE).map_err(BenchError::run)?;
    let _ = std::fs::remove_dir_all(&run);
    let step = |args: &[&std::ffi::OsStr]| -> Result<(), BenchError> {
        let o = std::process::Command::new(exe)
            .args(args)
            .output()
            .map_err(BenchError::run)?;
        if o.status.success() {
            Ok(())
        } else {
            Err(BenchError::Run(format!(
                "aepipe {:?}: {}",
                args.first(),
                String::from_utf8_lossy(&o.stderr).trim()
            )))
        }
    };
    let os = |s: &str| std::ffi::OsString::from(s);
    step(&[
        &os("synth-experiment"),
        &os("--out"),
        synth.as_os_str(),
        &os("--hits"),
        &os("2000"),
    ])?;
    step(&[
        &os("run"),
        &os("--config"),
        cfg.as_os_str(),
        synth.join("data").as_os_str(),
        &os("--out"),
        run.as_os_str(),
    ])?;
    let table = crate::workflow::RunDir::new(&run)
        .features()
        .path()
        .join(crate::pipeline::StreamJob::Features.table_file());
    let seed = dir.join("whole-seed.parquet");
    std::fs::copy(&table, &seed).map_err(BenchError::run)?;
    let html = run.join("report.html");
    let mut out = Vec::new();
    for &n in rows {
        repeat_rows(&seed, &table, n)?;
        let t0 = std::time::Instant::now();
        step(&[&os("report"), run.as_os_str()])?;
        let build_s = t0.elapsed().as_secs_f64();
        let page = std::fs::read_to_string(&html).map_err(BenchError::run)?;
        let mut row = ReportRow::measured(n, explorer_points(&page), page.len(), build_s);
        if let Some(py) = python {
            browse(py, script, &html, &mut row)?;
        }
        out.push(row);
    }
    Ok(out)
}

/// How many points the page's explorer embeds (its `"hit":[…]` list).
fn explorer_points(page: &str) -> usize {
    let Some(at) = page.find("\"hit\":[") else {
        return 0;
    };
    let rest = &page[at + 7..];
    let list = &rest[..rest.find(']').unwrap_or(0)];
    if list.is_empty() {
        0
    } else {
        list.matches(',').count() + 1
    }
}

/// Open `html` in Chromium through the DevTools `script`, filling `row`'s browser times.
fn browse(py: &Path, script: &Path, html: &Path, row: &mut ReportRow) -> Result<(), BenchError> {
    let o = std::process::Command::new(py)
        .arg(script)
        .arg(html)
        .output()
        .map_err(BenchError::run)?;
    if !o.status.success() {
        return Err(BenchError::Peer(
            String::from_utf8_lossy(&o.stderr)
                .lines()
                .last()
                .unwrap_or("")
                .into(),
        ));
    }
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).map_err(BenchError::run)?;
    row.first_paint_ms = v["first_paint_ms"].as_f64();
    row.load_s = v["load_s"].as_f64();
    row.errors = v["errors"].as_array().map(Vec::len);
    Ok(())
}

/// A synthetic test's features (2 000 hits of 1 024 samples, two channels).
fn seed_features(dir: &Path) -> Result<PathBuf, BenchError> {
    let data = dir.join("seed-data");
    let mut e = crate::synth::Experiment::new("bench_report", 2000, 7);
    e.n_samples = 1024;
    e.write_vallen(&data).map_err(BenchError::run)?;
    let cfg = crate::config::ValidConfig::default();
    let r = crate::pipeline::run(
        crate::pipeline::StreamJob::Features,
        &[data],
        &dir.join("seed"),
        &cfg,
        &crate::pipeline::StreamOptions::default(),
    )
    .map_err(BenchError::run)?;
    Ok(r.table_path)
}

/// `n` rows of `seed`'s, repeated, each repetition's hits moved on by 10⁷.
fn repeat_rows(seed: &Path, out: &Path, n: usize) -> Result<(), BenchError> {
    use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
    let file = std::fs::File::open(seed).map_err(BenchError::run)?;
    let builder = ParquetRecordBatchReaderBuilder::try_new(file).map_err(BenchError::run)?;
    let schema = builder.schema().clone();
    let batches: Vec<RecordBatch> = builder
        .build()
        .map_err(BenchError::run)?
        .collect::<Result<_, _>>()
        .map_err(BenchError::run)?;
    let hit = schema.index_of("hit").map_err(BenchError::run)?;
    let sink = std::fs::File::create(out).map_err(BenchError::run)?;
    let mut w = parquet::arrow::ArrowWriter::try_new(sink, schema.clone(), None)
        .map_err(BenchError::run)?;
    let (mut written, mut rep) = (0usize, 0i64);
    while written < n {
        for b in &batches {
            let take = b.num_rows().min(n - written);
            let b = b.slice(0, take);
            let hits = b.column(hit).as_primitive::<Int64Type>();
            let moved: Int64Array = hits
                .iter()
                .map(|h| h.map(|h| h + rep * 10_000_000))
                .collect();
            let mut cols = b.columns().to_vec();
            cols[hit] = Arc::new(moved) as Arc<dyn Array>;
            let nb = RecordBatch::try_new(schema.clone(), cols).map_err(BenchError::run)?;
            w.write(&nb).map_err(BenchError::run)?;
            written += take;
            if written >= n {
                break;
            }
        }
        rep += 1;
    }
    w.close().map_err(BenchError::run)?;
    Ok(())
}
