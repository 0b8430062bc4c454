//! `aepipe thesis` against its record: every entry `docs/thesis.md` names is declared and
//! every declared entry is named there; each runs (all together in ~30 s here) and gives the
//! verdict the record states; an unknown entry is refused before anything runs.

use crate::{aepipe, TempDir};

/// (entry, verdict) of each row of docs/thesis.md's table.
fn record() -> Vec<(String, String)> {
    record_rows()
        .into_iter()
        .map(|(id, _, verdict)| (id, verdict))
        .collect()
}

/// The cells of the rows of docs/thesis.md's table whose header starts with `header`.
fn table(header: &str) -> Vec<Vec<String>> {
    let text =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/thesis.md")).unwrap();
    text.lines()
        .skip_while(|l| !l.starts_with(header))
        .skip(2)
        .take_while(|l| l.starts_with("| `"))
        .map(|l| {
            l.trim_start_matches("| ")
                .trim_end_matches(" |")
                .split(" | ")
                .map(|c| c.trim().to_string())
                .collect()
        })
        .collect()
}

/// Each entry's tolerance, its source and its expected departure as `src/thesis/mod.rs`
/// declares them are the record's (its "Tolerances and expected departures" table), in
/// the same order: the record says why each verdict's bound is what it is.
#[test]
fn the_record_states_each_tolerance_and_departure_the_code_uses() {
    let rows = table("| entry | tolerance |");
    let declared = aepipe::thesis::ENTRIES;
    assert_eq!(rows.len(), declared.len(), "one row per entry");
    let pct = |r: f64| format!("{}", (r * 100.0 * 1e6).round() / 1e6);
    for (row, e) in rows.iter().zip(declared) {
        assert_eq!(row[0], format!("`{}`", e.id));
        assert_eq!(row[1], format!("±{} %", pct(e.tolerance.rel)), "{}", e.id);
        assert_eq!(row[2], e.tolerance.source, "{}", e.id);
        let want = match e.departs {
            None => "—".to_string(),
            Some(d) => format!(
                "{} ± {} % ({}): {} (±: {})",
                d.expected,
                pct(d.tolerance.rel),
                d.basis.as_str(),
                d.evidence,
                d.tolerance.source
            ),
        };
        assert_eq!(row[3], want, "{}", e.id);
    }
}

/// (entry, the value the record prints for aepipe, verdict) of each row of the table.
fn record_rows() -> Vec<(String, String, String)> {
    let text =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/thesis.md")).unwrap();
    text.lines()
        .skip_while(|l| !l.starts_with("| entry | where |"))
        .skip(2)
        .take_while(|l| l.starts_with("| `"))
        .map(|l| {
            let cells: Vec<&str> = l.split(" | ").map(str::trim).collect();
            (
                cells[0]
                    .trim_start_matches("| ")
                    .trim_matches('`')
                    .to_string(),
                cells[cells.len() - 2].to_string(),
                cells[cells.len() - 1].trim_end_matches(" |").to_string(),
            )
        })
        .collect()
}

/// The number a record cell opens with, and half a unit of its last printed digit: the
/// record's own precision. `52 135 1/s` → (52135, 0.5); `5.30·10⁴ 1/kg` → (53000, 50);
/// `−0.51 (p = …)` → (−0.51, 0.005); `1 533.3 kHz` → (1533.3, 0.05).
fn printed(cell: &str) -> Option<(f64, f64)> {
    let s = cell.replace('−', "-");
    let b: Vec<char> = s.chars().collect();
    let mut i = 0;
    let mut digits = String::new();
    if matches!(b.first(), Some('+' | '-')) {
        digits.push(b[0]);
        i = 1;
    }
    let mut decimals: Option<i32> = None;
    while i < b.len() {
        let c = b[i];
        if c.is_ascii_digit() {
            digits.push(c);
            if let Some(d) = decimals.as_mut() {
                *d += 1;
            }
        } else if c == '.' && decimals.is_none() {
            digits.push(c);
            decimals = Some(0);
        } else if c == ' '
            && decimals.is_none()
            && b.len() >= i + 4
            && b[i + 1..i + 4].iter().all(char::is_ascii_digit)
            && b.get(i + 4).is_none_or(|n| !n.is_ascii_digit())
        {
            // A thousands group.
        } else {
            break;
        }
        i += 1;
    }
    let mut v: f64 = digits.parse().ok()?;
    let mut exp = 0i32;
    let rest: String = b[i..].iter().collect();
    if let Some(e) = rest.strip_prefix("·10") {
        let sup = |c: char| "⁰¹²³⁴⁵⁶⁷⁸⁹".chars().position(|d| d == c);
        let neg = e.starts_with('⁻');
        let n: String = e
            .chars()
            .skip(neg as usize)
            .map_while(|c| sup(c).map(|d| char::from(b'0' + d as u8)))
            .collect();
        exp = n.parse::<i32>().ok()? * if neg { -1 } else { 1 };
        v *= 10f64.powi(exp);
    }
    Some((v, 0.5 * 10f64.powi(exp - decimals.unwrap_or(0))))
}

