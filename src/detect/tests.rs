use super::*;

fn params() -> Params {
    Params {
        threshold_v: Some(1.0),
        floating_factor: 4.0,
        floating_window: 1000,
        ddt: 10,
        rearm: 5,
        max_duration: 1000,
        pdt: 3,
        pre: 3,
        post: 4,
        split_gap: None,
    }
}

/// A stream of `n` zeros with unit spikes (2.0, above the 1.0 threshold) at `at`.
fn spikes(n: usize, at: &[usize]) -> Vec<f32> {
    let mut x = vec![0.0f32; n];
    for &k in at {
        x[k] = 2.0;
    }
    x
}

fn cut_in_blocks<T: Sample>(x: &[T], p: Params, unit_v: f64, block: usize) -> Vec<Cut> {
    let mut d = Detector::<T>::new(p, unit_v, 1e6);
    let mut out = Vec::new();
    for b in x.chunks(block) {
        d.push(b, &mut out);
    }
    d.finish(&mut out);
    out
}

fn cut(x: &[f32], p: Params) -> Vec<Cut> {
    let all = cut_in_blocks(x, p, 1.0, x.len().max(1));
    // Any block size gives the same hits.
    for b in [1usize, 7, 64, 1000] {
        assert_eq!(cut_in_blocks(x, p, 1.0, b), all, "blocks of {b}");
    }
    all
}

fn firsts(c: &[Cut]) -> Vec<(u64, u64)> {
    c.iter().map(|c| (c.first, c.last)).collect()
}

/// Each rule at its edge: one sample inside and one outside (ddt 10, rearm 5).
#[test]
fn ddt_and_rearm_at_their_edges() {
    let p = params();
    // A crossing ddt after the last continues the hit; one sample later it does not, and
    // falls in the blind time.
    assert_eq!(firsts(&cut(&spikes(400, &[100, 110]), p)), [(100, 110)]);
    assert_eq!(firsts(&cut(&spikes(400, &[100, 111]), p)), [(100, 100)]);
    // The hit ends at E = 110; blind 111..=115; armed at 116.
    assert_eq!(firsts(&cut(&spikes(400, &[100, 115]), p)), [(100, 100)]);
    assert_eq!(
        firsts(&cut(&spikes(400, &[100, 116]), p)),
        [(100, 100), (116, 116)]
    );
    let c = cut(&spikes(400, &[100, 116]), p);
    assert_eq!(c[0].end, 110);
    assert!(!c[0].by_max_duration && !c[0].at_stream_end);
    // The record: 3 samples before the first crossing, 4 after the last.
    assert_eq!((c[0].start, c[0].samples.len()), (97, 8));
    assert_eq!(c[0].samples[3], 2.0);
    assert_eq!((c[0].counts, c[0].peak, c[0].peak_v), (1, 100, 2.0));
    assert!((c[0].energy_eu - 4.0 / 1e6 * 1e14).abs() < 1e-3);
}

/// A hit is ended at max_duration whatever follows; the crossing at the end is no trigger.
#[test]
fn max_duration_ends_a_hit() {
    let p = Params {
        max_duration: 50,
        ..params()
    };
    let at: Vec<usize> = (100..=200).step_by(5).collect();
    let c = cut(&spikes(400, &at), p);
    // Crossings 100..145 belong to the first hit (< 150); E = 150; blind 151..=155; the
    // spike at 160 starts the second.
    assert_eq!(c[0].first, 100);
    assert_eq!(c[0].last, 145);
    assert_eq!(c[0].end, 150);
    assert!(c[0].by_max_duration);
    assert_eq!(c[1].first, 160);
    assert_eq!(c[1].last, 200);
    assert_eq!(c.len(), 2);
}

/// A hit under way at the stream's end is cut there, and says so.
#[test]
fn the_stream_ends_inside_a_hit() {
    // The last crossing at 114 would be continued to 124: the stream ends at 115.
    let c = cut(&spikes(116, &[100, 105, 114]), params());
    assert_eq!(c.len(), 1);
    assert_eq!((c[0].first, c[0].last), (100, 114));
    assert!(c[0].at_stream_end);
    assert_eq!(c[0].start + c[0].samples.len() as u64, 116);
}

/// Two bursts in one hit are flagged when the gap between them (samples below the
/// threshold) reaches split_gap.
#[test]
fn split_gap_flags_two_bursts() {
    // Crossings at 100 and 109: 8 samples below between them.
    let x = spikes(300, &[100, 109]);
    for (gap, flag) in [(8, true), (9, false)] {
        let p = Params {
            split_gap: Some(gap),
            ..params()
        };
        let c = cut(&x, p);
        assert_eq!(c.len(), 1);
        assert_eq!(c[0].two_bursts, flag, "split_gap {gap}");
    }
}

/// Gaussian noise of σ under a 6σ threshold: no hit in 2·10⁶ samples (expected 0.004).
#[test]
fn no_false_hit_at_the_stated_noise() {
    let mut rng = crate::util::Rng::new(3);
    let x: Vec<f32> = (0..2_000_000).map(|_| rng.normal() as f32).collect();
    let p = Params {
        threshold_v: Some(6.0),
        ..params()
    };
    assert!(cut_in_blocks(&x, p, 1.0, 65_536).is_empty());
}

