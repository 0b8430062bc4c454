//! The command line: the argument structs (clap, parsed in one place: [`args`]), the
//! dispatch to the library, the terminal printing, and the one map from an error to an exit
//! code ([`Failure::code`], the README's table). `main.rs` only parses and calls
//! [`dispatch`].

mod args;
mod bench;
mod commands;
mod exit;
mod inputs;
mod print;

pub use args::*;
pub use commands::dispatch;
pub use exit::{Failure, Outcome, UsageError};
