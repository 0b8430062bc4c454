//! `events.parquet`: one row per event (documented in `data-schema/events.md`).

use crate::model::columns as cols;
use crate::store::table::s;
use crate::store::{ColType, ColumnSpec, Table, Value};

/// One event as written.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct EventRow {
    pub experiment: String,
    /// 1-based in the experiment, in time order.
    pub event: u64,
    pub time_s: f64,
    pub first_hit_channel: u32,
    pub channels: Vec<i32>,
    /// `hit` of each of its hits in `hits.parquet`.
    pub hits: Vec<i64>,
    pub dt_to_first_s: Vec<f64>,
    pub close_reason: &'static str,
    pub arrival: &'static str,
    pub x_m: Option<f64>,
    pub y_m: Option<f64>,
    pub lucy_m: Option<f64>,
    pub location_status: Option<&'static str>,
    pub location_iterations: Option<i32>,
    pub zone: Option<&'static str>,
}

pub fn events_table() -> Table<EventRow> {
    let f = |name: &str, unit: &str, doc: &str| {
        ColumnSpec::new(name, ColType::Float64, unit, doc).nullable()
    };
    Table::new("events")
        .col(ColumnSpec::of(cols::EXPERIMENT, "", "experiment id"), |e: &EventRow| s(&e.experiment))
        .col(ColumnSpec::of(cols::EVENT, "", "1-based number of the event in its experiment, in time order (hits.parquet and features.parquet `event`)"), |e| Value::I64(Some(e.event as i64)))
        .col(ColumnSpec::of(cols::TIME_S, "s", "time of its first hit (start of event), on the acquisition's clock"), |e| Value::F64(Some(e.time_s)))
        .col(ColumnSpec::new("first_hit_channel", ColType::Int32, "", "channel of the first hit (VisualAE 1.CH)"), |e| Value::I32(Some(e.first_hit_channel as i32)))
        .col(ColumnSpec::of(cols::N_HITS, "", "hits in the event (guard hits included; 1 for a single-hit event)"), |e| Value::I32(Some(e.channels.len() as i32)))
        .col(ColumnSpec::new("channels", ColType::ListI32, "", "channel of each hit in time order (VisualAE 1.CH … n.CH; vallenae `channel_sequence`)"), |e| Value::I32s(Some(e.channels.clone())))
        .col(ColumnSpec::new("hits", ColType::ListI64, "", "`hit` of each of its hits in hits.parquet, in the same order"), |e| Value::I64s(Some(e.hits.clone())))
        .col(ColumnSpec::new("dt_to_first_s", ColType::ListF64, "s", "hit time of each later hit minus the first's (VisualAE DT12 … DT1n; n_hits − 1 values)"), |e| Value::F64s(Some(e.dt_to_first_s.clone())))
        .col(ColumnSpec::new("close_reason", ColType::Utf8, "", "why the event closed: dt1x_expired, dtnx_expired, duplicate_channel or end_of_stream"), |e| s(e.close_reason))
        .col(ColumnSpec::new("arrival", ColType::Utf8, "", "the arrival times location used: `arrival_s` of features.parquet (the [onset] picker), or `hit_time` (the system's threshold crossing)"), |e| s(e.arrival))
        .col(f(cols::X_M.name, "m", "source position: along the line for linear location (the sensors' x coordinate), x for planar; null: not located"), |e| Value::F64(e.x_m))
        .col(f(cols::Y_M.name, "m", "source y for planar location; null for linear"), |e| Value::F64(e.y_m))
        .col(f("lucy_m", "m", "location uncertainty (Vallen LUCY): RMS of the distance-difference residuals over the located hits, ‖(|p−s_k| − |p−s_1|) − v·Δt_1k‖ / √(n−1)"), |e| Value::F64(e.lucy_m))
        .col(ColumnSpec::new("location_status", ColType::Utf8, "", "located, beyond_sensor (linear: clamped to the nearer sensor), fallback (planar: the grid search gave the start), too_few_hits; null: no [location]").nullable(), |e| Value::Str(e.location_status.map(str::to_string)))
        .col(ColumnSpec::new("location_iterations", ColType::Int32, "", "Gauss–Newton iterations of planar location (0 for linear)").nullable(), |e| Value::I32(e.location_iterations))
        .col(ColumnSpec::of(cols::ZONE, "", "`inside` or `outside` the [location] zone; null: no zone or not located").nullable(), |e| Value::Str(e.zone.map(str::to_string)))
}

/// (experiment, event) → the event's source position (x, y, m; none where not located).
pub type Places = std::collections::HashMap<(String, i64), (Option<f64>, Option<f64>)>;

/// Every event's source position in an `events.parquet` (the report's explorer and the
/// VisualAE export place each hit at its event's source).
pub fn read_places(path: &std::path::Path) -> Result<Places, crate::store::StoreError> {
    let t = crate::store::TableScan::open(path)?;
    let df = t.columns(&[
        cols::EXPERIMENT.name,
        cols::EVENT.name,
        cols::X_M.name,
        cols::Y_M.name,
    ])?;
    let e = t.texts(&df, cols::EXPERIMENT)?;
    let n = t.i64s(&df, cols::EVENT)?;
    let x = t.floats(&df, cols::X_M)?;
    let y = t.floats(&df, cols::Y_M)?;
    Ok((0..df.height())
        .filter_map(|i| Some(((e[i].clone()?, n[i]?), (x[i], y[i]))))
        .collect())
}
