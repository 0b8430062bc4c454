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
    /// The burst's frequency, Hz.
    freq_hz: f64,
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
                amp: db_ae(peak).round(),
                rise_us: ((peak_i - first) as f64 / rate_hz * 1e6).round(),
                duration_us: ((last - first) as f64 / rate_hz * 1e6).round(),
                counts,
                para1: 1000.25 + 100.0 * k as f64,
                freq_hz: f,
            }
        })
        .collect()
}

/// dB_AE, computed here (not with the code under test): 20·log10(|V| / 1 µV).
fn db_ae(volts: f64) -> f64 {
    20.0 * (volts.abs() / 1e-6).log10()
}

/// Known levels (volts, dB_AE) worked out by hand, and the levels `f` gets wrong (beyond
/// 1e-9 dB).
fn db_levels_wrong(f: &dyn Fn(f64) -> f64) -> Vec<(f64, f64)> {
    const LEVELS: [(f64, f64); 6] = [
        (1e-6, 0.0),
        (1e-4, 40.0),
        (-1e-3, 60.0),
        (0.5, 113.979_400_086_720_37),
        (1.0, 120.0),
        (3.162_277_660_168_379_5e-6, 10.0),
    ];
    LEVELS
        .iter()
        .filter(|(v, db)| (f(*v) - db).abs() > 1e-9)
        .copied()
        .collect()
}

/// The fixtures' AMP is computed here, independently of aepipe: both it and
/// `aepipe::model::db_ae` give the known levels. Plants: 10·log10 (a power ratio) and a
/// 1 mV reference each get levels wrong.
#[test]
fn the_fixtures_db_ae_and_aepipes_agree_on_known_levels() {
    assert_eq!(db_levels_wrong(&db_ae), vec![]);
    assert_eq!(db_levels_wrong(&aepipe::model::db_ae), vec![]);
    assert!(!db_levels_wrong(&|v: f64| 10.0 * (v.abs() / 1e-6).log10()).is_empty());
    assert!(!db_levels_wrong(&|v: f64| 20.0 * (v.abs() / 1e-3).log10()).is_empty());
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

/// Why `rates` are not `n` records all at `want` (an empty table is not "all at").
fn rates_wrong(rates: &[String], want: &str, n: usize) -> Option<String> {
    if rates.len() != n {
        return Some(format!("{} records, not {n}", rates.len()));
    }
    let off: Vec<&String> = rates.iter().filter(|r| *r != want).collect();
    (!off.is_empty()).then(|| format!("{} of {n} not at {want}: {off:?}", off.len()))
}

/// features.parquet of `out` holds `n` records, every one at `want`.
fn assert_rates(out: &Path, want: &str, n: usize) {
    if let Some(why) = rates_wrong(&rates(out), want, n) {
        panic!("{}: {why}", out.display());
    }
}

/// The rate check cannot pass on an empty table. Plants: no records, one record too few,
/// and one record at another rate each fail it.
#[test]
fn the_rate_check_fails_on_an_empty_short_or_mixed_table() {
    let at = |r: &[&str]| r.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    assert_eq!(rates_wrong(&at(&["5000000.0"; 3]), "5000000.0", 3), None);
    assert!(rates_wrong(&[], "5000000.0", 3).is_some());
    assert!(rates_wrong(&at(&["5000000.0"; 2]), "5000000.0", 3).is_some());
    let mixed = at(&["5000000.0", "10000000.0", "5000000.0"]);
    assert!(rates_wrong(&mixed, "5000000.0", 3).is_some());
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
    assert_rates(&out, "10000000.0", h10.len());
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
    assert_rates(&out, "5000000.0", h10.len());
    // A 5 MHz test beside it: 5 MHz, agreeing (a manifest note, not a terminal line).
    let h5 = hits(12, 5e6, 4);
    let data5 = t.path().join("data5");
    write_waves(&data5, "EXP05", &h5);
    write_list(&data5, "EXP05", &COLS, &h5.iter().collect::<Vec<_>>());
    let out = t.path().join("five");
    let so = features(&data5, &out, None);
    assert_rates(&out, "5000000.0", h5.len());
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
    assert_eq!(recs.len(), 29);
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

/// A run's tables, as column → value text.
struct RunTables {
    series: Vec<BTreeMap<String, String>>,
    hits: Vec<BTreeMap<String, String>>,
    params: Vec<BTreeMap<String, String>>,
    classes: Vec<BTreeMap<String, String>>,
    stats: Vec<BTreeMap<String, String>>,
    rejects: Vec<BTreeMap<String, String>>,
    clusters: Vec<BTreeMap<String, String>>,
    trend: Vec<BTreeMap<String, String>>,
    /// Per experiment: the sources' (hits outside events, events' first hits) positive
    /// energies of features.parquet, the values statistics.parquet fits.
    energies: BTreeMap<String, Vec<f64>>,
    /// The manifest's counts by experiment.
    by: serde_json::Map<String, serde_json::Value>,
}

impl RunTables {
    fn read(out: &Path) -> RunTables {
        // A stage that did not run (no SOM, no clustering) left no table: no rows.
        let table = |p: &str| {
            let p = out.join(p);
            if p.is_file() {
                table_maps(&p)
            } else {
                Vec::new()
            }
        };
        let mut energies: BTreeMap<String, Vec<f64>> = BTreeMap::new();
        for r in table("features/features.parquet") {
            let first = r.get("event_first").map_or("", String::as_str);
            let e = r["energy_eu"].parse::<f64>().ok();
            if let Some(e) = e.filter(|e| e.is_finite() && *e > 0.0 && first != "false") {
                energies.entry(r["experiment"].clone()).or_default().push(e);
            }
        }
        let m: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(out.join("features/manifest.json")).unwrap(),
        )
        .unwrap();
        RunTables {
            series: table("series.parquet"),
            hits: table("features/hits.parquet"),
            params: table("features/parametric.parquet"),
            classes: table("som/classification.parquet"),
            stats: table("statistics.parquet"),
            rejects: table("features/rejects.parquet"),
            clusters: table("cluster/clusters.parquet"),
            trend: table("trend/trend.parquet"),
            energies,
            by: m["counts"]["by_experiment"].as_object().unwrap().clone(),
        }
    }
}

/// The rows of `t` of experiment `e`.
fn of<'a>(
    t: &'a [BTreeMap<String, String>],
    e: &'a str,
) -> impl Iterator<Item = &'a BTreeMap<String, String>> + 'a {
    t.iter().filter(move |x| x["experiment"] == e)
}

