//! `aepipe export trfdb` and `[export] trfdb`: what VisualAE would load, read back by an
//! independent reader. vallenae's `TrfDatabase` reads each written `.trfdb`; its rows are
//! compared, by TRAI, with the run's own tables read by pyarrow — the class codes decoded
//! through the class names aepipe declares, which the file's legends must equal, the
//! locations from events.parquet — on the real Vallen sets and on a synthetic test with
//! SOM classes, clusters and locations, where every field is compared unconditionally. The MISTRAS
//! chain gets a CSV keyed by aepipe's hit with the system's hit numbers from hits.parquet.

use crate::{aepipe, TempDir};
use std::path::Path;

/// vallenae's reading of `trfdb` against the run's tables in `run` for `experiment`: the
/// rows compared and the mismatches (empty when every value agrees), as JSON. With `full`
/// the run must have SOM classes, clusters and locations, and every field is compared
/// unconditionally. Codes are decoded through the class names aepipe declares (the
/// mechanisms, then unlike_references, then the run's map's other labels, sorted), which the
/// file's legends must equal. None after [`crate::skip`] when vallenae or pyarrow is absent.
fn compare(trfdb: &Path, run: &Path, experiment: &str, full: bool) -> Option<serde_json::Value> {
    let script = r#"
import json, math, os, sys
try:
    import vallenae as vae
    import pyarrow.parquet as pq
except ImportError as e:
    print(f"missing: {e}", file=sys.stderr)
    sys.exit(3)
trfdb, run, exp, full = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4] == "full"
with vae.io.TrfDatabase(trfdb) as t:
    df = t.read()
    info = t.fieldinfo()
    glob = t.globalinfo()
def table(p):
    return pq.read_table(p).to_pylist() if os.path.exists(p) else []
feats = [r for r in table(f"{run}/features/features.parquet") if r["experiment"] == exp]
key = lambda r: (r["channel"], r["hit"])
cls = {key(r): r for r in table(f"{run}/som/classification.parquet") if r["experiment"] == exp}
clu = {key(r): r for r in table(f"{run}/cluster/clusters.parquet") if r["experiment"] == exp}
ev = {r["event"]: r for r in table(f"{run}/features/events.parquet") if r["experiment"] == exp}
bad = []
# The codes as aepipe declares them (data-schema/trfdb.md): the mechanisms in order, then
# unlike_references, then any other label the run's map was trained on, sorted; the file's
# legends must say the same, and codes are decoded through these, not through the file.
MECH = ["bond_failure", "fibre_failure", "both", "erroneous", "unclassified"]
model = f"{run}/som/model/model.json"
trained = set(json.load(open(model))["som"]["labels"]) if os.path.exists(model) else set()
CLASSES = MECH + ["unlike_references"] + sorted(trained - set(MECH) - {"unlike_references"})
DECLARED = {"SOM_Class": CLASSES, "SOM_Node": CLASSES, "Criteria": MECH,
            "CrackMode": ["tensile", "shear"], "Zone": ["inside", "outside", "guard"]}
def legend(field):
    d = info[field]["Description"]
    return {float(k): v for k, v in (p.split(" = ") for p in d.split(": ", 1)[1].split("; "))}
for field, names in DECLARED.items():
    if field in info:
        want = {float(k + 1): n for k, n in enumerate(names)}
        if legend(field) != want:
            bad.append(f"{field}: the file's legend {legend(field)} is not aepipe's {want}")
if full:
    # A run with location, the SOM and clusters: every field must be there.
    for field in ["SOM_Class", "SOM_Node", "Novel", "QE", "Cluster", "X", "Y"]:
        if field not in info:
            bad.append(f"no {field} field")
    if not cls or not clu or not any(e.get("x_m") is not None for e in ev.values()):
        bad.append(f"the run lacks classes ({len(cls)}), clusters ({len(clu)}) or locations")
def same(what, trai, got, want):
    g = None if got is None or (isinstance(got, float) and math.isnan(got)) else got
    if (g is None) != (want is None) or (g is not None and not math.isclose(g, want, rel_tol=1e-12, abs_tol=1e-15)):
        bad.append(f"TRAI {trai} {what}: {got!r} vs {want!r}")
def decoded(what, trai, code, want):
    names = DECLARED[what]
    got = None if code != code else names[int(code) - 1] if 1 <= code <= len(names) else f"code {code}"
    if got != want:
        bad.append(f"TRAI {trai} {what}: {got!r} vs {want!r}")