/// int16 counts and the same stream in volts give the same hits.
#[test]
fn counts_and_volts_cut_alike() {
    let mut rng = crate::util::Rng::new(5);
    let unit = 1e-5;
    let mut counts: Vec<i16> = (0..200_000)
        .map(|_| (3.0 * rng.normal()).round() as i16)
        .collect();
    for (k, amp) in [(10_000usize, 200.0), (60_000, 900.0), (150_000, 80.0)] {
        for j in 0..400 {
            let v = amp * (-(j as f64) / 80.0).exp() * (j as f64 * 0.6).sin();
            counts[k + j] = counts[k + j].saturating_add(v.round() as i16);
        }
    }
    let volts: Vec<f32> = counts.iter().map(|&c| (c as f64 * unit) as f32).collect();
    let p = Params {
        threshold_v: Some(40.0 * unit),
        ..params()
    };
    let a = cut_in_blocks(&counts, p, unit, 4096);
    let b = cut_in_blocks(&volts, p, 1.0, 5000);
    assert_eq!(firsts(&a), firsts(&b));
    assert_eq!(a.len(), 3);
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.samples.len(), y.samples.len());
        assert!((x.peak_v - y.peak_v).abs() < 1e-9);
    }
}

/// The floating threshold: not armed in the first window, then factor × the noise RMS.
#[test]
fn a_floating_threshold_follows_the_noise() {
    let mut rng = crate::util::Rng::new(7);
    let mut x: Vec<f32> = (0..100_000).map(|_| (0.01 * rng.normal()) as f32).collect();
    // A burst in the first window (not armed yet) and one after.
    x[500] = 1.0;
    x[50_000] = 1.0;
    let p = Params {
        threshold_v: None,
        floating_factor: 8.0,
        floating_window: 10_000,
        ..params()
    };
    let mut d = Detector::<f32>::new(p, 1.0, 1e6);
    let mut out = Vec::new();
    d.push(&x, &mut out);
    d.finish(&mut out);
    assert_eq!(firsts(&out), [(50_000, 50_000)]);
    let thr = d.threshold_v().unwrap();
    assert!((thr - 0.08).abs() < 0.004, "{thr}");
}

/// A hit whose first crossing is the stream's first sample counts that rising edge.
#[test]
fn a_hit_at_the_first_sample_counts_its_edge() {
    let x = spikes(100, &[0, 5]);
    let c = cut(&x, params());
    assert_eq!(firsts(&c), [(0, 5)]);
    assert_eq!(c[0].counts, 2);
    assert_eq!(c[0].start, 0);
}

/// A floating threshold with hits (and their blind times) across window boundaries, fed in
/// blocks of any size: every burst found, the same hits whatever the blocks.
#[test]
fn a_floating_threshold_across_window_boundaries() {
    let mut rng = crate::util::Rng::new(9);
    let mut x: Vec<f32> = (0..60_000).map(|_| (0.01 * rng.normal()) as f32).collect();
    // Bursts of 30 samples ending near and across each 1 000-sample window boundary.
    let at = [5_990usize, 12_995, 20_000, 33_985, 41_999];
    for &k in &at {
        for j in 0..30 {
            x[k + j] += if j % 2 == 0 { 1.0 } else { -1.0 };
        }
    }
    x[50_000] = f32::NAN; // one bad sample: the threshold keeps its value
    x[55_000] = 1.0;
    let p = Params {
        threshold_v: None,
        floating_factor: 8.0,
        floating_window: 1000,
        ..params()
    };
    let all = cut_in_blocks(&x, p, 1.0, x.len());
    for b in [7usize, 64, 999, 1000, 4096] {
        assert_eq!(cut_in_blocks(&x, p, 1.0, b), all, "blocks of {b}");
    }
    let firsts: Vec<u64> = all.iter().map(|c| c.first).collect();
    assert_eq!(firsts, [5_990, 12_995, 20_000, 33_985, 41_999, 55_000]);
}

/// A detector snapshotted after any block, serialised as a watcher commits it, and
/// restored on the samples it held cuts on exactly as the one never stopped (fixed and
/// floating thresholds, a hit under way and a hit waiting for its post-trigger samples at
/// the cut); the frontier is never after a hit still to come.
#[test]
fn a_restored_detector_cuts_on_as_if_never_stopped() {
    let mut rng = crate::util::Rng::new(3);
    let mut x: Vec<f32> = (0..20_000).map(|_| 0.1 * rng.normal() as f32).collect();
    for at in [500usize, 530, 2_000, 2_012, 7_000, 7_900, 12_345, 19_950] {
        for j in 0..40 {
            x[at + j] += 3.0 * (-(j as f32) / 10.0).exp() * if j % 2 == 0 { 1.0 } else { -1.0 };
        }
    }
    let fixed = params();
    let floating = Params {
        threshold_v: None,
        ..params()
    };
    for p in [fixed, floating] {
        let whole = cut_in_blocks(&x, p, 1.0, 333);
        assert!(whole.len() >= 5, "{:?}: {}", p.threshold_v, whole.len());
        for stop in [505usize, 520, 540, 2_005, 2_030, 7_950, 12_400, 15_000] {
            let mut d = Detector::<f32>::new(p, 1.0, 1e6);
            let mut out = Vec::new();
            d.push(&x[..stop], &mut out);
            // Every hit not cut yet starts at the frontier or later.
            let u = d.frontier();
            let s: Snapshot =
                serde_json::from_str(&serde_json::to_string(&d.snapshot()).unwrap()).unwrap();
            let h = s.history();
            let held = &x[h.start as usize..h.end as usize];
            let mut r = Detector::<f32>::restore(p, 1.0, 1e6, s, held).expect("restored");
            assert!(Detector::<f32>::restore(p, 1.0, 1e6, r.snapshot(), &held[1..]).is_none());
            let before = out.len();
            for b in x[stop..].chunks(1000) {
                r.push(b, &mut out);
            }
            r.finish(&mut out);
            assert!(out[before..].iter().all(|c| c.first >= u), "stop {stop}");
            assert_eq!(out, whole, "stop {stop}, {:?}", p.threshold_v);
        }
    }
}
