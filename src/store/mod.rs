//! Tables on disk: column specs (mirroring `data-schema/`), the atomic Parquet writer and
//! readers.
//!
//! Every table aepipe writes is described by a [`TableSchema`]: an ordered list of
//! [`ColumnSpec`]s carrying name, type, unit and meaning. The same list builds the Arrow
//! schema, fills the batches and renders the documentation in `data-schema/`, so adding a
//! column is one entry plus one value where the row is made.
//!
//! Writes are atomic: a table is written to `.NAME.tmp-PID` beside its final path and renamed
//! only by [`TableWriter::finish`]; an interrupted run leaves no file under the final name.

use crate::model::columns::{kind, Col};
use arrow::array::{
    ArrayRef, BooleanBuilder, FixedSizeListBuilder, Float32Builder, Float64Builder, Int32Builder,
    Int64Builder, ListBuilder, RecordBatch, StringBuilder,
};
use arrow::datatypes::{DataType, Field, Schema, SchemaRef};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use parquet::arrow::ArrowWriter;
use parquet::basic::Compression;
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::Arc;

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: parquet: {source}")]
    Parquet {
        path: String,
        source: parquet::errors::ParquetError,
    },
    #[error("{path}: arrow: {source}")]
    Arrow {
        path: String,
        source: arrow::error::ArrowError,
    },
    #[error("{path}: {message}")]
    Schema { path: String, message: String },
    /// A table could not be read (missing, not Parquet, a column missing or of another type).
    #[error("{path}: {message}")]
    Read { path: String, message: String },
}

impl crate::util::HasKind for StoreError {
    fn kind(&self) -> crate::util::ErrorKind {
        match self {
            StoreError::Read { .. } => crate::util::ErrorKind::Usage,
            StoreError::Io { .. }
            | StoreError::Parquet { .. }
            | StoreError::Arrow { .. }
            | StoreError::Schema { .. } => crate::util::ErrorKind::Failed,
        }
    }
}

/// The Arrow type of a column kind.
pub trait KindType {
    const TYPE: ColType;
}

impl KindType for kind::Str {
    const TYPE: ColType = ColType::Utf8;
}
impl KindType for kind::I32 {
    const TYPE: ColType = ColType::Int32;
}
impl KindType for kind::I64 {
    const TYPE: ColType = ColType::Int64;
}
impl KindType for kind::F64 {
    const TYPE: ColType = ColType::Float64;
}
impl KindType for kind::Bool {
    const TYPE: ColType = ColType::Bool;
}

/// The column types aepipe writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColType {
    Utf8,
    Int32,
    Int64,
    Float32,
    Float64,
    Bool,
    /// Variable-length list of float32 (waveform samples).
    ListF32,
    /// Variable-length lists of int32, int64 and float64 (an event's channels, hits, delays).
    ListI32,
    ListI64,
    ListF64,
    /// Fixed-size list of float32 (e.g. the 200 time/frequency bins).
    FixedListF32(i32),
}

impl ColType {
    pub fn arrow(self) -> DataType {
        match self {
            ColType::Utf8 => DataType::Utf8,
            ColType::Int32 => DataType::Int32,
            ColType::Int64 => DataType::Int64,
            ColType::Float32 => DataType::Float32,
            ColType::Float64 => DataType::Float64,
            ColType::Bool => DataType::Boolean,
            ColType::ListF32 => {
                DataType::List(Arc::new(Field::new("item", DataType::Float32, true)))
            }
            ColType::ListI32 => DataType::List(Arc::new(Field::new("item", DataType::Int32, true))),
            ColType::ListI64 => DataType::List(Arc::new(Field::new("item", DataType::Int64, true))),
            ColType::ListF64 => {
                DataType::List(Arc::new(Field::new("item", DataType::Float64, true)))
            }
            ColType::FixedListF32(n) => {
                DataType::FixedSizeList(Arc::new(Field::new("item", DataType::Float32, true)), n)
            }
        }
    }