#[test]
fn the_record_cells_read_as_their_printed_precision() {
    let near = |cell: &str, v: f64, half: f64| {
        let (a, h) = printed(cell).unwrap();
        assert!(
            (a - v).abs() <= 1e-9 * v.abs().max(1.0) && (h - half).abs() <= 1e-12 * half.max(1e-12),
            "{cell}: {a} ± {h}"
        );
    };
    near("52 135 1/s (+4.3 %)", 52135.0, 0.5);
    near("5.30·10⁴ 1/kg (+68 %)", 53000.0, 50.0);
    near("−0.51 (p = 4·10⁻⁶)", -0.51, 0.005);
    near("1 533.3 kHz (−0.3 %)", 1533.3, 0.05);
    near("0.05466 1/s (+0.2 %)", 0.05466, 0.000005);
    near("8·10⁻⁷ 1/s", 8e-7, 5e-8);
    assert_eq!(printed("agrees"), None);
}

#[test]
fn every_entry_runs_and_gives_the_verdict_the_record_states() {
    let rows = record();
    let values = record_rows();
    let declared: Vec<&str> = aepipe::thesis::ENTRIES.iter().map(|e| e.id).collect();
    let named: Vec<&str> = rows.iter().map(|(id, _)| id.as_str()).collect();
    assert_eq!(
        named, declared,
        "docs/thesis.md and thesis::ENTRIES disagree"
    );
    let t = TempDir::new("thesis");
    for e in aepipe::thesis::ENTRIES {
        let o = aepipe::thesis::run(e, t.path()).unwrap();
        let want = &rows.iter().find(|(id, _)| id == e.id).unwrap().1;
        let got = o.verdict.as_str();
        assert_eq!(
            got, want,
            "{}: aepipe {} against {}",
            e.id, o.aepipe, e.thesis
        );
        // The value the record prints for aepipe is the run's, to the printed precision:
        // a departure is expected exactly where the record says, and a NaN or a value
        // elsewhere fails whichever the verdict.
        let cell = &values.iter().find(|(id, _, _)| id == e.id).unwrap().1;
        let (shown, half) =
            printed(cell).unwrap_or_else(|| panic!("{}: no number in {cell:?}", e.id));
        assert!(
            (o.aepipe - shown).abs() <= half * (1.0 + 1e-9),
            "{}: the run gives {} where the record prints {cell:?} (±{half})",
            e.id,
            o.aepipe
        );
        // Its figure and its data.
        let files: Vec<String> = std::fs::read_dir(&o.dir)
            .unwrap()
            .map(|f| f.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        for ext in [".parquet", ".png"] {
            assert!(
                files.iter().any(|f| f.ends_with(ext)),
                "{}: no {ext} in {files:?}",
                e.id
            );
        }
    }
    let (code, _, err) = aepipe(&["thesis", "fig-9.99", "--out", t.path().to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(
        err.contains("unknown entry") && err.contains("fig-3.14"),
        "{err}"
    );
}

/// docs/thesis.md covers chapters 3–6: every figure and table the thesis captions (read from
/// its text in `../shared/seed/`) has its row in the record's coverage table.
#[test]
fn the_record_names_every_figure_and_table() {
    let seed = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/seed/000_25ce7f3daeccd66a.txt");
    let Ok(thesis) = std::fs::read_to_string(&seed) else {
        crate::skip(
            "the_record_names_every_figure_and_table",
            &format!("{} is absent (the thesis's text)", seed.display()),
        );
        return;
    };
    let record =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/thesis.md")).unwrap();
    let rows: std::collections::BTreeSet<&str> = record
        .lines()
        .filter_map(|l| l.strip_prefix("| "))
        .filter_map(|l| l.split(" |").next())
        .collect();
    let mut captions = Vec::new();
    for line in thesis.lines() {
        for (word, short) in [("Figure ", "Fig. "), ("Table ", "Table ")] {
            let Some(rest) = line.strip_prefix(word) else {
                continue;
            };
            let Some((id, _)) = rest.split_once(':') else {
                continue;
            };
            let chapter = id.split('.').next().unwrap_or("");
            if ["3", "4", "5", "6"].contains(&chapter)
                && id.split('.').count() == 2
                && id.chars().all(|c| c.is_ascii_digit() || c == '.')
            {
                captions.push(format!("{short}{id}"));
            }
        }
    }
    captions.sort();
    captions.dedup();
    assert!(captions.len() > 80, "{} captions read", captions.len());
    let missing: Vec<&String> = captions
        .iter()
        .filter(|c| !rows.contains(c.as_str()))
        .collect();
    assert!(
        missing.is_empty(),
        "no row in docs/thesis.md for {missing:?}"
    );
}

/// A sensor's pressure in a scenario (band-limited, Pa) and its dominant frequency.
fn heard(name: &str, params: &[(&str, f64)], sensor: usize) -> (Vec<f64>, f64) {
    use aepipe::sim::scenario::{build, Params};
    let m = build(
        name,
        &Params(params.iter().map(|(k, v)| (k.to_string(), *v)).collect()),
    )
    .unwrap();
    let out = aepipe::sim::simulate(&m, &Default::default()).unwrap();
    let x = aepipe::sim::output::band_limited(&out.sensors[sensor], m.grid.as_ref().unwrap());
    let f = aepipe::sim::dominant_frequency(&x, out.sample_rate_hz);
    (x, f)
}

/// How far (of the peak) two runs of the same motion may differ: 100 × the mechanics' Newton
/// stop (a residual of 1e-8).
const SAME_MOTION: f64 = 1e-6;

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let peak = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
        / peak
}

/// Eq. 4.5.6's damaged mesh against what it generalises and against the string: intact, the
/// centre bond's failure is Fig. 4.8's (mesh3x3 without its second failure); bent along a
/// column and heard at sensor 2 it is its diagonal mirror bent along a row and heard at
/// sensor 1; and with the row's neighbouring bonds gone the released free length grows from
/// 1 to 1.5 and 2 mm, so its fundamental falls as 1/L at the same tension (Eq. 4.2.2).
///
/// The same motion by another formula, and a mirror image, agree to [`SAME_MOTION`] of the
/// peak: the mechanics' Newton iteration stops at a residual of 1e-8, so the runs may differ
/// there and not above (measured: 2.7e-9, 5.9e-12 and 3.0e-11). The bounds were 0.5 % and
/// 5 % while a bond's coupling direction turned on the round-off (2.8 % and 3.9 % then);
/// bonds are coupled per fibre now, and a wrong bond, direction or sensor moves the signal
/// by percent. Plant: the column-bent bond heard at the row-bent bond's sensor (sensor 1
/// instead of its mirror sensor 2) must differ by more than the bound.
#[test]
fn the_damaged_mesh_is_the_mesh_its_mirror_and_a_longer_string() {
    let (mesh, f_mesh) = heard("mesh3x3-bond-failure", &[("t2", -1.0)], 0);
    let (intact, f1) = heard("mesh3x3-damaged-bond-failure", &[], 0);
    // Not to the bit: the same shape by another formula differs at the Newton tolerance.
    let d = max_abs_diff(&mesh, &intact);
    eprintln!("intact vs mesh3x3: {d:e}");
    assert!(
        d < SAME_MOTION,
        "intact centre failure differs from mesh3x3 by {d}"
    );
    assert!((f1 / f_mesh - 1.0).abs() < 0.002, "{f1} vs {f_mesh}");
    // Bond 1 (the bottom row's middle) bent along its column, heard at sensor 2 (1.8 mm to
    // the left), mirrors bond 3 (the middle row's left) bent along its row, at sensor 1.
    let (col, _) = heard(
        "mesh3x3-damaged-bond-failure",
        &[("bond", 1.0), ("along", 1.0)],
        1,
    );
    let (row, _) = heard("mesh3x3-damaged-bond-failure", &[("bond", 3.0)], 0);
    let d = max_abs_diff(&row, &col);
    eprintln!("mirror: {d:e}");
    assert!(d < SAME_MOTION, "mirror differs by {d}");
    // Plant: the column-bent bond at the row-bent bond's own sensor is no mirror.
    let (wrong, _) = heard(
        "mesh3x3-damaged-bond-failure",
        &[("bond", 1.0), ("along", 1.0)],
        0,
    );
    let d = max_abs_diff(&row, &wrong);
    assert!(
        d > 100.0 * SAME_MOTION,
        "the wrong sensor passes as a mirror: {d}"
    );
    // And in a damaged mesh: bond 5 bent along its column after bonds 0 and 4, against bond
    // 7 bent along its row after bonds 0 and 4 (the mirror of {0, 4} is {0, 4}).
    let (col, _) = heard(
        "mesh3x3-damaged-bond-failure",
        &[("broken", 17.0), ("bond", 5.0), ("along", 1.0)],
        1,
    );
    let (row, _) = heard(
        "mesh3x3-damaged-bond-failure",
        &[("broken", 17.0), ("bond", 7.0)],
        0,
    );
    let d = max_abs_diff(&row, &col);
    eprintln!("damaged mirror: {d:e}");
    assert!(d < SAME_MOTION, "damaged mirror differs by {d}");
    // The centre with bond 5 gone (1.5 mm), with bonds 3 and 5 gone (2 mm).
    for (broken, l) in [(1 << 5, 1.5), ((1 << 3) | (1 << 5), 2.0)] {
        let span = aepipe::sim::paper::damaged_span(broken, 4, 0);
        assert!((span - l * 1e-3).abs() < 1e-12, "free length {span}");
        let (_, f) = heard(
            "mesh3x3-damaged-bond-failure",
            &[("broken", broken as f64)],
            0,
        );
        // Within 3 % (2 mm: +2.3 %; the mesh's 1 mm span already rings 2.7 % below the lone
        // plucked fibre of Fig. 4.17); 1/√L, say, would be 18 and 29 % off.
        assert!(
            (f * l / f1 - 1.0).abs() < 0.03,
            "{l} mm: {f} Hz, against {} from 1/L",
            f1 / l
        );
    }
    // The bent shape of an off-centre failure: bond 5 (the middle row's right) after bond 4
    // (the centre) is bent from bond 3 (−0.5 mm) to the held end (+1 mm), peaked at the
    // bond with the full kink, rising on one side and falling on the other.
    {
        use aepipe::sim::scenario::{build, Params};
        let m = build(
            "mesh3x3-damaged-bond-failure",
            &Params(vec![("broken".into(), 16.0), ("bond".into(), 5.0)]),
        )
        .unwrap();
        let a = 2e-3 / 28.0;
        let mut bent: Vec<(f64, f64)> = m
            .initial
            .iter()
            .filter(|ic| m.nodes[ic.node].y.abs() < 1e-12 && ic.dy != 0.0)
            .map(|ic| (m.nodes[ic.node].x, ic.dy))
            .collect();
        bent.sort_by(|p, q| p.0.total_cmp(&q.0));
        let xs: Vec<i64> = bent.iter().map(|p| (p.0 / a).round() as i64).collect();
        assert_eq!(xs, (-6..=13).collect::<Vec<_>>(), "bent between −7 and 14");
        let (at, peak) = bent
            .iter()
            .copied()
            .max_by(|p, q| p.1.total_cmp(&q.1))
            .unwrap();
        assert_eq!(((at / a).round(), peak), (7.0, 1e-5), "peaked at the bond");
        for w in bent.windows(2) {
            let rising = w[1].0 <= at;
            assert!((w[1].1 > w[0].1) == rising, "monotone on each side: {w:?}");
        }
    }
    // Refused by name: a bond failing twice, a bond outside the mesh.
    use aepipe::sim::scenario::{build, Params};
    let p = |kv: &[(&str, f64)]| Params(kv.iter().map(|(k, v)| (k.to_string(), *v)).collect());
    let e = build("mesh3x3-damaged-bond-failure", &p(&[("broken", 16.0)])).unwrap_err();
    assert!(e.to_string().contains("fails once"), "{e}");
    let e = build("mesh3x3-damaged-bond-failure", &p(&[("bond", 9.0)])).unwrap_err();
    assert!(e.to_string().contains("bond must be"), "{e}");
}
