//! What a watcher has read and written, committed after each flush's parts: the one
//! record that makes a restart exactly-once.

use super::pending::{Part, Pending};
use super::{WatchDir, WatchError};
use crate::config::ValidConfig;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// The watcher's committed position (`DIR/watch/state.json`).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct State {
    /// The effective configuration's hash: a folder is continued only with the settings
    /// that wrote it (another would give rows computed two ways).
    pub config_sha256: String,
    pub flushes: u32,
    /// Parts written so far; the next is `part-<parts>.parquet`, and any part numbered
    /// from here on is an uncommitted flush's.
    pub parts: u32,
    pub hits: u64,
    pub rows: u64,
    pub rejects: u64,
    /// SOM class → rows.
    pub classes: BTreeMap<String, u64>,
    /// Events built so far by experiment (the next part's are numbered on), and the
    /// channels seen (whether events are built at all).
    #[serde(default)]
    pub events: BTreeMap<String, u64>,
    #[serde(default)]
    pub channels: BTreeMap<String, std::collections::BTreeSet<u32>>,
    /// Source id → what has been read of it.
    pub sources: BTreeMap<String, SourceState>,
}

/// What has been read of one source.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct SourceState {
    /// A one-hit-per-file source: the files read, in reading order (the next file is hit
    /// `files.len() + 1`, even if some of these have left the folder).
    pub files: Vec<String>,
    /// A whole recording: read.
    pub whole: bool,
    /// A Vallen pair followed while it grows: how far it has been read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vallen: Option<crate::ingest::vallen::tail::Position>,
    /// A MISTRAS chain followed while it grows: how far it has been read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dta: Option<crate::ingest::dta::tail::Position>,
    /// A raw stream followed while it grows: how far its hits have been handed out.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stream: Option<crate::ingest::stream::tail::Position>,
}

impl State {
    /// The committed state of `dir` (a new one if there is none), with the parts of a flush
    /// that was not committed removed.
    pub fn recover(dir: &WatchDir, cfg: &ValidConfig) -> Result<State, WatchError> {
        let path = dir.state();
        let hash = cfg.hash();
        let state = match std::fs::read_to_string(&path) {
            Ok(text) => {
                let s: State = serde_json::from_str(&text).map_err(|e| WatchError::State {
                    path: path.display().to_string(),
                    message: format!("not a watcher's state: {e}"),
                })?;
                if s.config_sha256 != hash {
                    return Err(WatchError::State {
                        path: path.display().to_string(),
                        message: "written with another configuration; watch into a new \
                                  folder (or remove this one) to use these settings"
                            .into(),
                    });
                }
                s
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => State {
                config_sha256: hash,
                ..Default::default()
            },
            Err(e) => return Err(crate::util::IoAt::new(&path, e).into()),
        };
        remove_parts_from(&dir.table_dirs(), state.parts)?;
        // Temporary files of a killed watcher's atomic writes (state, page).
        crate::store::clean_stale_tmp(dir.path());
        crate::store::clean_stale_tmp(&dir.path().join("watch"));
        Ok(state)
    }

    /// Record a source's files as read (committed by the next [`State::commit`]).
    pub fn mark(&mut self, p: &Pending) {
        let s = self.sources.entry(p.source.id.clone()).or_default();
        if let Some(part) = &p.part {
            match part {
                Part::Vallen(w) => s.vallen = Some(w.end),
                Part::Dta { end, .. } => s.dta = Some(end.clone()),
                Part::Stream { end, .. } => s.stream = Some((**end).clone()),
            }
        } else if p.per_hit() {
            s.files
                .extend(p.source.files.iter().map(|f| f.display().to_string()));
        } else {
            s.whole = true;
        }
    }

    /// Write the state atomically: the flush's parts become the watcher's.
    pub fn commit(&self, dir: &WatchDir) -> Result<(), WatchError> {
        let text = serde_json::to_string_pretty(self).expect("state serialises");
        crate::util::write_atomic(&dir.state(), text.as_bytes())?;
        Ok(())
    }
}

/// Remove every `<table>/experiment=*/part-N.parquet` with `N >= from` in the watcher's
/// table folders: what a watcher killed between writing its parts and committing left.
fn remove_parts_from(tables: &[PathBuf], from: u32) -> Result<(), WatchError> {
    for t in tables {
        let Ok(exps) = std::fs::read_dir(t) else {
            continue;
        };
        for e in exps.flatten() {
            if !e.file_name().to_string_lossy().starts_with("experiment=") {
                continue;
            }
            let Ok(parts) = std::fs::read_dir(e.path()) else {
                continue;
            };
            for p in parts.flatten() {
                let name = p.file_name().to_string_lossy().to_string();
                let k = name
                    .strip_prefix("part-")
                    .and_then(|r| r.strip_suffix(".parquet"))
                    .and_then(|n| n.parse::<u32>().ok());
                if k.is_some_and(|k| k >= from) {
                    std::fs::remove_file(p.path())
                        .map_err(|err| crate::util::IoAt::new(&p.path(), err))?;
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A watcher killed after writing its parts and before committing: the restart removes
    /// exactly the parts numbered from the committed count on, in every table.
    #[test]
    fn recover_removes_the_uncommitted_flush_only() {
        let root = std::env::temp_dir().join(format!("aepipe-state-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let dir = WatchDir::new(&root);
        let cfg = ValidConfig::default();
        let mut files = Vec::new();
        for t in ["features", "hits", "classification"] {
            for (e, k) in [("a", 0), ("b", 1), ("a", 2), ("b", 3)] {
                let p = crate::store::shard::hive_file(&root, t, e, k);
                std::fs::create_dir_all(p.parent().unwrap()).unwrap();
                std::fs::write(&p, b"x").unwrap();
                files.push((p, k));
            }
        }
        // Another dataset in the same folder (not a table the watcher writes) is not its to
        // clean.
        let foreign = crate::store::shard::hive_file(&root, "shardrun", "a", 5);
        std::fs::create_dir_all(foreign.parent().unwrap()).unwrap();
        std::fs::write(&foreign, b"x").unwrap();
        std::fs::create_dir_all(root.join("watch")).unwrap();
        let s = State {
            config_sha256: cfg.hash(),
            parts: 2,
            ..Default::default()
        };
        s.commit(&dir).unwrap();
        let r = State::recover(&dir, &cfg).unwrap();
        assert_eq!(r.parts, 2);
        for (p, k) in &files {
            assert_eq!(p.is_file(), *k < 2, "{}", p.display());
        }
        assert!(foreign.is_file(), "another dataset's part was removed");
        // Another configuration is refused, not mixed in.
        let other = cfg.with(|c| c.live.flush_s = 5.0).unwrap();
        assert!(State::recover(&dir, &other).is_err());
        let _ = std::fs::remove_dir_all(&root);
    }
}
