//! A lab's AEwin series (issue 52): the hit list's values land in `hits.parquet` on the
//! right hits (a row missing, a row extra, columns reordered, a TIME column, a list from
//! another test), the rate a header-less export's hit list implies, a machine log that ends
//! early, and statistics withheld below their minimum. Every fixture is written here, the
//! way an AEwin system would write it: waveforms at a known rate, and a hit list whose
//! AMP / RISE / DURATION / COUN are measured on those waveforms at the system's threshold.

use crate::{aepipe, read_all, real_data, table_maps, table_rows, TempDir};
use std::collections::BTreeMap;
use std::path::Path;

/// The acquisition system's threshold, dB_AE, and the preamplifier, dB.
const THRESHOLD_DB: f64 = 40.0;
const GAIN_DB: f64 = 40.0;

/// One hit as the system recorded it.
#[derive(Debug, Clone)]
struct Hit {
    hit: u64,
    time_s: f64,
    /// Values at the ADC (volts, preamplifier included), one per sample.
    samples: Vec<f64>,
    /// The list's row: what the system measured.
    amp: f64,
    rise_us: f64,
    duration_us: f64,
    counts: u64,
    para1: f64,
}

/// `n` hits of a test at `rate_hz`: bursts of 150–400 kHz rising over 4–30 µs after a 20 µs
/// pretrigger, amplitudes 45–80 dB_AE, one every ~4 s; each measured as the system would.
fn hits(n: usize, rate_hz: f64, seed: u64) -> Vec<Hit> {
    let mut rng = aepipe::util::Rng::new(seed);
    let len = (400e-6 * rate_hz) as usize;
    let pre = (20e-6 * rate_hz) as usize;
    let gain = 10f64.powf(GAIN_DB / 20.0);
    let thr = 1e-6 * 10f64.powf(THRESHOLD_DB / 20.0);
    (0..n)
        .map(|k| {
            let amp_db = 45.0 + 35.0 * rng.uniform();
            let a = 1e-6 * 10f64.powf(amp_db / 20.0);
            let rise = 4e-6 + 26e-6 * rng.uniform();
            let tau = 40e-6 + 60e-6 * rng.uniform();
            let f = 150e3 + 250e3 * rng.uniform();
            let phase = rng.uniform() * std::f64::consts::TAU;
            // At the sensor: noise well below the threshold, then the burst.
            let sensor: Vec<f64> = (0..len)
                .map(|i| {
                    let t = (i as f64 - pre as f64) / rate_hz;
                    let env = if t < 0.0 {
                        0.0
                    } else if t < rise {
                        t / rise
                    } else {
                        (-(t - rise) / tau).exp()
                    };
                    a * env * (2.0 * std::f64::consts::PI * f * t + phase).sin()
                        + 3e-6 * rng.normal()
                })
                .collect();
            // What the system measures on them.
            let first = sensor.iter().position(|v| v.abs() >= thr).unwrap();
            let last = sensor.iter().rposition(|v| v.abs() >= thr).unwrap();
            let (peak_i, peak) = sensor.iter().enumerate().fold((0, 0f64), |m, (i, v)| {
                if v.abs() > m.1 {
                    (i, v.abs())
                } else {
                    m
                }
            });
            let counts = sensor
                .windows(2)
                .filter(|w| w[0] < thr && w[1] >= thr)
                .count() as u64;
            Hit {
                hit: k as u64 + 1,
                time_s: 2.0 + 4.0 * k as f64 + rng.uniform(),
                // AEwin writes volts with 6 decimals at the ADC.
                samples: sensor
                    .iter()
                    .map(|v| format!("{:.6}", v * gain).parse().unwrap())
                    .collect(),
                amp: aepipe::model::db_ae(peak).round(),
                rise_us: ((peak_i - first) as f64 / rate_hz * 1e6).round(),
                duration_us: ((last - first) as f64 / rate_hz * 1e6).round(),
                counts,
                para1: 1000.25 + 100.0 * k as f64,
            }
        })
        .collect()
}

fn wave_name(test: &str, h: &Hit) -> String {
    format!("{test}_1_{}_{}.txt", h.hit, (h.time_s * 1e6).round() as u64)
}