    /// The type's name as written in `data-schema/*.md`.
    pub fn doc_name(self) -> String {
        match self {
            ColType::Utf8 => "string".into(),
            ColType::Int32 => "int32".into(),
            ColType::Int64 => "int64".into(),
            ColType::Float32 => "float32".into(),
            ColType::Float64 => "float64".into(),
            ColType::Bool => "bool".into(),
            ColType::ListF32 => "list<float32>".into(),
            ColType::ListI32 => "list<int32>".into(),
            ColType::ListI64 => "list<int64>".into(),
            ColType::ListF64 => "list<float64>".into(),
            ColType::FixedListF32(n) => format!("fixed_size_list<float32, {n}>"),
        }
    }
}

/// The documentation name of an Arrow type as read back from a file (inverse of
/// [`ColType::doc_name`]); other types print in Arrow's own notation.
pub fn arrow_doc_name(dt: &DataType) -> String {
    match dt {
        DataType::Utf8 | DataType::LargeUtf8 | DataType::Utf8View => "string".into(),
        DataType::Int32 => "int32".into(),
        DataType::Int64 => "int64".into(),
        DataType::Float32 => "float32".into(),
        DataType::Float64 => "float64".into(),
        DataType::Boolean => "bool".into(),
        DataType::List(f) | DataType::LargeList(f) => {
            format!("list<{}>", arrow_doc_name(f.data_type()))
        }
        DataType::FixedSizeList(f, n) => {
            format!("fixed_size_list<{}, {n}>", arrow_doc_name(f.data_type()))
        }
        other => format!("{other}"),
    }
}

/// One column: name, type, whether it may be null, unit and meaning.
#[derive(Debug, Clone, PartialEq)]
pub struct ColumnSpec {
    pub name: String,
    pub ty: ColType,
    pub nullable: bool,
    pub unit: String,
    pub doc: String,
}

impl ColumnSpec {
    pub fn new(name: impl Into<String>, ty: ColType, unit: &str, doc: &str) -> ColumnSpec {
        ColumnSpec {
            name: name.into(),
            ty,
            nullable: false,
            unit: unit.into(),
            doc: doc.into(),
        }
    }

    /// A column of `col`'s name and kind (`crate::model::columns`): its declaration and its
    /// readers share the one constant.
    pub fn of<K: KindType>(col: Col<K>, unit: &str, doc: &str) -> ColumnSpec {
        ColumnSpec::new(col.name, K::TYPE, unit, doc)
    }

    /// The same column, allowed to be null.
    pub fn nullable(mut self) -> ColumnSpec {
        self.nullable = true;
        self
    }
}

/// A table's name and columns.
#[derive(Debug, Clone, PartialEq)]
pub struct TableSchema {
    pub name: String,
    pub columns: Vec<ColumnSpec>,
}

impl TableSchema {
    pub fn arrow_schema(&self) -> SchemaRef {
        Arc::new(Schema::new(
            self.columns
                .iter()
                .map(|c| Field::new(&c.name, c.ty.arrow(), c.nullable))
                .collect::<Vec<_>>(),
        ))
    }

    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.columns.iter().position(|c| c.name == name)
    }

    /// The Markdown column table used in `data-schema/NAME.md`.
    pub fn markdown_columns(&self) -> String {
        let mut s =
            String::from("| column | type | nullable | unit | meaning |\n|---|---|---|---|---|\n");
        for c in &self.columns {
            s.push_str(&format!(
                "| `{}` | {} | {} | {} | {} |\n",
                c.name,
                c.ty.doc_name(),
                if c.nullable { "yes" } else { "no" },
                if c.unit.is_empty() { "–" } else { &c.unit },
                c.doc
            ));
        }
        s
    }
}

/// One cell. `None` writes a null.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    Str(Option<String>),
    I32(Option<i32>),
    I64(Option<i64>),
    F32(Option<f32>),
    F64(Option<f64>),
    Bool(Option<bool>),
    F32s(Option<Vec<f32>>),
    I32s(Option<Vec<i32>>),
    I64s(Option<Vec<i64>>),
    F64s(Option<Vec<f64>>),
}

/// One row's cells in its table's column order. Only a table's declaration makes one
/// ([`table::Table::row`]), so no code lays cells out by position by hand.
#[derive(Debug, Clone, PartialEq)]
pub struct Row(Vec<Value>);

impl Row {
    pub(crate) fn new(cells: Vec<Value>) -> Row {
        Row(cells)
    }

    /// The cells, in the table's column order.
    pub fn cells(&self) -> &[Value] {
        &self.0
    }
}

