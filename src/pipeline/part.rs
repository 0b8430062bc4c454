//! One part of an experiment, the one way: its items streamed into the part's tables, then
//! the events step on them. A batch part is a whole experiment ([`Continuation::whole`]);
//! `aepipe watch` runs the parts of a recording still being written, each going on from the
//! parts before (events numbered on, channels seen so far, the hit after the part).

use super::layout::{PartTable, StreamDir};
use super::{stream, PipelineError, StreamJob, StreamOptions, StreamStats};
use crate::config::ValidConfig;
use crate::events::{EventsSummary, PartTables};
use crate::model::Item;
use std::collections::BTreeSet;
use std::path::Path;

/// Where a part goes on from: nothing for a whole experiment; for a part of a recording
/// read in parts, the events before it, the channels seen so far (this part's are added)
/// and, when known, the hit after it (time, channel), which closes its last event as the
/// whole experiment would.
#[derive(Debug, Default)]
pub struct Continuation {
    pub events_before: u64,
    pub channels: BTreeSet<u32>,
    pub next_hit: Option<(f64, u32)>,
}

impl Continuation {
    /// A whole experiment: nothing before it, nothing after.
    pub fn whole() -> Continuation {
        Continuation::default()
    }
}

/// What a part produced: the stream's counts and the events step's summary.
pub struct PartRun {
    pub stats: StreamStats,
    pub events: EventsSummary,
}

/// Stream `items` (one experiment's, `experiment`) into the tables of `dir`, then build its
/// events there (`events.parquet`, and the event columns of the hit tables).
#[allow(clippy::too_many_arguments)]
pub fn run_part(
    experiment: &str,
    items: impl Iterator<Item = Item> + Send,
    vaex: Option<&Path>,
    job: StreamJob,
    dir: &Path,
    cfg: &ValidConfig,
    opts: &StreamOptions,
    after: &mut Continuation,
) -> Result<PartRun, PipelineError> {
    let stats = stream(items, job, dir, cfg, opts)?;
    // Events need every hit of the part: a step after the stream.
    let tables = StreamDir::new(dir);
    let features = (job == StreamJob::Features).then(|| {
        (
            tables.table(PartTable::Main, job),
            PartTable::Main.schema(job, cfg),
        )
    });
    let events = crate::events::run_part_after(
        &PartTables {
            experiment,
            hits: &tables.table(PartTable::Hits, job),
            features: features.as_ref().map(|(p, s)| (p.as_path(), s.clone())),
            events: &tables.table(PartTable::Events, job),
            vaex,
        },
        &cfg.into(),
        after.events_before,
        &mut after.channels,
        after.next_hit,
    )?;
    after.events_before += events.events;
    Ok(PartRun { stats, events })
}
