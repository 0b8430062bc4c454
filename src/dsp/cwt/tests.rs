use super::*;

fn bank() -> WaveletBank {
    WaveletBank::from_config(&CwtConfig::default())
}

/// The default bank and its full-resolution power of `x` (n_freqs × n, row-major).
fn default_full_power(x: &[f32], fs: f64) -> (WaveletBank, Vec<f32>) {
    let b = bank();
    let mut cwt = Cwt::new(b.clone());
    cwt.load(x, fs);
    let mut out = vec![0.0; b.freqs_hz.len() * x.len()];
    cwt.full_power(x, fs, &mut out);
    (b, out)
}

/// The row of the grid frequency `f`.
fn row_of(b: &WaveletBank, f: f64) -> usize {
    b.freqs_hz
        .iter()
        .position(|&g| (g - f).abs() < 1.0)
        .unwrap()
}

fn sine(n: usize, f: f64, fs: f64, a: f64) -> Vec<f32> {
    (0..n)
        .map(|i| (a * (2.0 * PI * f * i as f64 / fs).sin()) as f32)
        .collect()
}

#[test]
fn default_grid_is_10_to_2500_khz_in_10_khz_steps() {
    let b = bank();
    assert_eq!(b.freqs_hz.len(), 250);
    assert!((b.freqs_hz[0] - 10e3).abs() < 1e-6);
    assert!((b.freqs_hz[249] - 2500e3).abs() < 1e-6);
    assert!((b.freqs_hz[1] - b.freqs_hz[0] - 10e3).abs() < 1e-6);
    // FWHM of 2 periods: Δf/f = FWHM_f / f ≈ 0.44.
    let f = 500e3;
    let rel = FWHM_SIGMAS * b.sigma_f(f) / f;
    assert!((rel - 0.4413).abs() < 1e-3, "{rel}");
    // Time FWHM = 2 periods.
    assert!((FWHM_SIGMAS * b.sigma_t(f) - 2.0 / f).abs() < 1e-15);
}

#[test]
fn sine_ridge_is_at_its_frequency_with_its_amplitude() {
    let fs = 10e6;
    let n = 4096;
    let b = bank();
    let mut cwt = Cwt::new(b.clone());
    let mut out = vec![0.0; b.freqs_hz.len() * n];
    for f_khz in [100.0, 250.0, 500.0, 750.0, 1000.0, 1200.0, 1750.0, 2000.0] {
        let f = f_khz * 1e3;
        let a = 0.37;
        let x = sine(n, f, fs, a);
        cwt.load(&x, fs);
        cwt.full_power(&x, fs, &mut out);
        // Middle of the record, away from the circular ends.
        let t = n / 2;
        let (best, p) = (0..b.freqs_hz.len())
            .map(|fi| (fi, out[fi * n + t]))
            .fold((0, 0.0f32), |m, c| if c.1 > m.1 { c } else { m });
        assert!(
            (b.freqs_hz[best] - f).abs() <= 10e3 + 1e-6,
            "{f_khz} kHz: ridge at {}",
            b.freqs_hz[best]
        );
        let amp = (p as f64).sqrt();
        assert!(
            (amp - a).abs() / a < 0.02,
            "{f_khz} kHz: |W| = {amp}, A = {a}"
        );
    }
}

#[test]
fn window_path_equals_full_path_on_the_window() {
    let fs = 10e6;
    let n = 4096;
    let mut x = sine(n, 250e3, fs, 0.1);
    for (i, v) in x.iter_mut().enumerate() {
        let t = i as f64 / fs;
        *v += (0.05 * (2.0 * PI * 1.2e6 * t).cos() * (-((t - 6e-5) / 3e-6).powi(2)).exp()) as f32;
    }
    let mut cwt = Cwt::new(bank());
    cwt.load(&x, fs);
    let mut full = vec![0.0; 250 * n];
    cwt.full_power(&x, fs, &mut full);
    let (a, b) = (500, 900);
    let mut worst = 0.0f64;
    let mut visited = 0;
    let peak = full.iter().cloned().fold(0.0f32, f32::max) as f64;
    cwt.window_power(&x, fs, a, b, |fi, p| {
        visited += 1;
        for (j, &v) in p.iter().enumerate() {
            let r = full[fi * n + a + j] as f64;
            worst = worst.max((v as f64 - r).abs() / peak);
        }
    });
    assert_eq!(visited, 250);
    assert!(worst < 1e-4, "worst difference {worst} of the peak");
}

#[test]
fn short_pulse_is_localised_in_time() {
    let fs = 10e6;
    let n = 4096;
    let t0 = 150e-6;
    let x: Vec<f32> = (0..n)
        .map(|i| {
            let t = i as f64 / fs - t0;
            ((2.0 * PI * 1.2e6 * t).cos() * (-(t / 1e-6).powi(2) / 2.0).exp()) as f32
        })
        .collect();
    let (b, out) = default_full_power(&x, fs);
    let fi = row_of(&b, 1.2e6);
    let row = &out[fi * n..(fi + 1) * n];
    let tmax = row
        .iter()
        .enumerate()
        .fold((0, 0.0f32), |m, (i, &v)| if v > m.1 { (i, v) } else { m })
        .0;
    assert!(
        ((tmax as f64 / fs) - t0).abs() < 1e-6,
        "peak at {} µs",
        tmax as f64 / fs * 1e6
    );
}