/// A header-less export: `dir/<test>/<test>_<ch>_<hit>_<µs>.txt`, one value per line.
fn write_waves(dir: &Path, test: &str, hits: &[Hit]) {
    let d = dir.join(test);
    std::fs::create_dir_all(&d).unwrap();
    for h in hits {
        let text: String = h.samples.iter().map(|v| format!("{v:.6}\n")).collect();
        std::fs::write(d.join(wave_name(test, h)), text).unwrap();
    }
}

/// The list's cells of a hit under a column name.
fn cell(h: &Hit, col: &str) -> String {
    match col {
        "ID" => "1".into(),
        "TIME" => format!("{:.7}", h.time_s),
        "PARA1" => format!("{:.4}", h.para1),
        "RISE" => format!("{}", h.rise_us),
        "COUN" => format!("{}", h.counts),
        "DURATION" => format!("{}", h.duration_us),
        "AMP" => format!("{}", h.amp),
        "X-LAB" => format!("{}", h.hit * 7),
        c => panic!("{c}"),
    }
}

/// `dir/<test>.TXT` with `cols`, one row per hit given (the list's own order).
fn write_list(dir: &Path, test: &str, cols: &[&str], rows: &[&Hit]) {
    let mut s = format!("\n {}\n", cols.join("  "));
    for h in rows {
        let cells: Vec<String> = cols.iter().map(|c| cell(h, c)).collect();
        s += &format!("  {}\n", cells.join("  "));
    }
    std::fs::write(dir.join(format!("{test}.TXT")), s).unwrap();
}

const COLS: [&str; 6] = ["ID", "PARA1", "RISE", "COUN", "DURATION", "AMP"];

/// hits.parquet's rows by hit: column → value as text.
fn hit_rows(out: &Path) -> Vec<BTreeMap<String, String>> {
    table_maps(&out.join("hits.parquet"))
}

/// `aepipe run --config CFG DATA --out OUT`, which must succeed: its terminal output.
fn run(cfg: &Path, data: &Path, out: &Path) -> String {
    crate::aepipe_ok(&[
        "run",
        "--config",
        cfg.to_str().unwrap(),
        data.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ])
}

fn num(r: &BTreeMap<String, String>, c: &str) -> Option<f64> {
    r[c].parse().ok()
}

/// The row of `hits.parquet` whose transient is the hit's waveform equals the list's row.
fn assert_lands(rows: &[BTreeMap<String, String>], h: &Hit, time_column: bool) {
    let r = rows
        .iter()
        .find(|r| r["transient"] == h.hit.to_string())
        .unwrap_or_else(|| panic!("no hit row for waveform {}", h.hit));
    assert_eq!(r["list_status"], "matched", "{r:?}");
    assert_eq!(num(r, "amplitude_db"), Some(h.amp), "{r:?}");
    assert_eq!(num(r, "rise_time_s"), Some(h.rise_us * 1e-6), "{r:?}");
    assert_eq!(num(r, "duration_s"), Some(h.duration_us * 1e-6), "{r:?}");
    assert_eq!(num(r, "counts"), Some(h.counts as f64), "{r:?}");
    assert_eq!(
        r["parametric"],
        format!("{{\"PARA1\":{}}}", h.para1),
        "{r:?}"
    );
    if time_column {
        assert_eq!(
            num(r, "time_s"),
            Some(format!("{:.7}", h.time_s).parse().unwrap())
        );
    }
}

fn manifest(out: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap()
}

