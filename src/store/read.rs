//! The one reader of the tables aepipe wrote, for the analysis side (trend, SOM, workflow,
//! report): arrow-rs reads the selected columns by row group and hands them to Polars
//! frames without a copy (Polars' lazy engine is not built: it brought ~190 crates, an HTTP
//! and TLS stack among them, for a filter and a select). The streaming write path (and the
//! streaming ingest of `waveforms.parquet`) is arrow-rs too.
//!
//! Columns come back as plain vectors keyed by [`HitKey`], and the `tf_bins` fixed-size list
//! (or any set of numeric columns) as an `ndarray` matrix, one row per hit.

use super::StoreError;
use crate::model::columns::{self as cols, kind, Col};
use ndarray::Array2;
use polars::prelude::*;
use std::path::{Path, PathBuf};

/// A hit's key in every table: (experiment, channel, hit).
pub type HitKey = (String, i32, i64);

/// Which rows of a hit-keyed table analysis counts (trend, SOM, class counts): sources, not
/// hits. Where the events step built events (`event_first` not null), one row per event —
/// the hit that opened it — and, with `exclude_outside`, only events not `outside` the
/// `[location] zone`; where it did not, every hit, less guard-suppressed ones with
/// `exclude_outside`. The tables themselves keep every row.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SourceRows {
    pub exclude_outside: bool,
}

impl SourceRows {
    /// The rule for one row, from its `event_first` and `zone`: a hit in no event
    /// (`event_first` null: events not built) unless a guard suppressed it, or an event's
    /// first hit unless its event lies outside the zone (those two exclusions only with
    /// `exclude_outside`). A null zone is in no zone.
    pub fn keeps(&self, event_first: Option<bool>, zone: Option<&str>) -> bool {
        match event_first {
            None => !(self.exclude_outside && zone == Some("guard")),
            Some(true) => !(self.exclude_outside && zone == Some("outside")),
            Some(false) => false,
        }
    }

    /// [`SourceRows::keeps`] of every row of a frame holding `event_first` and `zone`.
    pub fn mask(&self, df: &DataFrame) -> PolarsResult<Vec<bool>> {
        let first = df.column(cols::EVENT_FIRST.name)?.bool()?;
        let zone = df.column(cols::ZONE.name)?.str()?;
        Ok((0..df.height())
            .map(|i| self.keeps(first.get(i), zone.get(i)))
            .collect())
    }
}

/// The channel a row is grouped under in per-sensor series (trend, damage profile): its
/// own, or 0 for an event's first hit (the series of an experiment's events, whichever
/// sensor heard each first).
pub fn group_channel(channel: i32, event_first: Option<bool>) -> i32 {
    if event_first.is_some() {
        0
    } else {
        channel
    }
}

/// An opened table and its schema, read by row group.
pub struct TableScan {
    path: PathBuf,
    /// The row filter ([`TableScan::sources`]), applied to each batch.
    filter: Option<SourceRows>,
    schema: SchemaRef,
    /// The file's footer, parsed once: batches are read by row group with arrow-rs from it
    /// (a Polars scan parses the footer again at every collect, and a footer grows with
    /// the row groups, so slicing a large table batch by batch cost rows² / batch).
    meta: parquet::arrow::arrow_reader::ArrowReaderMetadata,
}

/// Rows read at a time by [`TableScan::batches`] (whole row groups are added until this is
/// reached): with the 200 `tf_bins` a batch holds ~13 MB of floats as read, ~26 MB as f64.
pub const BATCH_ROWS: usize = 16_384;

/// The row groups one batch reads.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BatchSpan {
    /// The file row of the batch's first row, and its rows (before the filter).
    pub first_row: usize,
    pub rows: usize,
    groups: std::ops::Range<usize>,
}

fn read_err(p: &Path, m: impl std::fmt::Display) -> StoreError {
    StoreError::Read {
        path: p.display().to_string(),
        message: m.to_string().replace('\n', " "),
    }
}

