//! The real Vallen sets cut short: the page walk's count always, vallenae's reading where
//! vallenae is installed.

use super::walk::Walk;
use super::{by_key, damaged, salvage_matches, walk};
use crate::{read_all, real_data, TempDir};
use aepipe::model::AeRecord;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

type Records = BTreeMap<(u32, u64), AeRecord>;

/// Each salvaged transient equals vallenae's reading of the intact `.tradb` (by channel and
/// TRAI): its sample count, first and last 32 samples, and the sum and sum of squares of
/// all of them (vallenae's float64 volts against aepipe's float32: to 1e-6 of the largest).
/// `Err` names the first that differs.
fn vallenae_matches(got: &Records, vallenae: &serde_json::Value) -> Result<(), String> {
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
            .ok_or_else(|| format!("vallenae has no {k:?}"))?;
        let s = &r.samples;
        if s.len() as u64 != v["n"].as_u64().unwrap() {
            return Err(format!("{k:?}: {} samples, vallenae {}", s.len(), v["n"]));
        }
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
            if !close(f64::from(*a), f(b), big) {
                return Err(format!("{k:?}: sample {a}, vallenae {b}"));
            }
        }
        let sum: f64 = s.iter().map(|x| f64::from(*x)).sum();
        let sumsq: f64 = s.iter().map(|x| f64::from(*x).powi(2)).sum();
        if !close(sum, f(&v["sum"]), big * s.len() as f64) {
            return Err(format!("{k:?}: sum {sum}, vallenae {}", v["sum"]));
        }
        if !close(sumsq, f(&v["sumsq"]), big * big * s.len() as f64) {
            return Err(format!(
                "{k:?}: sum of squares {sumsq}, vallenae {}",
                v["sumsq"]
            ));
        }
    }
    Ok(())
}

/// One real set: its intact reading, the page walk of its `.tradb`, and SetID → TRAI (one
/// acquisition: the TRAI is aepipe's hit number).
struct RealSet {
    src: std::path::PathBuf,
    id: String,
    walk: Walk,
    intact: Records,
    trai: BTreeMap<i64, u64>,
}

impl RealSet {
    fn open(src: &Path, id: &str, t: &TempDir) -> RealSet {
        let tradb = src.join(format!("{id}.tradb"));
        let only = t.path().join(format!("{id}-intact"));
        let d = damaged(src, &only, id, |_| {});
        let (recs, _) = read_all(&[d], &aepipe::config::ValidConfig::default());
        let trai = rusqlite::Connection::open(&tradb)
            .unwrap()
            .prepare("SELECT SetID, TRAI FROM tr_data")
            .unwrap()
            .query_map([], |r| Ok((r.get(0)?, r.get::<_, i64>(1)? as u64)))
            .unwrap()
            .map(Result::unwrap)
            .collect();
        RealSet {
            src: src.to_path_buf(),
            id: id.to_string(),
            walk: walk(&tradb),
            intact: by_key(recs),
            trai,
        }
    }

    /// The `.tradb` cut at `pct` % into `t`, read back and checked against the records
    /// `walk` finds whole before the cut ([`salvage_matches`]) — with no Python at all —
    /// and, when `vallenae` is given, against vallenae's reading of the intact file. The
    /// salvaged records.
    fn cut(
        &self,
        pct: usize,
        walk: &Walk,
        vallenae: Option<&serde_json::Value>,
        t: &TempDir,
    ) -> Result<Records, String> {
        let tradb = self.src.join(format!("{}.tradb", self.id));
        let cut = std::fs::metadata(&tradb).unwrap().len() as usize * pct / 100;
        let whole = (cut / walk.page) as u64;
        let expect: BTreeSet<u64> = walk
            .records
            .iter()
            .filter(|(_, pages)| pages.iter().all(|p| *p <= whole))
            .map(|(r, _)| self.trai[r])
            .collect();
        let to = t.path().join(format!("{}-{pct}", self.id));
        let d = damaged(&self.src, &to, &self.id, |b| b.truncate(cut));
        let (recs, _) = read_all(&[d], &aepipe::config::ValidConfig::default());
        let got = salvage_matches(recs, &self.intact, &expect)?;
        if let Some(v) = vallenae {
            vallenae_matches(&got, v).map_err(|e| format!("against vallenae: {e}"))?;
        }
        Ok(got)
    }
}

/// The real Vallen sets cut at 30, 60 and 90 %: the salvaged transients are exactly the
/// records the page walk finds whole, each equal to the intact file's (as aepipe reads it)
/// and, where vallenae is installed, to vallenae's reading; without vallenae the page-walk
/// checks still run (and `AEPIPE_REQUIRE_ALL=1` fails the test). Plant: `sample.tradb` cut
/// at 90 %, checked without vallenae against a walk that puts one whole record on a page
/// past the cut, is rejected; and a vallenae reading with one record's first sample moved by 1 V is
/// rejected by the vallenae comparison.
#[test]
fn the_real_tradbs_cut_short_give_back_what_their_pages_hold() {
    let name = "the_real_tradbs_cut_short_give_back_what_their_pages_hold";
    let Some(real) = real_data(name) else {
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
        let set = RealSet::open(&real.join(dir), id, &t);
        let tradb = set.src.join(format!("{id}.tradb"));
        let vallenae: Option<serde_json::Value> =
            crate::vendor::python(name, "vallenae_tradb.py", &[&tradb])
                .map(|s| serde_json::from_str(&s).unwrap());
        for pct in [30, 60, 90] {
            let got = set
                .cut(pct, &set.walk, vallenae.as_ref(), &t)
                .unwrap_or_else(|e| panic!("{id} cut at {pct} %: {e}"));
            report.push(format!(
                "{id} {pct} %: {} of {}{}",
                got.len(),
                set.walk.records.len(),
                if vallenae.is_some() {
                    ", as vallenae reads them"
                } else {
                    ", vallenae not compared"
                }
            ));
            if id == "sample" && pct == 90 {
                plant(&set, &got, vallenae.as_ref(), &t);
            }
        }
    }
    eprintln!("salvaged: {}", report.join("; "));
}

/// The plants of [`the_real_tradbs_cut_short_give_back_what_their_pages_hold`] on `set` cut
/// at 90 % (`got`: what its check passed).
fn plant(set: &RealSet, got: &Records, vallenae: Option<&serde_json::Value>, t: &TempDir) {
    let (key, _) = got
        .iter()
        .next()
        .expect("sample.tradb at 90 % salvages a record");
    let setid = *set.trai.iter().find(|(_, h)| **h == key.1).unwrap().0;
    let past = set.walk.records.values().flatten().max().unwrap() + 1;
    let mut wrong = set.walk.clone();
    wrong.records.get_mut(&setid).unwrap().push(past);
    assert!(
        set.cut(90, &wrong, None, t).is_err(),
        "a walk that loses TRAI {} passes the check without vallenae",
        key.1
    );
    if let Some(v) = vallenae {
        let mut v = v.clone();
        let rec = v
            .as_array_mut()
            .unwrap()
            .iter_mut()
            .find(|r| {
                r["trai"].as_u64() == Some(key.1) && r["channel"].as_u64() == Some(key.0 as u64)
            })
            .unwrap();
        rec["first"][0] = serde_json::json!(rec["first"][0].as_f64().unwrap() + 1.0);
        assert!(
            vallenae_matches(got, &v).is_err(),
            "a vallenae reading with TRAI {}'s first sample moved by 1 V passes",
            key.1
        );
    }
}
