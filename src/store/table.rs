//! Tables declared once: every column is one entry holding its [`ColumnSpec`] and the
//! function that fills it from the row's value, so the Arrow schema, the cells of a row and
//! the documentation in `data-schema/` all come from one list and cannot drift apart.
//! Adding a column is one `.col(…)` call in the table's declaration.
//!
//! A row consumes its value: a column declared with [`Table::col_take`] may move a payload
//! (a waveform's samples, a record's bins) into its cell instead of copying it.

use super::{ColType, ColumnSpec, Row, TableSchema, Value};
use crate::model::columns as cols;
use crate::model::crack::{af_khz, crack_mode, ra_ms_per_v, CrackModeConfig};
use crate::model::{AeRecord, HitRow, MarkerRow, ParametricRow, RecordKind, Reject};
use std::sync::Arc;

type Getter<T> = Arc<dyn Fn(&mut T) -> Value + Send + Sync>;

/// A table of rows made from values of `T`.
pub struct Table<T> {
    name: String,
    cols: Vec<(ColumnSpec, Getter<T>)>,
}

impl<T> Clone for Table<T> {
    fn clone(&self) -> Self {
        Table {
            name: self.name.clone(),
            cols: self.cols.clone(),
        }
    }
}

impl<T: 'static> Table<T> {
    pub fn new(name: &str) -> Table<T> {
        Table {
            name: name.to_string(),
            cols: Vec::new(),
        }
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// The same columns under another table name.
    pub fn renamed(mut self, name: &str) -> Self {
        self.name = name.to_string();
        self
    }

    /// Add a column: its spec and how a `T` fills it.
    pub fn col(
        mut self,
        spec: ColumnSpec,
        get: impl Fn(&T) -> Value + Send + Sync + 'static,
    ) -> Self {
        self.cols.push((spec, Arc::new(move |t: &mut T| get(t))));
        self
    }

    /// Add a column whose cell moves a payload out of the value (e.g. a waveform's samples
    /// with `std::mem::take`), so the row holds it without a copy. Only this column may read
    /// the payload.
    pub fn col_take(
        mut self,
        spec: ColumnSpec,
        get: impl Fn(&mut T) -> Value + Send + Sync + 'static,
    ) -> Self {
        self.cols.push((spec, Arc::new(get)));
        self
    }

    /// Add every column of `inner`, filled from the part of `T` that `part` points to.
    pub fn embed<U: 'static>(
        mut self,
        inner: Table<U>,
        part: impl Fn(&mut T) -> &mut U + Send + Sync + Clone + 'static,
    ) -> Self {
        for (spec, get) in inner.cols {
            let part = part.clone();
            self.cols
                .push((spec, Arc::new(move |t: &mut T| get(part(t)))));
        }
        self
    }

    /// Apply a function that adds columns (e.g. [`with_event_columns`]).
    pub fn pipe(self, f: impl FnOnce(Self) -> Self) -> Self {
        f(self)
    }

    /// The columns as a [`TableSchema`] (Arrow schema, documentation).
    pub fn schema(&self) -> TableSchema {
        TableSchema {
            name: self.name.clone(),
            columns: self.cols.iter().map(|(c, _)| c.clone()).collect(),
        }
    }

    /// The cells of one row, in column order.
    pub fn row(&self, mut t: T) -> Row {
        Row::new(self.cols.iter().map(|(_, get)| get(&mut t)).collect())
    }

    /// Write `rows` as this table to `path` (atomic, as every table: [`super::TableWriter`]),
    /// `row_group_rows` to a row group; the rows written.
    pub fn write_all(
        &self,
        path: &std::path::Path,
        metadata: &[(String, String)],
        row_group_rows: usize,
        rows: impl IntoIterator<Item = T>,
    ) -> Result<u64, super::StoreError> {
        let mut w = super::TableWriter::create(path, self.schema(), metadata, row_group_rows)?;
        for r in rows {
            w.push(self.row(r))?;
        }
        w.finish()
    }
}

/// A string cell.
pub fn s(v: &str) -> Value {
    Value::Str(Some(v.to_string()))
}

/// What identifies a transient record and carries its acquisition metadata: the leading
/// columns of the waveform, feature and simulated-waveform tables (same names, same order).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Identity {
    pub experiment: String,
    pub channel: u32,
    pub hit: u64,
    pub time_s: Option<f64>,
    pub sample_rate_hz: f64,
    pub pretrigger: u32,
    pub n_samples: usize,
    pub load_n: Option<f64>,
    pub extension_m: Option<f64>,
    pub label: Option<String>,
    pub threshold_v: Option<f64>,
    pub kind: RecordKind,
}