impl TableScan {
    /// Open `path` for scanning; fails when it is not a readable Parquet file. Reads the
    /// footer once, without the column statistics nothing here uses (a footer grows with
    /// the row groups: kept whole, a 3-million-row table's cost ~50 MB).
    pub fn open(path: &Path) -> Result<TableScan, StoreError> {
        use parquet::arrow::arrow_reader::{ArrowReaderMetadata, ArrowReaderOptions};
        use parquet::file::metadata::ParquetStatisticsPolicy as Keep;
        if !path.is_file() {
            return Err(read_err(path, "no such file"));
        }
        let file = std::fs::File::open(path).map_err(|e| read_err(path, e))?;
        let options = ArrowReaderOptions::new()
            .with_column_stats_policy(Keep::SkipAll)
            .with_size_stats_policy(Keep::SkipAll)
            .with_encoding_stats_policy(Keep::SkipAll);
        let meta = ArrowReaderMetadata::load(&file, options).map_err(|e| read_err(path, e))?;
        let schema = polars_schema(meta.schema()).map_err(|e| read_err(path, e))?;
        Ok(TableScan {
            path: path.to_path_buf(),
            filter: None,
            schema,
            meta,
        })
    }

    /// Rows in the file (before any filter).
    pub fn file_rows(&self) -> usize {
        self.meta.metadata().file_metadata().num_rows().max(0) as usize
    }

