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
    // 150 sources heard by two sensors: 300 feature rows, all of them points.
    assert_eq!(charts[1]["points"], 300, "{v}");
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
    interaction(&v["interaction"]);
}

/// Geometry and interaction against the run's own values (the script reads them from the
/// tables, not from the page): points drawn where their values put them, a drag zooming to
/// the dragged ranges, a Shift-drag selecting exactly the hits inside and every chart
/// highlighting them, each colouring's legend listing the run's own classes.
fn interaction(v: &serde_json::Value) {
    let f = |x: &serde_json::Value| x.as_f64().unwrap();
    let placed = v["placed"].as_array().unwrap();
    assert!(placed.len() >= 5, "{v}");
    for p in placed {
        for k in 0..2 {
            let (want, drawn) = (f(&p["expected"][k]), f(&p["chart"][k]));
            assert!((want - drawn).abs() < 0.01, "a point off its values: {p}");
        }
        assert!(
            !p["ink"].as_array().unwrap().is_empty(),
            "nothing drawn there: {p}"
        );
    }
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
    assert!(!want.is_empty() && want.len() < 300, "{s}");
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
    let legends = v["legends"].as_object().unwrap();
    assert!(legends.len() >= 3, "{v}");
    for (name, l) in legends {
        assert_eq!(l["legend"], l["expected"], "the {name} legend");
    }
}
