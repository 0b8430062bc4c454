//! The binary: exit codes, one-line errors, and the commands' printed summaries.

use crate::TempDir;
use std::process::Command;

fn aepipe(args: &[&str]) -> (i32, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_aepipe"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

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

#[test]
fn schema_command_prints_the_documented_table() {
    let (c, so, _) = aepipe(&["schema", "features"]);
    assert_eq!(c, 0);
    let doc = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/data-schema/features.md"
    ))
    .unwrap();
    assert!(
        doc.contains(&so),
        "data-schema/features.md does not contain `aepipe schema features` output"
    );
}

#[test]
fn cwt_command_draws_a_png_and_names_the_label() {
    let t = TempDir::new("cwtpng");
    let data = small_experiment(&t);
    let png = t.path().join("hit.png");
    let (c, so, se) = aepipe(&["cwt", &data, "--hit", "3", "--png", png.to_str().unwrap()]);
    if c == 1 && se.contains("no TrueType font") {
        eprintln!("SKIP cwt_command_draws_a_png_and_names_the_label: {se}");
        return;
    }
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
