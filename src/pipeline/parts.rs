//! Per-experiment parts: each experiment is streamed into its own folder
//! (`OUT/parts/<id>-<hash>/`: its tables, then `part.json`), so a run can resume and shards
//! can publish experiments independently.

use super::counts::PartStats;
use super::layout::{PartDir, PartTable, StreamDir};
use super::manifest::InputFile;
use super::{PipelineError, StreamJob, StreamOptions};
use crate::config::ValidConfig;
use crate::ingest::{self, Discovery, Source};
use crate::model::Reject;
use crate::util::{file_digest, write_atomic, IoAt};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What `OUT/parts/<key>/part.json` records of one finished experiment: enough to reuse
/// it on `--resume` only when nothing it depends on has changed.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize, PartialEq)]
struct PartRecord {
    tool_version: String,
    job: String,
    config_sha256: String,
    /// The source ids of the part (one experiment id).
    experiment: String,
    /// `(path, sha256)` of every input file the part read.
    inputs: Vec<(String, String)>,
    /// `(file name, sha256)` of each table in the part folder.
    outputs: Vec<(String, String)>,
    stats: PartStats,
}

/// A finished part that may be reused: its record parses and matches `want` (tool, job,
/// config, inputs), and every table still has the hash it was written with.
fn reusable_part(dir: &PartDir, want: &PartRecord) -> Option<PartRecord> {
    let text = std::fs::read_to_string(dir.record()).ok()?;
    let rec: PartRecord = serde_json::from_str(&text).ok()?;
    if (
        &rec.tool_version,
        &rec.job,
        &rec.config_sha256,
        &rec.experiment,
        &rec.inputs,
    ) != (
        &want.tool_version,
        &want.job,
        &want.config_sha256,
        &want.experiment,
        &want.inputs,
    ) {
        return None;
    }
    for (name, sha) in &rec.outputs {
        match file_digest(&dir.path().join(name)) {
            Ok((_, h)) if &h == sha => {}
            _ => return None,
        }
    }
    Some(rec)
}

/// One experiment's finished part: where its tables are and what it counted.
pub(crate) struct Part {
    pub(crate) id: String,
    /// The tables, in [`PartTable::ALL`] order.
    pub(crate) tables: [PathBuf; 6],
    pub(crate) stats: PartStats,
    pub(crate) reused: bool,
    /// `(path, sha256)` of the files it read.
    pub(crate) inputs: Vec<(String, String)>,
    /// `(file name, sha256)` of its tables, as recorded when they were written.
    pub(crate) outputs: Vec<(String, String)>,
    pub(crate) dir: PathBuf,
}

impl Part {
    /// Where this part's `t` is.
    pub(crate) fn table(&self, t: PartTable) -> &Path {
        &self.tables[t as usize]
    }
}

/// Discovery, the input digests and every owned experiment streamed into its part.
pub(crate) struct Produced {
    pub(crate) sources: Vec<Source>,
    pub(crate) discover_rejects: Vec<Reject>,
    pub(crate) skipped: Vec<(PathBuf, String)>,
    /// The manifest's `inputs` entries of the owned experiments.
    pub(crate) inputs_json: Vec<InputFile>,
    pub(crate) parts: Vec<Part>,
    pub(crate) t_discover: f64,
    pub(crate) t_hash: f64,
    pub(crate) t_stream: f64,
}

pub(crate) fn produce(
    job: StreamJob,
    inputs: &[PathBuf],
    out: &StreamDir,
    cfg: &ValidConfig,
    opts: &StreamOptions,
) -> Result<Produced, PipelineError> {
    let t0 = Instant::now();
    let parts_root = out.parts();
    if !opts.resume {
        let _ = std::fs::remove_dir_all(&parts_root);
    }
    let Discovery {
        mut sources,
        rejects: discover_rejects,
        skipped,
    } = ingest::discover(inputs, &cfg.ingest);
    if sources.is_empty() {
        return Err(nothing_to_read(inputs, &discover_rejects, &skipped));
    }
    if let Some(sh) = opts.shard {
        sources.retain(|s| sh.owns(&s.id));
    }
    let t_discover = t0.elapsed().as_secs_f64();

    let t1 = Instant::now();
    let (files, digested) = digest_inputs(&sources);
    let t_hash = t1.elapsed().as_secs_f64();
    let input_hash: BTreeMap<&Path, &str> = files
        .iter()
        .zip(&digested)
        .map(|((f, _), d)| (f.as_path(), d.sha256.as_str()))
        .collect();

    let t2 = Instant::now();
    let config_sha256 = cfg.hash();
    let mut parts = Vec::new();
    // Sources are sorted by id: one part per run of equal ids.
    for g in sources.chunk_by(|a, b| a.id == b.id) {
        let id = g[0].id.clone();
        let dir = out.part(&id);
        let want = wanted_record(job, &config_sha256, &id, g, &input_hash);
        let reused = if opts.resume {
            reusable_part(&dir, &want)
        } else {
            None
        };
        let reused_flag = reused.is_some();
        let rec = match reused {
            Some(rec) => rec,
            None => stream_part(g, &id, &dir, want, job, cfg, opts)?,
        };
        parts.push(Part {
            tables: PartTable::ALL.map(|t| dir.table(t, job)),
            id,
            stats: rec.stats,
            reused: reused_flag,
            inputs: rec.inputs,
            outputs: rec.outputs,
            dir: dir.path().to_path_buf(),
        });
    }
    Ok(Produced {
        discover_rejects,
        skipped,
        inputs_json: digested,
        parts,
        t_discover,
        t_hash,
        t_stream: t2.elapsed().as_secs_f64(),
        sources,
    })
}

