//! The trained reference map and the simulated library, made once (issue 52): `[som]
//! train_on = "reference"` simulates a library and trains a map on it, ~25 s that are the
//! same for every test of a series. Both are kept in the user's cache
//! ([`crate::store::cache`]) under a key of everything that decides them; a run with the
//! same key copies them into its own folder instead. The library has its own entry, so a
//! change of `[som]` trains a new map on the library already simulated.

use super::{RunJob, WorkflowError};
pub use crate::som::layout::MapCache;
use crate::store::cache::{key, Cache, Lookup};
use std::path::{Path, PathBuf};

const KIND: &str = "som-map";
const LIBRARY: &str = "reference-library";
/// What a simulated library's entry says of its making: runs, signals, seconds.
const LIBRARY_SUMMARY: &str = "library.json";

/// A reference library in a folder: how it was simulated (runs, signals, seconds), and
/// whether this call copied it from the cache instead.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Library {
    pub runs: usize,
    pub signals: u64,
    pub seconds: f64,
    pub reused: bool,
}

/// The library `def` in `dir` (`waveforms.parquet`): copied from `cache` when it holds the
/// same definition made by the same build, else simulated (and kept there when `cache` is
/// given).
pub fn library(
    cache: Option<&Path>,
    def: &crate::sim::reference::ReferenceConfig,
    dir: &crate::sim::reference::LibraryDir,
    progress: bool,
) -> Result<Library, WorkflowError> {
    let text = serde_json::to_string(def).expect("a library definition is JSON");
    let k = key(&[b"aepipe reference library v1", text.as_bytes()]);
    if let Some(root) = cache {
        if let Some(mut lib) = copy_entry(
            root,
            LIBRARY,
            &k,
            dir.path(),
            "the library is simulated again",
        )? {
            lib.reused = true;
            return Ok(lib);
        }
    }
    let (runs, signals, seconds) = crate::sim::reference::build_library(def, dir.path(), progress)?;
    let lib = Library {
        runs,
        signals,
        seconds,
        reused: false,
    };
    if let Some(root) = cache {
        let summary = dir.path().join(LIBRARY_SUMMARY);
        let json = serde_json::json!({"runs": runs, "signals": signals, "seconds": seconds});
        crate::util::write_atomic(&summary, json.to_string().as_bytes())?;
        let files = [dir.waveforms(), summary];
        let refs: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
        if let Err(e) = Cache::at(root).put(LIBRARY, &k, &refs) {
            eprintln!(
                "aepipe: cache: {}: {e}; the library is not kept",
                root.display()
            );
        }
    }
    Ok(lib)
}

/// Copy entry `kind`/`key`'s files into `to`; the library summary it holds, if any
/// (`Some(default)` without one). `None`: no entry, or a broken one (removed, said on
/// stderr with `then`).
fn copy_entry(
    root: &Path,
    kind: &str,
    key: &str,
    to: &Path,
    then: &str,
) -> Result<Option<Library>, WorkflowError> {
    let dir = match Cache::at(root).get(kind, key) {
        Lookup::Hit(d) => d,
        Lookup::Miss => return Ok(None),
        Lookup::Broken(why) => {
            eprintln!("aepipe: cache: {why}; {then}");
            return Ok(None);
        }
    };
    std::fs::create_dir_all(to).map_err(|e| crate::util::IoAt::new(to, e))?;
    let mut lib = Library {
        runs: 0,
        signals: 0,
        seconds: 0.0,
        reused: true,
    };
    for f in files(&dir)? {
        let name = f.file_name().expect("a file");
        if name == "entry.json" {
            continue;
        }
        if name == LIBRARY_SUMMARY {
            let v: serde_json::Value = std::fs::read_to_string(&f)
                .ok()
                .and_then(|t| serde_json::from_str(&t).ok())
                .unwrap_or_default();
            lib.runs = v["runs"].as_u64().unwrap_or(0) as usize;
            lib.signals = v["signals"].as_u64().unwrap_or(0);
            lib.seconds = v["seconds"].as_f64().unwrap_or(0.0);
        }
        let to = to.join(name);
        std::fs::copy(&f, &to).map_err(|e| crate::util::IoAt::new(&to, e))?;
    }
    Ok(Some(lib))
}

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
    Ok(copy_entry(cache, KIND, key, model_dir, "the map is made again")?.is_some())
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

