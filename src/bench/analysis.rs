//! `aepipe bench analysis --rows N`: the whole-batch stages on a study of N feature rows.
//!
//! A base run (the demo's strip: 651 sources, 1 302 hits at two sensors, a map trained on
//! the embedded library) is repeated into N rows, a batch at a time (bounded memory): each
//! repetition is a new experiment (or, with `--experiments E`, the repetitions are spread
//! over E experiments, their hits, times and events shifted so that each experiment's are
//! one test). Then trend, classification with the base's map, damage profile (with
//! evolution and location) and report run on it through `workflow::analyse`, exactly as
//! `aepipe merge` runs them, and each stage's time and peak resident memory are printed.

use super::BenchError;
use crate::model::columns as cols;
use arrow::array::{
    Array, ArrayRef, Float64Array, Int64Array, ListArray, RecordBatch, StringArray,
};
use arrow::datatypes::SchemaRef;
use parquet::arrow::ArrowWriter;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// What the benchmark did.
pub struct AnalysisBench {
    pub rows: u64,
    pub experiments: u64,
    /// Stage → (seconds, peak RSS bytes), in order, the table writing first.
    pub stages: Vec<(String, f64, Option<u64>)>,
    /// Bytes of the run folder (tables, pictures, report) and of the features table.
    pub disk_bytes: u64,
    pub features_bytes: u64,
    pub out: PathBuf,
}

/// A table read whole (the base run's are small).
fn read_all(path: &Path) -> Result<(SchemaRef, Vec<RecordBatch>), BenchError> {
    let (schema, _, batches) = crate::store::read_parquet(path).map_err(BenchError::run)?;
    Ok((schema, batches))
}

/// How one repetition shifts its copy: the experiment it belongs to, and the offsets that
/// make it continue that experiment's earlier repetitions.
struct Shift {
    experiment: String,
    hit: i64,
    time_s: f64,
    event: i64,
}

/// The base's batches with the key columns shifted.
fn shifted(batch: &RecordBatch, s: &Shift) -> Result<RecordBatch, BenchError> {
    let schema = batch.schema();
    let mut cols: Vec<ArrayRef> = Vec::with_capacity(batch.num_columns());
    for (f, c) in schema.fields().iter().zip(batch.columns()) {
        let n = c.len();
        let new: ArrayRef = match f.name().as_str() {
            name if name == cols::EXPERIMENT.name => {
                Arc::new(StringArray::from(vec![s.experiment.as_str(); n]))
            }
            name if name == cols::HIT.name && s.hit != 0 => add_i64(c, s.hit)?,
            name if name == cols::EVENT.name && s.event != 0 => add_i64(c, s.event)?,
            name if name == cols::TIME_S.name && s.time_s != 0.0 => {
                let a = c
                    .as_any()
                    .downcast_ref::<Float64Array>()
                    .ok_or_else(|| BenchError::run("time_s is not float64"))?;
                Arc::new(
                    a.iter()
                        .map(|v| v.map(|v| v + s.time_s))
                        .collect::<Float64Array>(),
                )
            }
            "hits" if s.hit != 0 => {
                // events.parquet: each event's hit numbers.
                let l = c
                    .as_any()
                    .downcast_ref::<ListArray>()
                    .ok_or_else(|| BenchError::run("hits is not a list"))?;
                let values = add_i64(l.values(), s.hit)?;
                Arc::new(
                    ListArray::try_new(
                        match l.data_type() {
                            arrow::datatypes::DataType::List(f) => f.clone(),
                            _ => return Err(BenchError::run("hits is not a list")),
                        },
                        l.offsets().clone(),
                        values,
                        l.nulls().cloned(),
                    )
                    .map_err(BenchError::run)?,
                )
            }
            _ => c.clone(),
        };
        cols.push(new);
    }
    RecordBatch::try_new(schema, cols).map_err(BenchError::run)
}

fn add_i64(c: &ArrayRef, d: i64) -> Result<ArrayRef, BenchError> {
    let a = c
        .as_any()
        .downcast_ref::<Int64Array>()
        .ok_or_else(|| BenchError::run("not int64"))?;
    Ok(Arc::new(
        a.iter().map(|v| v.map(|v| v + d)).collect::<Int64Array>(),
    ))
}

