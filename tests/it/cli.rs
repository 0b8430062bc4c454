//! The binary: exit codes, one-line errors, and the commands' printed summaries.

use crate::{aepipe, TempDir};

fn small_experiment(t: &TempDir) -> String {
    let mut e = aepipe::synth::Experiment::new("exp", 12, 7);
    e.n_samples = 256;
    e.write_vallen(&t.path().join("data")).unwrap();
    t.path().join("data").display().to_string()
}

#[test]
fn exit_codes_are_as_documented() {
    let t = TempDir::new("cli");
    let data = small_experiment(&t);
    let out = t.path().join("out").display().to_string();
    // 0: success.
    let (c, so, _) = aepipe(&["features", &data, "--out", &out, "--quiet"]);
    assert_eq!(c, 0);
    assert!(so.contains("12 rows, 0 rejects"), "{so}");
    // 1: usage error (missing --out) and configuration error (one line naming the file).
    let (c, _, _) = aepipe(&["features", &data]);
    assert_eq!(c, 1);
    let cfg = t.path().join("bad.toml");
    std::fs::write(&cfg, "[ingest]\nsampel_rate_hz = 5\n").unwrap();
    let (c, _, se) = aepipe(&[
        "features",
        &data,
        "--out",
        &out,
        "--config",
        cfg.to_str().unwrap(),
    ]);
    assert_eq!(c, 1);
    assert_eq!(se.trim().lines().count(), 1, "{se}");
    assert!(
        se.contains("bad.toml") && se.contains("sampel_rate_hz"),
        "{se}"
    );
    // 2: rejects under --strict (an unknown file named explicitly).
    let junk = t.path().join("junk.bin");
    std::fs::write(&junk, [0u8; 10]).unwrap();
    let (c, _, se) = aepipe(&[
        "features",
        &data,
        junk.to_str().unwrap(),
        "--out",
        &out,
        "--strict",
        "--quiet",
    ]);
    assert_eq!(c, 2, "{se}");
    assert!(se.contains("junk.bin"), "{se}");
    // Without --strict the same run succeeds and still writes the good hits.
    let (c, so, _) = aepipe(&[
        "features",
        &data,
        junk.to_str().unwrap(),
        "--out",
        &out,
        "--quiet",
    ]);
    assert_eq!(c, 0);
    assert!(so.contains("12 rows, 1 rejects"), "{so}");
    // 0 for --help.
    assert_eq!(aepipe(&["--help"]).0, 0);
}

#[test]
fn inspect_summarises_an_experiment() {
    let t = TempDir::new("inspect");
    let data = small_experiment(&t);
    let cfg = t.path().join("load.toml");
    std::fs::write(
        &cfg,
        "[ingest.vallen]\nload_param = \"PA0\"\nextension_param = \"PA1\"\n",
    )
    .unwrap();
    let (c, so, _) = aepipe(&["inspect", &data, "--config", cfg.to_str().unwrap()]);
    assert_eq!(c, 0);
    assert!(so.contains("exp  [vallen]"), "{so}");
    assert!(so.contains("hits           12"), "{so}");
    assert!(so.contains("sample rate    10000 kHz"), "{so}");
    assert!(so.contains("record length  256 samples"), "{so}");
    assert!(so.contains("(12 of 12 hits)"), "{so}");
    let (c, _, se) = aepipe(&["inspect", t.path().join("nothing-here").to_str().unwrap()]);
    assert_eq!(c, 1);
    assert!(se.contains("no such file"), "{se}");
}

/// Every table `aepipe schema` knows is documented, column for column, in its
/// `data-schema/<table>.md`.
#[test]
fn schema_command_prints_the_documented_table() {
    for table in aepipe::workflow::TABLES {
        let (c, so, _) = aepipe(&["schema", table]);
        assert_eq!(c, 0);
        let page = format!("{}/data-schema/{table}.md", env!("CARGO_MANIFEST_DIR"));
        let doc = std::fs::read_to_string(&page).unwrap_or_else(|e| panic!("{page}: {e}"));
        assert!(
            doc.contains(&so),
            "data-schema/{table}.md does not contain `aepipe schema {table}` output"
        );
    }
}

