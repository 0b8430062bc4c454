//! Fill columns of a finished table in place: how the events step writes `event`,
//! `event_first` and `zone` into a part's `hits.parquet` and `features.parquet` after the
//! stream (events need every hit of an experiment; the stream writes them one by one).

use super::{open_parquet, StoreError, TableSchema, TableWriter};
use arrow::array::{ArrayRef, RecordBatch};
use std::path::Path;

/// Replace the named columns of the table at `path` (of schema `table`) with `columns`,
/// one value per row in table order, keeping every other column, the key-value metadata and
/// the row-group size. Read and written in batches of 1 024 rows: memory is the replacement
/// columns plus one batch. Atomic: the file is replaced only when the new one is complete.
pub fn replace_columns(
    path: &Path,
    table: &TableSchema,
    columns: &[(&str, ArrayRef)],
    row_group_rows: usize,
) -> Result<u64, StoreError> {
    let bad = |m: String| StoreError::Schema {
        path: path.display().to_string(),
        message: m,
    };
    let (schema, kv, reader) = open_parquet(path, 1024)?;
    if schema.fields() != table.arrow_schema().fields() {
        return Err(bad(format!(
            "columns differ from the {} table's",
            table.name
        )));
    }
    let mut at = Vec::new();
    for (name, a) in columns {
        let i = table
            .index_of(name)
            .ok_or_else(|| bad(format!("no column {name}")))?;
        if a.data_type() != schema.field(i).data_type() {
            return Err(bad(format!(
                "{name}: {} given for {}",
                a.data_type(),
                schema.field(i).data_type()
            )));
        }
        at.push((i, a));
    }
    // The writer adds aepipe.table and aepipe.version itself.
    let meta: Vec<(String, String)> = kv
        .into_iter()
        .filter(|(k, _)| k != "aepipe.table" && k != "aepipe.version")
        .collect();
    let mut w = TableWriter::create(path, table.clone(), &meta, row_group_rows)?;
    let mut offset = 0usize;
    for b in reader {
        let b = b.map_err(|source| StoreError::Arrow {
            path: path.display().to_string(),
            source,
        })?;
        let n = b.num_rows();
        let mut cols = b.columns().to_vec();
        for (i, a) in &at {
            if offset + n > a.len() {
                return Err(bad(format!(
                    "{} values given for a table of more rows",
                    a.len()
                )));
            }
            cols[*i] = a.slice(offset, n);
        }
        let nb =
            RecordBatch::try_new(table.arrow_schema(), cols).map_err(|e| bad(e.to_string()))?;
        w.push_batch(&nb)?;
        offset += n;
    }
    if let Some((i, a)) = at.iter().find(|(_, a)| a.len() != offset) {
        return Err(bad(format!(
            "{} values given for column {} of a table of {offset} rows",
            a.len(),
            table.columns[*i].name
        )));
    }
    w.finish()
}
