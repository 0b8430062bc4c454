//! aepipe: acoustic-emission recordings of paper tensile tests → Parquet feature tables,
//! trend statistics, damage-mechanism classes and reports.
//!
//! Rooms (see `DESIGN.md` of the team and the README): [`model`] (the shared vocabulary),
//! [`ingest`] (sources), [`features`] (per-record transform), [`store`] (tables on disk),
//! [`pipeline`] (the staged streaming runner), [`inspect`] (human summaries), [`synth`]
//! (synthetic hits for the demo, fixtures and benchmarks).

pub mod analysis;
pub mod bench;
pub mod cli;
pub mod config;
pub mod demo;
pub mod dsp;
pub mod features;
pub mod ingest;
pub mod inspect;
pub mod model;
pub mod pipeline;
pub mod plot;
pub mod report;
pub mod sim;
pub mod som;
pub mod store;
pub mod synth;
pub mod util;
pub mod workflow;