impl Identity {
    pub fn of(r: &AeRecord) -> Identity {
        Identity {
            experiment: r.experiment.clone(),
            channel: r.channel,
            hit: r.hit,
            time_s: r.time_s,
            sample_rate_hz: r.sample_rate_hz,
            pretrigger: r.pretrigger,
            n_samples: r.samples.len(),
            load_n: r.load_n,
            extension_m: r.extension_m,
            label: r.label.clone(),
            threshold_v: r.threshold_v,
            kind: r.kind,
        }
    }
}

/// The identity columns (see [`Identity`]).
pub fn identity_table() -> Table<Identity> {
    Table::new("identity")
        .col(ColumnSpec::of(cols::EXPERIMENT, "", "experiment id: file stem of a Vallen pair or multi-hit file, folder name for one-hit-per-file folders; when two experiments of a batch would share one, their path below the input folder (`a/bearing`, `b/bearing`)"), |r: &Identity| s(&r.experiment))
        .col(ColumnSpec::of(cols::CHANNEL, "", "sensor channel as numbered by the acquisition system (0 = unknown)"), |r| Value::I32(Some(r.channel as i32)))
        .col(ColumnSpec::of(cols::HIT, "", "transient number inside the experiment, 1-based: Vallen TRAI (plus the largest TRAI of the earlier acquisitions after a restart; a pause keeps TRAI), a Vallen TXT export's Trai, MISTRAS waveform #, AEwin hit # (name or header), WaveExplorer event #; hits.parquet links each hit to it"), |r| Value::I64(Some(r.hit as i64)))
        .col(ColumnSpec::of(cols::TIME_S, "s", "trigger time since the start of the acquisition (null: the format does not record it)").nullable(), |r| Value::F64(r.time_s))
        .col(ColumnSpec::new("sample_rate_hz", ColType::Float64, "Hz", "sampling rate"), |r| Value::F64(Some(r.sample_rate_hz)))
        .col(ColumnSpec::new("pretrigger_samples", ColType::Int32, "samples", "samples recorded before the trigger"), |r| Value::I32(Some(r.pretrigger as i32)))
        .col(ColumnSpec::new("n_samples", ColType::Int32, "samples", "record length"), |r| Value::I32(Some(r.n_samples as i32)))
        .col(ColumnSpec::of(cols::LOAD_N, "N", "test-machine load at the hit time (null: no load channel)").nullable(), |r| Value::F64(r.load_n))
        .col(ColumnSpec::of(cols::EXTENSION_M, "m", "test-machine extension at the hit time (null: none)").nullable(), |r| Value::F64(r.extension_m))
        .col(ColumnSpec::of(cols::LABEL, "", "ground-truth or user label (simulator mechanism, hand label); null if none").nullable(), |r| Value::Str(r.label.clone()))
        .col(ColumnSpec::new("threshold_v", ColType::Float64, "V", "detection threshold the acquisition used (Vallen Thr); null if not recorded").nullable(), |r| Value::F64(r.threshold_v))
        .col(ColumnSpec::new("record_kind", ColType::Utf8, "", "`hit`: the waveform of a hit (hits.parquet links to it, or the format has no hit list); `standalone`: a waveform no hit points to (a MISTRAS waveform message without its hit, e.g. an automatic sensor test; a .tradb transient no .pridb hit links to)"), |r| s(r.kind.as_str()))
}

/// A row of the canonical waveform table: a record's identity, its samples (moved, not
/// copied) and its file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WaveformRow {
    pub id: Identity,
    pub samples: Vec<f32>,
    pub source_file: String,
}

impl From<AeRecord> for WaveformRow {
    fn from(r: AeRecord) -> WaveformRow {
        WaveformRow {
            id: Identity::of(&r),
            samples: r.samples,
            source_file: r.source_file,
        }
    }
}

/// The canonical waveform table: one row per hit, samples in volts.
pub fn waveforms_table() -> Table<WaveformRow> {
    Table::new("waveforms")
        .embed(identity_table(), |w: &mut WaveformRow| &mut w.id)
        .col_take(
            ColumnSpec::new(
                "samples_v",
                ColType::ListF32,
                "V",
                "the waveform, volts at the sensor",
            ),
            |w| Value::F32s(Some(std::mem::take(&mut w.samples))),
        )
        .col(
            ColumnSpec::new(
                "source_file",
                ColType::Utf8,
                "",
                "file the samples were read from",
            ),
            |w| s(&w.source_file),
        )
}