/// The error of a run whose inputs hold no source, listing what discovery passed over and
/// why (or "(no files)").
fn nothing_to_read(
    inputs: &[PathBuf],
    discover_rejects: &[Reject],
    skipped: &[(PathBuf, String)],
) -> PipelineError {
    // A run that reads nothing is the input's fault, never an empty table.
    let mut passed_over: Vec<String> = discover_rejects
        .iter()
        .map(|r| format!("{}: {}", r.source_file, r.reason))
        .chain(
            skipped
                .iter()
                .map(|(p, why)| format!("{}: {why}", p.display())),
        )
        .collect();
    if passed_over.is_empty() {
        passed_over.push("(no files)".into());
    }
    PipelineError::NothingToRead {
        inputs: inputs
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
        passed_over,
    }
}

/// Every file of the owned sources (with its source) and its manifest entry, digested in
/// parallel (an unreadable file is recorded, not an error), in the sources' order.
fn digest_inputs(sources: &[Source]) -> (Vec<(PathBuf, &Source)>, Vec<InputFile>) {
    let files: Vec<(PathBuf, &Source)> = sources
        .iter()
        .flat_map(|s| s.all_files().map(move |f| (f.clone(), s)))
        .collect();
    let digested: Vec<InputFile> = files
        .par_iter()
        .map(|(f, s)| {
            let (size_bytes, sha256) = match file_digest(f) {
                Ok((n, h)) => (Some(n), h),
                Err(e) => (None, format!("unreadable: {e}")),
            };
            InputFile {
                path: f.display().to_string(),
                experiment: s.id.clone(),
                format: s.format.as_str().to_string(),
                size_bytes,
                sha256,
            }
        })
        .collect();
    (files, digested)
}

/// The record a part of experiment `id` (sources `g`) must match to be reused: this tool,
/// job, configuration and the inputs' hashes; no outputs or counts yet.
fn wanted_record(
    job: StreamJob,
    config_sha256: &str,
    id: &str,
    g: &[Source],
    input_hash: &BTreeMap<&Path, &str>,
) -> PartRecord {
    PartRecord {
        tool_version: env!("CARGO_PKG_VERSION").into(),
        job: job.name().into(),
        config_sha256: config_sha256.to_string(),
        experiment: id.to_string(),
        inputs: g
            .iter()
            .flat_map(|s| s.all_files())
            .map(|f| {
                (
                    f.display().to_string(),
                    input_hash
                        .get(f.as_path())
                        .copied()
                        .unwrap_or("")
                        .to_string(),
                )
            })
            .collect(),
        outputs: Vec::new(),
        stats: PartStats::default(),
    }
}

/// Stream experiment `id` (sources `g`) into a fresh part folder, then record its tables'
/// hashes and counts in `want` and write it as `part.json`, last, so only a finished part
/// is ever reused.
fn stream_part(
    g: &[Source],
    id: &str,
    dir: &PartDir,
    want: PartRecord,
    job: StreamJob,
    cfg: &ValidConfig,
    opts: &StreamOptions,
) -> Result<PartRecord, PipelineError> {
    let _ = std::fs::remove_dir_all(dir.path());
    std::fs::create_dir_all(dir.path()).map_err(|e| IoAt::new(dir.path(), e))?;
    let items = g
        .iter()
        .flat_map(|s| ingest::open(s, cfg.read_settings(), &cfg.load));
    let run = super::part::run_part(
        id,
        items,
        g.iter().find_map(|s| s.vaex()),
        job,
        dir.path(),
        cfg,
        opts,
        &mut super::part::Continuation::whole(),
    )?;
    let mut rec = want;
    for t in PartTable::ALL {
        let p = dir.table(t, job);
        let (_, h) = file_digest(&p).map_err(|e| IoAt::new(&p, e))?;
        rec.outputs.push((t.file_name(job).to_string(), h));
    }
    rec.stats = PartStats::of(&run.stats);
    rec.stats.events = Some(run.events);
    let text = serde_json::to_string_pretty(&rec).expect("part record serialises");
    write_atomic(&dir.record(), text.as_bytes())?;
    Ok(rec)
}
