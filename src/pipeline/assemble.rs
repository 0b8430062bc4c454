//! A batch assembled from its parts: the whole-batch tables (discovery's rejects, then every
//! part in order) and the manifest that accounts for them. Apart from `manifest` (the
//! manifest's types) so that `parts`, which names its inputs in the manifest's terms, and
//! this, which reads what `parts` produced, do not import each other.

use super::counts::StreamStats;
use super::layout::{PartTable, StreamDir};
use super::manifest::{
    write_manifest, ExperimentEntry, Manifest, ManifestCounts, NoteEntry, Outputs, PartEntry,
    Skipped, TableOut, Timings, Tool,
};
use super::parts::Produced;
use super::stream::table_metadata;
use super::{PipelineError, RunReport, StreamJob, StreamOptions};
use crate::config::PipelineConfig;
use crate::store::{rejects_table, TableWriter};
use crate::util::{num_cpus, utc_now};
use std::time::Instant;

/// The whole-batch tables (discovery's rejects, then every part in order) and the manifest.
pub(crate) fn assemble(
    job: StreamJob,
    out_dir: &StreamDir,
    cfg: &PipelineConfig,
    opts: &StreamOptions,
    started: String,
    t0: Instant,
    p: Produced,
) -> Result<RunReport, PipelineError> {
    let manifest_path = out_dir.manifest();
    let mut stats = batch_stats(&p);
    write_batch_tables(job, out_dir, cfg, &p)?;
    stats.seconds = p.t_stream;

    let manifest = Manifest {
        tool: Tool::this(),
        job: job.name().into(),
        started_utc: started,
        finished_utc: utc_now(),
        threads: if opts.threads == 0 {
            num_cpus()
        } else {
            opts.threads
        },
        config_sha256: cfg.hash(),
        config: cfg.clone(),
        inputs: p.inputs_json.clone(),
        parts: part_entries(&p),
        skipped: skipped_entries(&p),
        experiments: experiment_entries(&p, &stats),
        outputs: outputs_of(job, out_dir, &stats),
        events: stats.events.clone(),
        notes: note_entries(&stats),
        streams: stats.streams.clone(),
        counts: ManifestCounts::of(&stats),
        timings_s: Timings {
            discover: p.t_discover,
            hash_inputs: p.t_hash,
            stream: stats.seconds,
            total: t0.elapsed().as_secs_f64(),
        },
        som_map: None,
    };
    write_manifest(&manifest_path, &manifest)?;
    Ok(RunReport {
        manifest_path,
        sources: p.sources,
        skipped: p.skipped,
        ..RunReport::of_tables(out_dir, job, stats)
    })
}

/// The whole-batch counts: discovery's rejects, then every part's counts, in order.
fn batch_stats(p: &Produced) -> StreamStats {
    let mut stats = StreamStats::default();
    for r in &p.discover_rejects {
        stats.add_reject(r);
    }
    for part in &p.parts {
        part.stats.add_to(&mut stats);
    }
    stats
}

/// Write each whole-batch table: discovery's rejects (rejects table only), then every
/// part's table appended in order.
fn write_batch_tables(
    job: StreamJob,
    out_dir: &StreamDir,
    cfg: &PipelineConfig,
    p: &Produced,
) -> Result<(), PipelineError> {
    let (table_meta, meta) = table_metadata(job, cfg);
    for t in PartTable::ALL {
        let kv = if t == PartTable::Main {
            &table_meta
        } else {
            &meta
        };
        let mut w = TableWriter::create(
            &out_dir.table(t, job),
            t.schema(job, cfg),
            kv,
            cfg.pipeline.row_group_rows,
        )?;
        if t == PartTable::Rejects {
            let rows = rejects_table();
            for r in &p.discover_rejects {
                w.push(rows.row(r.clone()))?;
            }
        }
        for part in &p.parts {
            w.append_file(part.table(t))?;
        }
        w.finish()?;
    }
    Ok(())
}

/// The manifest's `parts`: each part's experiment, folder and whether it was reused.
fn part_entries(p: &Produced) -> Vec<PartEntry> {
    p.parts
        .iter()
        .map(|x| PartEntry {
            experiment: x.id.clone(),
            dir: x.dir.display().to_string(),
            reused: x.reused,
        })
        .collect()
}

/// The manifest's `skipped`: the files discovery passed over and why.
fn skipped_entries(p: &Produced) -> Vec<Skipped> {
    p.skipped
        .iter()
        .map(|(p, why)| Skipped {
            path: p.display().to_string(),
            reason: why.clone(),
        })
        .collect()
}

/// The manifest's `experiments`: each source with its files, companions and the
/// acquisition setups the stream found for it.
fn experiment_entries(p: &Produced, stats: &StreamStats) -> Vec<ExperimentEntry> {
    p.sources
        .iter()
        .map(|s| ExperimentEntry {
            id: s.id.clone(),
            format: s.format.as_str().into(),
            files: s.files.len(),
            companions: s.companion_names(),
            acquisition: stats
                .setups
                .iter()
                .filter(|a| a.experiment == s.id)
                .cloned()
                .collect(),
        })
        .collect()
}

/// The manifest's `outputs`: each whole-batch table's path and row count.
fn outputs_of(job: StreamJob, out_dir: &StreamDir, stats: &StreamStats) -> Outputs {
    let out = |t: PartTable, rows: u64| TableOut {
        path: out_dir.table(t, job).display().to_string(),
        rows,
    };
    Outputs {
        table: out(PartTable::Main, stats.rows),
        hits: out(PartTable::Hits, stats.hits),
        rejects: out(PartTable::Rejects, stats.rejects),
        parametric: out(PartTable::Parametric, stats.parametric),
        markers: out(PartTable::Markers, stats.markers),
        events: out(
            PartTable::Events,
            stats.events.iter().map(|e| e.events).sum(),
        ),
    }
}

/// The manifest's `notes`: the stream's notes with their experiment and file.
fn note_entries(stats: &StreamStats) -> Vec<NoteEntry> {
    stats
        .notes
        .iter()
        .map(|n| NoteEntry {
            experiment: n.experiment.clone(),
            file: n.source_file.clone(),
            note: n.message.clone(),
            said: n.said,
        })
        .collect()
}