#[test]
fn two_tones_separate() {
    let fs = 10e6;
    let n = 4096;
    let x: Vec<f32> = sine(n, 250e3, fs, 0.2)
        .iter()
        .zip(sine(n, 750e3, fs, 0.1))
        .map(|(a, b)| a + b)
        .collect();
    let (b, out) = default_full_power(&x, fs);
    let t = n / 2;
    let at = |f: f64| out[row_of(&b, f) * n + t].sqrt();
    assert!(
        (at(250e3) - 0.2).abs() < 0.004 && (at(750e3) - 0.1).abs() < 0.002,
        "{} {}",
        at(250e3),
        at(750e3)
    );
    // A clear valley between them.
    assert!(at(500e3) < 0.1 * at(750e3), "valley {}", at(500e3));
}

#[test]
fn caches_stay_bounded_whatever_the_record_lengths() {
    let fs = 5e6;
    let mut cwt = Cwt::new(bank());
    let mut rng = crate::util::Rng::new(3);
    let mut padded = std::collections::BTreeSet::new();
    for _ in 0..300 {
        let n = 2250 + (rng.next_u64() % 40_000) as usize;
        let x = sine(n, 300e3, fs, 0.1);
        cwt.load(&x, fs);
        padded.insert(cwt.padded_len());
        cwt.window_power(&x, fs, 400, 600, |_, _| {});
    }
    // Many lengths, few FFT sizes, and every cache within its bound.
    assert!(padded.len() < 60, "{} padded lengths", padded.len());
    assert!(cwt.plans.len() <= MAX_PLANS);
    assert!(cwt.plan_points <= MAX_PLAN_POINTS);
    assert!(cwt.groups.len() <= MAX_GROUP_SETS);
    assert!(cwt.filter_taps <= 2 * MAX_FILTER_TAPS);
}

#[test]
fn a_record_without_pretrigger_reads_as_zeros_before_its_start() {
    // The same burst with 600 zeros in front (window at 600) and without (window at 0):
    // the short segments of the second read zeros before the record, so both agree.
    let fs = 10e6;
    let burst: Vec<f32> = (0..8192)
        .map(|i| {
            let t = i as f64 / fs;
            (0.1 * (2.0 * PI * 700e3 * t).sin() * (-t / 2e-5).exp()) as f32
        })
        .collect();
    let mut padded_x = vec![0.0f32; 600];
    padded_x.extend_from_slice(&burst);
    padded_x.truncate(8192);
    let b = bank();
    let mut with_zeros = std::collections::BTreeMap::new();
    let mut cwt = Cwt::new(b.clone());
    cwt.load(&padded_x, fs);
    cwt.window_power(&padded_x, fs, 600, 1000, |fi, p| {
        with_zeros.insert(fi, p.to_vec());
    });
    let mut cwt2 = Cwt::new(b.clone());
    cwt2.load(&burst, fs);
    let (mut compared, mut worst) = (0, 0.0f64);
    let peak = with_zeros.values().flatten().fold(0.0f32, |m, &v| m.max(v)) as f64;
    cwt2.window_power(&burst, fs, 0, 400, |fi, p| {
        let f = b.freqs_hz[fi];
        let margin = SUPPORT_SIGMAS * b.sigma_t(f) * fs;
        if margin < 550.0 {
            compared += 1;
            for (u, v) in p.iter().zip(&with_zeros[&fi]) {
                worst = worst.max((*u as f64 - *v as f64).abs() / peak);
            }
        }
    });
    assert!(compared > 150, "{compared}");
    assert!(worst < 1e-4, "worst difference {worst} of the peak");
}