/// Where a series row's counts disagree with independent counts over the run's tables.
fn series_counts_wrong(r: &BTreeMap<String, String>, t: &RunTables) -> Vec<String> {
    let e = r["experiment"].as_str();
    let mut wrong = Vec::new();
    let want = |col: &str, v: String| {
        (r[col] != v).then(|| format!("{e} {col}: {} (the tables: {v})", r[col]))
    };
    wrong.extend(want("hits", t.by[e]["hits"].to_string()));
    wrong.extend(want("rejects", of(&t.rejects, e).count().to_string()));
    let with_load = of(&t.hits, e).filter(|h| !h["load_n"].is_empty()).count();
    wrong.extend(want("hits_with_load", with_load.to_string()));
    let peak = of(&t.params, e)
        .filter_map(|p| p["load_n"].parse::<f64>().ok())
        .fold(f64::NEG_INFINITY, f64::max);
    let got = r["peak_load_n"].parse::<f64>().ok();
    if got != peak.is_finite().then_some(peak) {
        wrong.push(format!("{e} peak_load_n: {got:?} (parametric: {peak})"));
    }
    let mut by_class: BTreeMap<String, usize> = BTreeMap::new();
    for c in of(&t.classes, e) {
        *by_class.entry(c["som_label"].clone()).or_default() += 1;
    }
    let classified: usize = by_class.values().sum();
    if r["classified"].is_empty() {
        // No SOM stage: no classification rows either.
        if classified > 0 {
            wrong.push(format!(
                "{e} classified: null, {classified} classification rows"
            ));
        }
    } else {
        wrong.extend(want("classified", classified.to_string()));
    }
    for (class, n) in &by_class {
        if class == "unlike_references" {
            let share: f64 = r["unlike_references_share"].parse().unwrap();
            if (share - *n as f64 / classified as f64).abs() > 1e-12 {
                wrong.push(format!("{e} unlike_references_share: {share}"));
            }
        } else {
            wrong.extend(want(&format!("{class}_hits"), n.to_string()));
        }
    }
    let clusters: std::collections::BTreeSet<&String> = of(&t.clusters, e)
        .map(|c| &c["cluster"])
        .filter(|c| !c.is_empty())
        .collect();
    wrong.extend(want("clusters", clusters.len().to_string()));
    let significant = of(&t.trend, e)
        .filter(|x| x["p"].parse::<f64>().is_ok_and(|p| p < 0.01))
        .count();
    wrong.extend(want("significant_trends", significant.to_string()));
    wrong
}