/// The largest value of an int64 or float64 column over the batches (0 when none).
fn max_of(batches: &[RecordBatch], name: &str) -> f64 {
    let mut m = 0.0f64;
    for b in batches {
        let Some(c) = b.column_by_name(name) else {
            continue;
        };
        if let Some(a) = c.as_any().downcast_ref::<Int64Array>() {
            m = a.iter().flatten().fold(m, |m, v| m.max(v as f64));
        } else if let Some(a) = c.as_any().downcast_ref::<Float64Array>() {
            m = a.iter().flatten().fold(m, f64::max);
        }
    }
    m
}

/// Writes `rows` rows (or, for the events, every repetition's events) of the base table's
/// repetitions to `out`, as the pipeline writes its tables (Snappy, its row groups).
fn repeat_table(
    base: &Path,
    out: &Path,
    reps: &[Shift],
    rows: Option<u64>,
    row_group_rows: usize,
) -> Result<u64, BenchError> {
    let (schema, kv, batches) = crate::store::read_parquet(base).map_err(BenchError::run)?;
    let file = std::fs::File::create(out).map_err(BenchError::run)?;
    let props = parquet::file::properties::WriterProperties::builder()
        .set_compression(parquet::basic::Compression::SNAPPY)
        .set_max_row_group_row_count(Some(row_group_rows))
        .set_key_value_metadata(Some(
            kv.into_iter()
                .map(|(k, v)| parquet::file::metadata::KeyValue::new(k, v))
                .collect(),
        ))
        .build();
    let mut w = ArrowWriter::try_new(std::io::BufWriter::new(file), schema, Some(props))
        .map_err(BenchError::run)?;
    let mut written = 0u64;
    'outer: for s in reps {
        for b in &batches {
            let mut b = shifted(b, s)?;
            if let Some(n) = rows {
                let left = n - written;
                if left == 0 {
                    break 'outer;
                }
                if (b.num_rows() as u64) > left {
                    b = b.slice(0, left as usize);
                }
            }
            written += b.num_rows() as u64;
            w.write(&b).map_err(BenchError::run)?;
        }
    }
    w.close().map_err(BenchError::run)?;
    Ok(written)
}

fn dir_bytes(p: &Path) -> u64 {
    let mut n = 0;
    if let Ok(rd) = std::fs::read_dir(p) {
        for e in rd.flatten() {
            let path = e.path();
            n += if path.is_dir() {
                dir_bytes(&path)
            } else {
                e.metadata().map(|m| m.len()).unwrap_or(0)
            };
        }
    }
    n
}

/// Build the base (the demo's run) in `out/base` unless `base` names one already built.
fn base_run(base: Option<&Path>, out: &Path, threads: usize) -> Result<PathBuf, BenchError> {
    if let Some(b) = base {
        return Ok(b.to_path_buf());
    }
    let root = out.join("base");
    if root.join("run/som/model/model.json").is_file() {
        return Ok(root);
    }
    let id = "synthetic_notched_paper";
    crate::synth::synth_experiment(&root, id, 651, 2026, None, false).map_err(BenchError::run)?;
    let cfg = crate::synth::demo_config();
    let data = root.join("data");
    crate::workflow::run(&crate::workflow::RunJob::new(
        &cfg,
        std::slice::from_ref(&data),
        &root.join("run"),
        threads,
    ))
    .map_err(BenchError::run)?;
    Ok(root)
}