fn notes(out: &Path) -> Vec<String> {
    manifest(out)["notes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| n["note"].as_str().unwrap().to_string())
        .collect()
}

fn features(input: &Path, out: &Path, config: Option<&Path>) -> String {
    let (i, o) = (input.to_str().unwrap(), out.to_str().unwrap());
    let mut args = vec!["features", i, "--out", o];
    if let Some(c) = config {
        args.extend(["--config", c.to_str().unwrap()]);
    }
    let (c, so, se) = aepipe(&args);
    assert_eq!(c, 0, "{so}\n{se}");
    assert!(manifest(out)["counts"]["unbalanced"]
        .as_array()
        .unwrap()
        .is_empty());
    so
}

/// The rate of the records written to features.parquet.
fn rates(out: &Path) -> Vec<String> {
    let (names, rows) = table_rows(&out.join("features.parquet"));
    let k = names.iter().position(|n| n == "sample_rate_hz").unwrap();
    rows.into_iter().map(|r| r[k].clone()).collect()
}

#[test]
fn a_header_less_export_is_read_at_the_rate_its_hit_list_implies_unless_the_file_sets_one() {
    let t = TempDir::new("hitlist-rate");
    let data = t.path().join("data");
    let h10 = hits(12, 10e6, 3);
    write_waves(&data, "EXP10", &h10);
    write_list(&data, "EXP10", &COLS, &h10.iter().collect::<Vec<_>>());
    // Unset: 10 MHz, said on the terminal.
    let out = t.path().join("unset");
    let so = features(&data, &out, None);
    assert!(
        so.contains("EXP10: 10 MHz, implied by the hit list's rise times (configured 5 MHz;"),
        "{so}"
    );
    assert!(
        rates(&out).iter().all(|r| r == "10000000.0"),
        "{:?}",
        rates(&out)
    );
    for h in &h10 {
        assert_lands(&hit_rows(&out), h, false);
    }
    // Set to 5 MHz in the pipeline file: read at 5 MHz, the disagreement said.
    let cfg = t.path().join("five.toml");
    std::fs::write(&cfg, "[ingest.aewin]\nsample_rate_hz = 5e6\n").unwrap();
    let out = t.path().join("set");
    let so = features(&data, &out, Some(&cfg));
    assert!(
        so.contains("EXP10: 5 MHz as set in the pipeline file, though the hit list's rise times imply 10 MHz"),
        "{so}"
    );
    assert!(rates(&out).iter().all(|r| r == "5000000.0"));
    // A 5 MHz test beside it: 5 MHz, agreeing (a manifest note, not a terminal line).
    let h5 = hits(12, 5e6, 4);
    let data5 = t.path().join("data5");
    write_waves(&data5, "EXP05", &h5);
    write_list(&data5, "EXP05", &COLS, &h5.iter().collect::<Vec<_>>());
    let out = t.path().join("five");
    let so = features(&data5, &out, None);
    assert!(rates(&out).iter().all(|r| r == "5000000.0"));
    assert!(!so.contains("EXP05: 5 MHz"), "{so}");
    assert!(notes(&out)
        .iter()
        .any(|n| n.starts_with("EXP05: 5 MHz, as the hit list's rise times imply")));
    // Without a list, the doubt is said.
    std::fs::remove_file(data5.join("EXP05.TXT")).unwrap();
    let out = t.path().join("nolist");
    let so = features(&data5, &out, None);
    assert!(
        so.contains("EXP05: header-less waveform files and no hit list: read at 5 MHz"),
        "{so}"
    );
}

#[test]
fn hit_list_rows_land_on_their_waveforms_whatever_is_missing_extra_or_reordered() {
    let t = TempDir::new("hitlist-match");
    let hs = hits(15, 5e6, 7);
    let all: Vec<&Hit> = hs.iter().collect();
    // 1. One row missing in the middle: hit 8 is a waveform without a row.
    let d = t.path().join("missing");
    write_waves(&d, "EXP1", &hs);
    let rows: Vec<&Hit> = all.iter().copied().filter(|h| h.hit != 8).collect();
    write_list(&d, "EXP1", &COLS, &rows);
    let out = t.path().join("o1");
    let so = features(&d, &out, None);
    let got = hit_rows(&out);
    assert_eq!(got.len(), 15);
    for h in &rows {
        assert_lands(&got, h, false);
    }
    let lone = got.iter().find(|r| r["transient"] == "8").unwrap();
    assert_eq!(lone["list_status"], "no_list_row");
    assert_eq!(lone["amplitude_db"], "");
    assert!(
        so.contains(
            "1 waveform(s) without a row, 0 row(s) without a waveform: hit 8 has no list row"
        ),
        "{so}"
    );
    // 2. One row extra: the waveform of hit 4 is gone, its row stays, without a transient.
    let d = t.path().join("extra");
    write_waves(&d, "EXP2", &hs);
    std::fs::remove_file(d.join("EXP2").join(wave_name("EXP2", &hs[3]))).unwrap();
    write_list(&d, "EXP2", &COLS, &all);
    let out = t.path().join("o2");
    features(&d, &out, None);
    let got = hit_rows(&out);
    assert_eq!(got.len(), 15);
    for h in all.iter().filter(|h| h.hit != 4) {
        assert_lands(&got, h, false);
    }
    let lone: Vec<_> = got
        .iter()
        .filter(|r| r["list_status"] == "no_waveform")
        .collect();
    assert_eq!(lone.len(), 1);
    assert_eq!(num(lone[0], "amplitude_db"), Some(hs[3].amp));
    assert_eq!(lone[0]["transient"], "");
    // 3. Columns reordered, a TIME column and one aepipe does not know.
    let d = t.path().join("reordered");
    write_waves(&d, "EXP3", &hs);
    write_list(
        &d,
        "EXP3",
        &[
            "AMP", "TIME", "X-LAB", "DURATION", "ID", "COUN", "RISE", "PARA1",
        ],
        &all,
    );
    let out = t.path().join("o3");
    let so = features(&d, &out, None);
    assert!(
        so.contains("matched by time") || notes(&out).iter().any(|n| n.contains("matched by time"))
    );
    let got = hit_rows(&out);
    for h in &hs {
        assert_lands(&got, h, true);
        let r = got
            .iter()
            .find(|r| r["transient"] == h.hit.to_string())
            .unwrap();
        assert_eq!(
            r["vendor_features"],
            format!("{{\"X-LAB\":{}.0}}", h.hit * 7)
        );
    }
    // 4. Another test's list (its amplitudes do not fit): no value lands; its rows are
    // rejects saying why, and each waveform keeps a hit row of its own.
    let other = hits(15, 5e6, 99);
    let d = t.path().join("foreign");
    write_waves(&d, "EXP4", &hs);
    write_list(&d, "EXP4", &COLS, &other.iter().collect::<Vec<_>>());
    let out = t.path().join("o4");
    let so = features(&d, &out, None);
    assert!(
        so.contains("EXP4: hit list EXP4.TXT does not match the waveforms in any order"),
        "{so}"
    );
    let got = hit_rows(&out);
    assert_eq!(got.len(), 15);
    assert!(got.iter().all(|r| r["amplitude_db"].is_empty()));
    let (names, rej) = table_rows(&out.join("rejects.parquet"));
    let reason = names.iter().position(|n| n == "reason").unwrap();
    assert_eq!(
        rej.iter()
            .filter(|r| r[reason].contains("does not match the waveforms"))
            .count(),
        15
    );
}

/// EXP2009's own list lands row for row (read here by its own header), at the 5 MHz its
/// rise times imply, and the machine log's end is said.
#[test]
fn exp2009s_hit_list_lands_and_its_short_machine_log_is_said() {
    let Some(real) = real_data("exp2009s_hit_list_lands_and_its_short_machine_log_is_said") else {
        return;
    };
    let dir = real.join("aewin_cfrp_tensile");
    let t = TempDir::new("hitlist-exp2009");
    let out = t.path().join("o");
    let so = features(&dir, &out, None);
    let text = std::fs::read_to_string(dir.join("EXP2009.TXT")).unwrap();
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let head: Vec<&str> = lines.next().unwrap().split_whitespace().collect();
    let list: Vec<BTreeMap<&str, f64>> = lines
        .map(|l| {
            head.iter()
                .copied()
                .zip(l.split_whitespace().map(|v| v.parse::<f64>().unwrap()))
                .collect()
        })
        .collect();
    assert_eq!(list.len(), 29);
    let got = hit_rows(&out);
    assert_eq!(got.len(), 29);
    for (k, row) in list.iter().enumerate() {
        let r = &got[k];
        assert_eq!(r["transient"], (k + 1).to_string(), "hit order");
        assert_eq!(num(r, "amplitude_db"), Some(row["AMP"]));
        assert_eq!(num(r, "rise_time_s"), Some(row["RISE"] * 1e-6));
        assert_eq!(num(r, "duration_s"), Some(row["DURATION"] * 1e-6));
        assert_eq!(num(r, "counts"), Some(row["COUN"]));
        assert_eq!(num(r, "counts_to_peak"), Some(row["PCNTS"]));
        assert_eq!(num(r, "abs_energy_aj"), Some(row["ABS-ENERGY"]));
        assert_eq!(r["parametric"], format!("{{\"PARA1\":{}}}", row["PARA1"]));
    }
    let n = notes(&out);
    assert!(n.iter().any(|n| n.starts_with("EXP2009: hit list EXP2009.TXT matched in hit order: 29 of 29 row(s) paired with waveforms, AMP within 1 dB of the waveform's peak (less the preamplifier gain) for 27 of 29")), "{n:?}");
    assert!(
        n.iter()
            .any(|n| n.starts_with("EXP2009: 5 MHz, as the hit list's rise times imply")),
        "{n:?}"
    );
    // The log ends at 14.896 s (data README); the hits after it, counted from the names.
    let after = std::fs::read_dir(dir.join("EXP2009"))
        .unwrap()
        .filter(|e| {
            let name = e
                .as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .to_string();
            let us: f64 = name
                .trim_end_matches(".txt")
                .rsplit('_')
                .next()
                .unwrap()
                .parse()
                .unwrap();
            us * 1e-6 > 14.896
        })
        .count();
    assert_eq!(after, 23);
    assert!(
        so.contains(&format!(
            "EXP2009: {after} of 29 hits after the machine log ends at 14.9 s: no load"
        )),
        "{so}"
    );
    // The rates read: every record at 5 MHz.
    let (recs, _) = read_all(
        std::slice::from_ref(&dir),
        &aepipe::config::ValidConfig::default(),
    );
    assert!(recs.iter().all(|r| r.sample_rate_hz == 5e6));
}

/// A machine log that stops at 19.5 s of a 55 s test, 3 hits before it: the line naming
/// the experiment, the trend withheld (`n = 3: too few hits for a trend`, null r and p) on
/// the terminal, in trend.parquet and in series.parquet.
#[test]
fn a_log_that_ends_early_is_said_and_three_hits_state_no_trend() {
    let t = TempDir::new("hitlist-log");
    let data = t.path().join("data");
    let mut hs = hits(12, 5e6, 21);
    for (k, h) in hs.iter_mut().enumerate() {
        // 3 hits while the log runs (load rising to its end), 9 after it.
        h.time_s = if k < 3 {
            5.0 + 5.0 * k as f64
        } else {
            21.0 + 3.5 * k as f64
        };
    }
    write_waves(&data, "EXP3005", &hs);
    write_list(&data, "EXP3005", &COLS, &hs.iter().collect::<Vec<_>>());
    let mut log = String::from("Time;Extension;Load\n(sec);(mm);(N)\n");
    for i in 0..=195 {
        let s = i as f64 * 0.1;
        log += &format!(
            "{};{};{}\n",
            format!("{s:.1}").replace('.', ","),
            format!("{:.3}", s * 0.01).replace('.', ","),
            format!("{:.1}", 100.0 * s).replace('.', ",")
        );
    }
    std::fs::write(data.join("Specimen_RawData_3005.csv"), log).unwrap();
    let cfg = t.path().join("p.toml");
    std::fs::write(&cfg, "[som]\nenabled = false\n[report]\nenabled = false\n").unwrap();
    let out = t.path().join("run");
    let so = run(&cfg, &data, &out);
    assert!(
        so.contains("EXP3005: 9 of 12 hits after the machine log ends at 19.5 s: no load"),
        "{so}"
    );
    assert!(
        so.contains("n = 3: too few hits for a trend (trend.min_hits = 10)"),
        "{so}"
    );
    let (names, rows) = table_rows(&out.join("trend/trend.parquet"));
    let col = |n: &str| names.iter().position(|x| x == n).unwrap();
    assert!(!rows.is_empty());
    for r in &rows {
        assert_eq!((r[col("r")].as_str(), r[col("p")].as_str()), ("", ""));
        assert_eq!(
            r[col("note")],
            "n = 3: too few hits for a trend (trend.min_hits = 10)"
        );
    }
    let (names, rows) = table_rows(&out.join("series.parquet"));
    let col = |n: &str| names.iter().position(|x| x == n).unwrap();
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0][col("hits")], "12");
    assert_eq!(rows[0][col("hits_with_load")], "3");
    assert_eq!(rows[0][col("peak_load_n")], "1950.0");
    assert_eq!(rows[0][col("peak_load_s")], "19.5");
    assert_eq!(rows[0][col("significant_trends")], "0");
    assert!(rows[0][col("trend_note")].contains("n = 3: too few hits for a trend"));
    // With the minimum lowered to 3 the same hits do state a trend.
    std::fs::write(
        &cfg,
        "[som]\nenabled = false\n[report]\nenabled = false\n[trend]\nmin_hits = 3\n",
    )
    .unwrap();
    let so = run(&cfg, &data, &out);
    assert!(!so.contains("too few hits"), "{so}");
    let (names, rows) = table_rows(&out.join("trend/trend.parquet"));
    let r = names.iter().position(|x| x == "r").unwrap();
    assert!(rows.iter().any(|row| !row[r].is_empty()));
}