/// α̂ = 1 + n / Σ ln(x / x_min) over the energies ≥ x_min (the continuous power law's
/// maximum-likelihood exponent, Clauset, Shalizi & Newman 2009, eq. 3.1), and n.
fn mle_alpha(energies: &[f64], x_min: f64) -> (f64, usize) {
    let tail: Vec<f64> = energies.iter().copied().filter(|x| *x >= x_min).collect();
    let s: f64 = tail.iter().map(|x| (x / x_min).ln()).sum();
    (1.0 + tail.len() as f64 / s, tail.len())
}

/// Where a series row's `energy_n` and `alpha` disagree with the sources' energies: the
/// count, and α computed here at statistics.parquet's x_min (null below 50 energies).
fn series_energy_wrong(r: &BTreeMap<String, String>, t: &RunTables) -> Vec<String> {
    let e = r["experiment"].as_str();
    let x = t.energies.get(e).map_or(&[][..], Vec::as_slice);
    let mut wrong = Vec::new();
    if r["energy_n"] != x.len().to_string() {
        wrong.push(format!(
            "{e} energy_n: {} (features: {})",
            r["energy_n"],
            x.len()
        ));
    }
    let stat = of(&t.stats, e).next();
    let x_min = stat.and_then(|s| s["energy_x_min_eu"].parse::<f64>().ok());
    match (r["alpha"].parse::<f64>().ok(), x_min) {
        (None, None) if x.len() < 50 => {}
        (Some(alpha), Some(x_min)) if x.len() >= 50 => {
            let (mle, n) = mle_alpha(x, x_min);
            if (alpha - mle).abs() > 1e-9 * mle || n < 50 {
                wrong.push(format!(
                    "{e} alpha: {alpha} (here {mle} over {n} ≥ {x_min})"
                ));
            }
        }
        (a, m) => wrong.push(format!(
            "{e} alpha {a:?}, x_min {m:?} of {} energies",
            x.len()
        )),
    }
    wrong
}

/// α by the Python `powerlaw` package (Alstott et al.) at the same x_min, per experiment;
/// `None` after a skip when it is not installed.
fn powerlaw_alphas(
    dir: &Path,
    fits: &BTreeMap<String, (Vec<f64>, f64)>,
) -> Option<BTreeMap<String, f64>> {
    let input = dir.join("energies.json");
    std::fs::write(&input, serde_json::to_string(fits).unwrap()).unwrap();
    let script = "import json, sys\ntry:\n    import powerlaw\nexcept ImportError as e:\n    print(f'missing: {e}', file=sys.stderr); sys.exit(3)\nd = json.load(open(sys.argv[1]))\nprint(json.dumps({e: powerlaw.Fit(x, xmin=m, verbose=False).power_law.alpha for e, (x, m) in d.items()}))\n";
    let mut cmd = std::process::Command::new("python3");
    cmd.args(["-c", script]).arg(&input);
    let out = crate::reference("series_alpha_by_powerlaw", "pip install powerlaw", &mut cmd)?;
    Some(serde_json::from_slice(&out).unwrap())
}

/// Where a series row disagrees with the run's tables ([`series_counts_wrong`],
/// [`series_energy_wrong`]).
fn series_wrong(r: &BTreeMap<String, String>, t: &RunTables) -> Vec<String> {
    let mut w = series_counts_wrong(r, t);
    w.extend(series_energy_wrong(r, t));
    w
}

/// A test whose rows do count: 20 hits whose burst frequency rises from hit to hit (so each
/// band's partial power trends with the AE number, significantly) and a hit list with one
/// line that is not a row (a reject of the test). Its series row agrees with the run's
/// tables, with significant_trends and rejects above 0 and clusters counted. Plants: the
/// row with one significant trend or reject fewer fails the same check.
#[test]
fn a_series_row_counts_the_tests_rejects_clusters_and_significant_trends() {
    let t = TempDir::new("series-counts");
    let data = t.path().join("data");
    let mut hs = hits(20, 5e6, 31);
    hs.sort_by(|a, b| a.freq_hz.total_cmp(&b.freq_hz));
    for (k, h) in hs.iter_mut().enumerate() {
        h.hit = k as u64 + 1;
        h.time_s = 2.0 + 4.0 * k as f64;
    }
    write_waves(&data, "EXP4001", &hs);
    write_list(&data, "EXP4001", &COLS, &hs.iter().collect::<Vec<_>>());
    let list = data.join("EXP4001.TXT");
    let text = std::fs::read_to_string(&list).unwrap();
    std::fs::write(&list, format!("{text}  1  2\n")).unwrap();
    let cfg = t.path().join("p.toml");
    std::fs::write(
        &cfg,
        "[som]\nenabled = false\n[report]\nenabled = false\n[cluster]\nenabled = true\n",
    )
    .unwrap();
    let out = t.path().join("run");
    run(&cfg, &data, &out);
    let tables = RunTables::read(&out);
    assert_eq!(tables.series.len(), 1);
    let r = &tables.series[0];
    assert_eq!(series_wrong(r, &tables), Vec::<String>::new());
    assert_eq!((r["hits"].as_str(), r["rejects"].as_str()), ("20", "1"));
    assert_eq!(r["classified"], "");
    let significant: u64 = r["significant_trends"].parse().unwrap();
    assert!(significant > 0, "{r:?}");
    assert!(r["clusters"].parse::<u64>().unwrap() > 0, "{r:?}");
    for col in ["significant_trends", "rejects"] {
        let mut p = r.clone();
        p.insert(col.into(), (p[col].parse::<u64>().unwrap() - 1).to_string());
        assert!(
            !series_wrong(&p, &tables).is_empty(),
            "plant {col} − 1 passed"
        );
    }
}

