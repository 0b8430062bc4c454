//! The explorable report in a real browser: headless Chromium driven through the DevTools
//! protocol (`tests/python/browser_report.py`) opens the report of a synthetic run with
//! events located on a line, clusters and the SOM; no console error, no request to the
//! network, every chart draws its points, and a real mouse click on a point of the scatter
//! opens that hit — its waveform and CWT where the page embeds them, the `aepipe cwt`
//! command that draws them where it does not.

use crate::{aepipe, TempDir};
use std::path::Path;

/// What `tests/python/browser_report.py` saw of `report`, or None after [`crate::skip`].
pub fn browser(report: &Path) -> Option<serde_json::Value> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/browser_report.py");
    let o = crate::reference(
        "the report in a browser",
        "pip install playwright and a chromium; .ci/run does",
        std::process::Command::new("python3")
            .arg(&script)
            .arg(report),
    )?;
    Some(serde_json::from_slice(&o).unwrap())
}

#[test]
fn the_explorable_report_draws_and_opens_a_clicked_hit_in_a_browser() {
    let t = TempDir::new("explore");
    let data = t.path().join("synth");
    let (code, said, err) = aepipe(&[
        "synth-experiment",
        "--out",
        data.to_str().unwrap(),
        "--hits",
        "150",
    ]);
    assert_eq!(code, 0, "{said}\n{err}");
    let cfg = t.path().join("run.toml");
    std::fs::write(
        &cfg,
        "[cluster]\nenabled = true\nk_min = 2\nk_max = 3\n\n[report]\nexplorable_hits = 10\n\n\
         [location]\nkind = \"linear\"\nvelocity_m_s = 700\nsensors = { 1 = [-0.020], 2 = [0.020] }\n\
         zone = [-0.015, 0.015]\n",
    )
    .unwrap();
    let out = t.path().join("run");
    let (code, said, err) = aepipe(&[
        "run",
        "--config",
        cfg.to_str().unwrap(),
        data.join("data").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{said}\n{err}");
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    // The page names no script or style outside itself.
    assert!(!html.contains("<script src"), "an external script");
    assert!(!html.contains("<link"), "an external stylesheet");
    // Colour by class, cluster or zone.
    for c in ["\"SOM class\"", "\"cluster\"", "\"zone\""] {
        assert!(html.contains(c), "no colouring {c}");
    }
    let Some(v) = browser(&out.join("report.html")) else {
        return;
    };
    // 150 sources heard by two sensors: 300 feature rows, all of them points.
    explorer_works(&v, 300);
}

/// What a report's explorer must do in the browser, on a run of `rows` feature rows that all
/// fit the page as points: no console error, no request to the network, every chart drawn
/// with points (the cluster's validity chart among them), a click on a point opening that
/// hit, and the geometry and interaction of [`interaction`].
pub fn explorer_works(v: &serde_json::Value, rows: u64) {
    assert_eq!(v["errors"], serde_json::json!([]), "{v}");
    assert_eq!(v["requests"], serde_json::json!([]), "{v}");
    let charts = v["charts"].as_array().expect("the explorer ran");
    let titles: Vec<&str> = charts
        .iter()
        .map(|c| c["title"].as_str().unwrap())
        .collect();
    for want in [
        "Over the test",
        "Feature scatter",
        "Event location",
        "Cumulative hits per class",
        "Validity against k",
    ] {
        assert!(titles.contains(&want), "{titles:?}");
    }
    for c in charts {
        assert_eq!(c["drawn"], true, "{c}");
        assert!(c["points"].as_u64().unwrap() > 0, "{c}");
    }
    assert_eq!(charts[1]["points"], rows, "{v}");
    for c in v["clicks"].as_array().unwrap() {
        assert_eq!(c["found"], true, "{c}");
        assert_eq!(c["key"], c["expected"], "{c}");
        let key = c["expected"].as_str().unwrap();
        let hit = key.rsplit('|').next().unwrap();
        assert!(
            c["title"].as_str().unwrap().contains(&format!("hit {hit}")),
            "{c}"
        );
        if c["embedded"] == true {
            assert!(c["image_width"].as_u64().unwrap() > 100, "{c}");
        } else {
            let cmd = c["command"].as_str().unwrap();
            assert!(cmd.starts_with("aepipe cwt "), "{cmd}");
            assert!(cmd.contains(&format!("--hit {hit} ")), "{cmd}");
        }
    }
    interaction(&v["interaction"], rows);
}

/// Geometry and interaction against the run's own values (the script reads them from the
/// tables with pyarrow, not from the page): points drawn where their values put them and the
/// axes labelled with the ranges those values give ([`geometry_problems`]), a drag zooming to
/// the dragged ranges, a Shift-drag selecting exactly the hits inside and every chart
/// highlighting them, each colouring's legend listing exactly the run's own classes, every
/// table the checks need present ([`legend_problems`]).
/// Plant: the page's axis ranges widened by 10 % (a script replacing the scatter's full view
/// before the measurement) must fail the geometry check; the SOM's classification table
/// treated as absent, and that absence with the SOM's colouring gone from the page too (once
/// a vacuous pass), must fail the legend check.
fn interaction(v: &serde_json::Value, rows: u64) {
    let bad = legend_problems(&v["missing"], &v["legends"]);
    assert!(bad.is_empty(), "{}\n{v}", bad.join("\n"));
    let planted = &v["planted_absent"];
    let found = legend_problems(&planted["missing"], &planted["legends"]);
    for want in [
        "the run has no som/classification.parquet",
        "the SOM class legend has nothing to be checked against",
    ] {
        assert!(
            found.iter().any(|b| b == want),
            "{want} not found: {found:?}"
        );
    }
    // A run without a SOM: no table and no colouring, nothing left that could disagree.
    let mut without_som = v["legends"].clone();
    without_som.as_object_mut().unwrap().remove("SOM class");
    let absent = serde_json::json!(["som/classification.parquet"]);
    let found = legend_problems(&absent, &without_som);
    assert!(
        found.contains(&"no SOM class colouring".to_string())
            && found.contains(&"the run has no som/classification.parquet".to_string()),
        "{found:?}"
    );
    let bad = geometry_problems(&v["geometry"]);
    assert!(bad.is_empty(), "{}\n{}", bad.join("\n"), v["geometry"]);
    let found = geometry_problems(&v["planted_wide_axes"]);
    for want in ["a point off its values", "a tick label off"] {
        assert!(
            found.iter().any(|b| b.starts_with(want)),
            "the 10 % wider axes passed ({want}): {found:?}"
        );
    }
    let f = |x: &serde_json::Value| x.as_f64().unwrap();
    // The drag's ends are whole CSS pixels the script converts back; the page's own rounding
    // of a mouse position is below a thousandth of the range.
    let z = &v["zoom"];
    for k in 0..4 {
        let (want, got) = (f(&z["expected"][k]), f(&z["view"][k]));
        let span = (f(&z["expected"][k | 1]) - f(&z["expected"][k & 2])).abs();
        assert!(
            (want - got).abs() <= 1e-3 * span,
            "zoom {k}: {got} for {want}: {z}"
        );
    }
    let s = &v["selection"];
    let (want, got) = (
        s["expected"].as_array().unwrap(),
        s["selected"].as_array().unwrap(),
    );
    assert!(!want.is_empty() && (want.len() as u64) < rows, "{s}");
    assert_eq!(got, want, "the Shift-drag selected other hits");
    assert_eq!(s["said"], format!("{} points selected", want.len()));
    assert_eq!(s["grey_seen"], true, "the unselected are not faded: {s}");
    let coloured = |c: &serde_json::Value| {
        let h = c.as_str().unwrap();
        let ch: Vec<i64> = (0..3)
            .map(|k| i64::from_str_radix(&h[1 + 2 * k..3 + 2 * k], 16).unwrap())
            .collect();
        ch.iter().max().unwrap() - ch.iter().min().unwrap() > 60
    };
    let hl = s["highlighted"].as_array().unwrap();
    assert!(!hl.is_empty(), "{s}");
    for h in hl {
        assert!(
            h["colours"].as_array().unwrap().iter().any(coloured),
            "a selected hit not highlighted over the test: {h}"
        );
    }
}

/// What is wrong with one measurement of the scatter's geometry: each measured hit (those at
/// the ends of both axes among them) must be drawn within half a pixel of where its values
/// put it — the frame the page drew mapped onto the axis ranges derived from the table (the
/// data's extent padded 3 % in x, 5 % in y) — with ink there, and the five tick labels of
/// each axis must be those ranges' ticks to the labels' three figures.
fn geometry_problems(g: &serde_json::Value) -> Vec<String> {
    let mut bad = Vec::new();
    let Some(placed) = g["placed"].as_array() else {
        return vec![format!("no geometry measured: {g}")];
    };
    if placed.len() < 5 {
        bad.push(format!("only {} points measured", placed.len()));
    }
    let f = |x: &serde_json::Value| x.as_f64();
    for p in placed {
        for k in 0..2 {
            match (f(&p["expected"][k]), f(&p["chart"][k])) {
                (Some(want), Some(drawn)) if (want - drawn).abs() <= 0.5 => {}
                _ => bad.push(format!("a point off its values: {p}")),
            }
        }
        if p["ink"].as_array().is_none_or(|i| i.is_empty()) {
            bad.push(format!("nothing drawn where a point's values put it: {p}"));
        }
    }
    for (axis, lo) in [("x", 0), ("y", 2)] {
        let (Some(a), Some(b)) = (f(&g["full"][lo]), f(&g["full"][lo + 1])) else {
            bad.push(format!("no {axis} range derived: {g}"));
            continue;
        };
        let labels: Vec<f64> = g["ticks"][axis]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(|t| t.as_str()?.parse().ok())
            .collect();
        if labels.len() != 5 {
            bad.push(format!("a tick label off: {axis} has {labels:?}"));
            continue;
        }
        for (k, label) in labels.iter().enumerate() {
            let want = a + (b - a) * k as f64 / 4.0;
            // explore.js's fmt: three figures, or two in exponent form below 1e-3 and from 1e5.
            let m = want.abs();
            let figures = if m != 0.0 && !(1e-3..1e5).contains(&m) {
                2
            } else {
                3
            };
            // (A tick at zero is rounding noise either side: a billionth of the range.)
            let tol = if m <= 1e-9 * (b - a).abs() {
                1e-9 * (b - a).abs()
            } else {
                0.5 * 10f64.powf(m.log10().floor() - (figures - 1) as f64) * (1.0 + 1e-6)
            };
            if (label - want).abs() > tol {
                bad.push(format!(
                    "a tick label off: {axis} tick {k} reads {label}, the values give {want}"
                ));
            }
        }
    }
    bad
}

/// What is wrong with the legends against the run's tables: a table the checks need that is
/// missing, a colouring the run must offer (SOM class, cluster, zone) that is not offered, a
/// legend with no table to check it against or whose tables hold no class, a legend that does
/// not list exactly its tables' classes.
fn legend_problems(missing: &serde_json::Value, legends: &serde_json::Value) -> Vec<String> {
    let mut bad: Vec<String> = match missing.as_array() {
        Some(m) => m
            .iter()
            .map(|t| format!("the run has no {}", t.as_str().unwrap_or("?")))
            .collect(),
        None => vec![format!("no list of missing tables: {missing}")],
    };
    let Some(legends) = legends.as_object() else {
        bad.push(format!("no legends: {legends}"));
        return bad;
    };
    for want in ["SOM class", "cluster", "zone"] {
        if !legends.contains_key(want) {
            bad.push(format!("no {want} colouring"));
        }
    }
    for (name, l) in legends {
        match l["expected"].as_array() {
            None => bad.push(format!(
                "the {name} legend has nothing to be checked against"
            )),
            Some(e) if e.is_empty() => bad.push(format!("the run's tables hold no {name} class")),
            Some(_) if l["legend"] != l["expected"] => bad.push(format!(
                "the {name} legend lists {}, the tables {}",
                l["legend"], l["expected"]
            )),
            Some(_) => {}
        }
    }
    bad
}