impl std::ops::Index<usize> for Row {
    type Output = Value;
    fn index(&self, i: usize) -> &Value {
        &self.0[i]
    }
}

/// Build one Arrow column from the `col`-th cell of every row.
fn build_column(spec: &ColumnSpec, col: usize, rows: &[Row]) -> Result<ArrayRef, String> {
    let bad = |v: &Value| format!("column {}: expected {:?}, got {v:?}", spec.name, spec.ty);
    macro_rules! scalar {
        ($builder:ty, $variant:ident) => {{
            let mut b = <$builder>::with_capacity(rows.len());
            for r in rows {
                match &r[col] {
                    Value::$variant(v) => b.append_option(v.clone()),
                    other => return Err(bad(other)),
                }
            }
            Arc::new(b.finish()) as ArrayRef
        }};
    }
    macro_rules! list {
        ($builder:ty, $variant:ident) => {{
            let mut b = ListBuilder::new(<$builder>::new());
            for r in rows {
                match &r[col] {
                    Value::$variant(Some(v)) => {
                        b.values().append_slice(v);
                        b.append(true);
                    }
                    Value::$variant(None) => b.append(false),
                    other => return Err(bad(other)),
                }
            }
            Arc::new(b.finish()) as ArrayRef
        }};
    }
    Ok(match spec.ty {
        ColType::Utf8 => {
            let mut b = StringBuilder::with_capacity(rows.len(), rows.len() * 16);
            for r in rows {
                match &r[col] {
                    Value::Str(v) => b.append_option(v.as_deref()),
                    other => return Err(bad(other)),
                }
            }
            Arc::new(b.finish())
        }
        ColType::Int32 => scalar!(Int32Builder, I32),
        ColType::Int64 => scalar!(Int64Builder, I64),
        ColType::Float32 => scalar!(Float32Builder, F32),
        ColType::Float64 => scalar!(Float64Builder, F64),
        ColType::Bool => scalar!(BooleanBuilder, Bool),
        ColType::ListF32 => {
            let total: usize = rows
                .iter()
                .map(|r| match &r[col] {
                    Value::F32s(Some(v)) => v.len(),
                    _ => 0,
                })
                .sum();
            let mut b =
                ListBuilder::with_capacity(Float32Builder::with_capacity(total), rows.len());
            for r in rows {
                match &r[col] {
                    Value::F32s(Some(v)) => {
                        b.values().append_slice(v);
                        b.append(true);
                    }
                    Value::F32s(None) => b.append(false),
                    other => return Err(bad(other)),
                }
            }
            Arc::new(b.finish())
        }
        ColType::ListI32 => list!(Int32Builder, I32s),
        ColType::ListI64 => list!(Int64Builder, I64s),
        ColType::ListF64 => list!(Float64Builder, F64s),
        ColType::FixedListF32(n) => {
            let n = n as usize;
            let mut b = FixedSizeListBuilder::with_capacity(
                Float32Builder::with_capacity(rows.len() * n),
                n as i32,
                rows.len(),
            );
            for r in rows {
                match &r[col] {
                    Value::F32s(Some(v)) if v.len() == n => {
                        b.values().append_slice(v);
                        b.append(true);
                    }
                    Value::F32s(None) => {
                        b.values().append_nulls(n);
                        b.append(false);
                    }
                    other => return Err(bad(other)),
                }
            }
            Arc::new(b.finish())
        }
    })
}

/// Turn rows into one Arrow batch of the table's schema.
/// Rows that do not fit their table (a cell of another type, a row of another length): a
/// bug in the code that made them, reported instead of a panic.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct RowError(pub String);

pub fn rows_to_batch(table: &TableSchema, rows: &[Row]) -> Result<RecordBatch, RowError> {
    for (i, r) in rows.iter().enumerate() {
        if r.cells().len() != table.columns.len() {
            return Err(RowError(format!(
                "table {}: row {i} has {} cells, schema has {} columns",
                table.name,
                r.cells().len(),
                table.columns.len()
            )));
        }
    }
    let arrays = table
        .columns
        .iter()
        .enumerate()
        .map(|(i, c)| build_column(c, i, rows))
        .collect::<Result<Vec<_>, _>>()
        .map_err(RowError)?;
    RecordBatch::try_new(table.arrow_schema(), arrays).map_err(|e| RowError(e.to_string()))
}