/// The reject table: every hit (or file) that did not become a feature row.
pub fn rejects_table() -> Table<Reject> {
    Table::new("rejects")
        .col(ColumnSpec::of(cols::EXPERIMENT, "", "experiment id (empty when the file could not be assigned to one)"), |r: &Reject| s(&r.experiment))
        .col(ColumnSpec::new("source_file", ColType::Utf8, "", "the input file"), |r| s(&r.source_file))
        .col(ColumnSpec::new("record_id", ColType::Utf8, "", "which record (`ch1 hit 17`, `TRAI 12`, `event 3`); empty for a whole file"), |r| s(&r.record_id))
        .col(ColumnSpec::new("stage", ColType::Utf8, "", "pipeline stage: discover, read, validate or features"), |r| s(r.stage.as_str()))
        .col(ColumnSpec::new("reason", ColType::Utf8, "", "one line saying what is wrong"), |r| s(&r.reason))
        .col(ColumnSpec::new("record_type", ColType::Utf8, "", "what is lost: transient, hit, parametric, status, marker, or file (a whole file, or the rest of one, whose records could not be told apart)"), |r| s(r.record_type.as_str()))
}

/// The hit table: one row per hit of every source, with the acquisition system's own
/// features (see `data-schema/hits.md` for each vendor's name of each column) and the RA–AF
/// crack mode by `crack` (`[crack_mode]`; the schema does not depend on it).
pub fn hits_table(crack: CrackModeConfig) -> Table<HitRow> {
    let ra = |h: &HitRow| match (h.rise_time_s, h.amplitude_db) {
        (Some(r), Some(db)) => ra_ms_per_v(r, crate::model::db_to_v(db)),
        _ => None,
    };
    let af = |h: &HitRow| match (h.counts, h.duration_s) {
        (Some(c), Some(d)) => af_khz(c, d),
        _ => None,
    };
    let f = |name: &str, unit: &str, doc: &str| {
        ColumnSpec::new(name, ColType::Float64, unit, doc).nullable()
    };
    Table::new("hits")
        .col(ColumnSpec::of(cols::EXPERIMENT, "", "experiment id"), |h: &HitRow| s(&h.experiment))
        .col(ColumnSpec::new("acquisition", ColType::Int32, "", "1-based acquisition in the experiment (a Vallen database restarted into the same file holds several)"), |h| Value::I32(Some(h.acquisition as i32)))
        .col(ColumnSpec::of(cols::CHANNEL, "", "sensor channel"), |h| Value::I32(Some(h.channel as i32)))
        .col(ColumnSpec::of(cols::HIT, "", "1-based order of the hit in its experiment, as the system stored the hits"), |h| Value::I64(Some(h.hit as i64)))
        .col(f(cols::TIME_S.name, "s", "hit time since the start of the acquisition"), |h| Value::F64(h.time_s))
        .col(f("amplitude_db", "dB_AE", "peak amplitude, dB re 1 µV at the sensor"), |h| Value::F64(h.amplitude_db))
        .col(f("threshold_db", "dB_AE", "detection threshold"), |h| Value::F64(h.threshold_db))
        .col(f("rise_time_s", "s", "rise time"), |h| Value::F64(h.rise_time_s))
        .col(f("duration_s", "s", "duration"), |h| Value::F64(h.duration_s))
        .col(ColumnSpec::new("counts", ColType::Int64, "", "threshold crossings").nullable(), |h| Value::I64(h.counts))
        .col(ColumnSpec::new("counts_to_peak", ColType::Int64, "", "crossings up to the peak").nullable(), |h| Value::I64(h.counts_to_peak))
        .col(f("ra_ms_per_v", "ms/V", "RA value: rise_time_s over the peak amplitude in volts (from amplitude_db), JCMS-IIIB5706; null without both"), move |h| Value::F64(ra(h)))
        .col(f("af_khz", "kHz", "average frequency: counts over duration_s; null without counts or a positive duration"), move |h| Value::F64(af(h)))
        .col(ColumnSpec::new("crack_mode", ColType::Utf8, "", "tensile above the line af_khz = crack_mode.af_per_ra × ra_ms_per_v (default 1 kHz per ms/V), shear on or below it; null where RA or AF is (see docs/crack-mode in docs/classification.md)").nullable(), move |h| Value::Str(crack_mode(ra(h), af(h), crack.af_per_ra).map(|m| m.as_str().to_string())))
        .col(f(cols::ENERGY_EU.name, "eu", "Vallen energy (1 eu = 1e-14 V²s)"), |h| Value::F64(h.energy_eu))
        .col(f("energy_counts", "", "MISTRAS energy counts (ENER)"), |h| Value::F64(h.energy_counts))
        .col(f("abs_energy_aj", "aJ", "MISTRAS absolute energy"), |h| Value::F64(h.abs_energy_aj))
        .col(f("signal_strength_vs", "V·s", "signal strength"), |h| Value::F64(h.signal_strength_vs))
        .col(f("rms_v", "V", "RMS of the signal"), |h| Value::F64(h.rms_v))
        .col(f("avg_freq_hz", "Hz", "average frequency (counts / duration)"), |h| Value::F64(h.avg_freq_hz))
        .col(f("centroid_freq_hz", "Hz", "frequency centroid"), |h| Value::F64(h.centroid_freq_hz))
        .col(f("peak_freq_hz", "Hz", "peak frequency"), |h| Value::F64(h.peak_freq_hz))
        .col(f(cols::LOAD_N.name, "N", "test-machine load at the hit"), |h| Value::F64(h.load_n))
        .col(f(cols::EXTENSION_M.name, "m", "test-machine extension at the hit"), |h| Value::F64(h.extension_m))
        .col(ColumnSpec::new("parametric", ColType::Utf8, "", "the hit's parametric inputs as a JSON object of volts").nullable(), |h| Value::Str(h.parametric.clone()))
        .col(ColumnSpec::of(cols::TRANSIENT, "", "`hit` of this hit's transient in features/waveforms/rejects; null: no transient").nullable(), |h| Value::I64(h.transient.map(|t| t as i64)))
        .col(ColumnSpec::of(cols::TRAI, "", "Vallen TRAI as stored").nullable(), |h| Value::I64(h.trai))
        .col(ColumnSpec::new("vendor_features", ColType::Utf8, "", "further features the system recorded, a JSON object under the vendor's names and units (Vallen .trfdb, other MISTRAS CHIDs; a detected hit: two_bursts, ended_by ddt/max_duration/stream_end, first_sample, last_sample)").nullable(), |h| Value::Str(h.vendor_features.clone()))
        .col(ColumnSpec::new("source", ColType::Utf8, "", "who recorded the features: vallen, mistras, aewin, record (a format without a hit list), or detect (cut from a continuous recording by [detect]: the detector's time, duration and features)"), |h| s(h.source.as_str()))
        .col(ColumnSpec::new("source_file", ColType::Utf8, "", "the file the hit came from"), |h| s(&h.source_file))
        .col(ColumnSpec::of(cols::STATUS, "", "the system's hit flags as stored (Vallen `Status`: bit 8 = started after a hit timeout, which never opens an event; bit 4 = saturation); null: not recorded").nullable(), |h| Value::I64(h.status))
        .col(ColumnSpec::new("list_status", ColType::Utf8, "", "an AEwin test with a hit list <test>.TXT: matched (a list row and its waveform, the row's values above), no_list_row (a waveform the list lacks: no hardware features), no_waveform (a list row without a waveform file: transient null); null: no hit list. `status` holds the system's flags, so the match has its own column").nullable(), |h| Value::Str(h.list_status.map(str::to_string)))
        .pipe(with_event_columns)
}