/// Name the run's map in the features stage's `manifest.json` (`som_map`: its cache key and
/// whether the run reused it), written before the map existed.
pub fn name_in_manifest(manifest: &Path, c: &MapCache) -> Result<(), WorkflowError> {
    let bad = |e: String| WorkflowError::Input {
        path: manifest.display().to_string(),
        message: e,
    };
    let mut m = crate::pipeline::Manifest::read(manifest).map_err(|e| bad(e.0))?;
    m.som_map = Some(crate::pipeline::SomMapEntry {
        cache_key: c.key.clone(),
        reused: c.reused,
    });
    crate::pipeline::write_manifest(manifest, &m).map_err(|e| bad(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::ValidConfig;

    type KeyFn = dyn Fn(&RunJob) -> Result<String, WorkflowError>;

    /// A fresh folder under the system's temporary one.
    fn scratch(name: &str) -> PathBuf {
        let t = std::env::temp_dir().join(format!("aepipe-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&t);
        std::fs::create_dir_all(&t).unwrap();
        t
    }

    /// An entry copied out: its files, not its entry.json, and the library summary's counts
    /// read back (runs 3, signals 12, 1.5 s); an entry without a summary gives zeros.
    /// Plants (cargo mutants): either `==` of copy_entry as `!=`, copy_entry as `Ok(None)`,
    /// and `files` as an empty list each fail it.
    #[test]
    fn an_entry_copies_its_files_and_its_library_summary() {
        let t = scratch("copy-entry");
        let (w, s) = (t.join("waveforms.parquet"), t.join(LIBRARY_SUMMARY));
        std::fs::write(&w, b"rows").unwrap();
        std::fs::write(&s, br#"{"runs": 3, "signals": 12, "seconds": 1.5}"#).unwrap();
        let root = t.join("cache");
        Cache::at(&root).put(LIBRARY, "k", &[&w, &s]).unwrap();
        let to = t.join("out");
        let lib = copy_entry(&root, LIBRARY, "k", &to, "")
            .unwrap()
            .expect("an entry");
        assert_eq!(
            (lib.runs, lib.signals, lib.seconds, lib.reused),
            (3, 12, 1.5, true)
        );
        let mut names: Vec<String> = std::fs::read_dir(&to)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(names, [LIBRARY_SUMMARY, "waveforms.parquet"]);
        assert_eq!(
            std::fs::read(to.join("waveforms.parquet")).unwrap(),
            b"rows"
        );
        Cache::at(&root).put(LIBRARY, "k2", &[&w]).unwrap();
        let lib = copy_entry(&root, LIBRARY, "k2", &t.join("out2"), "")
            .unwrap()
            .unwrap();
        assert_eq!((lib.runs, lib.signals), (0, 0));
        assert!(copy_entry(&root, LIBRARY, "absent", &t.join("out3"), "")
            .unwrap()
            .is_none());
        let _ = std::fs::remove_dir_all(&t);
    }

    /// A map kept is reused byte for byte under its key, and only under it. Plants (cargo
    /// mutants): `reuse` as `Ok(true)` or `Ok(false)`, `keep` as `Ok(())` and `files` as an
    /// empty list each fail it.
    #[test]
    fn a_kept_map_is_reused_under_its_key_only() {
        let t = scratch("keep-reuse");
        let (model, cache) = (t.join("model"), t.join("cache"));
        std::fs::create_dir_all(&model).unwrap();
        std::fs::write(model.join("model.json"), b"{\"nodes\": 4}").unwrap();
        std::fs::write(model.join("codebook.bin"), [1u8, 2, 3]).unwrap();
        assert!(!reuse(&cache, "k", &t.join("none")).unwrap());
        keep(&cache, "k", &model).unwrap();
        let again = t.join("again");
        assert!(reuse(&cache, "k", &again).unwrap());
        for f in ["model.json", "codebook.bin"] {
            assert_eq!(
                std::fs::read(again.join(f)).unwrap(),
                std::fs::read(model.join(f)).unwrap(),
                "{f}"
            );
        }
        assert!(!reuse(&cache, "other", &t.join("other")).unwrap());
        let _ = std::fs::remove_dir_all(&t);
    }

    /// `job` with its configuration edited (for the plants below).
    fn edited(job: &RunJob, edit: impl FnOnce(&mut crate::config::PipelineConfig)) -> ValidConfig {
        job.config
            .clone()
            .with(edit)
            .expect("an edited test configuration")
    }

    /// What a map's key must follow, checked on `key`: the same settings give the same key;
    /// a changed `[dsp]` (it shapes the library's features), `[som]`, or named library file
    /// (its contents, at the same path and size) gives a new one; a changed `[report]` (it
    /// shows the run, it does not shape the map) keeps it. The first rule broken, or Ok.
    fn key_rules(key: &KeyFn) -> Result<(), String> {
        let t = std::env::temp_dir().join(format!(
            "aepipe-mapkey-{}-{:?}",
            std::process::id(),
            std::thread::current().id()
        ));
        let _ = std::fs::remove_dir_all(&t);
        std::fs::create_dir_all(&t).unwrap();
        let lib = t.join("waveforms.parquet");
        std::fs::write(&lib, b"library one").unwrap();
        let base = ValidConfig::default()
            .with(|c| c.som.reference_library = Some(lib.clone()))
            .unwrap();
        let k = |cfg: &ValidConfig| {
            key(&RunJob::new(cfg, &[], &t, 1)).map_err(|e| format!("no key: {e}"))
        };
        let k0 = k(&base)?;
        let with = |edit: fn(&mut crate::config::PipelineConfig)| base.clone().with(edit).unwrap();
        let out = (|| {
            if k(&base)? != k0 {
                return Err("the same settings give two keys".to_string());
            }
            if k(&with(|c| c.dsp.cwt.fwhm_periods = 2.5))? == k0 {
                return Err("a changed [dsp] keeps the key".into());
            }
            if k(&with(|c| c.som.seed = 8))? == k0 {
                return Err("a changed [som] keeps the key".into());
            }
            let report = with(|c| {
                c.report.enabled = false;
                c.report.gallery_per_class = 3;
            });
            if k(&report)? != k0 {
                return Err("a changed [report] makes a new key".into());
            }
            // Same path, same size, other bytes: only the contents tell them apart.
            std::fs::write(&lib, b"library two").unwrap();
            if k(&base)? == k0 {
                return Err("a changed library file keeps the key".into());
            }
            Ok(())
        })();
        let _ = std::fs::remove_dir_all(&t);
        out
    }

    /// The map's key changes with what shapes the map and only with that.
    /// Plants: a key that ignores `[dsp]`, one that names the library by its path and not
    /// its contents, and one that hashes `[report]` too — each fails its rule.
    #[test]
    fn the_map_key_changes_with_what_shapes_the_map_and_only_that() {
        key_rules(&map_key).unwrap();
        let ignores_dsp: &KeyFn = &|job| {
            let c = edited(job, |c| c.dsp = Default::default());
            map_key(&RunJob::new(&c, job.inputs, job.out, job.threads))
        };
        let library_by_path: &KeyFn = &|job| {
            let c = edited(job, |c| c.som.reference_library = None);
            let path = format!("{:?}", job.config.som.reference_library);
            let k = map_key(&RunJob::new(&c, job.inputs, job.out, job.threads))?;
            Ok(key(&[k.as_bytes(), path.as_bytes()]))
        };
        let hashes_report: &KeyFn = &|job| {
            let report = format!("{:?}", job.config.report);
            Ok(key(&[map_key(job)?.as_bytes(), report.as_bytes()]))
        };
        for (plant, rule) in [
            (ignores_dsp, "a changed [dsp] keeps the key"),
            (library_by_path, "a changed library file keeps the key"),
            (hashes_report, "a changed [report] makes a new key"),
        ] {
            assert_eq!(key_rules(plant), Err(rule.to_string()));
        }
    }
}
