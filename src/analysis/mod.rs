//! Analysis of written feature tables: trend statistics over an experiment (ch. 4.5.5) and
//! the damage evolution (cumulative sources, b- and Ib-value, sentry function, load cycles
//! with the Felicity ratio and Kaiser effect) and the energy power law.
//!
//! The tables are read through `store::TableScan` (column selection, by row group); the
//! statistics themselves are plain, tested Rust in [`stats`].

pub mod cycles;
pub mod evolution;
pub mod load;
pub mod powerlaw;
pub mod series;
pub mod settings;
pub mod stats;
pub mod trend;
