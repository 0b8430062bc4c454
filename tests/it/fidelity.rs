//! Fidelity (issue 14): the simulator, the ch. 4.7 criteria and the fibre-failure sweep
//! checked on signals the criteria were not tuned on. The library here is the embedded
//! definition with seed 4242, a seed no design choice was made on (material draws and noise
//! differ from every library looked at while choosing the criteria's thresholds).

use crate::TempDir;
use aepipe::sim::reference::{build_library, ReferenceFile};
use std::collections::BTreeMap;

/// (label, criteria label, fault) of every signal of a library's feature table.
fn labelled(dir: &std::path::Path) -> Vec<(String, String, String)> {
    let wf = dir.join("lib/waveforms.parquet");
    let out = dir.join("feat");
    let (c, _, se) = crate::aepipe(&[
        "features",
        &wf.display().to_string(),
        "--out",
        &out.display().to_string(),
    ]);
    assert_eq!(c, 0, "{se}");
    let (names, rows) = crate::table_rows(&out.join("features.parquet"));
    let (wn, wrows) = crate::table_rows(&wf);
    let col = |n: &str, names: &[String]| names.iter().position(|x| x == n).unwrap();
    let params: BTreeMap<(String, String), String> = wrows
        .iter()
        .map(|r| {
            (
                (r[col("hit", &wn)].clone(), r[col("channel", &wn)].clone()),
                r[col("sim_params", &wn)].clone(),
            )
        })
        .collect();
    rows.iter()
        .map(|r| {
            let p = &params[&(
                r[col("hit", &names)].clone(),
                r[col("channel", &names)].clone(),
            )];
            let v: serde_json::Value = serde_json::from_str(p).unwrap();
            (
                r[col("label", &names)].clone(),
                r[col("criteria_label", &names)].clone(),
                v["fault"].as_str().unwrap_or("").to_string(),
            )
        })
        .collect()
}

#[test]
fn the_criteria_give_the_simulated_library_its_mechanisms() {
    let d = TempDir::new("fidelity-lib");
    let mut f = ReferenceFile::default_library();
    f.reference.seed = 4242;
    let (_, n, _) = build_library(&f.reference, &d.path().join("lib"), false).unwrap();
    let rows = labelled(d.path());
    assert_eq!(rows.len() as u64, n);
    let count =
        |pred: &dyn Fn(&(String, String, String)) -> bool| rows.iter().filter(|r| pred(r)).count();
    // Bond failures must be called bond failures; a fibre failure may also be called "both"
    // (ch. 5.4: a fibre failure's contraction is a pulse and the structure it shakes a wave,
    // "theoretically all the AEs within this group should be classified as fibre failures").
    let bond = count(&|r| r.0 == "bond_failure");
    let fibre = count(&|r| r.0 == "fibre_failure");
    let bond_ok = count(&|r| r.0 == "bond_failure" && r.1 == "bond_failure");
    let fibre_ok = count(&|r| r.0 == "fibre_failure" && (r.1 == "fibre_failure" || r.1 == "both"));
    let both_for_fibre = count(&|r| r.0 == "fibre_failure" && r.1 == "both");
    eprintln!(
        "library (seed 4242): bond {bond_ok}/{bond}, fibre {fibre_ok}/{fibre} ({both_for_fibre} as both)"
    );
    // Per material draw and sensor: the mesh's 2 kinks × 2 stretches, the structure's 12
    // break points.
    let per = f.reference.variants * f.reference.sensors.len();
    assert_eq!((bond, fibre), (4 * per, 12 * per));
    assert!(
        (bond_ok + fibre_ok) as f64 >= 0.90 * (bond + fibre) as f64,
        "bond {bond_ok}/{bond}, fibre {fibre_ok}/{fibre}"
    );
    assert!(
        bond_ok as f64 >= 0.90 * bond as f64,
        "bond {bond_ok}/{bond}"
    );
    // The erroneous records: the time-domain checks see the faults they were made with.
    for fault in ["before_front", "clipped", "two_signals"] {
        let all = count(&|r| r.2 == fault);
        let seen = count(&|r| r.2 == fault && r.1 == "erroneous");
        eprintln!("{fault}: {seen}/{all} erroneous by the criteria");
        // 6 erroneous records from each of the mesh's 4 simulations per draw, 3 faults.
        assert_eq!(all, 8 * f.reference.variants, "{fault}");
        let need = if fault == "two_signals" { 0.75 } else { 1.0 };
        assert!(seen as f64 >= need * all as f64, "{fault}: {seen}/{all}");
    }
}

