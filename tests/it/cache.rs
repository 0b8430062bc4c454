//! Issue 52 item 5: the reference map made once. A second run with the same settings reuses
//! the cached map (and classifies byte for byte as the first), a changed `[som]` key makes a
//! new one, a corrupted entry is made again with a note and never used, and `--no-cache`
//! trains anew. On the real AEwin test (EXP2009), in a cache of the test's own.

use crate::{aepipe_with_cache, real_data, TempDir};

/// The map's cache key the run's `stages:` line names, and whether it was reused.
fn stage_cache(so: &str) -> Option<(String, bool)> {
    let l = so.lines().find(|l| l.starts_with("stages: "))?;
    if let Some((_, r)) = l.split_once("cached map ") {
        return Some((r.split([',', ' ']).next()?.to_string(), true));
    }
    let (_, r) = l.split_once(", map ")?;
    let (key, rest) = r.split_once(' ')?;
    rest.starts_with("made and cached")
        .then(|| (key.to_string(), false))
}

#[test]
fn the_map_is_made_once_per_settings_and_a_broken_entry_is_made_again() {
    let Some(real) = real_data("the_map_is_made_once_per_settings") else {
        return;
    };
    let t = TempDir::new("map-cache");
    let cache = t.path().join("cache");
    let data = real.join("aewin_cfrp_tensile");
    let cfg = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/aewin-cfrp.toml");
    let run = |out: &str, cfg: &std::path::Path, extra: &[&str]| {
        let o = t.path().join(out);
        let mut a = vec![
            "run",
            "--config",
            cfg.to_str().unwrap(),
            "--out",
            o.to_str().unwrap(),
            data.to_str().unwrap(),
        ];
        a.extend_from_slice(extra);
        let (code, so, se) = aepipe_with_cache(&a, &cache);
        assert_eq!(code, 0, "{so}{se}");
        let class = std::fs::read(o.join("som/classification.parquet")).unwrap();
        (so, se, class)
    };
    let (so1, _, c1) = run("r1", &cfg, &[]);
    let (k1, reused) = stage_cache(&so1).unwrap_or_else(|| panic!("no cache in:\n{so1}"));
    assert!(!reused, "a fresh cache reused {k1}:\n{so1}");
    // The second run reuses it: same key, same classes, and the run's JSON names the key.
    let (so2, _, c2) = run("r2", &cfg, &[]);
    assert_eq!(stage_cache(&so2), Some((k1.clone(), true)), "{so2}");
    assert_eq!(c1, c2, "the cached map classifies otherwise");
    let json = std::fs::read_to_string(t.path().join("r2/run.json")).unwrap();
    assert!(json.contains(&k1), "run.json does not name the map {k1}");
    // A changed [som] key makes a new map under a new key.
    let text = std::fs::read_to_string(&cfg).unwrap();
    let changed = t.path().join("changed.toml");
    std::fs::write(&changed, format!("{text}\n[som]\nseed = 8\n")).unwrap();
    let (so3, _, _) = run("r3", &changed, &[]);
    let (k3, reused3) = stage_cache(&so3).unwrap_or_else(|| panic!("{so3}"));
    assert!(!reused3 && k3 != k1, "{so3}");
    // A corrupted entry (one byte of the codebook's JSON) is made again, with a note.
    let entry = cache.join("aepipe/som-map").join(&k1);
    let json = entry.join("model.json");
    let mut b = std::fs::read(&json).unwrap();
    let i = b.iter().position(|c| c.is_ascii_digit()).unwrap();
    b[i] = if b[i] == b'9' { b'8' } else { b[i] + 1 };
    std::fs::write(&json, &b).unwrap();
    let (so4, se4, c4) = run("r4", &cfg, &[]);
    assert!(
        se4.contains("model.json fails its checksum") && se4.contains("made again"),
        "{se4}"
    );
    assert_eq!(stage_cache(&so4), Some((k1.clone(), false)), "{so4}");
    assert_eq!(c1, c4);
    // --no-cache trains and names no cache.
    let (so5, _, c5) = run("r5", &cfg, &["--no-cache"]);
    assert_eq!(stage_cache(&so5), None, "{so5}");
    assert_eq!(c1, c5);
}
