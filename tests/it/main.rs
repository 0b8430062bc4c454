//! aepipe's integration tests, in one binary (one link of the big dependency set).
//!
//! Tests that need the real recordings in `../shared/data/real/` print why they skip when
//! that folder is absent. Everything else makes its own fixtures with aepipe's own code.

mod architecture;
mod bad_input;
mod bonds;
mod cache;
mod cli;
mod corpus;
mod cycles;
mod detect;
mod docs;
mod dta;
mod e2e;
mod events;
mod exit_codes;
mod explore;
mod exports;
mod fidelity;
mod formats;
mod hitlist;
mod hits;
mod imports;
mod live;
mod pipeline;
mod real_data;
mod resume;
mod salvage;
mod scale;
mod shard;
mod sim;
mod sim3d;
mod sim_beyond;
mod som;
mod thesis;
mod transfer;
mod trend;
mod trfdb;
mod vendor;

use std::path::{Path, PathBuf};

/// The test build's cache root (`XDG_CACHE_HOME` of every aepipe the tests start): never
/// the user's `~/.cache`.
pub fn test_cache() -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("xdg-cache")
}

/// Run the aepipe binary: exit code, stdout, stderr. Its cache (`XDG_CACHE_HOME`) is the
/// test build's own, never the user's.
pub fn aepipe(args: &[&str]) -> (i32, String, String) {
    aepipe_with_cache(args, &test_cache())
}

/// [`aepipe`], which must succeed (else the test fails with its output): its stdout.
pub fn aepipe_ok(args: &[&str]) -> String {
    let (code, so, se) = aepipe(args);
    assert_eq!(code, 0, "aepipe {}:\n{so}\n{se}", args.join(" "));
    so
}

/// [`aepipe`] with `XDG_CACHE_HOME` = `cache`.
pub fn aepipe_with_cache(args: &[&str], cache: &Path) -> (i32, String, String) {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_aepipe"))
        .args(args)
        .env("XDG_CACHE_HOME", cache)
        .output()
        .unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// A synthetic Vallen experiment `<dir>/<id>.pridb/.tradb` of `hits` hits of 512 samples,
/// written with aepipe's writer; the `.tradb`'s path.
pub fn vallen_fixture(dir: &Path, id: &str, hits: usize, seed: u64) -> PathBuf {
    let mut e = aepipe::synth::Experiment::new(id, hits, seed);
    e.n_samples = 512;
    e.write_vallen(dir).unwrap();
    dir.join(format!("{id}.tradb"))
}

/// A test (or a part of one) cannot run because something it needs is absent. Locally it
/// says so and the caller returns; with `AEPIPE_REQUIRE_ALL=1` (set by `.ci/run`) it fails,
/// so CI cannot go green without running it.
pub fn skip(test: &str, why: &str) {
    if std::env::var("AEPIPE_REQUIRE_ALL").is_ok_and(|v| v == "1") {
        panic!("{test} cannot run and AEPIPE_REQUIRE_ALL=1: {why}");
    }
    eprintln!("SKIP {test}: {why}");
}

/// Run an independent reference (a Python script): its stdout. It skips (through [`skip`],
/// so it fails under `AEPIPE_REQUIRE_ALL=1`) only when what it needs is absent — `python3`
/// itself, or a module: the script's own exit 3 after an `ImportError`, or a
/// `ModuleNotFoundError`. Any other failure (an assertion in the script, a reader that
/// fails on a file aepipe wrote) fails the test, with the script's output: a check that
/// fails is never a skip. `install` says what to install when it skips.
pub fn reference(test: &str, install: &str, cmd: &mut std::process::Command) -> Option<Vec<u8>> {
    let o = match cmd.output() {
        Ok(o) => o,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            skip(
                test,
                &format!("{}: {e} ({install})", cmd.get_program().to_string_lossy()),
            );
            return None;
        }
        Err(e) => panic!(
            "{test}: {} could not be started: {e}",
            cmd.get_program().to_string_lossy()
        ),
    };
    if o.status.success() {
        return Some(o.stdout);
    }
    let err = String::from_utf8_lossy(&o.stderr);
    if o.status.code() == Some(3) || err.contains("ModuleNotFoundError") {
        let last = err
            .lines()
            .rev()
            .find(|l| !l.trim().is_empty())
            .unwrap_or("");
        skip(test, &format!("{last} ({install})"));
        return None;
    }
    panic!(
        "{test}: the reference failed ({}):\n{err}\n{}",
        o.status,
        String::from_utf8_lossy(&o.stdout)
    );
}

/// `../shared/data/real` beside the repository, or `None` after [`skip`].
pub fn real_data(test: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real");
    if p.join("README.md").is_file() {
        Some(p)
    } else {
        skip(
            test,
            &format!(
                "{} is absent (the real AE recordings live there)",
                p.display()
            ),
        );
        None
    }
}