#[test]
fn cwt_command_draws_a_png_and_names_the_label() {
    let t = TempDir::new("cwtpng");
    let data = small_experiment(&t);
    let png = t.path().join("hit.png");
    let (c, so, se) = aepipe(&["cwt", &data, "--hit", "3", "--png", png.to_str().unwrap()]);
    assert_eq!(c, 0, "{se}");
    assert!(
        so.contains("exp ch1 hit 3:") && so.contains("dominant"),
        "{so}"
    );
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
    // IHDR: width and height, big-endian, at bytes 16..24.
    let w = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
    let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
    assert_eq!((w, h), (1100, 760));
    assert!(
        bytes.len() > 20_000,
        "suspiciously small picture: {} bytes",
        bytes.len()
    );
    // A hit that is not there is one clear error.
    let (c, _, se) = aepipe(&["cwt", &data, "--hit", "999", "--png", png.to_str().unwrap()]);
    assert_eq!(c, 1);
    assert!(se.contains("no hit 999"), "{se}");
}

#[test]
fn simulate_and_run_commands_say_what_is_wrong_in_one_line() {
    let t = TempDir::new("cli-sim");
    let out = t.path().join("o").display().to_string();
    // A malformed model file: exit 1, the file and line named.
    let bad = t.path().join("bad.txt");
    std::fs::write(
        &bad,
        "Section System\ndt damping iters solver\n1e-8 0 10 Warp\nEnd System\n",
    )
    .unwrap();
    let (c, _, se) = aepipe(&["simulate", &bad.display().to_string(), "--out", &out]);
    assert_eq!(c, 1, "{se}");
    assert!(
        se.contains("bad.txt:3:") && se.contains("Warp") && se.trim().lines().count() == 1,
        "{se}"
    );
    // An unknown scenario lists the known ones.
    let (c, _, se) = aepipe(&["simulate", "--scenario", "mesh4x4", "--out", &out]);
    assert_eq!(c, 1);
    assert!(
        se.contains("mesh3x3-bond-failure") && se.contains("mesh4x4"),
        "{se}"
    );
    // An unstable grid names the limit.
    let (c, _, se) = aepipe(&[
        "simulate",
        "--scenario",
        "sho",
        "--param",
        "dt=0.02",
        "--out",
        &out,
    ]);
    assert_eq!(c, 1);
    assert!(se.contains("unstable"), "{se}");
    // A good scenario prints the sensor's dominant frequency (the SHO's 0.37 Hz).
    let (c, so, se) = aepipe(&[
        "simulate",
        "--scenario",
        "sho",
        "--param",
        "iterations=3000",
        // The SHO's test domain is no AE sensor: at 1 V/Pa its 7 mPa reach the 40 dB_AE
        // threshold (at the default 30 µV/Pa nothing would be recorded).
        "--scale",
        "1",
        "--out",
        &out,
    ]);
    assert_eq!(c, 0, "{se}");
    assert!(so.contains("sensor 1 at cell (50, 60): dominant"), "{so}");
    let (names, rows) = crate::table_rows(&t.path().join("o/waveforms.parquet"));
    let col = names
        .iter()
        .position(|n| n == "dominant_frequency_hz")
        .unwrap();
    let f: f64 = rows[0][col].parse().unwrap();
    // The SHO of Table 3.1 (lifted 0.1 m): ≈ 0.37 Hz.
    assert!((f - 0.3717).abs() < 0.03, "{f} Hz");
    // `aepipe report` on a folder that is not a run: exit 1, one line.
    let (c, _, se) = aepipe(&["report", &t.path().display().to_string()]);
    assert_eq!(c, 1);
    assert!(
        se.contains("run.json") && se.trim().lines().count() == 1,
        "{se}"
    );
    // A reference library with a misspelt scenario: exit 1 naming the file.
    let lib = t.path().join("lib.toml");
    std::fs::write(
        &lib,
        "[reference]\n[[reference.scenario]]\nname = \"pluck\"\n",
    )
    .unwrap();
    let (c, _, se) = aepipe(&[
        "reference",
        "--config",
        &lib.display().to_string(),
        "--out",
        &out,
    ]);
    assert_eq!(c, 1);
    assert!(se.contains("lib.toml") && se.contains("pluck"), "{se}");
}
