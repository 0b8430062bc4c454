//! Whole-signal FFT work in f64 for the simulator and the synthetic experiment: zero-phase
//! mask filters and power spectra. Plans come from a per-thread [`Planner64`] that keeps one
//! plan per (length, direction), each made by a fresh RustFFT planner, so a result depends
//! on the length alone (never on what else a thread planned before) and a signal's filter
//! costs no planning once its length was met. The cache is bounded.

use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use std::cell::RefCell;
use std::collections::HashMap;
use std::sync::Arc;

/// At most this many plans are kept per thread.
const MAX_PLANS: usize = 32;

/// Plans by (length, inverse?), each from a fresh planner.
#[derive(Default)]
pub struct Planner64 {
    plans: HashMap<(usize, bool), Arc<dyn Fft<f64>>>,
}

impl Planner64 {
    pub fn plan(&mut self, n: usize, inverse: bool) -> Arc<dyn Fft<f64>> {
        if let Some(p) = self.plans.get(&(n, inverse)) {
            return p.clone();
        }
        if self.plans.len() >= MAX_PLANS {
            self.plans.clear();
        }
        let mut planner = FftPlanner::new();
        let p = if inverse {
            planner.plan_fft_inverse(n)
        } else {
            planner.plan_fft_forward(n)
        };
        self.plans.insert((n, inverse), p.clone());
        p
    }
}

thread_local! {
    static PLANNER: RefCell<Planner64> = RefCell::new(Planner64::default());
}

/// `x` zero-padded to `n` (≥ its length) and transformed: its complex spectrum.
pub fn spectrum(x: &[f64], n: usize) -> Vec<Complex<f64>> {
    let mut buf: Vec<Complex<f64>> = (0..n)
        .map(|k| Complex::new(x.get(k).copied().unwrap_or(0.0), 0.0))
        .collect();
    PLANNER.with(|p| p.borrow_mut().plan(n, false).process(&mut buf));
    buf
}

/// A zero-phase filter: `x` zero-padded to `n`, its spectrum multiplied by `gain(f)` at each
/// bin's (folded) frequency `f` in Hz, transformed back; the first `x.len()` samples.
pub fn zero_phase(x: &[f64], n: usize, fs: f64, gain: impl Fn(f64) -> f64) -> Vec<f64> {
    if x.is_empty() {
        return vec![];
    }
    let mut buf = spectrum(x, n);
    for (k, c) in buf.iter_mut().enumerate() {
        let f = k.min(n - k) as f64 * fs / n as f64;
        *c *= gain(f) / n as f64;
    }
    PLANNER.with(|p| p.borrow_mut().plan(n, true).process(&mut buf));
    buf[..x.len()].iter().map(|c| c.re).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_all_pass_mask_gives_the_signal_back_and_a_band_mask_keeps_its_band() {
        let fs = 1e6;
        let x: Vec<f64> = (0..256)
            .map(|i| {
                let t = i as f64 / fs;
                (2.0 * std::f64::consts::PI * 50e3 * t).sin()
                    + (2.0 * std::f64::consts::PI * 300e3 * t).sin()
            })
            .collect();
        let same = zero_phase(&x, 256, fs, |_| 1.0);
        assert!(x.iter().zip(&same).all(|(a, b)| (a - b).abs() < 1e-12));
        // 50 kHz and 300 kHz fall on bins (12.8 and 76.8 of 256: not exactly; use a wide mask).
        let low = zero_phase(&x, 256, fs, |f| if f < 150e3 { 1.0 } else { 0.0 });
        let pure: Vec<f64> = (0..256)
            .map(|i| (2.0 * std::f64::consts::PI * 50e3 * i as f64 / fs).sin())
            .collect();
        let err: f64 = low
            .iter()
            .zip(&pure)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            / 256.0;
        assert!(err < 0.01, "{err}");
        // The same length twice gives the same bits (a cached plan equals a fresh one).
        assert_eq!(
            zero_phase(&x, 512, fs, |f| (-f / 1e5).exp()),
            zero_phase(&x, 512, fs, |f| (-f / 1e5).exp())
        );
    }
}
