//! The columns one room writes and another reads back, named once with their type. A
//! table's declaration builds its column from the constant (`ColumnSpec::of(HIT, …)` in
//! `store`) and a reader reads it through the same constant (`TableScan::i64s(&df, HIT)`),
//! so a renamed column is renamed everywhere or does not compile, and an integer key is read
//! as an integer.

use std::marker::PhantomData;

/// The kind of a column's values (the store maps it to an Arrow type).
pub mod kind {
    /// UTF-8 text.
    #[derive(Debug, Clone, Copy)]
    pub struct Str;
    /// 32-bit integer.
    #[derive(Debug, Clone, Copy)]
    pub struct I32;
    /// 64-bit integer.
    #[derive(Debug, Clone, Copy)]
    pub struct I64;
    /// 64-bit float.
    #[derive(Debug, Clone, Copy)]
    pub struct F64;
    /// Boolean.
    #[derive(Debug, Clone, Copy)]
    pub struct Bool;
}

use kind::{Bool, Str, F64, I32, I64};

/// A column: its name and the kind of its values.
#[derive(Debug)]
pub struct Col<K> {
    pub name: &'static str,
    kind: PhantomData<fn() -> K>,
}

impl<K> Clone for Col<K> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<K> Copy for Col<K> {}

impl<K> Col<K> {
    pub const fn new(name: &'static str) -> Col<K> {
        Col {
            name,
            kind: PhantomData,
        }
    }
}

impl<K> std::fmt::Display for Col<K> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name)
    }
}

// The key of every hit-keyed table.
pub const EXPERIMENT: Col<Str> = Col::new("experiment");
pub const CHANNEL: Col<I32> = Col::new("channel");
pub const HIT: Col<I64> = Col::new("hit");

// A hit's or record's time, load and extension.
pub const TIME_S: Col<F64> = Col::new("time_s");
pub const LOAD_N: Col<F64> = Col::new("load_n");
pub const EXTENSION_M: Col<F64> = Col::new("extension_m");

// `hits.parquet`'s link to its transient and its status.
pub const TRANSIENT: Col<I64> = Col::new("transient");
pub const STATUS: Col<I64> = Col::new("status");
pub const TRAI: Col<I64> = Col::new("trai");

// The event columns of the hit tables.
pub const EVENT: Col<I64> = Col::new("event");
pub const EVENT_FIRST: Col<Bool> = Col::new("event_first");
pub const ZONE: Col<Str> = Col::new("zone");

// Features the events step and the reports read.
pub const ARRIVAL_S: Col<F64> = Col::new("arrival_s");
pub const LABEL: Col<Str> = Col::new("label");
/// The ch. 4.7 criteria label of a feature row (a [`crate::model::Mechanism`] name).
pub const CRITERIA_LABEL: Col<Str> = Col::new("criteria_label");
pub const PEAK_AMPLITUDE_DB: Col<F64> = Col::new("peak_amplitude_db");
pub const ENERGY_EU: Col<F64> = Col::new("energy_eu");

// `classification.parquet`.
pub const SOM_LABEL: Col<Str> = Col::new("som_label");
pub const NODE_LABEL: Col<Str> = Col::new("node_label");
pub const REFERENCE_LABEL: Col<Str> = Col::new("reference_label");
pub const BMU_ROW: Col<I32> = Col::new("bmu_row");
pub const BMU_COL: Col<I32> = Col::new("bmu_col");

// `events.parquet` and `truth.parquet`.
pub const X_M: Col<F64> = Col::new("x_m");
pub const Y_M: Col<F64> = Col::new("y_m");
pub const N_HITS: Col<I32> = Col::new("n_hits");
pub const SOURCE_X_M: Col<F64> = Col::new("source_x_m");
pub const SOURCE_KIND: Col<Str> = Col::new("source_kind");
pub const MECHANISM: Col<Str> = Col::new("mechanism");
