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
}