    /// The named columns, a batch at a time (whole row groups up to about [`BATCH_ROWS`]
    /// rows, and never more than that: a larger row group is read in slices), in file
    /// order, the row filter applied within each batch: the rows of [`TableScan::select`]
    /// of those columns, in bounded memory. Each item also gives the file row of the
    /// batch's first row.
    pub fn batches<'a>(
        &'a self,
        columns: &'a [&'a str],
    ) -> impl Iterator<Item = Result<(usize, DataFrame), StoreError>> + 'a {
        self.batch_spans().into_iter().flat_map(move |span| {
            match self.span_reader(&span, columns) {
                Ok(r) => Box::new(r) as Box<dyn Iterator<Item = _>>,
                Err(e) => Box::new(std::iter::once(Err(e))),
            }
        })
    }

    /// The batches [`TableScan::batches`] reads, in order.
    pub fn batch_spans(&self) -> Vec<BatchSpan> {
        let groups = self.meta.metadata().row_groups();
        let mut spans = Vec::new();
        let (mut start, mut first, mut rows) = (0usize, 0usize, 0usize);
        for (k, g) in groups.iter().enumerate() {
            let n = g.num_rows().max(0) as usize;
            if rows > 0 && rows + n > BATCH_ROWS {
                spans.push(BatchSpan {
                    first_row: first,
                    rows,
                    groups: start..k,
                });
                start = k;
                first += rows;
                rows = 0;
            }
            rows += n;
        }
        if rows > 0 {
            spans.push(BatchSpan {
                first_row: first,
                rows,
                groups: start..groups.len(),
            });
        }
        spans
    }

    /// One span's batches (one, or slices of a row group larger than [`BATCH_ROWS`]):
    /// the named columns as Polars frames (the arrow arrays handed over without a copy),
    /// the row filter applied, each with its first file row.
    pub fn span_reader(
        &self,
        span: &BatchSpan,
        columns: &[&str],
    ) -> Result<impl Iterator<Item = Result<(usize, DataFrame), StoreError>> + '_, StoreError> {
        use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
        use parquet::arrow::ProjectionMask;
        let e = |m: &dyn std::fmt::Display| read_err(&self.path, m);
        let mut names: Vec<&str> = columns.to_vec();
        if self.filter.is_some() {
            names.extend([cols::EVENT_FIRST.name, cols::ZONE.name]);
        }
        self.require(&names, "")?;
        names.sort_unstable();
        names.dedup();
        let file = std::fs::File::open(&self.path).map_err(|x| e(&x))?;
        let mask = ProjectionMask::columns(
            self.meta.metadata().file_metadata().schema_descr(),
            names.iter().copied(),
        );
        let reader = ParquetRecordBatchReaderBuilder::new_with_metadata(file, self.meta.clone())
            .with_row_groups(span.groups.clone().collect())
            .with_projection(mask)
            .with_batch_size(span.rows.clamp(1, BATCH_ROWS))
            .build()
            .map_err(|x| e(&x))?;
        let mut first = span.first_row;
        Ok(reader.map(move |b| {
            let b = b.map_err(|x| read_err(&self.path, x))?;
            let at = first;
            first += b.num_rows();
            let df = to_polars(&b).map_err(|x| read_err(&self.path, x))?;
            let df = match &self.filter {
                Some(f) => f
                    .mask(&df)
                    .and_then(|m| df.filter(&BooleanChunked::from_slice("keep".into(), &m)))
                    .map_err(|x| read_err(&self.path, x))?,
                None => df,
            };
            Ok((at, df))
        }))
    }

    /// Only the rows that count as sources ([`SourceRows`]); a table without the event
    /// columns is left whole.
    pub fn sources(mut self, rows: SourceRows) -> TableScan {
        if self.schema.get(cols::EVENT_FIRST.name).is_none()
            || self.schema.get(cols::ZONE.name).is_none()
        {
            return self;
        }
        self.filter = Some(rows);
        self
    }

    /// Whether each row of a frame holding `event_first` and `zone` counts under `rows`
    /// (the rule [`TableScan::sources`] filters by, for a reader that keeps every row).
    pub fn counted(&self, df: &DataFrame, rows: SourceRows) -> Result<Vec<bool>, StoreError> {
        rows.mask(df).map_err(|e| self.err(e))
    }

    /// `event_first` of every row of a frame that selected it (all null when the table has
    /// no such column).
    pub fn event_first(&self, df: &DataFrame) -> Result<Vec<Option<bool>>, StoreError> {
        match df.column(cols::EVENT_FIRST.name) {
            Ok(_) => self.flags(df, cols::EVENT_FIRST),
            Err(_) => Ok(vec![None; df.height()]),
        }
    }

    /// A boolean column (nulls as `None`).
    pub fn bools(&self, df: &DataFrame, name: &str) -> Result<Vec<Option<bool>>, StoreError> {
        let b = df
            .column(name)
            .and_then(|c| c.bool().cloned())
            .map_err(|e| self.err(format!("{name}: {e}")))?;
        Ok((0..b.len()).map(|i| b.get(i)).collect())
    }

    /// `"event_first"` when the table has it (for a selection list).
    pub fn event_first_col(&self) -> Option<&'static str> {
        self.schema
            .get(cols::EVENT_FIRST.name)
            .map(|_| cols::EVENT_FIRST.name)
    }

    /// Column names in table order.
    pub fn column_names(&self) -> Vec<String> {
        self.schema.iter_names().map(|n| n.to_string()).collect()
    }

    pub fn dtype(&self, name: &str) -> Option<&DataType> {
        self.schema.get(name)
    }

    /// Fails naming the first of `names` the table lacks, with `why` appended.
    pub fn require(&self, names: &[&str], why: &str) -> Result<(), StoreError> {
        match names.iter().find(|n| self.schema.get(n).is_none()) {
            Some(n) => Err(read_err(&self.path, format!("no column {n}{why}"))),
            None => Ok(()),
        }
    }

    /// The named columns of every row (the row filter applied), read batch by batch through
    /// [`TableScan::batches`] and stacked into one chunk; a table without rows gives the
    /// columns with their types and no rows. Fails naming the first column the table lacks.
    pub fn columns(&self, names: &[&str]) -> Result<DataFrame, StoreError> {
        self.require(names, "")?;
        let mut out: Option<DataFrame> = None;
        for b in self.batches(names) {
            let (_, df) = b?;
            let df = df.select(names.iter().copied()).map_err(|e| self.err(e))?;
            match &mut out {
                None => out = Some(df),
                Some(o) => {
                    o.vstack_mut(&df).map_err(|e| self.err(e))?;
                }
            }
        }
        match out {
            Some(mut df) => {
                df.rechunk_mut();
                Ok(df)
            }
            None => {
                let schema: Schema = names
                    .iter()
                    .filter_map(|n| {
                        let t = self.schema.get(n)?;
                        Some(Field::new((*n).into(), t.clone()))
                    })
                    .collect();
                Ok(DataFrame::empty_with_schema(&schema))
            }
        }
    }

    fn err(&self, m: impl std::fmt::Display) -> StoreError {
        read_err(&self.path, m)
    }

    /// The (experiment, channel, hit) key of every row of a frame holding those columns.
    pub fn hit_keys(&self, df: &DataFrame) -> Result<Vec<HitKey>, StoreError> {
        let e = |x: PolarsError| self.err(x);
        let exp = df
            .column(cols::EXPERIMENT.name)
            .and_then(|c| c.str().cloned())
            .map_err(e)?;
        let ch = df
            .column(cols::CHANNEL.name)
            .and_then(|c| c.i32().cloned())
            .map_err(e)?;
        let hit = df
            .column(cols::HIT.name)
            .and_then(|c| c.i64().cloned())
            .map_err(e)?;
        Ok((0..df.height())
            .map(|i| {
                (
                    exp.get(i).unwrap_or("").to_string(),
                    ch.get(i).unwrap_or(0),
                    hit.get(i).unwrap_or(0),
                )
            })
            .collect())
    }

    /// An integer column read as integers (a `channel`, `hit`, `event` key; nulls as `None`).
    pub fn i64s(&self, df: &DataFrame, c: Col<kind::I64>) -> Result<Vec<Option<i64>>, StoreError> {
        self.ints(df, c.name)
    }

    /// A 32-bit integer column (nulls as `None`).
    pub fn i32s(&self, df: &DataFrame, c: Col<kind::I32>) -> Result<Vec<Option<i32>>, StoreError> {
        Ok(self
            .ints(df, c.name)?
            .into_iter()
            .map(|v| v.map(|v| v as i32))
            .collect())
    }

    fn ints(&self, df: &DataFrame, name: &str) -> Result<Vec<Option<i64>>, StoreError> {
        let c = df
            .column(name)
            .and_then(|c| c.cast(&DataType::Int64))
            .and_then(|c| c.i64().cloned())
            .map_err(|e| self.err(format!("{name}: {e}")))?;
        Ok((0..c.len()).map(|i| c.get(i)).collect())
    }

    /// A float column (nulls as `None`).
    pub fn floats(
        &self,
        df: &DataFrame,
        c: Col<kind::F64>,
    ) -> Result<Vec<Option<f64>>, StoreError> {
        self.f64s(df, c.name)
    }

    /// A text column (nulls as `None`).
    pub fn texts(
        &self,
        df: &DataFrame,
        c: Col<kind::Str>,
    ) -> Result<Vec<Option<String>>, StoreError> {
        self.strings(df, c.name)
    }

    /// A boolean column (nulls as `None`).
    pub fn flags(
        &self,
        df: &DataFrame,
        c: Col<kind::Bool>,
    ) -> Result<Vec<Option<bool>>, StoreError> {
        self.bools(df, c.name)
    }

    /// A string column (nulls as `None`).
    pub fn strings(&self, df: &DataFrame, name: &str) -> Result<Vec<Option<String>>, StoreError> {
        let c = df
            .column(name)
            .and_then(|c| c.str().cloned())
            .map_err(|e| self.err(format!("{name}: {e}")))?;
        Ok((0..c.len()).map(|i| c.get(i).map(str::to_string)).collect())
    }

    /// Any column as text, cast as Polars casts (nulls as `None`): a label column of any
    /// type.
    pub fn as_strings(
        &self,
        df: &DataFrame,
        name: &str,
    ) -> Result<Vec<Option<String>>, StoreError> {
        let c = df
            .column(name)
            .and_then(|c| c.cast(&DataType::String))
            .map_err(|e| self.err(format!("{name}: {e}")))?;
        let c = c.str().map_err(|e| self.err(format!("{name}: {e}")))?;
        Ok((0..c.len()).map(|i| c.get(i).map(str::to_string)).collect())
    }

    /// A numeric column as f64 (nulls as `None`).
    pub fn f64s(&self, df: &DataFrame, name: &str) -> Result<Vec<Option<f64>>, StoreError> {
        let c = df
            .column(name)
            .and_then(|c| c.cast(&DataType::Float64))
            .and_then(|c| c.f64().cloned())
            .map_err(|e| self.err(format!("{name}: {e}")))?;
        Ok((0..c.len()).map(|i| c.get(i)).collect())
    }

    /// `f` gets every row's key and the string in `column` (empty for null), in file
    /// order, a batch at a time.
    pub fn for_each_keyed_string<E: From<StoreError>>(
        &self,
        column: &str,
        mut f: impl FnMut(HitKey, String) -> Result<(), E>,
    ) -> Result<(), E> {
        let sel = [
            cols::EXPERIMENT.name,
            cols::CHANNEL.name,
            cols::HIT.name,
            column,
        ];
        self.require(&sel, "")?;
        for batch in self.batches(&sel) {
            let (_, df) = batch?;
            let keys = self.hit_keys(&df)?;
            let strings = self.strings(&df, column)?;
            for (k, s) in keys.into_iter().zip(strings) {
                f(k, s.unwrap_or_default())?;
            }
        }
        Ok(())
    }

    /// The numeric feature matrix of `columns` in a frame (a batch) that selected them (a
    /// fixed-size list such as `tf_bins` gives its elements, a numeric scalar one
    /// dimension), one row per hit, as f64. Rows where a value is null or not finite are
    /// left out; the mask says which rows are kept.
    pub fn matrix_of(
        &self,
        df: &DataFrame,
        columns: &[String],
    ) -> Result<(Array2<f64>, Vec<bool>), StoreError> {
        let n = df.height();
        // Per column: its width and a row-major block of values (NaN for null).
        let mut blocks: Vec<(usize, Vec<f64>)> = Vec::with_capacity(columns.len());
        for name in columns {
            let c = df.column(name).map_err(|e| self.err(e))?;
            match c.dtype() {
                DataType::Array(inner, width) if inner.is_primitive_numeric() => {
                    let ca = c.array().map_err(|e| self.err(e))?.rechunk();
                    let nn = ca.is_not_null();
                    let valid: Vec<bool> = (0..nn.len()).map(|i| nn.get(i) == Some(true)).collect();
                    let inner = ca
                        .get_inner()
                        .cast(&DataType::Float64)
                        .map_err(|e| self.err(format!("{name}: {e}")))?;
                    let vals = inner.f64().map_err(|e| self.err(format!("{name}: {e}")))?;
                    if vals.len() != n * width {
                        return Err(self.err(format!(
                            "{name}: {} values for {n} rows of width {width}",
                            vals.len()
                        )));
                    }
                    let mut v: Vec<f64> = (0..vals.len())
                        .map(|i| vals.get(i).unwrap_or(f64::NAN))
                        .collect();
                    for (i, ok) in valid.iter().enumerate() {
                        if !ok {
                            v[i * width..(i + 1) * width].fill(f64::NAN);
                        }
                    }
                    blocks.push((*width, v));
                }
                dt if dt.is_primitive_numeric() => {
                    let v = self.f64s(df, name)?;
                    blocks.push((1, v.into_iter().map(|x| x.unwrap_or(f64::NAN)).collect()));
                }
                other => {
                    return Err(self.err(format!(
                        "{name} is {other}, not a number or a fixed-size list of numbers"
                    )))
                }
            }
        }
        let dim: usize = blocks.iter().map(|b| b.0).sum();
        let mut keep = vec![true; n];
        let mut data = Vec::with_capacity(n * dim);
        let mut row = Vec::with_capacity(dim);
        for (i, k) in keep.iter_mut().enumerate() {
            row.clear();
            for (w, v) in &blocks {
                row.extend_from_slice(&v[i * w..(i + 1) * w]);
            }
            if row.iter().all(|x| x.is_finite()) {
                data.extend_from_slice(&row);
            } else {
                *k = false;
            }
        }
        let rows = data.len() / dim.max(1);
        let m = Array2::from_shape_vec((rows, dim), data).map_err(|e| self.err(e))?;
        Ok((m, keep))
    }
}

