//! The real Vallen sets cut short.

use super::{assert_salvaged, by_key, damaged, walk};
use crate::{read_all, real_data, TempDir};
use aepipe::model::AeRecord;
use std::collections::{BTreeMap, BTreeSet};

/// Each salvaged transient equals vallenae's reading of the intact `.tradb` (by channel and
/// TRAI): its sample count, first and last 32 samples, and the sum and sum of squares of
/// all of them (vallenae's float64 volts against aepipe's float32: to 1e-6 of the largest).
fn assert_as_vallenae_reads(
    got: &BTreeMap<(u32, u64), AeRecord>,
    vallenae: &serde_json::Value,
    what: &str,
) {
    let theirs: BTreeMap<(u32, u64), &serde_json::Value> = vallenae
        .as_array()
        .unwrap()
        .iter()
        .map(|v| {
            let n = |k: &str| v[k].as_u64().unwrap();
            ((n("channel") as u32, n("trai")), v)
        })
        .collect();
    let f = |v: &serde_json::Value| v.as_f64().unwrap();
    for (k, r) in got {
        let v = theirs
            .get(k)
            .unwrap_or_else(|| panic!("{what}: vallenae has no {k:?}"));
        let s = &r.samples;
        assert_eq!(
            s.len() as u64,
            v["n"].as_u64().unwrap(),
            "{what}: {k:?} samples"
        );
        let big = s.iter().fold(1e-12f64, |m, x| m.max(f64::from(x.abs())));
        let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-6 * scale;
        let ends = s
            .iter()
            .take(32)
            .chain(s.iter().skip(s.len().saturating_sub(32)));
        let want = v["first"]
            .as_array()
            .unwrap()
            .iter()
            .chain(v["last"].as_array().unwrap());
        for (a, b) in ends.zip(want) {
            assert!(close(f64::from(*a), f(b), big), "{what}: {k:?}: {a} vs {b}");
        }
        let sum: f64 = s.iter().map(|x| f64::from(*x)).sum();
        let sumsq: f64 = s.iter().map(|x| f64::from(*x).powi(2)).sum();
        assert!(
            close(sum, f(&v["sum"]), big * s.len() as f64),
            "{what}: {k:?} sum"
        );
        assert!(
            close(sumsq, f(&v["sumsq"]), big * big * s.len() as f64),
            "{what}: {k:?} sum of squares"
        );
    }
}

/// The real Vallen sets cut at 30, 60 and 90 %: the salvaged transients equal the intact
/// file's (as aepipe reads it — equal to vallenae's, `vendor::vallenae_reads_the_same`), and
/// their number is the page walk's count of records whose pages survived.
#[test]
fn the_real_tradbs_cut_short_give_back_what_their_pages_hold() {
    let Some(real) = real_data("the_real_tradbs_cut_short_give_back_what_their_pages_hold") else {
        return;
    };
    let t = TempDir::new("salvage-real");
    let mut report = Vec::new();
    for (dir, id) in [
        ("vallen/bearing", "bearing"),
        ("vallen/steel_plate", "sample"),
        ("vallen/steel_plate", "sample_plain"),
        ("plb_cfrp_vallen", "PLBS4_CP090_PCLO1"),
    ] {
        let src = real.join(dir);
        let tradb = src.join(format!("{id}.tradb"));
        let walk = walk(&tradb);
        let Some(vallenae) = crate::vendor::python(
            "the real tradbs cut short, against vallenae",
            "vallenae_tradb.py",
            &[&tradb],
        ) else {
            return;
        };
        let vallenae: serde_json::Value = serde_json::from_str(&vallenae).unwrap();
        let only = t.path().join(format!("{id}-intact"));
        let d = damaged(&src, &only, id, |_| {});
        let (recs, _) = read_all(&[d], &aepipe::config::ValidConfig::default());
        let intact = by_key(recs);
        // SetID → the hit of its record in aepipe's numbering (TRAI here: one acquisition).
        let trai: BTreeMap<i64, u64> = rusqlite::Connection::open(&tradb)
            .unwrap()
            .prepare("SELECT SetID, TRAI FROM tr_data")
            .unwrap()
            .query_map([], |r| Ok((r.get(0)?, r.get::<_, i64>(1)? as u64)))
            .unwrap()
            .map(Result::unwrap)
            .collect();
        let len = std::fs::metadata(&tradb).unwrap().len() as usize;
        for pct in [30, 60, 90] {
            let cut = len * pct / 100;
            let whole = (cut / walk.page) as u64;
            let expect: BTreeSet<u64> = walk
                .records
                .iter()
                .filter(|(_, pages)| pages.iter().all(|p| *p <= whole))
                .map(|(r, _)| trai[r])
                .collect();
            let d = damaged(&src, &t.path().join(format!("{id}-{pct}")), id, |b| {
                b.truncate(cut)
            });
            let what = format!("{id} cut at {pct} %");
            let got = assert_salvaged(&d, &intact, &expect, &what);
            assert_as_vallenae_reads(&got, &vallenae, &what);
            report.push(format!(
                "{id} {pct} %: {} of {}",
                expect.len(),
                walk.records.len()
            ));
        }
    }
    eprintln!("salvaged: {}", report.join("; "));
}