/// The columns the events step fills on `hits.parquet` and `features.parquet`, null until
/// it runs (and for an experiment without events).
pub const EVENT_COLUMNS: [&str; 3] = [cols::EVENT.name, cols::EVENT_FIRST.name, cols::ZONE.name];

/// Append [`EVENT_COLUMNS`] to a hit-keyed table.
pub fn with_event_columns<T: 'static>(t: Table<T>) -> Table<T> {
    t.col(ColumnSpec::of(cols::EVENT, "", "1-based event of the experiment this hit belongs to (events.parquet); null: in no event, or events not built").nullable(), |_| Value::I64(None))
        .col(ColumnSpec::of(cols::EVENT_FIRST, "", "true for the hit that opened its event (the first-hit channel's): the one hit per source that trend, SOM and class counts use when events are built; false for the event's other hits and for hits in no event; null: events not built").nullable(), |_| Value::Bool(None))
        .col(ColumnSpec::of(cols::ZONE, "", "`inside` / `outside` [location] zone (the event's), `guard` (a guard channel's hit in no event, or a hit a guard sensor kept from opening one); null: no zone, not located, or events not built").nullable(), |_| Value::Str(None))
}

/// `parametric.parquet`: the parametric / time-driven rows of every source, as recorded, with
/// the load and extension the pipeline maps them to.
pub fn parametric_table() -> Table<ParametricRow> {
    let f = |name: &str, unit: &str, doc: &str| {
        ColumnSpec::new(name, ColType::Float64, unit, doc).nullable()
    };
    Table::new("parametric")
        .col(ColumnSpec::of(cols::EXPERIMENT, "", "experiment id"), |r: &ParametricRow| s(&r.experiment))
        .col(ColumnSpec::new("row", ColType::Int64, "", "1-based order of the row in its experiment and source"), |r| Value::I64(Some(r.row as i64)))
        .col(f(cols::TIME_S.name, "s", "time since the start of the acquisition (for a load file: its own time × `time_scale_s` + the experiment's `[load.offset_s]`)"), |r| Value::F64(r.time_s))
        .col(f(cols::LOAD_N.name, "N", "the load this row gives (`[ingest.vallen]`/`[ingest.mistras]` mapping of a parametric input, or `[load]`); null: not mapped"), |r| Value::F64(r.load_n))
        .col(f(cols::EXTENSION_M.name, "m", "the extension this row gives; null: not mapped"), |r| Value::F64(r.extension_m))
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
        .col(ColumnSpec::of(cols::EXPERIMENT, "", "experiment id"), |r: &MarkerRow| s(&r.experiment))
        .col(ColumnSpec::new("row", ColType::Int64, "", "1-based order of the row in its experiment"), |r| Value::I64(Some(r.row as i64)))
        .col(f(cols::TIME_S.name, "s", "time since the start of the acquisition"), |r| Value::F64(r.time_s))
        .col(ColumnSpec::new("kind", ColType::Utf8, "", "label, datetime, section (Vallen SetType 4, 5, 6; MISTRAS comment 7 and test start 99 as label and datetime), status (Vallen SetType 3), start, stop, pause, abort (MISTRAS 128, 129, 130, 15)"), |r| s(r.kind.as_str()))
        .col(ColumnSpec::of(cols::CHANNEL, "", "status rows: the channel").nullable(), |r| Value::I32(r.channel.map(|c| c as i32)))
        .col(ColumnSpec::new("number", ColType::Int64, "", "Vallen marker number").nullable(), |r| Value::I64(r.number))
        .col(ColumnSpec::new("text", ColType::Utf8, "", "label text or date/time as recorded").nullable(), |r| Value::Str(r.text.clone()))
        .col(f("threshold_db", "dB_AE", "status rows: the channel's threshold"), |r| Value::F64(r.threshold_db))
        .col(f(cols::ENERGY_EU.name, "eu", "status rows: energy since the last status (1 eu = 1e-14 V²s)"), |r| Value::F64(r.energy_eu))
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
        let row = t.row(ParametricRow {
            experiment: "e".into(),
            row: 3,
            time_s: Some(1.5),
            ..Default::default()
        });
        assert_eq!(row.cells().len(), t.schema().columns.len());
        let batch = super::super::rows_to_batch(&t.schema(), &[row]).unwrap();
        assert_eq!(batch.num_rows(), 1);
        for schema in [
            markers_table().schema(),
            hits_table(Default::default()).schema(),
            rejects_table().schema(),
        ] {
            assert!(!schema.columns.is_empty());
        }
        let m = markers_table();
        assert!(super::super::rows_to_batch(&m.schema(), &[m.row(MarkerRow::default())]).is_ok());
        let h = hits_table(Default::default());
        assert!(super::super::rows_to_batch(&h.schema(), &[h.row(HitRow::default())]).is_ok());
    }

    #[test]
    fn a_waveform_row_moves_its_samples_and_keeps_its_length() {
        let w = WaveformRow {
            id: Identity {
                n_samples: 3,
                ..Default::default()
            },
            samples: vec![1.0, 2.0, 3.0],
            source_file: "f".into(),
        };
        let t = waveforms_table();
        let sch = t.schema();
        let row = t.row(w);
        assert_eq!(row[sch.index_of("n_samples").unwrap()], Value::I32(Some(3)));
        assert_eq!(
            row[sch.index_of("samples_v").unwrap()],
            Value::F32s(Some(vec![1.0, 2.0, 3.0]))
        );
        assert!(super::super::rows_to_batch(&sch, &[row]).is_ok());
    }
}
