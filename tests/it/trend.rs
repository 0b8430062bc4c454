//! Trend statistics (ch. 4.5.5): SciPy agreement through a golden file, a designed trend found
//! end to end, false positives at α = 0.01, and the null cases.

use crate::TempDir;
use aepipe::analysis::stats::linear_trend;
use aepipe::analysis::trend::{run_trend, Cutoff, TrendOptions};
use aepipe::config::PipelineConfig;
use aepipe::pipeline::{run, StreamJob, StreamOptions};
use aepipe::synth::{Experiment, Rng};

#[test]
fn trend_statistics_agree_with_scipy() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/golden/trend_scipy.json"
    ))
    .unwrap();
    let g: serde_json::Value = serde_json::from_str(&text).unwrap();
    let num = |v: &serde_json::Value| v.as_str().unwrap().parse::<f64>().unwrap();
    let rel = |a: f64, b: f64| {
        if a == b {
            0.0
        } else {
            (a - b).abs() / a.abs().max(b.abs())
        }
    };
    let cases = g["cases"].as_array().unwrap();
    assert_eq!(cases.len(), 11);
    for c in cases {
        let x: Vec<f64> = c["x"].as_array().unwrap().iter().map(num).collect();
        let y: Vec<f64> = c["y"].as_array().unwrap().iter().map(num).collect();
        let t = linear_trend(&x, &y).unwrap();
        let n = x.len();
        for (name, ours, theirs) in [
            ("r", t.r, num(&c["r"])),
            ("slope", t.slope, num(&c["slope"])),
            ("intercept", t.intercept, num(&c["intercept"])),
        ] {
            assert!(
                rel(ours, theirs) < 1e-9,
                "n={n} {name}: {ours} vs SciPy {theirs}"
            );
        }
        // SciPy's stderr is sqrt((1 − r²)·s_yy/s_xx/df), which cancels when r → 1; ours sums
        // the residuals. They agree to 1e-6 even on the near-perfect fit (r = 0.99999…).
        assert!(
            rel(t.slope_stderr, num(&c["stderr"])) < 1e-6,
            "n={n} stderr: {} vs SciPy {}",
            t.slope_stderr,
            num(&c["stderr"])
        );
        let p = num(&c["p_linregress"]);
        if p == 0.0 {
            // SciPy underflows to 0 below ~1e-300; ours must be at least that small.
            assert!(t.p < 1e-290, "n={n}: p {} where SciPy underflowed", t.p);
        } else {
            assert!(rel(t.p, p) < 1e-9, "n={n} p: {} vs SciPy {p}", t.p);
            assert!(
                rel(t.p, num(&c["p_pearsonr"])) < 1e-9,
                "n={n} p vs pearsonr"
            );
        }
    }
}

#[test]
fn no_trend_is_rarely_significant_at_one_percent() {
    // 200 seeds of trend-free power-ratio-like series (300 hits): a level-0.01 test must
    // reject in about 1 % of them, and in ≤ 5 % to pass.
    let mut significant = 0;
    for seed in 0..200 {
        let mut rng = Rng::new(seed);
        let x: Vec<f64> = (1..=300).map(f64::from).collect();
        let y: Vec<f64> = x.iter().map(|_| 0.25 + 0.05 * rng.normal()).collect();
        if linear_trend(&x, &y).unwrap().p < 0.01 {
            significant += 1;
        }
    }
    assert!(
        significant <= 10,
        "{significant} of 200 trend-free series significant at 0.01"
    );
}

