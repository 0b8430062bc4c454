//! Analysis of written feature tables: trend statistics over an experiment (ch. 4.5.5).
//!
//! The tables are read with Polars (lazy scan, column selection); the statistics themselves
//! are plain, tested Rust in [`stats`].

pub mod stats;
pub mod trend;
