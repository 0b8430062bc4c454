//! What a look hands the next flush: a source to read, whole or in part. The follower makes
//! them, the flush reads them, and the state commits where each part ended.

use crate::ingest::dta::tail::Position as DtaPosition;
use crate::ingest::stream::tail::Position as StreamPosition;
use crate::ingest::vallen::tail::Window;
use crate::ingest::Source;
use crate::model::Item;
use std::sync::{Arc, Mutex};
use std::time::SystemTime;

/// Sources to read at the next flush.
#[derive(Debug, Clone)]
pub struct Pending {
    /// For a one-hit-per-file source only its new files, numbered on from `first_hit`.
    pub source: Source,
    /// The newest modification time of its files (for the lag).
    pub written: Option<SystemTime>,
    /// Part of a recording still being written (else all of the source, or its new files).
    pub part: Option<Part>,
}

/// Part of a recording still being written.
#[derive(Debug, Clone)]
pub enum Part {
    /// The sets of a Vallen pair to read.
    Vallen(Box<Window>),
    /// What a MISTRAS chain held past the last look: the reader's items (read at the look:
    /// the reader's state goes on from message to message), and where it stands after them.
    Dta {
        items: Arc<Mutex<Vec<Item>>>,
        records: usize,
        /// Hit rows among the items (counted before the flush takes them).
        hits: usize,
        end: DtaPosition,
        next_hit: Option<(f64, u32)>,
    },
    /// The hits a raw stream's cutter handed out at the look, and where it stands after
    /// them.
    Stream {
        items: Arc<Mutex<Vec<Item>>>,
        hits: usize,
        end: Box<StreamPosition>,
        next_hit: Option<(f64, u32)>,
    },
}
