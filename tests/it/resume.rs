//! Crash safety and `--resume`: `aepipe run` killed with SIGKILL at random points never leaves
//! a table a reader accepts that is incomplete, and a resumed run ends with the same tables,
//! byte for byte, as a run that was never interrupted.

use crate::{files, TempDir};
use aepipe::util::Rng;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// A small `aepipe run` definition: the SOM trained on criteria labels (no library to build).
pub(crate) const CONFIG: &str =
    "[som]\ntrain_on = \"criteria\"\nfraction = 0.5\nrows = 4\ncols = 4\n";

/// Ten Vallen experiments `exp00`…`exp09` of 12 hits, seeds `seed0`…`seed0 + 9`.
pub(crate) fn batch(dir: &Path, seed0: u64) -> Vec<String> {
    (0..10u64)
        .map(|i| {
            let id = format!("exp{i:02}");
            crate::vallen_fixture(dir, &id, 12, seed0 + i);
            id
        })
        .collect()
}

fn run_args(cfg: &Path, data: &Path, out: &Path, resume: bool) -> Vec<String> {
    let mut a = vec![
        "run".to_string(),
        "--config".into(),
        cfg.display().to_string(),
        data.display().to_string(),
        "--out".into(),
        out.display().to_string(),
        "--threads".into(),
        "2".into(),
    ];
    if resume {
        a.push("--resume".into());
    }
    a
}

/// Run to the end; the wall time.
fn run_to_end(args: &[String]) -> Duration {
    let t = Instant::now();
    let o = Command::new(env!("CARGO_BIN_EXE_aepipe"))
        .env("XDG_CACHE_HOME", crate::test_cache())
        .args(args)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "aepipe {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&o.stderr)
    );
    t.elapsed()
}

