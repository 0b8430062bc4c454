//! Measurement chains and the leave-one-family-out table: a test heard through a chain, and
//! `aepipe bench transfer` at a cheap scale, its cells checked against the goals and its
//! criteria columns recomputed here from the written tables.

use crate::{aepipe_ok, table_rows, TempDir};
use std::collections::BTreeMap;
use std::path::Path;

/// Median of the non-null values of `column` in `table`.
fn median(table: &Path, column: &str) -> f64 {
    let (names, rows) = table_rows(table);
    let c = names.iter().position(|n| n == column).unwrap();
    let mut v: Vec<f64> = rows.iter().filter_map(|r| r[c].parse().ok()).collect();
    assert!(!v.is_empty(), "no {column} in {}", table.display());
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// A test heard through the 150 kHz resonant sensor keeps its hits' peak frequencies at the
/// library's own lines (above 200 kHz: the plane bond failure's 250 kHz fundamental; a
/// narrowband ring is not moved by a q = 3 resonance 100 kHz away), but the balance of its
/// spectrum moves by the chain's gain: see below. (The test first asked for the peaks at
/// 150 kHz; measured, the resonant median peak was 232 kHz against the flat 239 kHz.) `--chain flat` is the flat
/// recording itself: the same hits and truth as no `--chain`. An unknown chain is a usage
/// error (exit 1) naming the file's chains.
#[test]
fn a_test_heard_through_a_resonant_sensor_has_its_spectrum_weighted_by_the_sensor() {
    let d = TempDir::new("chain-synth");
    let lib = crate::e2e::small_library_seeded(d.path(), "lib", 2008, 1);
    let lib = lib.to_str().unwrap();
    let run = |name: &str, chain: Option<&str>| -> (String, std::path::PathBuf) {
        let out = d.path().join(name);
        let o = out.to_str().unwrap();
        let mut args = vec![
            "synth-experiment",
            "--out",
            o,
            "--hits",
            "80",
            "--seed",
            "31",
            "--library",
            lib,
        ];
        if let Some(c) = chain {
            args.extend(["--chain", c]);
        }
        let said = aepipe_ok(&args);
        let feats = out.join("features");
        aepipe_ok(&[
            "features",
            out.join("data").to_str().unwrap(),
            "--out",
            feats.to_str().unwrap(),
            "--quiet",
        ]);
        (said, feats.join("features.parquet"))
    };
    let (said_none, none) = run("none", None);
    let (said_flat, flat) = run("flat", Some("flat"));
    let (said_r, resonant) = run("resonant", Some("resonant-150k"));
    assert!(
        said_r.contains("heard through the resonant-150k chain"),
        "{said_r}"
    );
    // The flat chain changes nothing.
    let hits = |s: &str| {
        s.split(" hits")
            .next()
            .unwrap()
            .rsplit(' ')
            .next()
            .unwrap()
            .to_string()
    };
    assert_eq!(
        hits(&said_none),
        hits(&said_flat),
        "{said_none}\n{said_flat}"
    );
    let rows =
        |p: &Path| table_rows(&p.parent().unwrap().parent().unwrap().join("truth.parquet")).1;
    assert_eq!(rows(&none), rows(&flat));
    let col = "peak_freq_hz";
    let f = median(&none, col);
    assert_eq!(f, median(&flat, col));
    // A narrowband ring keeps its line: the peak stays at the library's own.
    let r = median(&resonant, col);
    assert!(f > 200e3, "flat median peak {f} Hz");
    assert!(
        (r - f).abs() <= 30e3,
        "resonant median peak {r} Hz (flat {f} Hz)"
    );
    // What the sensor changes is the balance between its resonance and the bond wave's
    // 750 kHz harmonic: each hit's 100–200 kHz over 700–800 kHz power, through the chain,
    // is the flat one's times G, the ratio of the chain's mean power gain over the two
    // bands (exactly so for a noise-free record whose spectrum is flat within each band).
    // The medians over the hits are held to G within a factor 3 either way: the bands'
    // own spectral shapes and the sensor noise added after the chain move it.
    let chain = aepipe::sim::chain::ChainFile::shipped()
        .get("resonant-150k")
        .unwrap()
        .check(aepipe::synth::SAMPLE_RATE_HZ)
        .unwrap();
    let band_gain = |lo: f64| -> f64 {
        (0..100)
            .map(|k| chain.gain(lo + (k as f64 + 0.5) * 1e3).powi(2))
            .sum::<f64>()
            / 100.0
    };
    let g = band_gain(100e3) / band_gain(700e3);
    let balance = |p: &Path| -> f64 {
        let (names, rows) = table_rows(p);
        let k = |c: &str| names.iter().position(|n| n == c).unwrap();
        let (lo, hi) = (k("pr_100_200khz"), k("pr_700_800khz"));
        let mut v: Vec<f64> = rows
            .iter()
            .filter_map(|r| Some(r[lo].parse::<f64>().ok()? / r[hi].parse::<f64>().ok()?))
            .filter(|x| x.is_finite())
            .collect();
        assert!(
            v.len() >= 40,
            "{} hits with both bands in {}",
            v.len(),
            p.display()
        );
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let moved = balance(&resonant) / balance(&flat);
    println!("100–200 over 700–800 kHz: × {moved:.1} through the chain; G = {g:.1}");
    assert!(g > 10.0, "the chain's band gain ratio {g}");
    assert!(
        moved >= g / 3.0 && moved <= 3.0 * g,
        "× {moved} against G = {g}"
    );
    let (code, _, err) = crate::aepipe(&[
        "synth-experiment",
        "--out",
        d.path().join("x").to_str().unwrap(),
        "--library",
        lib,
        "--chain",
        "r15",
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("no chain named r15") && err.contains("resonant-150k"),
        "{err}"
    );
}

type HitKey = (String, String, String);

/// `column` of each (experiment, channel, hit) of a table.
fn labels(path: &Path, column: &str) -> BTreeMap<HitKey, String> {
    let (n, rows) = table_rows(path);
    let k = |c: &str| n.iter().position(|x| x == c).unwrap();
    let (e, c, h, m) = (k("experiment"), k("channel"), k("hit"), k(column));
    rows.iter()
        .map(|r| ((r[e].clone(), r[c].clone(), r[h].clone()), r[m].clone()))
        .collect()
}

/// Per true mechanism (bond, fibre): (labelled it, held), over the hits `within` holds;
/// and how many of those bond and fibre failures are labelled unlike_references.
fn recalls(
    truth: &BTreeMap<HitKey, String>,
    label: &BTreeMap<HitKey, String>,
    within: &BTreeMap<HitKey, String>,
) -> (BTreeMap<&'static str, (usize, usize)>, usize) {
    let mut rec: BTreeMap<&'static str, (usize, usize)> = BTreeMap::new();
    let mut novel = 0;
    for key in within.keys() {
        let (Some(m), Some(l)) = (truth.get(key), label.get(key)) else {
            continue;
        };
        for mech in ["bond_failure", "fibre_failure"] {
            if m == mech {
                let e = rec.entry(mech).or_default();
                e.1 += 1;
                e.0 += usize::from(l == mech);
                novel += usize::from(l == "unlike_references");
            }
        }
    }
    (rec, novel)
}

/// `aepipe bench transfer` at a cheap scale: 120 sources a test, one evaluation seed
/// (7401, written here before the first run), libraries of one material draw per grid point.
/// Every cell is there (2 families × 3 chains), each against the runs' own tables:
/// The map's recalls and novel share are recomputed from each run's classification table,
/// the criteria label's from its features table on the same hits.
///
/// The goals the transfer work asks of every cell are balanced accuracy ≥ 90 %, bond and
/// fibre recall ≥ 85 % and ≤ 5 % of true mechanisms called novel. Today's maps do not reach
/// them across families (docs/fidelity.md, "Leave one family out"): this test prints which
/// cells meet them and asserts none, so that it cannot be passed by a bound chosen after
/// the result. Its assertions are the table's truth, not the classes' quality.
#[test]
fn the_leave_one_family_out_table_at_a_cheap_scale() {
    let d = TempDir::new("transfer");
    let out = d.path().join("t");
    let said = aepipe_ok(&[
        "bench",
        "transfer",
        "--out",
        out.to_str().unwrap(),
        "--hits",
        "120",
        "--seeds",
        "7401",
        "--train-variants",
        "1",
        "--test-variants",
        "1",
    ]);
    println!("{said}");
    let table = out.join("transfer.parquet");
    crate::pipeline::check_against_schema_file(&table, "transfer.md");
    let (names, rows) = table_rows(&table);
    let k = |c: &str| names.iter().position(|x| x == c).unwrap();
    assert_eq!(rows.len(), 6, "{rows:?}");
    let cells: Vec<(String, String)> = rows
        .iter()
        .map(|r| (r[k("family")].clone(), r[k("chain")].clone()))
        .collect();
    for fam in ["plane", "3d"] {
        for chain in ["flat", "resonant-150k", "wideband-650k"] {
            assert!(cells.contains(&(fam.into(), chain.into())), "{cells:?}");
        }
    }
    let num = |r: &Vec<String>, c: &str| -> f64 { r[k(c)].parse().unwrap_or(f64::NAN) };
    for r in &rows {
        let (fam, chain) = (&r[k("family")], &r[k("chain")]);
        assert_eq!(
            r[k("trained_on")],
            if fam == "plane" { "3d" } else { "plane" }
        );
        // The map's columns from the cell's classification table, the criteria's from its
        // features table on the same hits (those the map classified).
        let dir = out
            .join(format!("{fam}-left-out"))
            .join(format!("{chain}-7401"));
        let truth = labels(&dir.join("truth.parquet"), "mechanism");
        let som = labels(&dir.join("run/som/classification.parquet"), "som_label");
        let criteria = labels(&dir.join("run/features/features.parquet"), "criteria_label");
        let (map, novel) = recalls(&truth, &som, &som);
        let (rec, _) = recalls(&truth, &criteria, &som);
        let bf = map.values().map(|v| v.1).sum::<usize>();
        for (prefix, tally) in [("", &map), ("criteria_", &rec)] {
            for (col, m) in [
                ("bond_recall", "bond_failure"),
                ("fibre_recall", "fibre_failure"),
            ] {
                let want = tally[m].0 as f64 / tally[m].1 as f64;
                let col = format!("{prefix}{col}");
                assert!(
                    (num(r, &col) - want).abs() < 1e-12,
                    "{fam} {chain} {col}: {} vs {want}",
                    num(r, &col),
                );
            }
        }
        assert!(
            (num(r, "novel_share") - novel as f64 / bf as f64).abs() < 1e-12,
            "{fam} {chain}"
        );
        assert_eq!(num(r, "bond_fibre_hits"), bf as f64);
        let bal = num(r, "balanced_accuracy");
        let goal = bal >= 0.90
            && num(r, "bond_recall") >= 0.85
            && num(r, "fibre_recall") >= 0.85
            && num(r, "novel_share") <= 0.05;
        println!(
            "{fam} left out, {chain}: balanced {bal:.3}, goal {}",
            if goal { "met" } else { "not met" }
        );
        assert_eq!(
            num(r, "balanced_accuracy"),
            (num(r, "bond_recall") + num(r, "fibre_recall")) / 2.0
        );
        assert!(num(r, "bond_fibre_hits") >= 40.0, "{fam} {chain}: {r:?}");
    }
}
