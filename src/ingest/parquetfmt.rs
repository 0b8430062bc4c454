//! aepipe's own `waveforms.parquet` (round trip of `aepipe waveforms`, simulator output).
//! Read batch by batch; the rows carry their own experiment ids.

use super::Source;
use crate::ingest::settings::ReadSettings;
use crate::model::columns as cols;
use crate::model::{AeRecord, Item, Reject, Stage};
use crate::store;
use arrow::array::{Array, AsArray, RecordBatch};
use arrow::datatypes::{Float32Type, Float64Type, Int32Type, Int64Type};
use std::collections::VecDeque;

struct Reader {
    path: String,
    id: String,
    /// `None` after a broken batch: later offsets cannot be trusted.
    batches: Option<parquet::arrow::arrow_reader::ParquetRecordBatchReader>,
    queue: VecDeque<Item>,
}

fn col<'a>(b: &'a RecordBatch, name: &str) -> Result<&'a dyn Array, String> {
    b.column_by_name(name)
        .map(|a| a.as_ref())
        .ok_or_else(|| format!("no column {name}: not an aepipe waveforms table"))
}

fn records(b: &RecordBatch, path: &str) -> Result<Vec<AeRecord>, String> {
    let exp = col(b, cols::EXPERIMENT.name)?
        .as_string_opt::<i32>()
        .ok_or("experiment: expected string")?;
    let ch = col(b, cols::CHANNEL.name)?
        .as_primitive_opt::<Int32Type>()
        .ok_or("channel: expected int32")?;
    let hit = col(b, cols::HIT.name)?
        .as_primitive_opt::<Int64Type>()
        .ok_or("hit: expected int64")?;
    let time = col(b, cols::TIME_S.name)?
        .as_primitive_opt::<Float64Type>()
        .ok_or("time_s: expected float64")?;
    let rate = col(b, "sample_rate_hz")?
        .as_primitive_opt::<Float64Type>()
        .ok_or("sample_rate_hz: expected float64")?;
    let pre = col(b, "pretrigger_samples")?
        .as_primitive_opt::<Int32Type>()
        .ok_or("pretrigger_samples: expected int32")?;
    let load = col(b, cols::LOAD_N.name)?
        .as_primitive_opt::<Float64Type>()
        .ok_or("load_n: expected float64")?;
    let ext = col(b, cols::EXTENSION_M.name)?
        .as_primitive_opt::<Float64Type>()
        .ok_or("extension_m: expected float64")?;
    let label = col(b, cols::LABEL.name)?
        .as_string_opt::<i32>()
        .ok_or("label: expected string")?;
    let thr = col(b, "threshold_v")?
        .as_primitive_opt::<Float64Type>()
        .ok_or("threshold_v: expected float64")?;
    let samples = col(b, "samples_v")?
        .as_list_opt::<i32>()
        .ok_or("samples_v: expected list<float32>")?;
    let src = b
        .column_by_name("source_file")
        .and_then(|a| a.as_string_opt::<i32>().cloned());
    // Written since the column was added; older tables' records are their hits'.
    let kind = b
        .column_by_name("record_kind")
        .and_then(|a| a.as_string_opt::<i32>().cloned());
    let opt = |a: &arrow::array::PrimitiveArray<Float64Type>, i: usize| {
        if a.is_null(i) {
            None
        } else {
            Some(a.value(i))
        }
    };
    (0..b.num_rows())
        .map(|i| {
            let s = samples.value(i);
            let s = s
                .as_primitive_opt::<Float32Type>()
                .ok_or("samples_v: expected list<float32>")?;
            Ok(AeRecord {
                kind: match &kind {
                    Some(a) if !a.is_null(i) => crate::model::RecordKind::parse(a.value(i))
                        .ok_or_else(|| format!("record_kind: unknown value {:?}", a.value(i)))?,
                    _ => crate::model::RecordKind::Hit,
                },
                experiment: exp.value(i).to_string(),
                channel: ch.value(i).max(0) as u32,
                hit: hit.value(i).max(0) as u64,
                time_s: opt(time, i),
                sample_rate_hz: rate.value(i),
                pretrigger: pre.value(i).max(0) as u32,
                samples: s.values().to_vec(),
                load_n: opt(load, i),
                extension_m: opt(ext, i),
                label: if label.is_null(i) {
                    None
                } else {
                    Some(label.value(i).to_string())
                },
                threshold_v: opt(thr, i),
                source_file: match &src {
                    Some(a) if !a.is_null(i) => a.value(i).to_string(),
                    _ => path.to_string(),
                },
            })
        })
        .collect()
}

impl Iterator for Reader {
    type Item = Item;
    fn next(&mut self) -> Option<Item> {
        loop {
            if let Some(it) = self.queue.pop_front() {
                return Some(it);
            }
            let batch = self.batches.as_mut()?.next()?;
            let res = batch
                .map_err(|e| e.to_string())
                .and_then(|b| records(&b, &self.path));
            match res {
                Ok(rs) => self.queue.extend(rs.into_iter().map(Item::Record)),
                Err(reason) => {
                    // A broken batch: report it and stop (later offsets cannot be trusted).
                    self.queue.push_back(Item::Reject(Reject {
                        record_type: crate::model::RecordType::File,
                        experiment: self.id.clone(),
                        source_file: self.path.clone(),
                        record_id: String::new(),
                        stage: Stage::Read,
                        reason,
                    }));
                    self.batches = None;
                }
            }
        }
    }
}

/// aepipe's own `waveforms.parquet`.
pub(crate) const FORMAT: crate::ingest::FormatSpec = crate::ingest::FormatSpec {
    name: "parquet (waveforms)",
    one_hit_per_file: false,
    numbered_by_place: false,
    follow: crate::ingest::Follow::Whole,
    open,
};

pub fn open(src: &Source, _cfg: &ReadSettings) -> Box<dyn Iterator<Item = Item> + Send> {
    let path = &src.files[0];
    match store::open_parquet(path, 64) {
        Ok((schema, _, batches)) if schema.field_with_name("samples_v").is_ok() => {
            Box::new(Reader {
                path: path.display().to_string(),
                id: src.id.clone(),
                batches: Some(batches),
                queue: VecDeque::new(),
            })
        }
        Ok(_) => Box::new(std::iter::once(Item::Reject(Reject {
            record_type: crate::model::RecordType::File,
            experiment: src.id.clone(),
            source_file: path.display().to_string(),
            record_id: String::new(),
            stage: Stage::Read,
            reason: "Parquet file has no samples_v column: not an aepipe waveforms table".into(),
        }))),
        Err(e) => Box::new(std::iter::once(Item::Reject(Reject {
            record_type: crate::model::RecordType::File,
            experiment: src.id.clone(),
            source_file: path.display().to_string(),
            record_id: String::new(),
            stage: Stage::Read,
            reason: e.to_string(),
        }))),
    }
}