/// Start a run and SIGKILL it after `after` (if it is still running then).
fn run_killed(args: &[String], after: Duration) -> bool {
    let mut c = Command::new(env!("CARGO_BIN_EXE_aepipe"))
        .env("XDG_CACHE_HOME", crate::test_cache())
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t = Instant::now();
    while t.elapsed() < after {
        if c.try_wait().unwrap().is_some() {
            return false;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    c.kill().unwrap(); // SIGKILL on Unix
    c.wait().unwrap();
    true
}

/// Every table and JSON file a reader would open after a kill is whole: Parquet files read to
/// the end with the row count their part record or manifest states, JSON parses.
fn check_nothing_half_written(out: &Path) {
    for p in files(out) {
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        if name.starts_with('.') {
            // A temporary name: no reader opens it, and the next run removes it.
            assert!(name.contains(".tmp-"), "{}", p.display());
            continue;
        }
        if name.ends_with(".parquet") {
            let (_, _, batches) = aepipe::store::read_parquet(&p)
                .unwrap_or_else(|e| panic!("a killed run left a broken table: {e}"));
            let rows: usize = batches.iter().map(|b| b.num_rows()).sum();
            // A part's tables match what its record says (when the record exists).
            let rec = p.with_file_name("part.json");
            if let Ok(t) = std::fs::read_to_string(&rec) {
                let v: serde_json::Value = serde_json::from_str(&t).unwrap();
                let stated = match name.as_str() {
                    "hits.parquet" => &v["stats"]["hits"],
                    "rejects.parquet" => &v["stats"]["rejects"],
                    "parametric.parquet" => &v["stats"]["parametric"],
                    "markers.parquet" => &v["stats"]["markers"],
                    "events.parquet" => &v["stats"]["events"]["events"],
                    _ => &v["stats"]["rows"],
                };
                assert_eq!(stated.as_u64().unwrap() as usize, rows, "{}", p.display());
            }
        } else if name.ends_with(".json") {
            let t = std::fs::read_to_string(&p).unwrap();
            serde_json::from_str::<serde_json::Value>(&t)
                .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        }
    }
}

/// The outputs that must not depend on interruptions: every table and the SOM model (the
/// manifest, run.json and the report carry times).
fn results(out: &Path) -> Vec<(String, Vec<u8>)> {
    files(out)
        .into_iter()
        .filter(|p| {
            let n = p.file_name().unwrap().to_string_lossy().to_string();
            !n.starts_with('.') && (n.ends_with(".parquet") || n == "model.json")
        })
        .map(|p| {
            (
                p.strip_prefix(out).unwrap().display().to_string(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect()
}

#[test]
#[cfg(unix)]
fn killed_runs_resume_to_the_uninterrupted_result_20_times() {
    let t = TempDir::new("resume");
    let data = t.path().join("data");
    batch(&data, 100);
    let cfg = t.path().join("cfg.toml");
    std::fs::write(&cfg, CONFIG).unwrap();

    let reference = t.path().join("ref");
    let full = run_to_end(&run_args(&cfg, &data, &reference, false));
    let want = results(&reference);
    let names: Vec<&str> = want.iter().map(|(n, _)| n.as_str()).collect();
    assert!(names.contains(&"features/features.parquet"), "{names:?}");
    assert!(names.contains(&"som/model/model.json"), "{names:?}");
    assert_eq!(
        names
            .iter()
            .filter(|n| n.starts_with("features/parts/"))
            .count(),
        60,
        "ten experiments, six tables each: {names:?}"
    );

    let seed = 0x5eed_2026;
    let mut rng = Rng::new(seed);
    let mut killed = 0;
    for trial in 0..20 {
        let out = t.path().join(format!("t{trial}"));
        // A plain run killed somewhere in its run time, then a resumed one killed too, then
        // a resumed one to the end.
        for resume in [false, true] {
            let after = full.mul_f64(rng.uniform());
            if run_killed(&run_args(&cfg, &data, &out, resume), after) {
                killed += 1;
            }
            check_nothing_half_written(&out);
        }
        run_to_end(&run_args(&cfg, &data, &out, true));
        let got = results(&out);
        assert_eq!(
            got.iter().map(|(n, _)| n).collect::<Vec<_>>(),
            want.iter().map(|(n, _)| n).collect::<Vec<_>>(),
            "trial {trial} (seed {seed:#x}): other files"
        );
        for ((n, a), (_, b)) in got.iter().zip(&want) {
            assert!(a == b, "trial {trial} (seed {seed:#x}): {n} differs");
        }
        std::fs::remove_dir_all(&out).unwrap();
    }
    eprintln!("resume: {killed} of 40 runs killed while running (seed {seed:#x})");
    // Most kills land while the run is running (a kill after its end is no test).
    assert!(killed >= 20, "only {killed} of 40 runs were killed");
}

#[test]
fn resume_reuses_finished_parts_and_redoes_changed_ones() {
    let t = TempDir::new("resume2");
    let data = t.path().join("data");
    batch(&data, 100);
    let cfg = t.path().join("cfg.toml");
    std::fs::write(&cfg, CONFIG).unwrap();
    let out = t.path().join("out");
    run_to_end(&run_args(&cfg, &data, &out, false));
    let before = results(&out);
    // One experiment's waveforms change (its .tradb rewritten from another seed); one part
    // table is damaged on disk.
    crate::vallen_fixture(&data, "exp03", 12, 999);
    let parts = out.join("features/parts");
    let p7 = std::fs::read_dir(&parts)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| {
            p.file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with("exp07-")
        })
        .unwrap();
    std::fs::write(p7.join("hits.parquet"), b"PAR1 not a table").unwrap();
    run_to_end(&run_args(&cfg, &data, &out, true));
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("features/manifest.json")).unwrap())
            .unwrap();
    let redone: Vec<&str> = m["parts"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| !p["reused"].as_bool().unwrap())
        .map(|p| p["experiment"].as_str().unwrap())
        .collect();
    assert_eq!(redone, ["exp03", "exp07"]);
    let after = results(&out);
    // exp07 is restored as it was; exp03's part changed with its input.
    let by = |v: &[(String, Vec<u8>)], pre: &str| -> Vec<Vec<u8>> {
        v.iter()
            .filter(|(n, _)| n.contains(pre))
            .map(|(_, b)| b.clone())
            .collect()
    };
    assert_eq!(by(&before, "/exp07-"), by(&after, "/exp07-"));
    assert_ne!(by(&before, "/exp03-"), by(&after, "/exp03-"));
    assert_eq!(by(&before, "/exp05-"), by(&after, "/exp05-"));
}