/// A scratch folder removed when dropped.
pub struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(tag: &str) -> TempDir {
        use std::sync::atomic::{AtomicU32, Ordering};
        static N: AtomicU32 = AtomicU32::new(0);
        let p = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!(
            "{tag}-{}-{}",
            std::process::id(),
            N.fetch_add(1, Ordering::Relaxed)
        ));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }
    pub fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A synthetic experiment (`hits` hits of 1024 samples, seeded) written as a Vallen pair in
/// DIR/data, and its features in DIR/f with `cfg`; returns the features table.
pub fn synthetic_features(
    dir: &Path,
    id: &str,
    hits: usize,
    seed: u64,
    cfg: &aepipe::config::ValidConfig,
    threads: usize,
) -> PathBuf {
    let data = dir.join("data");
    let mut e = aepipe::synth::Experiment::new(id, hits, seed);
    e.n_samples = 1024;
    e.write_vallen(&data).unwrap();
    aepipe::pipeline::run(
        aepipe::pipeline::StreamJob::Features,
        &[data],
        &dir.join("f"),
        cfg,
        &aepipe::pipeline::StreamOptions::with_threads(threads),
    )
    .unwrap()
    .table_path
}

/// Read every column of a Parquet table as strings (for comparisons across tables).
pub fn table_rows(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let (schema, _, batches) = aepipe::store::read_parquet(path).unwrap();
    let names: Vec<String> = schema.fields().iter().map(|f| f.name().clone()).collect();
    let mut rows = Vec::new();
    for b in batches {
        let cols: Vec<_> = (0..b.num_columns())
            .map(|c| {
                arrow::util::display::ArrayFormatter::try_new(
                    b.column(c).as_ref(),
                    &Default::default(),
                )
                .unwrap()
            })
            .collect();
        for r in 0..b.num_rows() {
            rows.push(cols.iter().map(|f| f.value(r).to_string()).collect());
        }
    }
    (names, rows)
}

/// A Parquet table's rows as column → value text ([`table_rows`]).
pub fn table_maps(path: &Path) -> Vec<std::collections::BTreeMap<String, String>> {
    let (names, rows) = table_rows(path);
    rows.into_iter()
        .map(|r| names.iter().cloned().zip(r).collect())
        .collect()
}

/// Every file below `dir`, sorted.
pub fn files(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(rd) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// Records of all sources found under `inputs`, with the default configuration.
pub fn read_all(
    inputs: &[PathBuf],
    cfg: &aepipe::config::ValidConfig,
) -> (Vec<aepipe::model::AeRecord>, Vec<aepipe::model::Reject>) {
    let d = aepipe::ingest::discover(inputs, &cfg.ingest);
    let mut recs = Vec::new();
    let mut rejs = d.rejects;
    for s in &d.sources {
        for it in aepipe::ingest::open(s, cfg.read_settings(), &cfg.load) {
            match it {
                aepipe::model::Item::Record(r) => recs.push(r),
                aepipe::model::Item::Reject(r) => rejs.push(r),
                _ => {}
            }
        }
    }
    (recs, rejs)
}

/// A reference that fails is a failing test, and only an absent module is a skip: a
/// planted failing assertion must fail, a planted missing module must skip.
#[test]
fn a_failing_reference_fails_and_only_an_absent_module_skips() {
    let python = |code: &str| {
        let mut c = std::process::Command::new("python3");
        c.args(["-c", code]);
        c
    };
    if python("pass").output().is_err() {
        skip(
            "a_failing_reference_fails_and_only_an_absent_module_skips",
            "no python3",
        );
        return;
    }
    // What `reference` does with a script: "returned …", or its panic's message.
    let outcome = |code: &str| match std::panic::catch_unwind(|| {
        reference("planted", "-", &mut python(code))
    }) {
        Ok(out) => format!("returned {out:?}"),
        Err(p) => p
            .downcast_ref::<String>()
            .cloned()
            .unwrap_or_else(|| "a panic".into()),
    };
    let s = outcome("assert 1 + 1 == 3, 'planted defect'");
    assert!(
        s.contains("the reference failed") && s.contains("planted defect"),
        "{s}"
    );
    let strict = std::env::var("AEPIPE_REQUIRE_ALL").is_ok_and(|v| v == "1");
    let s = outcome("import aepipe_no_such_module_xyz");
    if strict {
        assert!(
            s.contains("cannot run") && s.contains("No module named"),
            "{s}"
        );
    } else {
        assert_eq!(s, "returned None");
    }
    let s = outcome("import sys; print('missing: x', file=sys.stderr); sys.exit(3)");
    assert!(
        if strict {
            s.contains("cannot run")
        } else {
            s == "returned None"
        },
        "{s}"
    );
    let ok = reference("ok", "-", &mut python("print(6 * 7)"));
    assert_eq!(ok.as_deref(), Some(&b"42\n"[..]));
}
