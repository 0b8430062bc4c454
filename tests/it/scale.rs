//! The whole-batch stages in bounded memory (issue 26): `aepipe bench analysis` runs trend,
//! classification, damage profile and report on a 300 000-row study in a child process, which
//! reads its peak resident memory from the kernel at every stage (VmHWM, reset at the
//! stage's start); the largest is held under a limit the in-memory stages exceeded (measured on such a study, release build: `aepipe som
//! classify` 819 MB, `aepipe trend` 248 MB before; 111 MB and 88 MB now; the whole
//! benchmark peaks near 160 MB here). (The parent's `wait4` rusage cannot say: a spawned
//! child's `ru_maxrss` includes the test process's own RSS from before the exec.) The
//! results are checked against computations that are
//! independent of the streaming: every experiment of the study is a copy of a small base run,
//! so its classification and damage profile must be the base's; and the trend of the whole
//! study must equal the in-memory computation (`read_series` / `select` / `trends`) to 1e-12.

use crate::{table_rows, TempDir};
use std::path::Path;

/// Peak RSS the study may reach, MB.
const LIMIT_MB: u64 = 300;

/// A base run: a synthetic one-sensor test of `hits` hits, run with the demo's pipeline
/// (the map trained on its own criteria labels, so no library is simulated).
fn base_run(dir: &Path, hits: usize) {
    crate::vallen_fixture(&dir.join("data"), "base", hits, 17);
    let cfg = dir.join("base.toml");
    let demo = include_str!("../../pipelines/demo.toml");
    let toml = if demo.contains("[som]") {
        demo.replacen("[som]", "[som]\ntrain_on = \"criteria\"", 1)
    } else {
        format!("{demo}\n[som]\ntrain_on = \"criteria\"\n")
    };
    std::fs::write(&cfg, toml).unwrap();
    let (code, _, err) = crate::aepipe(&[
        "run",
        "--config",
        cfg.to_str().unwrap(),
        dir.join("data").to_str().unwrap(),
        "--out",
        dir.join("run").to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
}

/// A table's rows as strings, the experiment column renamed to `as_experiment`, for the
/// rows of `experiment` only.
fn rows_of(path: &Path, experiment: &str, as_experiment: &str) -> Vec<Vec<String>> {
    let (names, rows) = table_rows(path);
    let e = names.iter().position(|n| n == "experiment").unwrap();
    rows.into_iter()
        .filter(|r| r[e] == experiment)
        .map(|mut r| {
            r[e] = as_experiment.to_string();
            r
        })
        .collect()
}

#[test]
fn a_300k_row_study_runs_in_bounded_memory_and_equals_the_small_computations() {
    let t = TempDir::new("scale");
    let base = t.path().join("base");
    base_run(&base, 400);
    let out = t.path().join("study");
    let (code, so, se) = crate::aepipe(&[
        "bench",
        "analysis",
        "--rows",
        "300000",
        "--base",
        base.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{so}\n{se}");
    let base_rows = table_rows(&base.join("run/features/features.parquet"))
        .1
        .len();
    let experiments = 300_000usize.div_ceil(base_rows);
    assert!(
        so.contains(&format!("300000 feature rows in {experiments} experiments")),
        "{so}"
    );
    let peak: u64 = so
        .lines()
        .find_map(|l| l.strip_prefix("peak RSS of the stages: "))
        .and_then(|v| v.trim_end_matches(" MB").parse().ok())
        .unwrap_or_else(|| panic!("no peak line (not Linux?):\n{so}"));
    eprintln!("bench analysis, 300 000 rows: peak RSS {peak} MB");
    assert!(
        peak < LIMIT_MB,
        "peak RSS {peak} MB over the {LIMIT_MB} MB limit:\n{so}"
    );
    let run = out.join("run");
    // Classification and damage profile: each experiment is the base test again, so its
    // rows are the base run's (same map, same rows), for the first, a middle and the last.
    let bsom = base.join("run/som");
    for k in [0, experiments / 2, experiments - 1] {
        let exp = format!("base-{k:06}");
        for table in ["classification.parquet", "damage_profile.parquet"] {
            let want = rows_of(&bsom.join(table), "base", &exp);
            let got = rows_of(&run.join("som").join(table), &exp, &exp);
            assert!(!want.is_empty(), "{table}");
            assert_eq!(got, want, "{table} of {exp}");
        }
    }
    // Trend: the streamed fit against the in-memory one over the whole 300 000-row table.
    use aepipe::analysis::trend::{read_series, select, trends};
    let feats = run.join("features/features.parquet");
    let cfg = aepipe::synth::demo_config();
    let (columns, series) = read_series(&[feats], &[], cfg.source_rows()).unwrap();
    assert_eq!(series.len(), experiments);
    let (names, rows) = table_rows(&run.join("trend/trend.parquet"));
    let col = |n: &str| names.iter().position(|c| c == n).unwrap();
    let mut compared = 0;
    for s in &series {
        let sel = select(s, cfg.trend.cutoff, cfg.trend.min_load_span_n);
        for want in trends(s, &columns, &sel, cfg.trend.alpha, cfg.trend.min_hits) {
            let got = rows
                .iter()
                .find(|r| {
                    r[col("experiment")] == want.experiment
                        && r[col("channel")] == want.channel.to_string()
                        && r[col("column")] == want.column
                })
                .unwrap_or_else(|| panic!("no trend row for {want:?}"));
            assert_eq!(got[col("n")], want.n.to_string());
            assert_eq!(got[col("cutoff")], want.cutoff);
            if let Some(f) = want.fit {
                for (name, v) in [
                    ("r", f.r),
                    ("p", f.p),
                    ("slope", f.slope),
                    ("intercept", f.intercept),
                ] {
                    let g: f64 = got[col(name)].parse().unwrap();
                    assert!(
                        (g - v).abs() <= 1e-12 * v.abs().max(1e-300),
                        "{} {} {name}: {g} vs {v}",
                        want.experiment,
                        want.column
                    );
                }
                compared += 1;
            } else {
                assert_eq!(got[col("r")], "", "{want:?}");
            }
        }
    }
    assert!(compared > 1000, "{compared}");
}