ratios = [c for c in (feats[0].keys() if feats else []) if c.startswith("pr_") and c.endswith("khz")]
for f in feats:
    trai = f["hit"]
    if trai not in df.index:
        bad.append(f"TRAI {trai}: no row")
        continue
    row = df.loc[trai]
    # vallenae leaves out a column that is null in every row.
    r = {c: row.get(c, float("nan")) for c in info}
    same("RA", trai, r["RA"], f["ra_ms_per_v"])
    same("AF", trai, r["AF"], f["af_khz"])
    same("Event", trai, r["Event"], f["event"])
    decoded("Criteria", trai, r["Criteria"], f["criteria_label"])
    decoded("CrackMode", trai, r["CrackMode"], f["crack_mode"])
    decoded("Zone", trai, r["Zone"], f["zone"])
    for k, name in enumerate(ratios):
        same(f"PR{k+1:02d}", trai, r.get(f"PR{k+1:02d}", float("nan")), f[name])
    if full or cls:
        c = cls.get(key(f))
        decoded("SOM_Class", trai, r.get("SOM_Class", float("nan")), c and c["som_label"])
        decoded("SOM_Node", trai, r.get("SOM_Node", float("nan")), c and c["node_label"])
        same("Novel", trai, r.get("Novel", float("nan")), None if c is None or c["novel"] is None else float(c["novel"]))
        same("QE", trai, r.get("QE", float("nan")), c and c["quantization_error"])
    if full or clu:
        u = clu.get(key(f))
        same("Cluster", trai, r.get("Cluster", float("nan")), u and u["cluster"])
    if full or "X" in info:
        e = ev.get(f["event"])
        mm = lambda v: None if e is None or e.get(v) is None else e[v] * 1e3
        same("X", trai, r.get("X", float("nan")), mm("x_m"))
        same("Y", trai, r.get("Y", float("nan")), mm("y_m"))
print(json.dumps({
    "rows": len(df), "features": len(feats), "bad": bad[:20], "n_bad": len(bad),
    "ratios": len(ratios),
    "units": {k: v["Unit"] for k, v in info.items()},
    "reference_id": str(glob.get("ReferenceID", "")),
    "writer": str(glob.get("WriterID", "")), "valid_sets": glob.get("ValidSets"),
}))
"#;
    let o = crate::reference(
        "trfdb read back by vallenae",
        "pip install vallenae pyarrow",
        std::process::Command::new("python3")
            .args(["-c", script])
            .arg(trfdb)
            .arg(run)
            .arg(experiment)
            .arg(if full { "full" } else { "part" }),
    )?;
    Some(serde_json::from_slice(&o).unwrap())
}

