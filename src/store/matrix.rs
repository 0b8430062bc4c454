//! Feature tables read as matrices, a batch at a time: the rows whose named columns are all
//! usable, with their keys, an optional label column and the time-domain quality. The SOM
//! and clustering both read their inputs here, each with its own errors.

use super::read::{HitKey, SourceRows, TableScan};
use super::StoreError;
use crate::model::columns as cols;
use ndarray::Array2;
use std::path::PathBuf;

/// Per-hit vectors read from feature tables: the rows of one batch whose every named column
/// is usable, their keys, labels and quality.
#[derive(Debug, Clone)]
pub struct HitMatrix {
    pub keys: Vec<HitKey>,
    /// One row per kept hit.
    pub data: Array2<f64>,
    pub labels: Vec<Option<String>>,
    /// Each row's time-domain quality (`features.parquet`'s `quality_fault`).
    pub quality: Vec<Quality>,
    /// Rows left out because a feature was null or not finite (flat or empty records).
    pub skipped: usize,
}

/// A row's time-domain quality check, as its feature table states it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Quality {
    /// The table has no `quality_fault` column (written by another tool or an older aepipe).
    Unknown,
    Sound,
    /// The fault's kind (`clipped`, `two_bursts`, …).
    Fault(String),
}

impl HitMatrix {
    pub fn dim(&self) -> usize {
        self.data.ncols()
    }
}

/// `features.parquet`'s time-domain quality column, and its alias when read.
const QUALITY: &str = "quality_fault";

/// The usable rows of the tables a batch at a time ([`super::read::BATCH_ROWS`] rows of a file):
/// `f` gets each batch's usable rows, in file order, so memory does not grow with the
/// table. Every batch has the same dimension (else an error naming the file). The reading's
/// errors reach the caller through `serr`, in its own room's words.
pub fn for_each_matrix<E>(
    paths: &[PathBuf],
    columns: &[String],
    label: Option<&str>,
    sources: SourceRows,
    serr: impl Fn(StoreError) -> E,
    mut f: impl FnMut(HitMatrix) -> Result<(), E>,
) -> Result<(), E> {
    let mut dim = None;
    for p in paths {
        let t = TableScan::open(p).map_err(&serr)?.sources(sources);
        let mut need = vec![cols::EXPERIMENT.name, cols::CHANNEL.name, cols::HIT.name];
        need.extend(label);
        t.require(&need, "").map_err(&serr)?;
        let names: Vec<&str> = columns.iter().map(String::as_str).collect();
        t.require(&names, "").map_err(&serr)?;
        // The label may be any column, a key column included (`--label experiment`), read as
        // text; a column named twice is read once (the batch reader selects each name once).
        let mut sel: Vec<&str> = vec![cols::EXPERIMENT.name, cols::CHANNEL.name, cols::HIT.name];
        sel.extend(label);
        let has_quality = t.dtype(QUALITY).is_some();
        if has_quality {
            sel.push(QUALITY);
        }
        sel.extend(columns.iter().map(String::as_str));
        for batch in t.batches(&sel) {
            let (_, df) = batch.map_err(&serr)?;
            let k = t.hit_keys(&df).map_err(&serr)?;
            let l = match label {
                Some(name) => t.as_strings(&df, name).map_err(&serr)?,
                None => vec![None; k.len()],
            };
            let q: Vec<Quality> = if has_quality {
                t.as_strings(&df, QUALITY)
                    .map_err(&serr)?
                    .into_iter()
                    .map(|f| match f {
                        Some(f) if !f.is_empty() => Quality::Fault(f),
                        _ => Quality::Sound,
                    })
                    .collect()
            } else {
                vec![Quality::Unknown; k.len()]
            };
            let (m, keep) = t.matrix_of(&df, columns).map_err(&serr)?;
            if m.nrows() > 0 {
                match dim {
                    Some(d) if d != m.ncols() => {
                        return Err(serr(StoreError::Read {
                            path: p.display().to_string(),
                            message: format!("rows of dimension {d} and {}", m.ncols()),
                        }))
                    }
                    _ => dim = Some(m.ncols()),
                }
            }
            let mut input = HitMatrix {
                keys: Vec::with_capacity(m.nrows()),
                data: m,
                labels: Vec::with_capacity(keep.len()),
                quality: Vec::with_capacity(keep.len()),
                skipped: 0,
            };
            for (((key, lab), q), kept) in k.into_iter().zip(l).zip(q).zip(&keep) {
                if *kept {
                    input.keys.push(key);
                    input.labels.push(lab);
                    input.quality.push(q);
                } else {
                    input.skipped += 1;
                }
            }
            f(input)?;
        }
    }
    Ok(())
}