/// Streams rows of one table into a Parquet file, atomically.
pub struct TableWriter {
    table: TableSchema,
    final_path: PathBuf,
    tmp_path: PathBuf,
    writer: Option<ArrowWriter<BufWriter<File>>>,
    pending: Vec<Row>,
    batch_rows: usize,
    rows: u64,
}

pub use crate::util::tmp_path_for;

pub mod cache;
pub mod matrix;
pub mod read;
pub mod rewrite;
pub mod shard;
pub mod spill;
pub mod table;
pub use matrix::{for_each_matrix, HitMatrix, Quality};
pub use read::{group_channel, HitKey, SourceRows, TableScan};
pub use table::{
    hits_table, identity_table, markers_table, parametric_table, rejects_table, waveforms_table,
    Identity, Table, WaveformRow,
};

/// Remove temporary files left in `dir` by an interrupted earlier run.
pub fn clean_stale_tmp(dir: &Path) {
    if let Ok(rd) = std::fs::read_dir(dir) {
        for e in rd.flatten() {
            let n = e.file_name().to_string_lossy().to_string();
            if n.starts_with('.') && n.contains(".tmp-") {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
}

impl TableWriter {
    /// Start a table at `path` (written under a temporary name until [`finish`](Self::finish)).
    /// `metadata` goes into the Parquet key-value metadata.
    pub fn create(
        path: &Path,
        table: TableSchema,
        metadata: &[(String, String)],
        row_group_rows: usize,
    ) -> Result<TableWriter, StoreError> {
        let tmp_path = tmp_path_for(path);
        let file = File::create(&tmp_path).map_err(|source| StoreError::Io {
            path: tmp_path.display().to_string(),
            source,
        })?;
        let mut kv: Vec<KeyValue> = vec![
            KeyValue::new("aepipe.table".into(), table.name.clone()),
            KeyValue::new(
                "aepipe.version".into(),
                env!("CARGO_PKG_VERSION").to_string(),
            ),
        ];
        kv.extend(
            metadata
                .iter()
                .map(|(k, v)| KeyValue::new(k.clone(), v.clone())),
        );
        let props = WriterProperties::builder()
            .set_compression(Compression::SNAPPY)
            .set_max_row_group_row_count(Some(row_group_rows.max(1)))
            .set_created_by(format!("aepipe {}", env!("CARGO_PKG_VERSION")))
            .set_key_value_metadata(Some(kv))
            .build();
        let writer = ArrowWriter::try_new(
            BufWriter::with_capacity(1 << 20, file),
            table.arrow_schema(),
            Some(props),
        )
        .map_err(|source| StoreError::Parquet {
            path: tmp_path.display().to_string(),
            source,
        })?;
        Ok(TableWriter {
            table,
            final_path: path.to_path_buf(),
            tmp_path,
            writer: Some(writer),
            pending: Vec::new(),
            batch_rows: row_group_rows.clamp(1, 1024),
            rows: 0,
        })
    }

    pub fn table(&self) -> &TableSchema {
        &self.table
    }

    /// Rows accepted so far.
    pub fn rows(&self) -> u64 {
        self.rows + self.pending.len() as u64
    }

    pub fn push(&mut self, row: Row) -> Result<(), StoreError> {
        self.pending.push(row);
        if self.pending.len() >= self.batch_rows {
            self.flush_pending()?;
        }
        Ok(())
    }

    fn flush_pending(&mut self) -> Result<(), StoreError> {
        if self.pending.is_empty() {
            return Ok(());
        }
        let batch = rows_to_batch(&self.table, &self.pending).map_err(|e| StoreError::Schema {
            path: self.final_path.display().to_string(),
            message: e.to_string(),
        })?;
        self.rows += self.pending.len() as u64;
        self.pending.clear();
        self.writer
            .as_mut()
            .expect("writer open until finish")
            .write(&batch)
            .map_err(|source| StoreError::Parquet {
                path: self.tmp_path.display().to_string(),
                source,
            })
    }

    /// Append every row of a finished table of the same schema: how a run assembles its
    /// whole-batch tables from per-experiment parts. Read in batches of 1 024 rows, so the
    /// bytes written depend on the rows alone, not on how the part was written.
    pub fn append_file(&mut self, path: &Path) -> Result<u64, StoreError> {
        self.flush_pending()?;
        let (schema, _, reader) = open_parquet(path, 1024)?;
        let want = self.table.arrow_schema();
        if schema.fields() != want.fields() {
            return Err(StoreError::Schema {
                path: path.display().to_string(),
                message: format!("columns differ from the {} table's", self.table.name),
            });
        }
        let mut n = 0u64;
        for b in reader {
            let b = b.map_err(|source| StoreError::Arrow {
                path: path.display().to_string(),
                source,
            })?;
            n += self.push_batch(&b)?;
        }
        Ok(n)
    }

    /// Append a batch whose columns are the table's (by position and type).
    pub fn push_batch(&mut self, b: &RecordBatch) -> Result<u64, StoreError> {
        self.flush_pending()?;
        // The batch may carry the schema as read back; write it as ours.
        let b =
            RecordBatch::try_new(self.table.arrow_schema(), b.columns().to_vec()).map_err(|e| {
                StoreError::Schema {
                    path: self.final_path.display().to_string(),
                    message: e.to_string(),
                }
            })?;
        self.writer
            .as_mut()
            .expect("writer open until finish")
            .write(&b)
            .map_err(|source| StoreError::Parquet {
                path: self.tmp_path.display().to_string(),
                source,
            })?;
        self.rows += b.num_rows() as u64;
        Ok(b.num_rows() as u64)
    }

    /// Write the footer, sync, and rename to the final name. Returns the row count.
    pub fn finish(mut self) -> Result<u64, StoreError> {
        self.flush_pending()?;
        let writer = self.writer.take().expect("finish once");
        let path = self.tmp_path.display().to_string();
        let buf = writer.into_inner().map_err(|source| StoreError::Parquet {
            path: path.clone(),
            source,
        })?;
        let file = buf.into_inner().map_err(|e| StoreError::Io {
            path: path.clone(),
            source: e.into_error(),
        })?;
        file.sync_all().map_err(|source| StoreError::Io {
            path: path.clone(),
            source,
        })?;
        drop(file);
        std::fs::rename(&self.tmp_path, &self.final_path).map_err(|source| StoreError::Io {
            path: self.final_path.display().to_string(),
            source,
        })?;
        Ok(self.rows)
    }
}

impl Drop for TableWriter {
    fn drop(&mut self) {
        // Not finished (error or panic): leave nothing behind under either name.
        if self.writer.is_some() {
            let _ = std::fs::remove_file(&self.tmp_path);
        }
    }
}

/// Parquet key-value metadata as `(key, value)` pairs.
pub type KeyValues = Vec<(String, String)>;

/// Open a Parquet file for batch-wise reading.
pub fn open_parquet(
    path: &Path,
    batch_size: usize,
) -> Result<
    (
        SchemaRef,
        KeyValues,
        parquet::arrow::arrow_reader::ParquetRecordBatchReader,
    ),
    StoreError,
> {
    let file = File::open(path).map_err(|source| StoreError::Io {
        path: path.display().to_string(),
        source,
    })?;
    let builder =
        ParquetRecordBatchReaderBuilder::try_new(file).map_err(|source| StoreError::Parquet {
            path: path.display().to_string(),
            source,
        })?;
    let schema = builder.schema().clone();
    let kv = builder
        .metadata()
        .file_metadata()
        .key_value_metadata()
        .map(|v| {
            v.iter()
                .map(|kv| (kv.key.clone(), kv.value.clone().unwrap_or_default()))
                .collect()
        })
        .unwrap_or_default();
    let reader = builder
        .with_batch_size(batch_size)
        .build()
        .map_err(|source| StoreError::Parquet {
            path: path.display().to_string(),
            source,
        })?;
    Ok((schema, kv, reader))
}

/// Read a whole (small) Parquet table: schema, key-value metadata and batches.
pub fn read_parquet(path: &Path) -> Result<(SchemaRef, KeyValues, Vec<RecordBatch>), StoreError> {
    let (schema, kv, reader) = open_parquet(path, 8192)?;
    let batches = reader
        .collect::<Result<Vec<_>, _>>()
        .map_err(|source| StoreError::Arrow {
            path: path.display().to_string(),
            source,
        })?;
    Ok((schema, kv, batches))
}

/// Parse the column table of a `data-schema/*.md` file: `(name, type)` in order.
/// Rows look like ``| `name` | type | nullable | unit | meaning |``.
pub fn parse_schema_markdown(text: &str) -> Vec<(String, String, bool)> {
    text.lines()
        .filter_map(|l| {
            let cells: Vec<&str> = l
                .trim()
                .trim_matches('|')
                .split('|')
                .map(str::trim)
                .collect();
            if cells.len() >= 3 && cells[0].starts_with('`') && cells[0].ends_with('`') {
                Some((
                    cells[0].trim_matches('`').to_string(),
                    cells[1].to_string(),
                    cells[2] == "yes",
                ))
            } else {
                None
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markdown_round_trips_through_the_parser() {
        let t = waveforms_table().schema();
        let parsed = parse_schema_markdown(&t.markdown_columns());
        assert_eq!(parsed.len(), t.columns.len());
        for (c, (n, ty, nullable)) in t.columns.iter().zip(parsed) {
            assert_eq!(c.name, n);
            assert_eq!(c.ty.doc_name(), ty);
            assert_eq!(c.nullable, nullable);
        }
    }

    #[test]
    fn arrow_names_invert_doc_names() {
        for ty in [
            ColType::Utf8,
            ColType::Int32,
            ColType::Int64,
            ColType::Float32,
            ColType::Float64,
            ColType::Bool,
            ColType::ListF32,
            ColType::FixedListF32(200),
        ] {
            assert_eq!(arrow_doc_name(&ty.arrow()), ty.doc_name());
        }
    }

    #[test]
    fn wrong_cell_type_is_an_error_not_a_panic() {
        let t = rejects_table().schema();
        let row = Row::new(vec![Value::I32(Some(1)); 6]);
        let err = rows_to_batch(&t, &[row]).unwrap_err();
        assert!(err.to_string().contains("experiment"), "{err}");
    }

    /// `TableScan::columns` (arrow-rs by row group, stacked) gives the frame Polars' own
    /// Parquet reader reads: four row groups in one batch, and an empty table.
    #[test]
    fn columns_through_the_batch_reader_equal_polars_own_reader() {
        use polars::prelude::{ParquetReader, SerReader};
        let dir = std::env::temp_dir().join(format!("aepipe-cols-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for rows in [0usize, 35] {
            let path = dir.join(format!("t{rows}.parquet"));
            let mut w = TableWriter::create(&path, rejects_table().schema(), &[], 10).unwrap();
            for i in 0..rows {
                w.push(rejects_table().row(crate::model::Reject {
                    record_type: crate::model::RecordType::Hit,
                    experiment: format!("e{}", i % 3),
                    source_file: "f".into(),
                    record_id: format!("r{i}"),
                    stage: crate::model::Stage::Read,
                    reason: "x".into(),
                }))
                .unwrap();
            }
            w.finish().unwrap();
            let t = read::TableScan::open(&path).unwrap();
            let names = ["record_id", "experiment"];
            let a = t.columns(&names).unwrap();
            let b = ParquetReader::new(std::fs::File::open(&path).unwrap())
                .with_columns(Some(names.iter().map(|n| n.to_string()).collect()))
                .finish()
                .unwrap();
            assert_eq!(a.height(), rows);
            assert!(a.equals_missing(&b), "{a:?}\n{b:?}");
            if rows > 0 {
                assert!(t.batch_spans().len() == 1 && a.height() > 10);
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn unfinished_writer_leaves_nothing() {
        let dir = std::env::temp_dir().join(format!("aepipe-store-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.parquet");
        {
            let mut w = TableWriter::create(&path, rejects_table().schema(), &[], 10).unwrap();
            w.push(rejects_table().row(crate::model::Reject {
                record_type: crate::model::RecordType::Transient,
                experiment: "e".into(),
                source_file: "f".into(),
                record_id: "r".into(),
                stage: crate::model::Stage::Read,
                reason: "x".into(),
            }))
            .unwrap();
            assert!(tmp_path_for(&path).exists());
        }
        assert!(!path.exists());
        assert!(!tmp_path_for(&path).exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