/// The `.pridb`'s FileID, read with SQLite directly.
fn file_id(pridb: &Path) -> String {
    let c =
        rusqlite::Connection::open_with_flags(pridb, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
            .unwrap();
    c.query_row(
        "SELECT Value FROM ae_globalinfo WHERE Key = 'FileID'",
        [],
        |r| r.get::<_, String>(0),
    )
    .unwrap()
}

fn run(data: &Path, out: &Path, toml: &str) {
    let cfg = out.with_extension("toml");
    std::fs::write(&cfg, toml).unwrap();
    crate::aepipe_ok(&[
        "run",
        "--config",
        cfg.to_str().unwrap(),
        data.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
}

/// The real Vallen pairs run and exported: every transient with a feature row is a row
/// vallenae reads back with the run's values, the field info gives the units, the file
/// points at its `.pridb`, and the lab's own `sample.trfdb` beside the pair is untouched.
#[test]
fn the_real_vallen_sets_are_written_back_for_visualae() {
    let Some(real) = crate::real_data("the_real_vallen_sets_are_written_back_for_visualae") else {
        return;
    };
    let t = TempDir::new("trfdb-real");
    let lab = real.join("vallen/steel_plate/sample.trfdb");
    let before = std::fs::read(&lab).unwrap();
    for (set, exp) in [("steel_plate", "sample"), ("bearing", "bearing")] {
        let out = t.path().join(set);
        run(
            &real.join("vallen").join(set),
            &out,
            "[export]\ntrfdb = true\n",
        );
        let db = out.join("export").join(format!("{exp}.aepipe.trfdb"));
        assert!(db.is_file(), "{}", db.display());
        let Some(v) = compare(&db, &out, exp, false) else {
            return;
        };
        assert!(v["features"].as_u64().unwrap() > 0, "{v}");
        assert_eq!(v["rows"], v["features"], "{set}: one row per feature row");
        assert_eq!(v["valid_sets"], v["rows"], "{set}");
        assert!(
            v["bad"].as_array().unwrap().is_empty(),
            "{set}: {}",
            v["bad"]
        );
        assert_eq!(v["units"]["RA"], "[ms/V]");
        assert_eq!(v["units"]["PR01"], "[1]");
        assert!(v["writer"].as_str().unwrap().starts_with("aepipe "));
        let pridb = real.join("vallen").join(set).join(format!("{exp}.pridb"));
        assert_eq!(
            v["reference_id"].as_str().unwrap(),
            file_id(&pridb),
            "{set}"
        );
    }
    assert!(
        std::fs::read(&lab).unwrap() == before,
        "the lab's .trfdb changed"
    );
}

/// A synthetic test with two channels' events, clusters and the SOM: `aepipe export trfdb`
/// writes what `[export] trfdb` wrote, refuses to replace it without `--force` (exit 1,
/// the file unchanged), and replaces it with `--force`.
#[test]
fn a_run_with_clusters_and_events_exports_and_an_export_is_replaced_only_when_forced() {
    let t = TempDir::new("trfdb-synth");
    let data = t.path().join("data");
    let (code, said, err) = aepipe(&[
        "synth-experiment",
        "--out",
        data.to_str().unwrap(),
        "--hits",
        "120",
    ]);
    assert_eq!(code, 0, "{said}\n{err}");
    let out = t.path().join("run");
    run(
        &data.join("data"),
        &out,
        "[export]\ntrfdb = true\n\n[cluster]\nenabled = true\nk_min = 2\nk_max = 3\n\n\
         [location]\nkind = \"linear\"\nvelocity_m_s = 2700.0\n\
         sensors = { 1 = [-0.020], 2 = [0.020] }\nzone = [-0.015, 0.015]\n",
    );
    let exported = out.join("export");
    let dbs: Vec<_> = std::fs::read_dir(&exported)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .collect();
    assert_eq!(dbs.len(), 1, "{dbs:?}");
    let db = &dbs[0];
    let exp = db
        .file_name()
        .unwrap()
        .to_str()
        .unwrap()
        .trim_end_matches(".aepipe.trfdb")
        .to_string();
    let Some(v) = compare(db, &out, &exp, true) else {
        return;
    };
    assert_eq!(v["rows"], v["features"], "{v}");
    assert!(v["bad"].as_array().unwrap().is_empty(), "{}", v["bad"]);
    assert!(v["units"].get("Cluster").is_some(), "{v}");
    assert!(v["units"].get("SOM_Class").is_some(), "{v}");
    assert_eq!(v["units"]["X"], "[mm]", "{v}");
    assert!(v["ratios"].as_u64().unwrap() >= 25, "{v}");
    // The comparison can fail: a copy with one location moved, one SOM code changed and the
    // SOM legend's first two names swapped is caught on each count.
    let planted = t.path().join("planted.trfdb");
    std::fs::copy(db, &planted).unwrap();
    let c = rusqlite::Connection::open(&planted).unwrap();
    c.execute_batch(
        "UPDATE trf_data SET X = X + 1.0 WHERE TRAI = (SELECT min(TRAI) FROM trf_data WHERE X IS NOT NULL);
         UPDATE trf_data SET SOM_Class = SOM_Class + 1 WHERE TRAI = (SELECT max(TRAI) FROM trf_data WHERE SOM_Class IS NOT NULL);
         UPDATE trf_fieldinfo SET Description = replace(replace(replace(Description, '1 = bond_failure', '1 = X'), '2 = fibre_failure', '2 = bond_failure'), '1 = X', '1 = fibre_failure') WHERE field = 'SOM_Node';",
    )
    .unwrap();
    drop(c);
    let p = compare(&planted, &out, &exp, true).unwrap();
    let bad = p["bad"].to_string();
    for want in [" X: ", " SOM_Class: ", "SOM_Node: the file's legend"] {
        assert!(
            bad.contains(want),
            "the planted {want:?} was not caught: {bad}"
        );
    }

    // Again into the same folder: refused, then forced.
    let first = std::fs::read(db).unwrap();
    let (code, _, err) = aepipe(&["export", "trfdb", out.to_str().unwrap()]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("--force"), "{err}");
    assert!(std::fs::read(db).unwrap() == first);
    let (code, said, err) = aepipe(&["export", "trfdb", out.to_str().unwrap(), "--force"]);
    assert_eq!(code, 0, "{err}");
    assert!(said.contains(&format!("export {exp}: ")), "{said}");
    let v = compare(db, &out, &exp, true).unwrap();
    assert!(v["bad"].as_array().unwrap().is_empty(), "{}", v["bad"]);
}

/// A MISTRAS chain is not a Vallen pair: a CSV keyed by aepipe's hit, each row with the
/// hit number hits.parquet gives its waveform, and the run's values.
#[test]
fn a_mistras_chain_gets_a_csv_keyed_by_its_hit_numbers() {
    let Some(real) = crate::real_data("a_mistras_chain_gets_a_csv_keyed_by_its_hit_numbers") else {
        return;
    };
    let t = TempDir::new("trfdb-dta");
    let out = t.path().join("run");
    run(
        &real.join("mistras_dta"),
        &out,
        "[export]\ntrfdb = true\n\n[som]\nenabled = false\n",
    );
    let csv = out.join("export").join("210527-CH1-15.aepipe.csv");
    let mut r = csv::Reader::from_path(&csv).unwrap();
    let header: Vec<String> = r.headers().unwrap().iter().map(str::to_string).collect();
    let at = |n: &str| header.iter().position(|h| h == n).unwrap();
    let (hit, vendor, ra) = (at("hit"), at("vendor_hit"), at("RA"));
    // The run's own tables: features' hit → RA, hits' transient → hit number.
    let (fnames, frows) = crate::table_rows(&out.join("features").join("features.parquet"));
    let fc = |n: &str| fnames.iter().position(|h| h == n).unwrap();
    let ra_of: std::collections::HashMap<String, String> = frows
        .iter()
        .map(|r| (r[fc("hit")].clone(), r[fc("ra_ms_per_v")].clone()))
        .collect();
    let (hnames, hrows) = crate::table_rows(&out.join("features").join("hits.parquet"));
    let hc = |n: &str| hnames.iter().position(|h| h == n).unwrap();
    let vendor_of: std::collections::HashMap<String, String> = hrows
        .iter()
        .filter(|r| !r[hc("transient")].is_empty())
        .map(|r| (r[hc("transient")].clone(), r[hc("hit")].clone()))
        .collect();
    let mut n = 0;
    for rec in r.records() {
        let rec = rec.unwrap();
        let h = rec[hit].to_string();
        assert_eq!(
            vendor_of.get(&h).map(String::as_str).unwrap_or(""),
            &rec[vendor],
            "hit {h}"
        );
        let want: Option<f64> = ra_of[&h].parse().ok();
        let got: Option<f64> = rec[ra].parse().ok();
        assert_eq!(got, want, "hit {h}: RA");
        n += 1;
    }
    assert_eq!(n, frows.len(), "one row per feature row");
    assert!(n > 0);
}

/// The demo's own run folder exported afterwards by `aepipe export trfdb`: every row read
/// back by vallenae with the run's values.
#[test]
fn the_demo_run_is_written_back_for_visualae() {
    let t = TempDir::new("trfdb-demo");
    let root = t.path().join("demo");
    let (code, said, err) = aepipe(&[
        "demo",
        "--out",
        root.to_str().unwrap(),
        "--hits",
        "150",
        "--no-cross-model",
        "--no-report",
    ]);
    assert_eq!(code, 0, "{said}\n{err}");
    let run = root.join("run");
    let (code, said, err) = aepipe(&["export", "trfdb", run.to_str().unwrap()]);
    assert_eq!(code, 0, "{said}\n{err}");
    let dbs: Vec<_> = std::fs::read_dir(run.join("export"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .collect();
    assert_eq!(dbs.len(), 1, "{dbs:?}");
    let exp = dbs[0]
        .file_name()
        .unwrap()
        .to_str()
        .unwrap()
        .trim_end_matches(".aepipe.trfdb")
        .to_string();
    assert!(said.contains(&format!("export {exp}: ")), "{said}");
    let Some(v) = compare(&dbs[0], &run, &exp, false) else {
        return;
    };
    assert!(v["features"].as_u64().unwrap() > 0, "{v}");
    assert_eq!(v["rows"], v["features"], "{v}");
    assert!(v["bad"].as_array().unwrap().is_empty(), "{}", v["bad"]);
    assert!(v["units"].get("SOM_Class").is_some(), "{v}");
}