/// An arrow-rs batch as a Polars frame: each column's array crosses by the Arrow
/// C Data Interface, which both implement, so the buffers are shared, not copied.
fn to_polars(batch: &arrow::array::RecordBatch) -> Result<DataFrame, String> {
    let schema = batch.schema();
    let mut cols: Vec<Column> = Vec::with_capacity(schema.fields().len());
    for (k, f) in schema.fields().iter().enumerate() {
        let data = batch.column(k).to_data();
        let (array, ffi_schema) =
            arrow::ffi::to_ffi(&data).map_err(|x| format!("{}: {x}", f.name()))?;
        // SAFETY: arrow-rs's FFI_ArrowArray / FFI_ArrowSchema and polars-arrow's
        // ArrowArray / ArrowSchema are both the C Data Interface's #[repr(C)] structs
        // (same fields, same order). The schema is only read here and released by
        // arrow-rs when dropped; the array is moved into Polars, which calls its
        // release callback when the chunk is dropped (arrow-rs's Drop never runs on it).
        let chunk = unsafe {
            let s = &*(&ffi_schema as *const arrow::ffi::FFI_ArrowSchema
                as *const polars_arrow::ffi::ArrowSchema);
            let field = polars_arrow::ffi::import_field_from_c(s)
                .map_err(|x| format!("{}: {x}", f.name()))?;
            let a: polars_arrow::ffi::ArrowArray = std::mem::transmute(array);
            polars_arrow::ffi::import_array_from_c(a, field.dtype)
                .map_err(|x| format!("{}: {x}", f.name()))?
        };
        let s = Series::from_arrow_chunks(f.name().as_str().into(), vec![chunk])
            .map_err(|x| format!("{}: {x}", f.name()))?;
        cols.push(s.into());
    }
    DataFrame::new(batch.num_rows(), cols).map_err(|x| x.to_string())
}

