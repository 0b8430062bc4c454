//! Sharded runs: `aepipe run --shard K/N` for every K, then `aepipe merge`, give the same
//! per-experiment feature tables (byte for byte) and the same trend, SOM model and
//! classification as one unsharded run, for 1, 3 and 4 shards. The shards' Hive-partitioned
//! dataset opens in Polars, DuckDB and pyarrow.

use crate::{aepipe, TempDir};
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::resume::CONFIG;

fn ok(args: &[&str]) -> String {
    let (c, so, se) = aepipe(args);
    assert_eq!(c, 0, "aepipe {}: {se}", args.join(" "));
    so
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

/// The part folder of `id` in an unsharded run's features folder.
fn unsharded_part(features: &Path, id: &str) -> PathBuf {
    std::fs::read_dir(features.join("parts"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| {
            let n = p.file_name().unwrap().to_string_lossy().to_string();
            n.rsplit_once('-').map(|(a, _)| a) == Some(id)
        })
        .unwrap_or_else(|| panic!("no part of {id}"))
}

/// The Hive file of `id`'s `table` in a sharded folder (whichever shard wrote it).
fn hive(dir: &Path, table: &str, id: &str) -> PathBuf {
    let d = dir.join(table).join(format!("experiment={id}"));
    let files: Vec<PathBuf> = std::fs::read_dir(&d)
        .unwrap_or_else(|e| panic!("{}: {e}", d.display()))
        .flatten()
        .map(|e| e.path())
        .collect();
    assert_eq!(files.len(), 1, "{files:?}");
    files[0].clone()
}

#[test]
fn one_three_and_four_shards_merge_to_the_unsharded_run() {
    let t = TempDir::new("shard");
    let data = t.path().join("data");
    let ids = crate::resume::batch(&data, 300);
    let cfg = t.path().join("cfg.toml");
    std::fs::write(&cfg, CONFIG).unwrap();
    let whole = t.path().join("whole");
    ok(&["run", "--config", &s(&cfg), &s(&data), "--out", &s(&whole)]);

    let same = |a: &Path, b: &Path| {
        assert!(
            std::fs::read(a).unwrap() == std::fs::read(b).unwrap(),
            "{} differs from {}",
            b.display(),
            a.display()
        );
    };
    for n in [1u32, 3, 4] {
        let dir = t.path().join(format!("s{n}"));
        // Shards in reverse order, with another thread count: neither may matter.
        for k in (0..n).rev() {
            let so = ok(&[
                "run",
                "--config",
                &s(&cfg),
                &s(&data),
                "--out",
                &s(&dir),
                "--shard",
                &format!("{k}/{n}"),
                "--threads",
                "1",
            ]);
            assert!(so.contains("aepipe merge"), "{so}");
        }
        ok(&["merge", &s(&dir), "--threads", "2"]);
        // Per experiment: the shard's published tables are the unsharded run's part tables.
        let mut per_shard = vec![0; n as usize];
        for id in &ids {
            let part = unsharded_part(&whole.join("features"), id);
            for (table, file) in [
                ("features", "features.parquet"),
                ("hits", "hits.parquet"),
                ("rejects", "rejects.parquet"),
            ] {
                let h = hive(&dir, table, id);
                same(&part.join(file), &h);
                if table == "features" {
                    let k: usize = h
                        .file_stem()
                        .unwrap()
                        .to_string_lossy()
                        .trim_start_matches("part-")
                        .parse()
                        .unwrap();
                    per_shard[k] += 1;
                }
            }
        }
        if n > 1 {
            // The hash spreads ten experiments over every shard.
            assert!(per_shard.iter().all(|&c| c > 0), "{per_shard:?}");
        }
        // The merged run equals the unsharded one.
        let merged = dir.join("merged");
        for f in [
            "features/features.parquet",
            "features/hits.parquet",
            "features/rejects.parquet",
            "trend/trend.parquet",
            "som/model/model.json",
            "som/classification.parquet",
        ] {
            same(&whole.join(f), &merged.join(f));
        }
        assert!(merged.join("report.html").exists());
    }

    // `aepipe features --shard` + `merge --tables-only` = `aepipe features`.
    let plain = t.path().join("plain");
    ok(&["features", &s(&data), "--out", &s(&plain), "--quiet"]);
    let fs = t.path().join("fs");
    for k in 0..3 {
        ok(&[
            "features",
            &s(&data),
            "--out",
            &s(&fs),
            "--quiet",
            "--shard",
            &format!("{k}/3"),
        ]);
    }
    let merged = t.path().join("fs-merged");
    ok(&["merge", &s(&fs), "--tables-only", "--out", &s(&merged)]);
    for f in ["features.parquet", "hits.parquet", "rejects.parquet"] {
        same(&plain.join(f), &merged.join(f));
    }

    // A missing shard: the merge refuses and names it.
    let dir = t.path().join("s4");
    std::fs::remove_file(dir.join("shards/shard-2-of-4.json")).unwrap();
    let (c, _, se) = aepipe(&["merge", &s(&dir), "--out", &s(&t.path().join("m"))]);
    assert_eq!(c, 1, "{se}");
    assert!(
        se.contains("shard(s) 2 of 4 missing") && se.contains("resubmit"),
        "{se}"
    );
    // A shard run with another config: refused too.
    std::fs::write(&cfg, format!("{CONFIG}seed = 9\n")).unwrap();
    ok(&[
        "run",
        "--config",
        &s(&cfg),
        &s(&data),
        "--out",
        &s(&dir),
        "--shard",
        "2/4",
    ]);
    let (c, _, se) = aepipe(&["merge", &s(&dir), "--out", &s(&t.path().join("m"))]);
    assert_eq!(c, 1, "{se}");
    assert!(se.contains("another config"), "{se}");
    // Bad --shard values are usage errors.
    for bad in ["4/4", "1", "a/b", "0/0"] {
        let (c, _, _) = aepipe(&["features", &s(&data), "--out", &s(&dir), "--shard", bad]);
        assert_eq!(c, 1, "--shard {bad}");
    }

    // The dataset opens in Polars, DuckDB and pyarrow, with `experiment` a column.
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/read_dataset.py");
    if let Some(o) = crate::reference(
        "sharded dataset readers",
        "pip install polars duckdb pyarrow",
        Command::new("python3")
            .arg(&script)
            .arg(t.path().join("s3/features")),
    ) {
        let so = String::from_utf8_lossy(&o);
        let (_, rows) = crate::table_rows(&whole.join("features/features.parquet"));
        for reader in ["polars", "duckdb", "pyarrow"] {
            let want = format!("{reader} {} rows, 10 experiments", rows.len());
            assert!(so.contains(&want), "{want} not in:\n{so}");
        }
    }
}

/// `aepipe reference --shard K/N` simulates a hash-chosen part of the scenario grid; the
/// merged library holds the same signals, in the same order, as one unsharded run.
#[test]
fn a_reference_library_in_three_shards_merges_to_the_same_signals() {
    let t = TempDir::new("shard-ref");
    let cfg = t.path().join("lib.toml");
    std::fs::write(
        &cfg,
        "[reference]\nvariants = 2\nsensors = [[125, 100], [100, 125]]\n\
         [[reference.scenario]]\nname = \"mesh3x3-bond-failure\"\nparams = { t2 = [-1], iterations = [2000] }\n\
         [[reference.scenario]]\nname = \"structure2x1-fibre-failure\"\nparams = { point = [2, 5, 7, 12], iterations = [2000] }\n",
    )
    .unwrap();
    let whole = t.path().join("whole");
    ok(&["reference", "--config", &s(&cfg), "--out", &s(&whole)]);
    let dir = t.path().join("sh");
    for k in 0..3 {
        ok(&[
            "reference",
            "--config",
            &s(&cfg),
            "--out",
            &s(&dir),
            "--shard",
            &format!("{k}/3"),
        ]);
    }
    // Every shard simulated something (10 grid points over 3 shards).
    for k in 0..3 {
        let p = dir.join(format!("waveforms/experiment=reference/part-{k}.parquet"));
        let (_, rows) = crate::table_rows(&p);
        assert!(!rows.is_empty(), "shard {k} is empty");
    }
    ok(&["merge", &s(&dir)]);
    let (na, a) = crate::table_rows(&whole.join("waveforms.parquet"));
    let (nb, b) = crate::table_rows(&dir.join("merged/waveforms.parquet"));
    assert_eq!(na, nb);
    // (1 bond + 4 fibre grid points) × 2 material draws × 2 sensors.
    assert_eq!(a.len(), 20);
    assert!(
        a == b,
        "the merged library's rows differ from the unsharded library's"
    );
    // A changed part is refused (the shard recorded its hash), then a missing shard.
    let part = dir.join("waveforms/experiment=reference/part-2.parquet");
    let saved = std::fs::read(&part).unwrap();
    std::fs::write(&part, b"not the part the shard wrote").unwrap();
    let (c, _, se) = aepipe(&["merge", &s(&dir), "--out", &s(&t.path().join("m"))]);
    assert_eq!(c, 1, "{se}");
    assert!(
        se.contains("missing or changed since shard 2 wrote it"),
        "{se}"
    );
    std::fs::write(&part, saved).unwrap();
    std::fs::remove_file(dir.join("shards/shard-1-of-3.json")).unwrap();
    let (c, _, se) = aepipe(&["merge", &s(&dir), "--out", &s(&t.path().join("m"))]);
    assert_eq!(c, 1, "{se}");
    assert!(se.contains("1 of 3 missing"), "{se}");
}