/// The fast full path (interpolated along time or across frequency) against one full-length
/// inverse FFT per frequency: white noise
/// (every band full), decaying bursts at 250 kHz, 900 kHz and 1.8 MHz over a noise floor, at
/// record lengths whose padded grids divide by 4 096, 1 024 and 128, and for the features'
/// wavelet (2 periods) and the peers' Morlet ω0 = 6.
#[test]
fn fast_full_path_is_within_1e_4_of_each_rows_peak_of_the_exact_one() {
    let mut rng = crate::util::Rng::new(11);
    let mut noise = |n: usize, a: f64| -> Vec<f64> {
        (0..n)
            .map(|_| a * (rng.range(-1.0, 1.0) + rng.range(-1.0, 1.0)))
            .collect()
    };
    let mut cases = Vec::new();
    for (n, fs) in [(4096usize, 10e6), (3000, 5e6), (10_000, 5e6)] {
        cases.push((n, fs, noise(n, 1.0)));
        let mut x = noise(n, 0.01);
        for (f0, t0, tau) in [(250e3, 0.1, 60e-6), (900e3, 0.12, 5e-6), (1.8e6, 0.2, 3e-6)] {
            let t0 = t0 * n as f64 / fs;
            for (i, v) in x.iter_mut().enumerate() {
                let t = i as f64 / fs - t0;
                if t > 0.0 {
                    *v += (-t / tau).exp() * (2.0 * PI * f0 * t).sin();
                }
            }
        }
        cases.push((n, fs, x));
    }
    let mut worst = 0.0f64;
    for fwhm in [2.0, FWHM_SIGMAS * 6.0 / (2.0 * PI)] {
        let b = WaveletBank {
            fwhm_periods: fwhm,
            ..bank()
        };
        for (n, fs, x) in &cases {
            let x: Vec<f32> = x.iter().map(|&v| v as f32).collect();
            let mut cwt = Cwt::new(b.clone());
            cwt.load(&x, *fs);
            let fe = cwt.fast_path_error(&x, *fs);
            let global = fe.peak;
            let (mut not_exact, mut along_time, mut across_freq) = (0, 0, 0);
            for (fi, r) in fe.rows.iter().enumerate() {
                not_exact += usize::from(!r.bit_equal);
                // f32 rounding of the two transforms differs by ~1e-7 of the scalogram.
                let rel = r.err / (r.peak + 1e-6 * global);
                assert!(
                    rel < 1e-4,
                    "n={n} fwhm={fwhm} row {fi}: {rel:e} of the row's peak"
                );
                assert!(
                    r.err < 5e-5 * global,
                    "n={n} row {fi}: {:e}",
                    r.err / global
                );
                match cwt.decimation(fi, cwt.padded_len(), *fs) {
                    Some(d) if d > across::MAX_DECIMATION => along_time += 1,
                    Some(_) => across_freq += 1,
                    None => {}
                }
                worst = worst.max(rel);
            }
            // Both interpolations are exercised (anchor rows and rows in no run are exact).
            eprintln!(
                "n={n} fs={fs} fwhm={fwhm:.3}: {along_time} rows along time, {across_freq} \
                 across frequency, {not_exact} not bit-equal to the exact path"
            );
            assert!(along_time >= 30 && across_freq >= 40 && not_exact >= 150);
        }
    }
    eprintln!("worst error of the fast path: {worst:.2e} of a row's peak");
}

/// Where the bounds above do not hold row by row: a pure tone exactly on a bin, 3–5σ_f off
/// the centre of the rows that see it on their filter's tail (the interpolation is least
/// accurate at a band's edge, and no other content fills the row); and a user's grid with a
/// hole wider than the anchor spacing (a run ends there). Against the exact path, relative to
/// the scalogram's peak.
#[test]
fn fast_full_path_on_pure_tones_and_a_grid_with_a_hole_stays_within_5e_5_of_the_peak() {
    let (n, fs) = (4096usize, 10e6);
    let fwhm = FWHM_SIGMAS * 6.0 / (2.0 * PI);
    let mut worst = 0.0f64;
    let mut check = |freqs: Vec<f64>, x: &[f32], row_bound: Option<f64>| {
        let mut cwt = Cwt::new(WaveletBank {
            freqs_hz: freqs,
            fwhm_periods: fwhm,
        });
        cwt.load(x, fs);
        let fe = cwt.fast_path_error(x, fs);
        let global = fe.peak;
        for r in &fe.rows {
            let (err, peak) = (r.err, r.peak);
            assert!(
                err < 5e-5 * global,
                "{:e} of the scalogram's peak",
                err / global
            );
            if let Some(b) = row_bound {
                assert!(
                    err < b * (peak + 1e-6 * global),
                    "{:e} of the row's peak",
                    err / peak
                );
            }
            worst = worst.max(err / global);
        }
    };
    // Tones on bins 3, 4 and 4.9 σ_f below 740 kHz (a row decimated by 4), the whole grid.
    let df = fs / n as f64;
    let sigma = FWHM_SIGMAS * 740e3 / (2.0 * PI * fwhm);
    for k_sigma in [3.0, 4.0, 4.9] {
        let k = ((740e3 - k_sigma * sigma) / df).round();
        let x: Vec<f32> = (0..n)
            .map(|i| (2.0 * PI * k * i as f64 / n as f64).sin() as f32)
            .collect();
        check(bank().freqs_hz, &x, None);
    }
    // White noise on a grid with two holes (750–1000 kHz, then 1.6–2.5 MHz).
    let mut rng = crate::util::Rng::new(5);
    let x: Vec<f32> = (0..n).map(|_| rng.range(-1.0, 1.0) as f32).collect();
    let holey: Vec<f64> = (75..=100)
        .chain(160..=250)
        .map(|k| k as f64 * 10e3)
        .collect();
    check(holey, &x, Some(1e-4));
    eprintln!("worst: {worst:.2e} of the scalogram's peak");
}
