//! Every exit code of the README's table, through the binary, for every command:
//! 0 success, 1 usage/configuration/input error, 2 `--strict` with rejects, 3 an output that
//! cannot be written. "Cannot be written" is made the same way everywhere: `--out` (or the
//! output file) lies under a regular file, so creating it fails even for root.
//!
//! Every command's 0 is here too: the heavy ones on small inputs (`demo --hits 60`, a
//! four-simulation library, benchmarks on a few signals).

use crate::TempDir;
use std::path::Path;
use std::process::Command;

fn code(args: &[&str]) -> (i32, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_aepipe"))
        .env("XDG_CACHE_HOME", crate::test_cache())
        .args(args)
        .env("AEPIPE_FONT", "")
        .output()
        .unwrap();
    let se = String::from_utf8_lossy(&o.stderr).into_owned();
    (o.status.code().unwrap_or(-1), se)
}

fn expect(want: i32, args: &[&str]) {
    let (c, se) = code(args);
    assert_eq!(c, want, "aepipe {}\nstderr: {se}", args.join(" "));
    if want == 1 || want == 3 {
        // One line that names the problem (clap's usage errors print their own block).
        let last = se.trim().lines().last().unwrap_or("");
        assert!(
            !last.is_empty(),
            "aepipe {}: nothing on stderr",
            args.join(" ")
        );
    }
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

/// A 12-hit Vallen experiment, its features, a trained SOM model and a run-less folder.
struct Fixture {
    t: TempDir,
}

impl Fixture {
    fn new() -> Fixture {
        let t = TempDir::new("exit");
        let mut e = aepipe::synth::Experiment::new("exp", 40, 7);
        e.n_samples = 512;
        e.write_vallen(&t.path().join("data")).unwrap();
        std::fs::write(t.path().join("file"), b"a regular file").unwrap();
        std::fs::write(t.path().join("bad.toml"), "[ingest]\nsampel_rate_hz = 5\n").unwrap();
        Fixture { t }
    }
    fn p(&self, rel: &str) -> String {
        s(&self.t.path().join(rel))
    }
    /// An output path that cannot be created.
    fn blocked(&self) -> String {
        self.p("file/out")
    }
}

#[test]
fn stream_commands_inspect_cwt_schema() {
    let f = Fixture::new();
    let data = f.p("data");
    for cmd in ["features", "waveforms"] {
        expect(0, &[cmd, &data, "--out", &f.p(cmd), "--quiet"]);
        expect(1, &[cmd, &data]);
        expect(
            1,
            &[cmd, &data, "--out", &f.p(cmd), "--config", &f.p("bad.toml")],
        );
        expect(
            2,
            &[
                cmd,
                &data,
                &f.p("file"),
                "--out",
                &f.p(cmd),
                "--strict",
                "--quiet",
            ],
        );
        expect(3, &[cmd, &data, "--out", &f.blocked(), "--quiet"]);
    }
    expect(0, &["inspect", &data]);
    expect(1, &["inspect", &f.p("nothing")]);
    expect(1, &["inspect", &data, "--config", &f.p("bad.toml")]);
    let png = f.p("hit.png");
    expect(0, &["cwt", &data, "--hit", "3", "--png", &png]);
    assert!(Path::new(&png).is_file());
    expect(1, &["cwt", &data, "--hit", "999", "--png", &png]);
    expect(1, &["cwt", &data, "--png", &png]);
    expect(
        3,
        &[
            "cwt",
            &data,
            "--hit",
            "3",
            "--png",
            &format!("{}/hit.png", f.blocked()),
        ],
    );
    expect(0, &["schema", "trend"]);
    expect(1, &["schema", "nonsense"]);
    expect(1, &["schema", "features", "--config", &f.p("bad.toml")]);
}

#[test]
fn analysis_commands() {
    let f = Fixture::new();
    expect(
        0,
        &["features", &f.p("data"), "--out", &f.p("f"), "--quiet"],
    );
    let feats = f.p("f/features.parquet");
    // trend
    expect(
        0,
        &["trend", &feats, "--out", &f.p("trend"), "--cutoff", "none"],
    );
    expect(
        1,
        &[
            "trend",
            &feats,
            "--out",
            &f.p("trend"),
            "--cutoff",
            "sometimes",
        ],
    );
    expect(1, &["trend", &f.p("file"), "--out", &f.p("trend")]);
    expect(
        3,
        &["trend", &feats, "--out", &f.blocked(), "--cutoff", "none"],
    );
    // som train / classify / show
    let model = f.p("model");
    expect(
        0,
        &["som", "train", &feats, "--out", &model, "--fraction", "1"],
    );
    expect(
        1,
        &[
            "som",
            "train",
            &feats,
            "--out",
            &model,
            "--label",
            "no_such_column",
        ],
    );
    expect(1, &["som", "train", &feats, "--out", &model, "--rows", "0"]);
    expect(
        1,
        &[
            "som",
            "train",
            &feats,
            "--out",
            &model,
            "--fraction",
            "1e30",
        ],
    );
    expect(
        3,
        &[
            "som",
            "train",
            &feats,
            "--out",
            &f.blocked(),
            "--fraction",
            "1",
        ],
    );
    expect(
        0,
        &["som", "classify", &model, &feats, "--out", &f.p("cls")],
    );
    expect(
        1,
        &[
            "som",
            "classify",
            &f.p("data"),
            &feats,
            "--out",
            &f.p("cls"),
        ],
    );
    expect(
        3,
        &["som", "classify", &model, &feats, "--out", &f.blocked()],
    );
    expect(0, &["som", "show", &model, "--png", &f.p("u.png")]);
    expect(1, &["som", "show", &f.p("nothing")]);
    expect(
        3,
        &[
            "som",
            "show",
            &model,
            "--png",
            &format!("{}/u.png", f.blocked()),
        ],
    );
    // report: not a run folder (1); bench stream (0, 1, 3)
    expect(1, &["report", &f.p("data")]);
    expect(
        0,
        &[
            "bench",
            "stream",
            "--hits",
            "20",
            "--samples",
            "256",
            "--out",
            &f.p("bs"),
        ],
    );
    expect(1, &["bench", "stream", "--hits", "many"]);
    expect(
        3,
        &["bench", "stream", "--hits", "20", "--out", &f.blocked()],
    );
}

#[test]
fn simulator_and_workflow_commands_fail_with_the_right_code() {
    let f = Fixture::new();
    let data = f.p("data");
    // simulate: bad sweep and unknown scenario (1), unwritable output (3)
    expect(
        1,
        &[
            "simulate",
            "--scenario",
            "sho",
            "--sweep",
            "point=a..b",
            "--out",
            &f.p("s"),
        ],
    );
    expect(1, &["simulate", "--scenario", "nope", "--out", &f.p("s")]);
    // Absurd sizes are refused before anything runs (iterations 1e30 saturates to usize::MAX).
    expect(
        1,
        &[
            "simulate",
            "--scenario",
            "sho",
            "--param",
            "iterations=1e30",
            "--out",
            &f.p("s"),
        ],
    );
    expect(
        3,
        &[
            "simulate",
            "--scenario",
            "sho",
            "--param",
            "iterations=50",
            "--out",
            &f.blocked(),
        ],
    );
    // reference: unreadable definition (1), unwritable output (3)
    expect(
        1,
        &[
            "reference",
            "--config",
            &f.p("nothing.toml"),
            "--out",
            &f.p("r"),
        ],
    );
    expect(3, &["reference", "--out", &f.blocked()]);
    // synth-experiment: a library without both mechanisms (1), unwritable output (3)
    expect(
        1,
        &[
            "synth-experiment",
            "--out",
            &f.p("x"),
            "--library",
            &f.p("file"),
        ],
    );
    expect(3, &["synth-experiment", "--out", &f.blocked()]);
    // run: missing pipeline or bad config (1 — it used to exit 3), unwritable output (3);
    // the --config form and the positional form parse alike.
    expect(1, &["run", &data, "--out", &f.p("run")]);
    expect(
        1,
        &[
            "run",
            "--config",
            &f.p("bad.toml"),
            &data,
            "--out",
            &f.p("run"),
        ],
    );
    expect(1, &["run", &f.p("bad.toml"), &data, "--out", &f.p("run")]);
    expect(
        3,
        &[
            "run",
            "--config",
            "pipelines/notched-paper.toml",
            &data,
            "--out",
            &f.blocked(),
        ],
    );
    expect(
        3,
        &[
            "run",
            "pipelines/notched-paper.toml",
            &data,
            "--out",
            &f.blocked(),
        ],
    );
    // watch: a bad --until-idle, a wrong [live] value, an unknown key (1); an output it
    // cannot create (3)
    expect(
        1,
        &["watch", &data, "--out", &f.p("w"), "--until-idle", "-1"],
    );
    std::fs::write(f.t.path().join("live.toml"), "[live]\npoll_s = 0\n").unwrap();
    for cfg in ["live.toml", "bad.toml"] {
        let args = ["watch", &data, "--out", &f.p("w"), "--config", &f.p(cfg)];
        expect(1, &args);
    }
    expect(
        3,
        &["watch", &data, "--out", &f.blocked(), "--until-idle", "0"],
    );
    // demo: bad flag (1), unwritable output (3)
    expect(1, &["demo", "--hits", "many"]);
    expect(3, &["demo", "--out", &f.blocked()]);
    // bench som / cwt without the peers' inputs (1); bench sim with a bad list (1)
    expect(1, &["bench", "som", "--inputs", &f.p("nothing")]);
    expect(1, &["bench", "cwt", "--inputs", &f.p("nothing")]);
    expect(1, &["bench", "sim", "--masses", "x"]);
    // usage errors and --help
    expect(1, &["no-such-command"]);
    expect(0, &["--help"]);
    expect(0, &["--version"]);
}

#[test]
fn pictures_need_no_system_font_and_a_bad_font_override_is_a_usage_error() {
    let f = Fixture::new();
    let png = f.p("hit.png");
    // No AEPIPE_FONT and no font directories: the embedded DejaVu Sans draws the labels.
    let o = Command::new(env!("CARGO_BIN_EXE_aepipe"))
        .env("XDG_CACHE_HOME", crate::test_cache())
        .args(["cwt", &f.p("data"), "--hit", "2", "--png", &png])
        .env_remove("AEPIPE_FONT")
        .env("XDG_DATA_DIRS", f.p("nothing"))
        .env("FONTCONFIG_PATH", f.p("nothing"))
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let bytes = std::fs::read(&png).unwrap();
    assert!(bytes.starts_with(b"\x89PNG") && bytes.len() > 10_000);
    // AEPIPE_FONT naming a file that is not a font: exit 1, the variable named.
    let o = Command::new(env!("CARGO_BIN_EXE_aepipe"))
        .env("XDG_CACHE_HOME", crate::test_cache())
        .args(["cwt", &f.p("data"), "--hit", "2", "--png", &png])
        .env("AEPIPE_FONT", f.p("file"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let se = String::from_utf8_lossy(&o.stderr);
    assert!(
        se.contains("AEPIPE_FONT") && se.contains("file: not a TrueType font"),
        "{se}"
    );
}

#[test]
fn the_library_synthesis_run_report_and_bench_commands_exit_0() {
    let f = Fixture::new();
    // A tiny reference library through the binary.
    let lib_toml = f.p("lib.toml");
    std::fs::write(
        &lib_toml,
        "[reference]\nsensors = [[125, 100]]\n\
         [[reference.scenario]]\nname = \"mesh3x3-bond-failure\"\nparams = { t2 = [-1], iterations = [3000] }\n\
         [[reference.scenario]]\nname = \"structure2x1-fibre-failure\"\nparams = { point = [2, 7], iterations = [3000] }\n",
    )
    .unwrap();
    expect(
        0,
        &[
            "reference",
            "--config",
            &lib_toml,
            "--out",
            &f.p("lib"),
            "--threads",
            "2",
        ],
    );
    let lib = f.p("lib/waveforms.parquet");
    expect(
        0,
        &[
            "synth-experiment",
            "--out",
            &f.p("x"),
            "--hits",
            "40",
            "--library",
            &lib,
        ],
    );
    // run --config with that library, then report from the run folder.
    let pipe = f.p("pipe.toml");
    std::fs::write(
        &pipe,
        format!("[som]\nreference_library = \"{lib}\"\n[report]\ngallery_per_class = 1\n"),
    )
    .unwrap();
    let run = f.p("run");
    expect(
        0,
        &[
            "run",
            "--config",
            &pipe,
            &f.p("x/data"),
            "--out",
            &run,
            "--truth",
            &f.p("x/truth.parquet"),
        ],
    );
    assert!(Path::new(&run).join("report.html").is_file());
    expect(0, &["report", &run]);
    // Benchmarks on inputs written here (the peers' file layout, small).
    let inputs = f.t.path().join("peers");
    std::fs::create_dir_all(&inputs).unwrap();
    let f32s = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let f64s = |v: &[f64]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let sig: Vec<f32> = (0..2 * 4096).map(|i| ((i as f32) * 0.05).sin()).collect();
    std::fs::write(inputs.join("w1_signals_f32.bin"), f32s(&sig)).unwrap();
    let freqs: Vec<f64> = (1..=250).map(|k| k as f64 * 1e4).collect();
    std::fs::write(inputs.join("w1_freqs_hz_f64.bin"), f64s(&freqs)).unwrap();
    let data: Vec<f64> = (0..30 * 200)
        .map(|i| ((i * 7919) % 101) as f64 / 100.0)
        .collect();
    std::fs::write(inputs.join("w3_som_data_f64.bin"), f64s(&data)).unwrap();
    std::fs::write(
        inputs.join("w3_som_init_f64.bin"),
        &f64s(&data[..]).repeat(4)[..100 * 200 * 8],
    )
    .unwrap();
    let dir = inputs.to_str().unwrap();
    expect(
        0,
        &[
            "bench",
            "cwt",
            "--inputs",
            dir,
            "--threads",
            "1",
            "--repeats",
            "1",
            "--skip-full",
        ],
    );
    expect(0, &["bench", "som", "--inputs", dir, "--repeats", "1"]);
    expect(
        0,
        &[
            "bench",
            "sim",
            "--masses",
            "100",
            "--steps",
            "2",
            "--repeats",
            "1",
        ],
    );
    // The README's main job, small: simulation, synthesis, features, trend, SOM, report.
    let demo = f.p("demo");
    expect(
        0,
        &[
            "demo",
            "--out",
            &demo,
            "--hits",
            "60",
            "--threads",
            "2",
            "--no-cross-model",
        ],
    );
    assert!(Path::new(&demo).join("run/report.html").is_file());
}
