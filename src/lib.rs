//! aepipe: acoustic-emission recordings of paper tensile tests → Parquet feature tables,
//! trend statistics, damage-mechanism classes and reports, with a hybrid vibro-acoustic
//! simulator for labelled reference signals.
//!
//! The rooms, one line each, in the order of the README's direction (a room uses only rooms
//! above it; `tests/it/architecture.rs` enforces it):
//!
//! - [`util`]: hashing, atomic writes, shards, error kinds — used by everything.
//! - [`model`]: the shared vocabulary (records, hits, rejects, mechanisms, parametric rows).
//! - [`store`]: tables declared once, the atomic Parquet writer, the readers, shards.
//! - [`detect`]: cutting a continuous recording into hits (the `[detect]` stage).
//! - [`ingest`]: sources — discovery and the readers of every recording format.
//! - [`dsp`]: spectrum, power ratios, CWT, hit features, FFT filters.
//! - [`features`]: the per-record transform into a feature row and its criteria label.
//! - [`events`]: hits → events (VisualAE's event builder), source location, zones.
//! - [`sim`]: the hybrid vibro-acoustic simulator and reference libraries (ch. 3–4).
//! - [`analysis`]: trend statistics of the features (ch. 4.5.5).
//! - [`som`]: the self-organising map, its tables, novelty and the damage profile (ch. 5).
//! - [`cluster`]: clustering hits by their own features, validity indices, the choice of k.
//! - [`export`]: results written back for the lab's tools (a VisualAE `.trfdb`, a CSV).
//! - [`config`]: the pipeline file: every room's settings gathered and checked into a
//!   `ValidConfig`.
//! - [`inspect`]: human summaries of what the inputs hold.
//! - [`pipeline`]: the staged streaming runner, parts, manifest, shards.
//! - [`synth`]: synthetic experiments for the demo, fixtures and benchmarks.
//! - [`plot`]: the pictures (PNG).
//! - [`report`]: the self-contained HTML report.
//! - [`workflow`]: `aepipe run`: the stages in order, the run folder, report rebuilds.
//! - [`demo`]: the demo on data it makes itself.
//! - [`bench`]: benchmarks against the peers.
//! - [`live`]: `aepipe watch`: a running test followed, classified and committed exactly once.
//! - [`thesis`]: `aepipe thesis`: the thesis's computed results beside its own values.
//! - [`cli`]: the command line (feature `cli`, on by default; the library builds without it).

pub mod analysis;
pub mod bench;
#[cfg(feature = "cli")]
pub mod cli;
pub mod cluster;
pub mod config;
pub mod demo;
pub mod detect;
pub mod dsp;
pub mod events;
pub mod export;
pub mod features;
pub mod ingest;
pub mod inspect;
pub mod live;
pub mod model;
pub mod pipeline;
pub mod plot;
pub mod report;
pub mod sim;
pub mod som;
pub mod store;
pub mod synth;
pub mod thesis;
pub mod util;
pub mod workflow;