#[test]
fn designed_trend_is_found_with_the_right_signs_end_to_end() {
    // The synthetic experiment shifts power from ~750 to ~250 kHz as damage accumulates.
    let t = TempDir::new("trend");
    let data = t.path().join("data");
    let mut e = Experiment::new("notched", 400, 77);
    e.n_samples = 2048;
    e.write_vallen(&data).unwrap();
    let mut cfg = PipelineConfig::default();
    cfg.ingest.vallen.load_param = Some(aepipe::config::ParamInput(0));
    let cfg = cfg.check().unwrap();
    let f = run(
        StreamJob::Features,
        &[data],
        &t.path().join("f"),
        &cfg,
        &StreamOptions::with_threads(2),
    )
    .unwrap();
    let rep = run_trend(
        std::slice::from_ref(&f.table_path),
        &t.path().join("trend"),
        &TrendOptions::default(),
    )
    .unwrap();
    let get = |c: &str| {
        rep.significant
            .iter()
            .find(|r| r.column == c)
            .unwrap_or_else(|| panic!("{c} not significant: {:?}", rep.significant))
    };
    let (low, high) = (get("pr_200_300khz"), get("pr_700_800khz"));
    assert!(
        low.significant && low.fit.unwrap().slope > 0.0,
        "200-300 kHz: {low:?}"
    );
    assert!(
        high.significant && high.fit.unwrap().slope < 0.0,
        "700-800 kHz: {high:?}"
    );
    // Peak-load cut-off: the load peaks at 80 % of the test; hits after it are left out.
    let sel = &rep.selections[0];
    assert!(
        sel.peak_load_n.unwrap() > 59.0
            && sel.hits_used < sel.hits_total
            && sel.hits_used > sel.hits_total / 2,
        "{sel:?}"
    );
    assert_eq!(low.n, sel.hits_used);
    // The table on disk says the same, and matches data-schema/trend.md.
    let (names, rows) = crate::table_rows(&rep.table_path);
    assert_eq!(rows.len(), 25);
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/data-schema/trend.md"))
        .unwrap();
    let cols: Vec<String> = aepipe::store::parse_schema_markdown(&doc)
        .into_iter()
        .map(|c| c.0)
        .collect();
    assert_eq!(
        names, cols,
        "trend.parquet drifted from data-schema/trend.md"
    );
    let m: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(t.path().join("trend/trend_manifest.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(
        m["selections"][0]["hits_used"].as_u64().unwrap() as usize,
        sel.hits_used
    );
}

#[test]
fn missing_load_falls_back_to_all_hits_and_says_so() {
    let t = TempDir::new("trendnoload");
    // No load mapping: load_n is null.
    let features = crate::synthetic_features(
        t.path(),
        "noload",
        60,
        5,
        &aepipe::config::ValidConfig::default(),
        1,
    );
    let rep = run_trend(
        &[features],
        &t.path().join("trend"),
        &TrendOptions {
            cutoff: Cutoff::PeakLoad,
            ..Default::default()
        },
    )
    .unwrap();
    let sel = &rep.selections[0];
    assert_eq!(sel.hits_used, 60);
    assert!(sel.note.as_ref().unwrap().contains("no load channel"));
    // A constant series (every hit's sample rate is 10 MHz) gets no fit, and says why.
    let c = run_trend(
        &[t.path().join("f/features.parquet")],
        &t.path().join("t-const"),
        &TrendOptions {
            columns: vec!["sample_rate_hz".into()],
            ..Default::default()
        },
    )
    .unwrap();
    assert!(c.significant.is_empty());
    let (names, rows) = crate::table_rows(&c.table_path);
    let col = |n: &str| names.iter().position(|c| c == n).unwrap();
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0][col("r")], "", "{:?}", rows[0]);
    assert!(rows[0][col("note")].contains("constant"), "{:?}", rows[0]);
    // Asking for an absent column is one clear error.
    let err = run_trend(
        &[t.path().join("f/features.parquet")],
        &t.path().join("t2"),
        &TrendOptions {
            columns: vec!["nope".into()],
            ..Default::default()
        },
    )
    .err()
    .unwrap();
    assert!(err.to_string().contains("no column nope"), "{err}");
}

/// A Vallen pair of 40 hits over 4 s whose PA0 channel carries `load(t)` (N per mV = 1).
fn pair_with_load(
    dir: &std::path::Path,
    id: &str,
    load: impl Fn(f64) -> f64,
) -> std::path::PathBuf {
    use aepipe::ingest::vallen::{write_pair, HitToWrite};
    let sig: Vec<Vec<f32>> = (0..40)
        .map(|k| {
            (0..1024)
                .map(|i| {
                    let on = if i >= 200 { 1.0 } else { 0.0 };
                    on * 0.02
                        * (1.0 + (k % 5) as f32)
                        * (i as f32 * 0.16).sin()
                        * (-((i as f32 - 200.0).max(0.0)) / 300.0).exp()
                })
                .collect()
        })
        .collect();
    let hits = sig.iter().enumerate().map(|(k, s)| HitToWrite {
        channel: 1,
        trai: k as u64 + 1,
        time_s: 0.1 * (k + 1) as f64,
        sample_rate_hz: 10e6,
        pretrigger: 200,
        samples_v: s,
        restart: false,
        transient: true,
    });
    let par: Vec<(f64, f64, f64)> = (0..=90)
        .map(|i| {
            let t = i as f64 * 0.05;
            (t, load(t), 0.0)
        })
        .collect();
    std::fs::create_dir_all(dir).unwrap();
    write_pair(&dir.join(id), hits, &par, 1e-3, 1e-3).unwrap();
    dir.to_path_buf()
}

