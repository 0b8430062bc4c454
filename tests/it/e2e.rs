//! End to end: the reference library feeds a synthetic notched-paper experiment written as a
//! Vallen pair with its ground truth; vallenae and aepipe's ingest see the same hits.

use crate::TempDir;
use aepipe::sim::reference::{build_library, ReferenceFile};
use std::path::Path;

/// A small library: one bond failure and three fibre break points, one sensor.
fn small_library(dir: &Path) -> std::path::PathBuf {
    small_library_seeded(dir, "lib", 2008, 1)
}

/// A small library in `dir/name` with its own seed: with `variants` > 1 every grid point
/// gets that many material draws (E, t, w within ±10 %), and the noise is seeded too.
pub(crate) fn small_library_seeded(
    dir: &Path,
    name: &str,
    seed: u64,
    variants: usize,
) -> std::path::PathBuf {
    let cfg = dir.join(format!("{name}.toml"));
    std::fs::write(
        &cfg,
        format!(
            "[reference]\nseed = {seed}\nvariants = {variants}\nsensors = [[125, 100]]\n\
             [[reference.scenario]]\nname = \"mesh3x3-bond-failure\"\nparams = {{ t2 = [-1], iterations = [3000] }}\n\
             [[reference.scenario]]\nname = \"structure2x1-fibre-failure\"\nparams = {{ point = [2, 7, 12], iterations = [3000] }}\n"
        ),
    )
    .unwrap();
    let f = ReferenceFile::read(&cfg).unwrap();
    build_library(&f.reference, &dir.join(name), false).unwrap();
    dir.join(name).join("waveforms.parquet")
}

#[test]
fn synthetic_experiment_from_the_library_is_a_readable_vallen_pair_with_truth() {
    let d = TempDir::new("e2e-synth");
    let lib = small_library(d.path());
    let summary =
        aepipe::synth::synth_experiment(d.path(), "exp", 120, 5, Some(&lib), false).unwrap();
    // 120 sources on the strip, each heard by one or both sensors: the summary says how many
    // hits that made, and the truth has one row per hit, each naming its source.
    assert!(summary.starts_with("120 sources, "), "{summary}");
    let n_hits: usize = summary["120 sources, ".len()..]
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!((120..=240).contains(&n_hits), "{summary}");
    let truth = d.path().join("truth.parquet");
    crate::pipeline::check_against_schema_file(&truth, "truth.md");
    let (names, rows) = crate::table_rows(&truth);
    assert_eq!(rows.len(), n_hits);
    let mech = names.iter().position(|n| n == "mechanism").unwrap();
    let src = names.iter().position(|n| n == "reference_signals").unwrap();
    let ev = names.iter().position(|n| n == "event").unwrap();
    let ch = names.iter().position(|n| n == "channel").unwrap();
    let mut per_source = std::collections::BTreeMap::<u64, Vec<String>>::new();
    for r in &rows {
        per_source
            .entry(r[ev].parse().unwrap())
            .or_default()
            .push(r[ch].clone());
    }
    assert_eq!(per_source.len(), 120);
    assert_eq!(
        per_source.keys().copied().collect::<Vec<_>>(),
        (1..=120).collect::<Vec<_>>()
    );
    for chans in per_source.values() {
        let mut c = chans.clone();
        c.sort();
        c.dedup();
        assert_eq!(c.len(), chans.len(), "a source heard twice by one sensor");
    }
    // Sources, not hits, carry the mechanism mix.
    let count = |m: &str| {
        rows.iter()
            .filter(|r| r[mech] == m)
            .map(|r| &r[ev])
            .collect::<std::collections::BTreeSet<_>>()
            .len()
    };
    assert!(
        count("bond_failure") > 80 && count("fibre_failure") >= 1,
        "{rows:?}"
    );
    // Every hit names the library signals it was built from.
    assert!(rows.iter().all(|r| r[src].contains("reference hit")));

    // aepipe's Vallen ingest reads the pair back: same hits, in order, and the rising load.
    let cfg = aepipe::demo::demo_config();
    let (recs, rejs) = crate::read_all(&[d.path().join("data")], &cfg);
    assert!(rejs.is_empty(), "{rejs:?}");
    assert_eq!(recs.len(), n_hits);
    // Hits are numbered 1… in time order over both sensors (as a Vallen system numbers them).
    let mut by_hit: Vec<&aepipe::model::AeRecord> = recs.iter().collect();
    by_hit.sort_by_key(|r| r.hit);
    assert!(by_hit.iter().zip(1..).all(|(r, k)| r.hit == k));
    assert!(by_hit.windows(2).all(|w| w[0].time_s <= w[1].time_s));
    assert!(by_hit[0].load_n.unwrap() < by_hit[60].load_n.unwrap());

    // vallenae (if installed) sees the same hits and samples.
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/vallenae_read.py");
    let Some(out) = crate::reference(
        "vallenae part",
        "pip install vallenae",
        std::process::Command::new("python3")
            .arg(&script)
            .arg(d.path().join("data/exp")),
    ) else {
        return;
    };
    let v: serde_json::Value = serde_json::from_slice(&out).unwrap();
    assert_eq!(v["hits"].as_u64(), Some(n_hits as u64));
    let tr = v["transients"].as_array().unwrap();
    assert_eq!(tr.len(), n_hits);
    for (t, r) in tr.iter().zip(&by_hit) {
        assert_eq!(t["trai"].as_u64(), Some(r.hit));
        assert_eq!(t["n"].as_u64(), Some(r.samples.len() as u64));
        assert_eq!(t["pretrigger"].as_u64(), Some(r.pretrigger as u64));
        assert!((t["time"].as_f64().unwrap() - r.time_s.unwrap()).abs() < 1e-6);
        for (a, b) in t["first"].as_array().unwrap().iter().zip(&r.samples) {
            assert!(
                (a.as_f64().unwrap() - *b as f64).abs() < 1e-9,
                "hit {}: {a} vs {b}",
                r.hit
            );
        }
    }
}