/// `series.parquet` on the real sets: one row per experiment of the manifest, each count
/// equal to an independent count over the run's own tables (hits with load over
/// hits.parquet, the peak over parametric.parquet, classes over classification.parquet, α
/// from statistics.parquet), and the terminal's table for these 2–20 tests.
#[test]
fn the_series_table_of_the_real_sets_agrees_with_the_runs_tables() {
    let Some(real) = real_data("the_series_table_of_the_real_sets_agrees_with_the_runs_tables")
    else {
        return;
    };
    let t = TempDir::new("series-real");
    let out = t.path().join("run");
    let cfg = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/aewin-cfrp.toml");
    let sets = ["aewin_cfrp_tensile", "plb_cfrp_vallen", "mistras_dta"].map(|s| real.join(s));
    let mut args = vec![
        "run",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(sets.iter().map(|p| p.to_str().unwrap()));
    let (c, so, se) = aepipe(&args);
    assert_eq!(c, 0, "{so}\n{se}");
    let table = |p: &str| table_maps(&out.join(p));
    let series = table("series.parquet");
    let hits = table("features/hits.parquet");
    let params = table("features/parametric.parquet");
    let classes = table("som/classification.parquet");
    let stats = table("statistics.parquet");
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("features/manifest.json")).unwrap())
            .unwrap();
    let by = m["counts"]["by_experiment"].as_object().unwrap();
    let experiments: Vec<&String> = by.keys().filter(|e| !e.is_empty()).collect();
    assert_eq!(series.len(), experiments.len());
    assert!(series.len() >= 4, "{series:?}");
    // The terminal's table: a header and one line per test.
    assert!(
        so.lines()
            .any(|l| l.starts_with("series ") && l.contains("alpha")),
        "{so}"
    );
    for r in &series {
        let e = &r["experiment"];
        assert_eq!(r["hits"], by[e]["hits"].to_string());
        let mine = |t: &[BTreeMap<String, String>]| -> Vec<BTreeMap<String, String>> {
            t.iter()
                .filter(|x| &x["experiment"] == e)
                .cloned()
                .collect()
        };
        let with_load = mine(&hits)
            .iter()
            .filter(|h| !h["load_n"].is_empty())
            .count();
        assert_eq!(r["hits_with_load"], with_load.to_string(), "{e}");
        let peak = mine(&params)
            .iter()
            .filter_map(|p| p["load_n"].parse::<f64>().ok())
            .fold(f64::NEG_INFINITY, f64::max);
        match peak.is_finite() {
            true => assert_eq!(r["peak_load_n"].parse::<f64>().unwrap(), peak, "{e}"),
            false => assert_eq!(r["peak_load_n"], "", "{e}"),
        }
        let mut by_class: BTreeMap<String, usize> = BTreeMap::new();
        for c in mine(&classes) {
            *by_class.entry(c["som_label"].clone()).or_default() += 1;
        }
        let classified: usize = by_class.values().sum();
        assert_eq!(r["classified"], classified.to_string(), "{e}");
        for (class, n) in &by_class {
            if class == "unlike_references" {
                let share: f64 = r["unlike_references_share"].parse().unwrap();
                assert!((share - *n as f64 / classified as f64).abs() < 1e-12, "{e}");
            } else {
                assert_eq!(r[&format!("{class}_hits")], n.to_string(), "{e} {class}");
            }
        }
        let alpha = mine(&stats)[0]["energy_alpha"].clone();
        assert_eq!(r["alpha"], alpha, "{e}");
    }
    let exp = series
        .iter()
        .find(|r| r["experiment"] == "EXP2009")
        .unwrap();
    assert_eq!(exp["hits_with_load"], "6");
}
