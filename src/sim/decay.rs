//! The decay of a simulated signal (Eqs. 3.5.1–3.5.2): its envelope fitted by
//! y = y₀·e^(−γt), and the mechano-acoustic attenuation ratio α = γ/b of a model with
//! frictional damping b.
//!
//! The envelope is half the peak-to-peak swing in each period of the signal's dominant
//! frequency, from the period that holds the global peak on, until it falls below [`FLOOR`]
//! of the first (the rest is the solver's round-off or the recording's end). Half the swing,
//! not the largest |x|, so that an offset (a displaced equilibrium, leading silence that
//! moves the mean) does not floor the envelope: one period of a damped sine is e^(−γT)
//! times the period before it, swing and all. ln y is fitted by least squares
//! against t; R² says how exponential the decay is (a structure whose modes beat gives a
//! lower one).

/// Envelope points below this share of the peak are not fitted.
pub const FLOOR: f64 = 1e-3;

/// An exponential fit to a signal's envelope.
#[derive(Debug, Clone, PartialEq)]
pub struct Decay {
    /// γ, 1/s: the envelope falls as e^(−γt).
    pub gamma_hz: f64,
    /// y₀ of the fit, at `t0_s`, in the signal's unit.
    pub y0: f64,
    /// Time of the first envelope point (the global peak's period), s from the signal's
    /// first sample.
    pub t0_s: f64,
    /// Coefficient of determination of the fit of ln y.
    pub r2: f64,
    /// The envelope points fitted: (t s, half the swing of that period).
    pub points: Vec<(f64, f64)>,
}

impl Decay {
    /// α = γ/b (1/kg) for a model with frictional damping `b` (kg/s); none without damping.
    pub fn alpha_per_kg(&self, b: f64) -> Option<f64> {
        (b > 0.0).then(|| self.gamma_hz / b)
    }

    /// The fitted envelope at time `t` s.
    pub fn at(&self, t: f64) -> f64 {
        self.y0 * (-self.gamma_hz * (t - self.t0_s)).exp()
    }
}

/// Fit the decay of `x` sampled every `dt` s whose dominant period is `period_s`. None
/// when the signal is silent, the period is not finite and positive, or fewer than three
/// periods stand above [`FLOOR`].
pub fn fit(x: &[f64], dt: f64, period_s: f64) -> Option<Decay> {
    if !(dt > 0.0 && period_s.is_finite() && period_s > 0.0) || x.len() < 4 {
        return None;
    }
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    let a = |k: usize| (x[k] - mean).abs();
    let peak_k = (0..x.len()).max_by(|&i, &j| a(i).total_cmp(&a(j)))?;
    if a(peak_k) <= 0.0 || !a(peak_k).is_finite() {
        return None;
    }
    let w = ((period_s / dt).round() as usize).max(1);
    // Windows aligned so that the global peak's window starts half a period before it.
    let start = peak_k.saturating_sub(w / 2);
    let mut points: Vec<(f64, f64)> = Vec::new();
    let mut k = start;
    while k + w <= x.len() {
        let win = &x[k..k + w];
        let (lo, hi) = win
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
                (l.min(v), h.max(v))
            });
        let swing = 0.5 * (hi - lo);
        if swing <= 0.0 || points.first().is_some_and(|p| swing < FLOOR * p.1) {
            break;
        }
        // The window's time: midway between its crest and its trough (which of the two is
        // "farther" from the centre would be decided by rounding).
        let at = |v: f64| win.iter().position(|&x| x == v).unwrap_or(0);
        let kk = 0.5 * (at(hi) + at(lo)) as f64;
        points.push(((k as f64 + kk) * dt, swing));
        k += w;
    }
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let (st, sl) = points
        .iter()
        .fold((0.0, 0.0), |(st, sl), &(t, v)| (st + t, sl + v.ln()));
    let (mt, ml) = (st / n, sl / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for &(t, v) in &points {
        let (dx, dy) = (t - mt, v.ln() - ml);
        sxy += dx * dy;
        sxx += dx * dx;
        syy += dy * dy;
    }
    if sxx <= 0.0 {
        return None;
    }
    let slope = sxy / sxx;
    let t0 = points[0].0;
    let r2 = if syy > 0.0 {
        (sxy * sxy) / (sxx * syy)
    } else {
        1.0
    };
    Some(Decay {
        gamma_hz: -slope,
        y0: (ml + slope * (t0 - mt)).exp(),
        t0_s: t0,
        r2,
        points,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_damped_sine_gives_back_its_decay_constant() {
        let (fs, f, g) = (10e6, 250e3, 5.0e4);
        let x: Vec<f64> = (0..4000)
            .map(|k| {
                let t = k as f64 / fs;
                if t < 20e-6 {
                    0.0
                } else {
                    let t = t - 20e-6;
                    2.0 * (-g * t).exp() * (2.0 * std::f64::consts::PI * f * t).sin()
                }
            })
            .collect();
        let d = fit(&x, 1.0 / fs, 1.0 / f).unwrap();
        assert!((d.gamma_hz / g - 1.0).abs() < 0.01, "{d:?}");
        assert!(d.r2 > 0.999, "{}", d.r2);
        // y₀ is the envelope at its first point, 2·e^(−γ·(t0 − 20 µs)), to within the
        // half-period between a swing's crest and trough (e^(γT/2) = 1.105 here).
        let want = 2.0 * (-g * (d.t0_s - 20e-6)).exp();
        assert!((d.y0 / want - 1.0).abs() < 0.105, "{} vs {want}", d.y0);
        assert_eq!(d.alpha_per_kg(0.0), None);
        assert!((d.alpha_per_kg(1.5e-6).unwrap() - d.gamma_hz / 1.5e-6).abs() < 1e-6);
    }

    #[test]
    fn silence_and_too_short_a_decay_fit_nothing() {
        assert_eq!(fit(&[0.0; 100], 1e-7, 4e-6), None);
        // A decay that is below the floor after two periods.
        let x: Vec<f64> = (0..400)
            .map(|k| (-(k as f64) * 0.5).exp() * (k as f64 * 0.63).sin())
            .collect();
        assert_eq!(fit(&x, 1.0, 10.0), None);
        assert_eq!(fit(&x, 1.0, f64::NAN), None);
    }
}