#[test]
fn run_classifies_against_truth_finds_the_trend_and_writes_a_report_a_browser_renders() {
    let d = TempDir::new("e2e-run");
    // Held out: the map is trained on one library and classifies an experiment built from
    // another (other seed: other material draws and noise).
    let train = small_library_seeded(d.path(), "train-lib", 11, 2);
    let lib = small_library_seeded(d.path(), "exp-lib", 12, 2);
    // The experiment: 300 hits from its library, seed 9.
    aepipe::synth::synth_experiment(d.path(), "exp", 300, 9, Some(&lib), false).unwrap();
    let mut cfg = aepipe::demo::demo_config().into_inner();
    cfg.som.reference_library = Some(train.clone());
    cfg.report.gallery_per_class = 2;
    let cfg = cfg.check().unwrap();
    let out = d.path().join("run");
    let s = aepipe::workflow::run(&aepipe::workflow::RunJob {
        truth: Some(&d.path().join("truth.parquet")),
        ..aepipe::workflow::RunJob::new(&cfg, &[d.path().join("data")], &out, 2)
    })
    .unwrap();
    // The designed shift (ch. 4.5.5): 200–300 kHz rising, 700–800 kHz falling, p < 0.01.
    let t = s.trend.as_ref().unwrap();
    let row = |c: &str| {
        t.significant
            .iter()
            .find(|r| r.column == c)
            .unwrap_or_else(|| panic!("{c} is not significant: {:?}", t.significant))
    };
    let (lo, hi) = (row("pr_200_300khz"), row("pr_700_800khz"));
    assert!(lo.significant && lo.fit.unwrap().r > 0.0, "{:?}", lo.fit);
    assert!(hi.significant && hi.fit.unwrap().r < 0.0, "{:?}", hi.fit);
    // Bond vs fibre failures against the truth.
    let truth = s.truth.as_ref().unwrap();
    assert!(truth.bond_fibre_total > 200);
    assert!(
        truth.accuracy().unwrap() >= 0.95,
        "{}/{}",
        truth.bond_fibre_correct,
        truth.bond_fibre_total
    );
    // The report: one file, every picture embedded, the sections there.
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    for part in [
        "Hits by class",
        "Trend of the power ratios",
        "Self-organising map",
        "Table 5.4",
        "Against the ground truth",
        "Damage profile (Fig. 6.1)",
        "CWT gallery",
        "CWT gallery by cluster",
        "cumulative hits per cluster",
        "feature distributions per cluster",
        "location by cluster",
        "manifest.json",
    ] {
        assert!(html.contains(part), "report lacks {part}");
    }
    // The cluster pictures joined every clustered hit to its feature row.
    let c = s.cluster.as_ref().expect("the demo pipeline clusters");
    assert_eq!(c.pictured, c.report.sizes);
    assert!(c.report.sizes.iter().sum::<usize>() > 200);
    // The evolution by cluster: one series per cluster, one row per clustered source.
    let cevo = out.join("cluster").join("evolution.parquet");
    crate::pipeline::check_against_schema_file(&cevo, "evolution.md");
    let (names, rows) = crate::table_rows(&cevo);
    let class = names.iter().position(|n| n == "class").unwrap();
    for (k, n) in c.report.sizes.iter().enumerate() {
        let got = rows
            .iter()
            .filter(|r| r[class] == format!("cluster {k}"))
            .count();
        assert_eq!(got, *n, "cluster {k}");
    }
    assert_eq!(
        rows.iter().filter(|r| r[class] == "all").count(),
        c.report.rows
    );
    let images = html.matches("<img ").count();
    assert!(images >= 6, "{images} images");
    assert_eq!(html.matches("src=\"data:image/png;base64,").count(), images);
    assert!(!html.contains("class=\"missing\""));
    // `aepipe report RUN_DIR` writes the same report again from the run's folder (only the
    // stage timings line may differ).
    let (again, _) = aepipe::workflow::rebuild_report(&out).unwrap();
    let strip = |h: &str| match (h.find("Stages:"), h.find("</p><details>")) {
        (Some(a), Some(b)) if a < b => format!("{}{}", &h[..a], &h[b..]),
        _ => h.to_string(),
    };
    assert_eq!(
        strip(&std::fs::read_to_string(again).unwrap()),
        strip(&html)
    );

    // The thesis's own procedure (ch. 5.4): train on a balanced 10 % of the run's hits with
    // their criteria labels; the map then reproduces those labels for most hits.
    let crit = cfg
        .clone()
        .with(|c| {
            c.som.train_on = aepipe::config::TrainOn::Criteria;
            c.report.enabled = false;
        })
        .unwrap();
    let c = aepipe::workflow::run(&aepipe::workflow::RunJob::new(
        &crit,
        &[d.path().join("data")],
        &d.path().join("run-criteria"),
        2,
    ))
    .unwrap();
    let m = c.som.as_ref().unwrap();
    assert!(m.trained_on.contains("criteria labels"), "{}", m.trained_on);
    assert!(
        m.confusion.accuracy().unwrap() > 0.6,
        "{}/{}",
        m.confusion.correct,
        m.confusion.total
    );
    assert!(!d.path().join("run-criteria/report.html").exists());

    // A real browser decodes every picture (headless Chromium, if installed).
    let Some(chromium) = ["chromium", "chromium-browser", "google-chrome"]
        .iter()
        .find(|b| {
            std::process::Command::new(b)
                .arg("--version")
                .output()
                .is_ok_and(|o| o.status.success())
        })
    else {
        crate::skip(
            "browser part",
            "no chromium (Debian package `chromium`; .ci/run installs it)",
        );
        return;
    };
    let url = format!("file://{}", out.join("report.html").display());
    let dom = std::process::Command::new(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--virtual-time-budget=10000",
            "--dump-dom",
            &url,
        ])
        .output()
        .unwrap();
    let dom = String::from_utf8_lossy(&dom.stdout);
    let want = format!("data-images-loaded=\"{images}/{images}\"");
    assert!(
        dom.contains(&want),
        "chromium: {}",
        dom.split("data-images-loaded")
            .nth(1)
            .map(|s| &s[..20.min(s.len())])
            .unwrap_or("no self-check attribute")
    );
    let png = d.path().join("report.png");
    let shot = std::process::Command::new(chromium)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--window-size=1280,3000",
        ])
        .arg(format!("--screenshot={}", png.display()))
        .arg(&url)
        .output()
        .unwrap();
    assert!(shot.status.success() && std::fs::metadata(&png).unwrap().len() > 10_000);
}