/// Fig. 4.23 says a fibre failure's frequency rises with 1/L of the piece left on fibre 2's
/// side (13 − p springs of 71.4 µm). At the library's step (Appendix A's 10 ns) the model with
/// bonds coupled per fibre (issue 51) does not: at sensor 1 every break point rings in the
/// thesis's 800–1 700 kHz, but the frequency is not linear in 1/L over points 1–8. That is
/// the step's, not the structure's: implicit Euler damps a 1.25 MHz mode at ω²Δt/2 ≈ 3·10⁵
/// 1/s at 10 ns, gone in microseconds; at a converged step points 7–12 rise with the break
/// point, though points 1–6 still do not order
/// ([`the_fibre_failure_converges_in_the_step_and_rises_with_the_break_point`]).
#[test]
fn fibre_failure_frequency_does_not_follow_the_released_length() {
    use aepipe::sim::scenario::{self, Params};
    let g = scenario::paper_grid();
    let mut f = Vec::new();
    for p in 1..=12 {
        let m = scenario::build(
            "structure2x1-fibre-failure",
            &Params(vec![
                ("point".into(), p as f64),
                ("iterations".into(), 6000.0),
            ]),
        )
        .unwrap();
        let out = aepipe::sim::simulate(&m, &Default::default()).unwrap();
        let s = aepipe::sim::output::band_limited(&out.sensors[0], &g);
        f.push(aepipe::sim::dominant_frequency(&s, 1e7));
    }
    eprintln!(
        "dominant (kHz): {:?}",
        f.iter().map(|x| (x / 1e3).round()).collect::<Vec<_>>()
    );
    let inv_l: Vec<f64> = (1..=12).map(|p| 1.0 / (13 - p) as f64).collect();
    assert!(f.iter().all(|&x| (800e3..1700e3).contains(&x)), "{f:?}");
    let fit = aepipe::analysis::stats::linear_trend(&inv_l[..8], &f[..8]).unwrap();
    assert!(
        fit.r < 0.9,
        "r = {}: the frequency follows 1/L again",
        fit.r
    );
    // Not strictly rising with the point either.
    assert!(!f[..8].windows(2).all(|w| w[1] > w[0]), "{f:?}");
}