/// A load channel of noise is no load: no peak-load cut, all hits tested, and the cut-off
/// says why; the same test with a real load (a ramp to 50 N and the break) is cut at its peak.
#[test]
fn a_load_channel_of_noise_gives_no_peak_load_cut() {
    let t = TempDir::new("noise-load");
    let mut rng = Rng::new(3);
    let noise: Vec<f64> = (0..=90).map(|_| 0.3 * rng.normal()).collect();
    let data = pair_with_load(&t.path().join("noise"), "noise", |t| {
        noise[(t / 0.05).round() as usize]
    });
    let ramp = pair_with_load(&t.path().join("ramp"), "ramp", |t| {
        if t <= 3.0 {
            50.0 * t / 3.0
        } else {
            2.0
        }
    });
    let cfg = aepipe::config::ValidConfig::default()
        .with(|c| {
            c.ingest.vallen.load_param = Some(aepipe::config::ParamInput(0));
            c.events.enabled = Some(false);
        })
        .unwrap();
    for (dir, cut) in [(data, false), (ramp, true)] {
        let out = dir.join("f");
        let r = run(
            StreamJob::Features,
            std::slice::from_ref(&dir),
            &out,
            &cfg,
            &StreamOptions::with_threads(1),
        )
        .unwrap();
        let rep = run_trend(
            &[r.table_path],
            &out.join("trend"),
            &TrendOptions {
                cutoff: Cutoff::PeakLoad,
                ..Default::default()
            },
        )
        .unwrap();
        let sel = &rep.selections[0];
        if cut {
            assert!(sel.hits_used < sel.hits_total, "{sel:?}");
            assert!(sel.cutoff.starts_with("peak-load"), "{sel:?}");
            assert!((sel.peak_load_n.unwrap() - 50.0).abs() < 2.0, "{sel:?}");
        } else {
            assert_eq!((sel.hits_used, sel.hits_total), (40, 40), "{sel:?}");
            assert!(
                sel.cutoff
                    .starts_with("none (all hits): the load channel spans")
                    && sel.cutoff.contains("within its noise"),
                "{sel:?}"
            );
            assert_eq!(sel.peak_load_n, None);
        }
    }
}

/// The real pencil-lead breaks on CFRP plates: their PA0 holds no load (constant, or a few
/// ADC codes below 1 N), so the trend tests every source.
#[test]
fn the_real_cfrp_plate_tests_have_no_load_and_every_hit_is_tested() {
    let Some(real) =
        crate::real_data("the_real_cfrp_plate_tests_have_no_load_and_every_hit_is_tested")
    else {
        return;
    };
    let t = TempDir::new("cfrp-load");
    let cfg = PipelineConfig::from_file(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/notched-paper.toml"),
    )
    .unwrap();
    let r = run(
        StreamJob::Features,
        &[real.join("plb_cfrp_vallen")],
        &t.path().join("f"),
        &cfg,
        &StreamOptions::with_threads(2),
    )
    .unwrap();
    let rep = run_trend(
        &[r.table_path],
        &t.path().join("trend"),
        &TrendOptions {
            cutoff: Cutoff::PeakLoad,
            min_load_span_n: cfg.trend.min_load_span_n,
            sources: cfg.source_rows(),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(rep.selections.len(), 3, "{:?}", rep.selections);
    for sel in &rep.selections {
        assert_eq!(sel.hits_used, sel.hits_total, "{sel:?}");
        assert!(
            sel.cutoff
                .starts_with("none (all hits): the load channel spans"),
            "{sel:?}"
        );
    }
}