/// Run the benchmark: `rows` feature rows over `experiments` experiments (default: one per
/// repetition of the base) in `out/run`.
pub fn analysis(
    rows: u64,
    experiments: Option<u64>,
    base: Option<&Path>,
    out: &Path,
    threads: usize,
) -> Result<AnalysisBench, BenchError> {
    if rows == 0 {
        return Err(BenchError::Run("--rows must be ≥ 1".into()));
    }
    std::fs::create_dir_all(out).map_err(BenchError::run)?;
    let base = base_run(base, out, threads)?;
    let bfeat = base.join("run/features");
    let (_, fb) = read_all(&bfeat.join("features.parquet"))?;
    let base_rows: u64 = fb.iter().map(|b| b.num_rows() as u64).sum();
    if base_rows == 0 {
        return Err(BenchError::Run("the base run has no feature rows".into()));
    }
    let reps = rows.div_ceil(base_rows);
    let experiments = experiments.unwrap_or(reps).clamp(1, reps);
    let hit_span = max_of(&fb, cols::HIT.name) as i64;
    let time_span = max_of(&fb, cols::TIME_S.name).ceil() + 1.0;
    let (_, eb) = read_all(&bfeat.join("events.parquet"))?;
    let event_span = max_of(&fb, cols::EVENT.name).max(max_of(&eb, cols::EVENT.name)) as i64;
    // Repetitions are named after the base's experiment.
    let base_exp = fb
        .iter()
        .find_map(|b| {
            let c = b.column_by_name(cols::EXPERIMENT.name)?;
            let s = c.as_any().downcast_ref::<StringArray>()?;
            (!s.is_empty()).then(|| s.value(0).to_string())
        })
        .unwrap_or_else(|| cols::EXPERIMENT.name.into());
    // Repetition r belongs to experiment r·E/R and is its j-th.
    let mut shifts = Vec::with_capacity(reps as usize);
    let mut first_of = u64::MAX;
    let mut last_exp = u64::MAX;
    for r in 0..reps {
        let e = r * experiments / reps;
        if e != last_exp {
            first_of = r;
            last_exp = e;
        }
        let j = (r - first_of) as i64;
        shifts.push(Shift {
            experiment: format!("{base_exp}-{e:06}"),
            hit: j * hit_span,
            time_s: j as f64 * time_span,
            event: j * event_span,
        });
    }
    let run = out.join("run");
    let _ = std::fs::remove_dir_all(&run);
    let fdir = run.join("features");
    std::fs::create_dir_all(&fdir).map_err(BenchError::run)?;
    let rg = crate::synth::demo_config().pipeline.row_group_rows;
    let mut log = crate::workflow::StageLog::default();
    let written = log.time("write features", || -> Result<u64, BenchError> {
        let n = repeat_table(
            &bfeat.join("features.parquet"),
            &fdir.join("features.parquet"),
            &shifts,
            Some(rows),
            rg,
        )?;
        repeat_table(
            &bfeat.join("events.parquet"),
            &fdir.join("events.parquet"),
            &shifts,
            None,
            rg,
        )?;
        for t in ["hits", "rejects", "parametric", "markers"] {
            let f = format!("{t}.parquet");
            std::fs::copy(bfeat.join(&f), fdir.join(&f)).map_err(BenchError::run)?;
        }
        std::fs::copy(bfeat.join("manifest.json"), fdir.join("manifest.json"))
            .map_err(BenchError::run)?;
        Ok(n)
    })?;
    let features = crate::pipeline::RunReport::of_tables(
        &crate::pipeline::StreamDir::new(&fdir),
        crate::pipeline::StreamJob::Features,
        crate::pipeline::StreamStats {
            records_read: written,
            hits: written,
            rows: written,
            ..Default::default()
        },
    );
    let model = base.join("run/som/model");
    let cfg = crate::synth::demo_config()
        .with(|c| c.som.model = Some(model.to_path_buf()))
        .map_err(BenchError::run)?;
    let data = base.join("data");
    let summary = crate::workflow::analyse(
        &crate::workflow::RunJob::new(&cfg, std::slice::from_ref(&data), &run, threads),
        features,
        log,
    )
    .map_err(BenchError::run)?;
    let stages = summary
        .stages()
        .into_iter()
        .map(|(k, s, rss)| (k.to_string(), s, rss))
        .collect();
    Ok(AnalysisBench {
        rows: written,
        experiments,
        stages,
        disk_bytes: dir_bytes(&run),
        features_bytes: std::fs::metadata(fdir.join("features.parquet"))
            .map(|m| m.len())
            .unwrap_or(0),
        out: run,
    })
}
