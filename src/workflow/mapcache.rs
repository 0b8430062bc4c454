//! The trained reference map, made once (issue 52): `[som] train_on = "reference"` simulates
//! a library and trains a map on it, ~25 s that are the same for every test of a series. The
//! map is kept in the user's cache ([`crate::store::cache`]) under a key of everything that
//! decides it; a run with the same key copies it into its own `som/model/` instead.

use super::{RunJob, WorkflowError};
pub use crate::som::layout::MapCache;
use crate::store::cache::{key, Cache, Lookup};
use std::path::{Path, PathBuf};

const KIND: &str = "som-map";

/// The key of the map a reference-trained run would make: aepipe's build, the `[som]`
/// settings, every setting that shapes the library's features (the pipeline definition less
/// the sections that only read or show the run's own hits), and the library — the named
/// file's SHA-256, or the embedded definition's text.
pub fn map_key(job: &RunJob) -> Result<String, WorkflowError> {
    let mut c = job.config.clone().into_inner();
    c.load = Default::default();
    c.live = Default::default();
    c.report = Default::default();
    c.export = Default::default();
    c.cluster = Default::default();
    c.trend = Default::default();
    c.evolution = Default::default();
    c.location = Default::default();
    let settings = toml::to_string(&c).map_err(|e| WorkflowError::Input {
        path: "the pipeline definition".into(),
        message: e.to_string(),
    })?;
    let library = match &job.config.som.reference_library {
        Some(p) => {
            let (size, sha) = crate::util::file_digest(p).map_err(|e| WorkflowError::Input {
                path: p.display().to_string(),
                message: e.to_string(),
            })?;
            format!("file {size} {sha}")
        }
        None => format!("embedded {}", crate::sim::reference::DEFAULT_TOML),
    };
    Ok(key(&[
        b"aepipe som map v1",
        settings.as_bytes(),
        library.as_bytes(),
    ]))
}

/// The cached map for this run, copied into `model_dir` (`None`: no entry; a broken entry is
/// removed, said on stderr, and not used).
pub fn reuse(cache: &Path, key: &str, model_dir: &Path) -> Result<bool, WorkflowError> {
    let dir = match Cache::at(cache).get(KIND, key) {
        Lookup::Hit(d) => d,
        Lookup::Miss => return Ok(false),
        Lookup::Broken(why) => {
            eprintln!("aepipe: cache: {why}; the map is made again");
            return Ok(false);
        }
    };
    std::fs::create_dir_all(model_dir).map_err(|e| crate::util::IoAt::new(model_dir, e))?;
    for f in files(&dir)? {
        if f.file_name().is_some_and(|n| n == "entry.json") {
            continue;
        }
        let to = model_dir.join(f.file_name().expect("a file"));
        std::fs::copy(&f, &to).map_err(|e| crate::util::IoAt::new(&to, e))?;
    }
    Ok(true)
}

/// Keep the map in `model_dir` under `key`. A cache that cannot be written costs the next
/// run its time, not this run its result: said on stderr.
pub fn keep(cache: &Path, key: &str, model_dir: &Path) -> Result<(), WorkflowError> {
    let fs = files(model_dir)?;
    let refs: Vec<&Path> = fs.iter().map(PathBuf::as_path).collect();
    if let Err(e) = Cache::at(cache).put(KIND, key, &refs) {
        eprintln!(
            "aepipe: cache: {}: {e}; the map is not kept",
            cache.display()
        );
    }
    Ok(())
}

fn files(dir: &Path) -> Result<Vec<PathBuf>, WorkflowError> {
    let rd = std::fs::read_dir(dir).map_err(|e| crate::util::IoAt::new(dir, e))?;
    let mut v: Vec<PathBuf> = rd
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.is_file())
        .collect();
    v.sort();
    Ok(v)
}