/// `series.parquet` on the real sets, clustering on: one row per experiment of the
/// manifest, each column equal to an independent count over the run's own tables (hits
/// with load over hits.parquet, the peak over parametric.parquet, classes over
/// classification.parquet, rejects over rejects.parquet, distinct clusters over
/// clusters.parquet, significant trends as trend.parquet's rows with p < 0.01; none has
/// any here, [`a_series_row_counts_the_tests_rejects_clusters_and_significant_trends`]
/// has some), energy_n and α from the sources' energies of features.parquet (α
/// computed here by maximum likelihood at statistics.parquet's x_min, and by the Python
/// `powerlaw` package when installed), and the terminal's table for these 2–20 tests.
/// Plants: a row with one reject, cluster, significant trend or energy too many, or the
/// cumulative exponent α − 1 in place of α, each fail the checks.
#[test]
fn the_series_table_of_the_real_sets_agrees_with_the_runs_tables() {
    let Some(real) = real_data("the_series_table_of_the_real_sets_agrees_with_the_runs_tables")
    else {
        return;
    };
    let t = TempDir::new("series-real");
    let out = t.path().join("run");
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/aewin-cfrp.toml");
    let cfg = t.path().join("p.toml");
    let text = std::fs::read_to_string(base).unwrap();
    std::fs::write(&cfg, format!("{text}\n[cluster]\nenabled = true\n")).unwrap();
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
    let t_ = RunTables::read(&out);
    let series = &t_.series;
    let experiments: Vec<&String> = t_.by.keys().filter(|e| !e.is_empty()).collect();
    assert_eq!(series.len(), experiments.len());
    assert!(series.len() >= 4, "{series:?}");
    // The terminal's table: a header and one line per test.
    assert!(
        so.lines()
            .any(|l| l.starts_with("series ") && l.contains("alpha") && l.contains("clusters")),
        "{so}"
    );
    let check = |r: &BTreeMap<String, String>| series_wrong(r, &t_);
    for r in series {
        assert_eq!(check(r), Vec::<String>::new());
    }
    let exp = series
        .iter()
        .find(|r| r["experiment"] == "EXP2009")
        .unwrap();
    assert_eq!(exp["hits_with_load"], "6");
    let fitted: Vec<&BTreeMap<String, String>> =
        series.iter().filter(|r| !r["alpha"].is_empty()).collect();
    assert!(!fitted.is_empty(), "{series:?}");
    // Plants: one too many of each count, the cumulative exponent for α.
    for col in ["rejects", "clusters", "significant_trends", "energy_n"] {
        let mut p = series[0].clone();
        p.insert(col.into(), (p[col].parse::<u64>().unwrap() + 1).to_string());
        assert!(!check(&p).is_empty(), "plant {col} + 1 passed");
    }
    let mut p = fitted[0].clone();
    p.insert(
        "alpha".into(),
        (p["alpha"].parse::<f64>().unwrap() - 1.0).to_string(),
    );
    assert!(!check(&p).is_empty(), "plant alpha − 1 passed");
    // The same α by the Python powerlaw package at the same x_min.
    let fits: BTreeMap<String, (Vec<f64>, f64)> = fitted
        .iter()
        .map(|r| {
            let e = &r["experiment"];
            let x_min = of(&t_.stats, e).next().unwrap()["energy_x_min_eu"]
                .parse()
                .unwrap();
            (e.clone(), (t_.energies[e].clone(), x_min))
        })
        .collect();
    if let Some(alphas) = powerlaw_alphas(t.path(), &fits) {
        assert_eq!(alphas.len(), fitted.len());
        for r in &fitted {
            let a: f64 = r["alpha"].parse().unwrap();
            let b = alphas[&r["experiment"]];
            assert!(
                (a - b).abs() < 1e-9 * b,
                "{}: {a} against powerlaw's {b}",
                r["experiment"]
            );
        }
    }
}
