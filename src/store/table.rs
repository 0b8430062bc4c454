//! Tables declared once: every column is one entry holding its [`ColumnSpec`] and the
//! function that fills it from the row's value, so the Arrow schema, the cells of a row and
//! the documentation in `data-schema/` all come from one list and cannot drift apart.
//! Adding a column is one `.col(…)` call.

use super::{ColType, ColumnSpec, Row, TableSchema, Value};
use crate::model::{MarkerRow, ParametricRow};

type Getter<T> = Box<dyn Fn(&T) -> Value + Send + Sync>;

/// A table of rows made from values of `T`.
pub struct Table<T> {
    name: String,
    cols: Vec<(ColumnSpec, Getter<T>)>,
}

impl<T> Table<T> {
    pub fn new(name: &str) -> Table<T> {
        Table {
            name: name.to_string(),
            cols: Vec::new(),
        }
    }

    /// Add a column: its spec and how a `T` fills it.
    pub fn col(
        mut self,
        spec: ColumnSpec,
        get: impl Fn(&T) -> Value + Send + Sync + 'static,
    ) -> Self {
        self.cols.push((spec, Box::new(get)));
        self
    }

    /// The columns as a [`TableSchema`] (Arrow schema, documentation).
    pub fn schema(&self) -> TableSchema {
        TableSchema {
            name: self.name.clone(),
            columns: self.cols.iter().map(|(c, _)| c.clone()).collect(),
        }
    }

    /// The cells of one row, in column order.
    pub fn row(&self, t: &T) -> Row {
        self.cols.iter().map(|(_, get)| get(t)).collect()
    }
}

fn s(v: &str) -> Value {
    Value::Str(Some(v.to_string()))
}

/// `parametric.parquet`: the parametric / time-driven rows of every source, as recorded, with
/// the load and extension the pipeline maps them to.
pub fn parametric_table() -> Table<ParametricRow> {
    let f = |name: &str, unit: &str, doc: &str| {
        ColumnSpec::new(name, ColType::Float64, unit, doc).nullable()
    };
    Table::new("parametric")
        .col(ColumnSpec::new("experiment", ColType::Utf8, "", "experiment id"), |r: &ParametricRow| s(&r.experiment))
        .col(ColumnSpec::new("row", ColType::Int64, "", "1-based order of the row in its experiment and source"), |r| Value::I64(Some(r.row as i64)))
        .col(f("time_s", "s", "time since the start of the acquisition (for a load file: its own time × `time_scale_s` + the experiment's `[load.offset_s]`)"), |r| Value::F64(r.time_s))
        .col(f("load_n", "N", "the load this row gives (`[ingest.vallen]`/`[ingest.mistras]` mapping of a parametric input, or `[load]`); null: not mapped"), |r| Value::F64(r.load_n))
        .col(f("extension_m", "m", "the extension this row gives; null: not mapped"), |r| Value::F64(r.extension_m))
        .col(ColumnSpec::new("inputs", ColType::Utf8, "", "the raw inputs, a JSON object under the vendor's names: Vallen `PA0`… in mV, MISTRAS `PARA1`… in V, a load file's columns in its own units").nullable(), |r| Value::Str(r.inputs.clone()))
        .col(ColumnSpec::new("extra", ColType::Utf8, "", "further fields of the record, JSON: Vallen `PCTD`, `PCTA`, `Status`; MISTRAS time-driven channel features by channel (`{\"3\": {\"ASL\": 25}}`)").nullable(), |r| Value::Str(r.extra.clone()))
        .col(ColumnSpec::new("source", ColType::Utf8, "", "vallen (SetType 1), mistras (message 2 or 3), load_file (`[load]`), machine_log (AEwin Specimen_RawData)"), |r| s(r.source.as_str()))
        .col(ColumnSpec::new("source_file", ColType::Utf8, "", "the file the row came from"), |r| s(&r.source_file))
}

/// `markers.parquet`: markers (labels, date/time, section starts; MISTRAS start, stop,
/// pause) and status records of every source.
pub fn markers_table() -> Table<MarkerRow> {
    let f = |name: &str, unit: &str, doc: &str| {
        ColumnSpec::new(name, ColType::Float64, unit, doc).nullable()
    };
    Table::new("markers")
        .col(ColumnSpec::new("experiment", ColType::Utf8, "", "experiment id"), |r: &MarkerRow| s(&r.experiment))
        .col(ColumnSpec::new("row", ColType::Int64, "", "1-based order of the row in its experiment"), |r| Value::I64(Some(r.row as i64)))
        .col(f("time_s", "s", "time since the start of the acquisition"), |r| Value::F64(r.time_s))
        .col(ColumnSpec::new("kind", ColType::Utf8, "", "label, datetime, section (Vallen SetType 4, 5, 6; MISTRAS comment 7 and test start 99 as label and datetime), status (Vallen SetType 3), start, stop, pause, abort (MISTRAS 128, 129, 130, 15)"), |r| s(r.kind.as_str()))
        .col(ColumnSpec::new("channel", ColType::Int32, "", "status rows: the channel").nullable(), |r| Value::I32(r.channel.map(|c| c as i32)))
        .col(ColumnSpec::new("number", ColType::Int64, "", "Vallen marker number").nullable(), |r| Value::I64(r.number))
        .col(ColumnSpec::new("text", ColType::Utf8, "", "label text or date/time as recorded").nullable(), |r| Value::Str(r.text.clone()))
        .col(f("threshold_db", "dB_AE", "status rows: the channel's threshold"), |r| Value::F64(r.threshold_db))
        .col(f("energy_eu", "eu", "status rows: energy since the last status (1 eu = 1e-14 V²s)"), |r| Value::F64(r.energy_eu))
        .col(f("rms_v", "V", "status rows: RMS"), |r| Value::F64(r.rms_v))
        .col(f("signal_strength_vs", "V·s", "status rows: signal strength"), |r| Value::F64(r.signal_strength_vs))
        .col(ColumnSpec::new("flags", ColType::Int64, "", "status rows: the record's status flags as stored").nullable(), |r| Value::I64(r.flags))
        .col(ColumnSpec::new("source_file", ColType::Utf8, "", "the file the row came from"), |r| s(&r.source_file))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schema_and_row_come_from_one_list() {
        let t = parametric_table();
        let row = t.row(&ParametricRow {
            experiment: "e".into(),
            row: 3,
            time_s: Some(1.5),
            ..Default::default()
        });
        assert_eq!(row.len(), t.schema().columns.len());
        let batch = super::super::rows_to_batch(&t.schema(), &[row]).unwrap();
        assert_eq!(batch.num_rows(), 1);
        let m = markers_table();
        let row = m.row(&MarkerRow::default());
        assert!(super::super::rows_to_batch(&m.schema(), &[row]).is_ok());
    }
}