/// Fig. 4.24, at the source: from 1.0 % to 2.0 % extension of fibre 3 (point 7) the released
/// piece's free end rings at one frequency (every run within half the 60 µs record's bin,
/// ±8.3 kHz, of the mean; measured 1 137.7–1 141.0 kHz) with more energy. The thesis puts it
/// at "around 1175 kHz"; the model's 1 138.6 kHz is 3.1 % under (pinned, below).
/// Plants: a spread of one bin and the thesis's own 1175 kHz each fail their check. At the sensor
/// the band-limited spectrum's peak does move (928 → 1161 → 1139 kHz): there the piece's ring is
/// mixed with the tension-dependent motion of the structure (see docs/fidelity.md).
#[test]
fn a_failing_fibre_rings_at_one_frequency_whatever_its_extension() {
    use aepipe::sim::scenario::{self, Params};
    let mut rows = Vec::new();
    let mut out_len = 0;
    for k in 0..6 {
        let stretch = 0.010 + 0.002 * k as f64;
        let m = scenario::build(
            "structure2x1-fibre-failure",
            &Params(vec![
                ("point".into(), 7.0),
                ("stretch".into(), stretch),
                ("iterations".into(), 6000.0),
            ]),
        )
        .unwrap();
        // Node velocities every 10 steps of 10 ns: 10 MHz, like the sensors.
        let opts = aepipe::sim::SimOptions {
            trajectory_every: Some(10),
            snapshot_every: None,
        };
        let out = aepipe::sim::simulate(&m, &opts).unwrap();
        let energy = |i: usize| {
            out.trajectory
                .iter()
                .map(|f| f.u[i][0].powi(2))
                .sum::<f64>()
        };
        let node = (0..m.nodes.len())
            .max_by(|&a, &b| energy(a).total_cmp(&energy(b)))
            .unwrap();
        let ux: Vec<f64> = out.trajectory.iter().map(|f| f.u[node][0]).collect();
        out_len = ux.len();
        rows.push((
            stretch,
            node,
            aepipe::sim::dominant_frequency(&ux, 1e7),
            energy(node),
        ));
    }
    eprintln!("(stretch, node, f, Σu²): {rows:?}");
    // The same node moves most each time: the free end the break leaves (fibre 3's centre).
    assert!(rows.iter().all(|r| r.1 == rows[0].1), "{rows:?}");
    let mean = rows.iter().map(|r| r.2).sum::<f64>() / rows.len() as f64;
    // One frequency: every run within half a bin of the record's resolution (600 frames at
    // 10 MHz, 60 µs: 1/T = 16.7 kHz, ±8.3 kHz), not the ±5 % (±58 kHz) it once allowed.
    let half_bin = 0.5 * 1e7 / out_len as f64;
    let one = |f: &[f64]| {
        let m = f.iter().sum::<f64>() / f.len() as f64;
        f.iter().all(|x| (x - m).abs() <= half_bin)
    };
    // Against the thesis's "around 1175 kHz" at ±2 % (written before the first run, in place
    // of anywhere in the 800–1 700 kHz every break point spans) it failed: the free end rings
    // at 1 138.6 kHz, 3.1 % under it (not the step's: implicit Euler's phase error at
    // ωΔt = 0.072 is −0.17 %). Recorded in docs/fidelity.md and pinned here at the measured
    // value ± half a bin, a regression guard, not a verdict.
    let pinned = |m: f64| (m - 1138.6e3).abs() <= half_bin && (m / 1175e3 - 1.0).abs() > 0.02;
    let f: Vec<f64> = rows.iter().map(|r| r.2).collect();
    assert!(one(&f), "{rows:?}: spread beyond ±{half_bin} Hz");
    assert!(
        pinned(mean),
        "{mean} Hz: the pin is 1138.6 kHz ± {half_bin} Hz"
    );
    // Plants: one run a bin off; the thesis's own value.
    let mut off = f.clone();
    off[3] += 2.0 * half_bin;
    assert!(!one(&off) && !pinned(1175e3));
    // More extension, more strain energy released: the ring grows with it.
    assert!(rows.windows(2).all(|w| w[1].3 > w[0].3), "{rows:?}");
}

/// The fibre failure at Fig. 4.26–4.28's break points (1, 7, 12), 36 µm grid, sensor 1, over
/// 40 µs at the step halved twice (5, 2.5, 1.25 ns): each point's dominant frequency holds
/// within 1.5 %, and it rises with the break point as the thesis's does (800, 1 250,
/// 1 750 kHz). At Appendix A's 10 ns the same runs miss it: implicit Euler's damping
/// (ω²Δt/2) takes the high modes out, and point 12 rings more than 40 % low.
#[test]
fn the_fibre_failure_converges_in_the_step_and_rises_with_the_break_point() {
    use aepipe::sim::scenario::{self, Params};
    let at = |point: u32, dt: f64| -> f64 {
        let m = scenario::build(
            "structure2x1-fibre-failure",
            &Params(vec![
                ("point".into(), point as f64),
                ("grid_um".into(), 36.0),
                ("dt".into(), dt),
                ("iterations".into(), (40e-6 / dt).round()),
            ]),
        )
        .unwrap();
        let g = m.grid.clone().unwrap();
        let out = aepipe::sim::simulate(&m, &Default::default()).unwrap();
        let s = aepipe::sim::output::band_limited(&out.sensors[0], &g);
        aepipe::sim::dominant_frequency(&s, out.sample_rate_hz)
    };
    let mut converged = Vec::new();
    for point in [1, 7, 12] {
        let f: Vec<f64> = [5e-9, 2.5e-9, 1.25e-9]
            .iter()
            .map(|&dt| at(point, dt))
            .collect();
        eprintln!(
            "point {point}: {:?} kHz",
            f.iter()
                .map(|x| (x / 1e2).round() / 10.0)
                .collect::<Vec<_>>()
        );
        let (lo, hi) = f
            .iter()
            .fold((f64::MAX, f64::MIN), |(l, h), &x| (l.min(x), h.max(x)));
        assert!(hi / lo - 1.0 < 0.015, "point {point}: {f:?}");
        converged.push(f[1]);
    }
    assert!(
        converged[0] < converged[1] && converged[1] < converged[2],
        "{converged:?}"
    );
    let coarse = at(12, 1e-8);
    assert!(
        coarse < 0.6 * converged[2],
        "10 ns: {coarse} against {}",
        converged[2]
    );
}