/// `aepipe demo ARGS --out OUT`, asserted to succeed; its standard output.
fn demo(out: &Path, args: &[&str]) -> String {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_aepipe"))
        .arg("demo")
        .args(args)
        .arg("--out")
        .arg(out)
        .env("XDG_CACHE_HOME", crate::test_cache())
        .output()
        .unwrap();
    let so = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(
        o.status.success(),
        "{so}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    so
}

/// The README's demo numbers are the demo's: `aepipe demo` with its defaults (651 hits, seed
/// 2026), and every headline number it prints is the one the README states.
#[test]
fn the_readme_states_the_numbers_the_demo_prints() {
    let t = TempDir::new("demo-readme");
    let so = demo(t.path(), &[]);
    demo_report_is_explorable(t.path());
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    let after = |line_start: &str, sep: &str| -> String {
        let l = so
            .lines()
            .find(|l| l.trim_start().starts_with(line_start))
            .unwrap_or_else(|| panic!("no '{line_start}' line in:\n{so}"));
        l.split(sep).nth(1).unwrap().trim().to_string()
    };
    // "562/567 = 99.1 %" and "585/651 = 89.9 %"
    let acc = after("accuracy against the ground truth", ": ");
    let agree = after("agreement with the ch. 4.7 criteria labels", ": ");
    // "erroneous records kept from the mechanisms: 20/21 (8 called erroneous, 12 unlike the
    // references); overall the thesis's way (…): 493/543 = 90.8 %"
    let err_line = so
        .lines()
        .find(|l| l.starts_with("erroneous records kept from the mechanisms"))
        .and_then(|l| l.split_once(": "))
        .unwrap_or_else(|| panic!("no erroneous-recall line in:\n{so}"))
        .1
        .to_string();
    let recall = err_line.split(';').next().unwrap().trim().to_string();
    let overall = err_line.rsplit(": ").next().unwrap().trim().to_string();
    for (what, v) in [
        ("accuracy", &acc),
        ("criteria agreement", &agree),
        ("erroneous recall", &recall),
        ("overall accuracy the thesis's way", &overall),
    ] {
        assert!(
            readme.contains(v.as_str()),
            "the README does not state the demo's {what} {v}"
        );
    }
    assert!(readme.contains(&format!("**{acc}**")), "intro: {acc}");
    // Issue 51 item 5, at the demo's scale (a 3-D library of one material draw): the classes
    // asked about another model, both ways. "  plane map on a 3-D test: balanced accuracy
    // 69.7 %; …". The README states both; the bound is 60 %, below what was measured (69.7
    // and 65.0 %) and far below the 90 % goal, which the corrected physics does not
    // reach (docs/fidelity.md "Classes on another model"): a fall under it is a regression.
    for what in ["plane map on a 3-D test", "3-D map on the plane test"] {
        let l = so
            .lines()
            .find(|l| l.trim_start().starts_with(what))
            .unwrap_or_else(|| panic!("no '{what}' line in:\n{so}"));
        let b = l
            .split("balanced accuracy ")
            .nth(1)
            .and_then(|r| r.split(" %").next())
            .unwrap_or_else(|| panic!("no balanced accuracy in '{l}'"));
        assert!(
            readme.contains(&format!("{what}: balanced accuracy {b} %")),
            "the README does not state '{what}: balanced accuracy {b} %'"
        );
        let b: f64 = b.parse().unwrap();
        assert!(
            b >= 60.0,
            "{what}: balanced accuracy {b} % < the stated 60 %"
        );
    }
    // The Table 5.4 matrix the demo prints is the README's, line for line.
    let table: Vec<&str> = so
        .lines()
        .skip_while(|l| !l.starts_with("Table 5.4"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .map(str::trim)
        .collect();
    assert!(table.len() >= 4, "{so}");
    for l in &table {
        assert!(readme.contains(l), "README lacks the Table 5.4 line '{l}'");
    }
    // Issue 14's targets, held out: the map is trained on the embedded library (seed 2008)
    // and classifies an experiment built from a library simulated with the demo's seed.
    let ratio = |v: &str| -> f64 {
        let v = v.split(" =").next().unwrap().split(' ').next().unwrap();
        let (k, n) = v.split_once('/').unwrap();
        k.trim().parse::<f64>().unwrap() / n.trim().parse::<f64>().unwrap()
    };
    assert!(ratio(&acc) >= 0.95, "bond vs fibre {acc}");
    // Issue 14 asked 80 % at the demo's seed; with the erroneous area read by the quality
    // check (issue 24) it is 20/21 there (the map alone 16/21); the held-out seeds are
    // erroneous_records_are_recognised_on_held_out_seeds's.
    assert!(ratio(&recall) >= 0.85, "erroneous recall {recall}");
    // Issue 23's targets, against the truth of where each source was:
    // "events: 649 built for 651 sources (544 specimen, 107 grip); …"
    // "location: 543 specimen events, error median 0.16 mm, 90 % within 1.20 mm"
    // "zone: 107/107 grip sources removed (100.0 %), 1/544 specimen sources lost (0.2 %)"
    let line = |start: &str| -> String {
        so.lines()
            .find(|l| l.starts_with(start))
            .unwrap_or_else(|| panic!("no '{start}' line in:\n{so}"))
            .to_string()
    };
    let (ev, loc, zone) = (line("events: "), line("location: "), line("zone: "));
    for l in [&ev, &loc, &zone] {
        assert!(
            readme.contains(l.as_str()),
            "README lacks the demo's line '{l}'"
        );
    }
    let num = |l: &str, after: &str| -> f64 {
        l.split(after)
            .nth(1)
            .unwrap()
            .split_whitespace()
            .next()
            .unwrap()
            .trim_end_matches([',', '%'])
            .parse()
            .unwrap()
    };
    let (built, sources) = (num(&ev, "events: "), num(&ev, "built for "));
    assert!((built - sources).abs() <= 0.01 * sources, "{ev}");
    assert!(num(&loc, "error median ") <= 5.0, "{loc}");
    let pct = |part: &str| -> f64 {
        let inside = part.split('(').nth(1).unwrap().split(' ').next().unwrap();
        inside.parse().unwrap()
    };
    let (grip, lost) = zone.split_once(", ").unwrap();
    assert!(pct(grip) >= 95.0, "{zone}");
    assert!(pct(lost) <= 2.0, "{zone}");
    damage_profile_matches_the_truth(t.path());
    evolution_matches_the_profile(t.path());
    // "200 - 300 kHz    r = +0.22  p = 2.4e-5  slope …" → README "200–300 kHz r = +0.22, p = 2.4e-5"
    for band in ["200 - 300 kHz", "700 - 800 kHz"] {
        let l = so
            .lines()
            .find(|l| l.trim_start().starts_with(band))
            .unwrap_or_else(|| panic!("{band} is not significant any more:\n{so}"));
        let w: Vec<&str> = l.split_whitespace().collect();
        let (r, p) = (w[6], w[9]);
        let stated = format!("{} r = {r}, p = {p}", band.replace(" - ", "–"));
        // (The README writes minus as U+2212.)
        assert!(
            readme.replace('\u{2212}', "-").contains(&stated),
            "README lacks '{stated}'"
        );
    }
}

/// The demo's own report, as a user opens it: within the page's bound, with its Explore
/// section, and in headless Chromium every chart drawn with every feature row a point, a
/// clicked point opening its hit (`explore::explorer_works`). The demo's pictures once
/// filled the bound and the section was left out without a word.
fn demo_report_is_explorable(dir: &Path) {
    let report = dir.join("run/report.html");
    let html = std::fs::read_to_string(&report).unwrap();
    assert!(
        html.len() <= aepipe::report::PAGE_BYTES,
        "{} bytes",
        html.len()
    );
    assert!(
        html.contains("<h2 id=explore>"),
        "the demo's report has no Explore section"
    );
    let (_, rows) = crate::table_rows(&dir.join("run/features/features.parquet"));
    if let Some(v) = crate::explore::browser(&report) {
        crate::explore::explorer_works(&v, rows.len() as u64);
    }
}

/// The demo's damage profile (Fig. 6.1) against what is known of the synthetic test: every
/// hit once, in time order, with the load curve the experiment was made with, running counts
/// that are the class column's, and the classes' course over the test close to the truth's.
fn damage_profile_matches_the_truth(dir: &Path) {
    let table = dir.join("run/som/damage_profile.parquet");
    crate::pipeline::check_against_schema_file(&table, "damage_profile.md");
    let (names, rows) = crate::table_rows(&table);
    let col = |n: &str| names.iter().position(|x| x == n).unwrap();
    let (tn, trows) = crate::table_rows(&dir.join("truth.parquet"));
    let truth: std::collections::BTreeMap<String, String> = trows
        .iter()
        .map(|r| {
            let c = |n: &str| tn.iter().position(|x| x == n).unwrap();
            (r[c("hit")].clone(), r[c("mechanism")].clone())
        })
        .collect();
    // One row per event of the gauge section: the trend, the map and the profile count
    // sources inside the zone, not hits.
    let (en, erows) = crate::table_rows(&dir.join("run/features/events.parquet"));
    let zone = en.iter().position(|x| x == "zone").unwrap();
    let inside = erows.iter().filter(|r| r[zone] == "inside").count();
    assert!(inside > 500, "{inside} events inside");
    assert_eq!(rows.len(), inside);
    assert!(rows.iter().all(|r| r[col("channel")] == "0"));
    let f = |r: &Vec<String>, n: &str| r[col(n)].parse::<f64>().unwrap();
    let (t_peak, peak_n) = (0.8 * 60.0, 60.0);
    let mut counts = std::collections::BTreeMap::<String, u64>::new();
    let mut prev_t = f64::NEG_INFINITY;
    let peak_at = rows
        .iter()
        .max_by(|a, b| f(a, "load_n").total_cmp(&f(b, "load_n")))
        .map(|r| f(r, "time_s"))
        .unwrap();
    assert!((peak_at - t_peak).abs() < 1.0, "peak load at {peak_at} s");
    for r in &rows {
        let t = f(r, "time_s");
        assert!(t >= prev_t);
        prev_t = t;
        // The load recorded at 10 Hz on PA0, interpolated: the curve it was made from.
        let want = aepipe::synth::load_curve(t, t_peak, peak_n);
        assert!(
            (f(r, "load_n") - want).abs() < 0.5,
            "{t} s: {} vs {want}",
            f(r, "load_n")
        );
        let class = r[col("class")].clone();
        *counts.entry(class).or_default() += 1;
        for c in ["bond_failure", "fibre_failure", "erroneous"] {
            assert_eq!(
                r[col(&format!("n_{c}"))],
                counts.get(c).copied().unwrap_or(0).to_string()
            );
        }
        assert_eq!(r[col("before_peak_load")] == "true", t < peak_at, "{t} s");
    }
    // Bond failures, the bulk, follow the truth's course: at every tenth of the test the
    // running count is within 5 % of the true one.
    let mut tb = 0.0;
    for (i, r) in rows.iter().enumerate() {
        if truth[&r[col("hit")]] == "bond_failure" {
            tb += 1.0;
        }
        if (i + 1) % 65 == 0 {
            let sb = f(r, "n_bond_failure");
            assert!(
                (sb - tb).abs() <= 0.05 * tb.max(20.0),
                "hit {}: {sb} vs {tb}",
                i + 1
            );
        }
    }
    // Fibre failures (with the "both" hits the thesis would count as fibre failures): the
    // share before the peak load in the profile is the truth's within 15 points.
    let share = |is: &dyn Fn(&Vec<String>) -> bool| {
        let all: Vec<&Vec<String>> = rows.iter().filter(|r| is(r)).collect();
        all.iter()
            .filter(|r| r[col("before_peak_load")] == "true")
            .count() as f64
            / all.len().max(1) as f64
    };
    let som = share(&|r| r[col("class")] == "fibre_failure");
    let tru = share(&|r| {
        let m = &truth[&r[col("hit")]];
        m == "fibre_failure" || m == "both"
    });
    assert!(
        (som - tru).abs() < 0.15,
        "before the peak: SOM {som:.2}, truth {tru:.2}"
    );
}

/// The demo's damage evolution against its damage profile and feature table: the running
/// counts are the profile's, the hits are the events' hits, and the last window's b- and
/// Ib-value recomputed here from the features' amplitudes (Aki; Shiotani) are the table's.
fn evolution_matches_the_profile(dir: &Path) {
    let table = dir.join("run/som/evolution.parquet");
    crate::pipeline::check_against_schema_file(&table, "evolution.md");
    let (names, rows) = crate::table_rows(&table);
    let col = |n: &str| names.iter().position(|x| x == n).unwrap();
    let (pn, prof) = crate::table_rows(&dir.join("run/som/damage_profile.parquet"));
    let pcol = |n: &str| pn.iter().position(|x| x == n).unwrap();
    let all: Vec<&Vec<String>> = rows.iter().filter(|r| r[col("class")] == "all").collect();
    assert_eq!(all.len(), prof.len());
    for (k, (e, p)) in all.iter().zip(&prof).enumerate() {
        assert_eq!(e[col("hit")], p[pcol("hit")]);
        assert_eq!(e[col("cum_sources")], (k + 1).to_string());
    }
    for class in ["bond_failure", "fibre_failure", "erroneous"] {
        let n = rows.iter().filter(|r| r[col("class")] == class).count();
        let last = prof.last().unwrap()[pcol(&format!("n_{class}"))].clone();
        assert_eq!(n.to_string(), last, "{class}");
    }
    // Two sensors: nearly every event has both hits.
    let hits: f64 = all.last().unwrap()[col("cum_hits")].parse().unwrap();
    assert!(
        hits > 1.9 * all.len() as f64 && hits <= 2.0 * all.len() as f64,
        "{hits}"
    );
    // The last window (50 sources) from the features' amplitudes.
    let (fnm, feats) = crate::table_rows(&dir.join("run/features/features.parquet"));
    let fc = |n: &str| fnm.iter().position(|x| x == n).unwrap();
    let amp: std::collections::BTreeMap<&str, f64> = feats
        .iter()
        .map(|r| {
            (
                r[fc("hit")].as_str(),
                r[fc("peak_amplitude_db")].parse().unwrap(),
            )
        })
        .collect();
    let m: Vec<f64> = prof[prof.len() - 50..]
        .iter()
        .map(|p| amp[p[pcol("hit")].as_str()] / 20.0)
        .collect();
    let above: Vec<f64> = m.iter().copied().filter(|&x| x >= 2.0).collect();
    let b = std::f64::consts::LOG10_E / (above.iter().sum::<f64>() / above.len() as f64 - 2.0);
    let mu = m.iter().sum::<f64>() / 50.0;
    let sd = (m.iter().map(|x| (x - mu).powi(2)).sum::<f64>() / 49.0).sqrt();
    let n_ge = |x: f64| m.iter().filter(|&&v| v >= x).count() as f64;
    let ib = (n_ge(mu - sd).log10() - n_ge(mu + sd).log10()) / (2.0 * sd);
    let last = all.last().unwrap();
    let got_b: f64 = last[col("b_value")].parse().unwrap();
    let got_ib: f64 = last[col("ib_value")].parse().unwrap();
    assert!((got_b - b).abs() < 1e-9 * b, "b {got_b} vs {b}");
    assert!((got_ib - ib).abs() < 1e-9 * ib.abs(), "Ib {got_ib} vs {ib}");
    assert!(all[48][col("b_value")].is_empty() && !all[49][col("b_value")].is_empty());
}

/// The erroneous records' acceptance, held out: the demo's pipeline on the evaluation seeds
/// 101–108, written here before their first run and never changed after it (the quality
/// check's clip rule, the reading of the map's erroneous area and the library's 4 material
/// draws were chosen on seeds 11–14 and the real files; seeds 31–38, which this test ran
/// before, grew from 31–32 after those gave 96.6 % against the 97 % bound, so they are
/// retired, not reused). Pooled over the eight: erroneous records kept from the mechanisms
/// ≥ 85 %, bond vs fibre ≥ 97 %, thesis-way (Table 5.4: the true mechanism, or an erroneous
/// record kept from the mechanisms, over all sources) ≥ 88 %, the goals as asked.
/// And classification.parquet keeps its contract: a novel hit is unlike_references whatever
/// its node or fault; any other hit is erroneous exactly when its features carry a quality
/// fault, and node_label is the map's own reading.
#[test]
fn erroneous_records_are_recognised_on_held_out_seeds() {
    let t = TempDir::new("demo-held-out");
    let ratio = |s: &str| -> (usize, usize) {
        let s = s.split(" = ").next().unwrap().trim();
        let s = s.split(' ').next().unwrap();
        let (a, b) = s.split_once('/').unwrap_or_else(|| panic!("'{s}'"));
        (a.trim().parse().unwrap(), b.trim().parse().unwrap())
    };
    let (mut bf, mut er, mut all) = ((0, 0), (0, 0), (0, 0));
    for seed in ["101", "102", "103", "104", "105", "106", "107", "108"] {
        let out = t.path().join(seed);
        let so = demo(&out, &["--seed", seed, "--no-cross-model", "--no-report"]);
        // --no-report: the run's tables and figures without the page.
        assert!(!out.join("run/report.html").exists() && !so.contains("report: "));
        assert!(out.join("run/run.json").is_file());
        let line = |start: &str| -> String {
            so.lines()
                .find(|l| l.starts_with(start))
                .unwrap_or_else(|| panic!("no '{start}' line in:\n{so}"))
                .split_once(": ")
                .unwrap()
                .1
                .to_string()
        };
        let add = |sum: &mut (usize, usize), (a, b): (usize, usize)| {
            sum.0 += a;
            sum.1 += b;
        };
        add(&mut bf, ratio(&line("accuracy against the ground truth")));
        let e = line("erroneous records kept from the mechanisms");
        add(&mut er, ratio(e.split(';').next().unwrap()));
        add(&mut all, ratio(e.rsplit(": ").next().unwrap()));
        let (names, rows) =
            crate::table_rows(&out.join("run").join("som").join("classification.parquet"));
        let k = |n: &str| names.iter().position(|c| c == n).unwrap();
        let (som, node, fault, novel) = (
            k("som_label"),
            k("node_label"),
            k("quality_fault"),
            k("novel"),
        );
        for r in &rows {
            if r[novel] == "true" {
                assert_eq!(r[som], "unlike_references", "seed {seed}: {r:?}");
                continue;
            }
            assert_eq!(r[novel], "false", "seed {seed}: calibrated map, {r:?}");
            assert_eq!(
                r[som] == "erroneous",
                !r[fault].is_empty(),
                "seed {seed}: {r:?}"
            );
            if r[fault].is_empty() && r[node] != "erroneous" {
                assert_eq!(
                    r[som], r[node],
                    "seed {seed}: a sound hit keeps its node's class"
                );
            }
        }
        // The map alone calls some hits erroneous; the quality reading re-reads them.
        assert!(rows.iter().any(|r| r[node] == "erroneous"), "seed {seed}");
    }
    let pct = |(a, b): (usize, usize)| 100.0 * a as f64 / b as f64;
    assert!(er.1 >= 30, "too few erroneous events to judge: {er:?}");
    assert!(pct(er) >= 85.0, "erroneous recall {}/{}", er.0, er.1);
    assert!(pct(bf) >= 97.0, "bond vs fibre {}/{}", bf.0, bf.1);
    eprintln!(
        "held out 101-108: erroneous {}/{} = {:.1} %, bond vs fibre {}/{} = {:.1} %, thesis-way {}/{} = {:.1} %",
        er.0, er.1, pct(er), bf.0, bf.1, pct(bf), all.0, all.1, pct(all)
    );
    assert!(pct(all) >= 88.0, "thesis-way {}/{}", all.0, all.1);
}

/// Issue 39's novelty acceptance, held out: on demo seeds 41 and 42, never used to choose
/// anything (the conformal rule was chosen on the default seed 2026), at most 3 % of the
/// hits whose truth is a bond or fibre failure are unlike the references, and every novel
/// hit is `unlike_references` with its quantisation error beyond the stated threshold.
#[test]
fn reference_like_hits_of_unseen_seeds_are_seldom_novel() {
    let t = TempDir::new("demo-novelty");
    let (mut novel_bf, mut all_bf) = (0usize, 0usize);
    for seed in ["41", "42"] {
        let out = t.path().join(seed);
        let so = demo(&out, &["--seed", seed, "--no-cross-model", "--no-report"]);
        let threshold: f64 = so
            .lines()
            .find_map(|l| l.split_once("beyond quantisation error "))
            .and_then(|(_, r)| r.split(' ').next())
            .unwrap_or_else(|| panic!("no novelty line in:\n{so}"))
            .parse()
            .unwrap();
        let (tn, truth) = crate::table_rows(&out.join("truth.parquet"));
        let tk = |n: &str| tn.iter().position(|c| c == n).unwrap();
        let key = (tk("experiment"), tk("channel"), tk("hit"));
        let mech: std::collections::HashMap<(String, String, String), String> = truth
            .iter()
            .map(|r| {
                (
                    (r[key.0].clone(), r[key.1].clone(), r[key.2].clone()),
                    r[tk("mechanism")].clone(),
                )
            })
            .collect();
        let (names, rows) =
            crate::table_rows(&out.join("run").join("som").join("classification.parquet"));
        let k = |n: &str| names.iter().position(|c| c == n).unwrap();
        for r in &rows {
            let qe: f64 = r[k("quantization_error")].parse().unwrap();
            assert_eq!(r[k("quantization_error")], r[k("bmu_distance")]);
            let novel = r[k("novel")] == "true";
            // The printed threshold is rounded to 4 decimals.
            assert!(
                (qe - threshold).abs() < 1e-4 || novel == (qe > threshold),
                "seed {seed}: {r:?}"
            );
            assert_eq!(novel, r[k("som_label")] == "unlike_references", "{r:?}");
            let m = &mech[&(
                r[k("experiment")].clone(),
                r[k("channel")].clone(),
                r[k("hit")].clone(),
            )];
            if m == "bond_failure" || m == "fibre_failure" {
                all_bf += 1;
                novel_bf += usize::from(novel);
            }
        }
    }
    assert!(all_bf >= 800, "{all_bf} bond and fibre hits");
    assert!(
        novel_bf as f64 <= 0.03 * all_bf as f64,
        "{novel_bf} of {all_bf} true bond and fibre hits novel"
    );
}

/// Issue 39's novelty acceptance on a stranger's test: pencil-lead breaks on carbon-fibre
/// plates read with the paper map are ≥ 80 % unlike its references, and the terminal says
/// the map's classes do not describe these tests.
#[test]
fn pencil_lead_breaks_on_cfrp_are_unlike_the_paper_map() {
    let Some(real) = crate::real_data("pencil_lead_breaks_on_cfrp_are_unlike_the_paper_map") else {
        return;
    };
    let t = TempDir::new("cfrp-novelty");
    let cfg = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/notched-paper.toml");
    let out = t.path().join("run");
    let (code, so, se) = crate::aepipe(&[
        "run",
        "--config",
        cfg.to_str().unwrap(),
        real.join("plb_cfrp_vallen").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{so}{se}");
    let (names, rows) = crate::table_rows(&out.join("som").join("classification.parquet"));
    let k = |n: &str| names.iter().position(|c| c == n).unwrap();
    let novel = rows.iter().filter(|r| r[k("novel")] == "true").count();
    assert!(rows.len() >= 150, "{} rows", rows.len());
    assert!(
        novel as f64 >= 0.8 * rows.len() as f64,
        "{novel} of {} novel",
        rows.len()
    );
    assert!(
        so.contains("the map's classes do not describe these tests"),
        "{so}"
    );
    let report = std::fs::read_to_string(out.join("report.html")).unwrap();
    // The report's first lines say so too, before the inputs.
    let first = report
        .find("classes do not describe these tests")
        .expect("report");
    assert!(first < report.find("<h2>Inputs").unwrap());
}

/// Issue 51's acceptance for the classification on the corrected library, held out: seeds 51
/// and 52 were never used to choose anything (the library's 4 material draws were chosen on
/// seeds 11–14). Each is a demo test drawn with a mix that holds enough fibre failures to
/// measure their recall (`--shares bond_failure=0.45,fibre_failure=0.35,both=0.1,
/// erroneous=0.1`), run through the demo's pipeline (`pipelines/demo.toml`, the map trained
/// on the embedded library, seed 2008) and scored against its truth. Pooled: at least 200
/// true fibre failures; bond-failure recall ≥ 97 %, fibre-failure recall ≥ 90 %, erroneous
/// records kept from the mechanisms ≥ 85 %, true mechanisms unlike the references ≤ 3 %.
#[test]
fn each_mechanism_is_recalled_on_held_out_tests_that_hold_enough_of_it() {
    let t = TempDir::new("shares-held-out");
    let frac = |s: &str| -> (usize, usize) {
        let s = s.trim().split([' ', ';', ',']).next().unwrap();
        let (a, b) = s.split_once('/').unwrap_or_else(|| panic!("'{s}'"));
        (a.parse().unwrap(), b.parse().unwrap())
    };
    let (mut bond, mut fibre, mut kept, mut novel) = ((0, 0), (0, 0), (0, 0), (0, 0));
    let add = |sum: &mut (usize, usize), (a, b): (usize, usize)| {
        sum.0 += a;
        sum.1 += b;
    };
    for seed in ["51", "52"] {
        let dir = t.path().join(seed);
        let (code, so, se) = crate::aepipe(&[
            "synth-experiment",
            "--out",
            dir.to_str().unwrap(),
            "--seed",
            seed,
            "--shares",
            "bond_failure=0.45,fibre_failure=0.35,both=0.1,erroneous=0.1",
        ]);
        assert_eq!(code, 0, "{so}{se}");
        assert!(so.contains("mechanisms drawn as bond_failure=0.45"), "{so}");
        let cfg = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/demo.toml");
        let (code, so, se) = crate::aepipe(&[
            "run",
            "--config",
            cfg.to_str().unwrap(),
            "--out",
            dir.join("run").to_str().unwrap(),
            "--truth",
            dir.join("truth.parquet").to_str().unwrap(),
            dir.join("data").to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{so}{se}");
        let line = |start: &str| -> &str {
            so.lines()
                .find(|l| l.starts_with(start))
                .unwrap_or_else(|| panic!("no '{start}' line in:\n{so}"))
        };
        let recall = line("recall by true class");
        let of = |class: &str| {
            let at = recall
                .find(&format!("{class} "))
                .unwrap_or_else(|| panic!("no {class} in {recall}"));
            frac(&recall[at + class.len() + 1..])
        };
        add(&mut bond, of("bond_failure"));
        add(&mut fibre, of("fibre_failure"));
        let e = line("erroneous records kept from the mechanisms");
        add(&mut kept, frac(e.split_once(": ").unwrap().1));
        let u = line("unlike the references, by truth");
        add(
            &mut novel,
            frac(u.split_once("bond and fibre failures ").unwrap().1),
        );
        // The balanced accuracy printed is the mean of the two recalls printed.
        let (b, f) = (of("bond_failure"), of("fibre_failure"));
        let want = 50.0 * (b.0 as f64 / b.1 as f64 + f.0 as f64 / f.1 as f64);
        let got: f64 = recall
            .rsplit("balanced accuracy (mean of bond and fibre recalls) ")
            .next()
            .unwrap()
            .trim_end_matches(" %")
            .parse()
            .unwrap();
        assert!((got - want).abs() < 0.051, "{got} vs {want}: {recall}");
    }
    let pct = |(a, b): (usize, usize)| 100.0 * a as f64 / b as f64;
    eprintln!(
        "held out 51–52: bond {bond:?} fibre {fibre:?} erroneous kept {kept:?} novel {novel:?}"
    );
    assert!(fibre.1 >= 200, "too few fibre failures to judge: {fibre:?}");
    assert!(pct(bond) >= 97.0, "bond-failure recall {bond:?}");
    assert!(pct(fibre) >= 90.0, "fibre-failure recall {fibre:?}");
    assert!(pct(kept) >= 85.0, "erroneous kept {kept:?}");
    assert!(
        pct(novel) <= 3.0,
        "true mechanisms unlike the references {novel:?}"
    );
}