/// The Polars schema of an arrow-rs schema (each field through the C Data Interface, as the
/// batches cross).
fn polars_schema(schema: &arrow::datatypes::Schema) -> Result<SchemaRef, String> {
    let mut fields = Vec::with_capacity(schema.fields().len());
    for f in schema.fields() {
        let ffi = arrow::ffi::FFI_ArrowSchema::try_from(f.as_ref())
            .map_err(|x| format!("{}: {x}", f.name()))?;
        // SAFETY: both structs are the C Data Interface's ArrowSchema (#[repr(C)]); it is
        // only read here and released by arrow-rs.
        let field = unsafe {
            polars_arrow::ffi::import_field_from_c(
                &*(&ffi as *const arrow::ffi::FFI_ArrowSchema
                    as *const polars_arrow::ffi::ArrowSchema),
            )
        }
        .map_err(|x| format!("{}: {x}", f.name()))?;
        fields.push(Field::new(
            field.name.clone(),
            DataType::from_arrow_field(&field),
        ));
    }
    Ok(std::sync::Arc::new(Schema::from_iter(fields)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The source rule, row by row, written out by hand for every combination of
    /// `event_first` and `zone`.
    #[test]
    fn the_source_rule_row_by_row() {
        let zones = [None, Some("guard"), Some("outside"), Some("inside")];
        // (event_first, [kept for each zone above]) without and with exclude_outside
        let all = [
            (None, [true; 4]),
            (Some(false), [false; 4]),
            (Some(true), [true; 4]),
        ];
        let zoned = [
            (None, [true, false, true, true]),
            (Some(false), [false; 4]),
            (Some(true), [true, true, false, true]),
        ];
        for (exclude, table) in [(false, all), (true, zoned)] {
            let rows = SourceRows {
                exclude_outside: exclude,
            };
            for (first, kept) in table {
                for (z, want) in zones.iter().zip(kept) {
                    assert_eq!(rows.keeps(first, *z), want, "{exclude} {first:?} {z:?}");
                }
            }
        }
    }

    /// The frame's mask is the rule of each row, nulls included.
    #[test]
    fn the_mask_applies_the_rule_to_each_row() {
        let df = DataFrame::new_infer_height(vec![
            Column::new(
                cols::EVENT_FIRST.name.into(),
                [None, Some(true), Some(true), Some(false), None],
            ),
            Column::new(
                cols::ZONE.name.into(),
                [Some("guard"), Some("outside"), None, Some("inside"), None],
            ),
        ])
        .unwrap();
        let m = |exclude_outside| SourceRows { exclude_outside }.mask(&df).unwrap();
        let (t, f) = (true, false);
        assert_eq!(m(false), [t, t, t, f, t]);
        assert_eq!(m(true), [f, f, t, f, t]);
    }
}
