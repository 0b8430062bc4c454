//! Trend statistics in plain Rust (thesis Eq. 4.5.5 and Table 4.3): Pearson's r, the
//! two-sided p value of H0: ρ = 0 (Student t with n − 2 degrees of freedom, as SciPy's
//! `linregress`), and the least-squares line y = m·x + c.
//!
//! p is computed as the regularised incomplete beta `I_{df/(df+t²)}(df/2, 1/2)`, which keeps
//! full relative precision for tiny p (1e-250) where `1 − cdf(t)` would cancel.

/// Why a trend has no numbers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum NoTrend {
    /// Fewer than 3 points: no degrees of freedom left for p.
    TooFew(usize),
    /// x or y does not vary: r is undefined.
    Constant(&'static str),
    /// NaN or infinite input.
    NotFinite,
}

impl std::fmt::Display for NoTrend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NoTrend::TooFew(n) => write!(f, "n = {n} < 3: no trend can be tested"),
            NoTrend::Constant(which) => write!(f, "{which} is constant: r is undefined"),
            NoTrend::NotFinite => write!(f, "NaN or infinite values"),
        }
    }
}

/// Pearson correlation, its two-sided p value and the least-squares line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearTrend {
    pub n: usize,
    pub r: f64,
    pub p: f64,
    pub slope: f64,
    pub intercept: f64,
    /// Standard error of the slope.
    pub slope_stderr: f64,
}

/// Fit y against x.
pub fn linear_trend(x: &[f64], y: &[f64]) -> Result<LinearTrend, NoTrend> {
    assert_eq!(x.len(), y.len());
    let mut f = TrendFit::default();
    for (&a, &b) in x.iter().zip(y) {
        f.pass1(a, b);
    }
    f.end1()?;
    for (&a, &b) in x.iter().zip(y) {
        f.pass2(a, b);
    }
    f.end2()?;
    for (&a, &b) in x.iter().zip(y) {
        f.pass3(a, b);
    }
    Ok(f.finish())
}

/// [`linear_trend`] in three passes over the points, so that a series too large to hold
/// can be fitted as it streams by: the means, then the sums about them (numerically
/// stable), then the residuals. Every sum adds in the points' order, as a slice's would,
/// so a streamed fit equals the in-memory one to the bit.
#[derive(Debug, Clone)]
pub struct TrendFit {
    n: usize,
    sx: f64,
    sy: f64,
    finite: bool,
    mx: f64,
    my: f64,
    sxx: f64,
    syy: f64,
    sxy: f64,
    fit: Option<LinearTrend>,
    sse: f64,
}

impl Default for TrendFit {
    fn default() -> Self {
        TrendFit {
            n: 0,
            // `Iterator::sum` of f64 starts from −0.0.
            sx: -0.0,
            sy: -0.0,
            finite: true,
            mx: 0.0,
            my: 0.0,
            sxx: 0.0,
            syy: 0.0,
            sxy: 0.0,
            fit: None,
            sse: -0.0,
        }
    }
}

impl TrendFit {
    /// Points seen in pass 1.
    pub fn points(&self) -> usize {
        self.n
    }

    pub fn pass1(&mut self, x: f64, y: f64) {
        self.n += 1;
        self.sx += x;
        self.sy += y;
        self.finite &= x.is_finite() && y.is_finite();
    }

    /// After pass 1: whether there is a trend to fit at all.
    pub fn end1(&mut self) -> Result<(), NoTrend> {
        if self.n < 3 {
            return Err(NoTrend::TooFew(self.n));
        }
        if !self.finite {
            return Err(NoTrend::NotFinite);
        }
        let nf = self.n as f64;
        self.mx = self.sx / nf;
        self.my = self.sy / nf;
        Ok(())
    }

    pub fn pass2(&mut self, x: f64, y: f64) {
        let (dx, dy) = (x - self.mx, y - self.my);
        self.sxx += dx * dx;
        self.syy += dy * dy;
        self.sxy += dx * dy;
    }

    /// After pass 2: r, p, the line (pass 3 then sums the residuals).
    pub fn end2(&mut self) -> Result<(), NoTrend> {
        let (sxx, syy, sxy) = (self.sxx, self.syy, self.sxy);
        if sxx == 0.0 {
            return Err(NoTrend::Constant("x"));
        }
        if syy == 0.0 {
            return Err(NoTrend::Constant("y"));
        }
        let r = (sxy / (sxx.sqrt() * syy.sqrt())).clamp(-1.0, 1.0);
        let slope = sxy / sxx;
        let intercept = self.my - slope * self.mx;
        let df = self.n as f64 - 2.0;
        let one_minus_r2 = ((1.0 - r) * (1.0 + r)).max(0.0);
        let p = if one_minus_r2 == 0.0 {
            0.0
        } else {
            // t² = df·r²/(1 − r²); x = df/(df + t²) = 1 − r².
            beta_inc(df / 2.0, 0.5, one_minus_r2)
        };
        self.fit = Some(LinearTrend {
            n: self.n,
            r,
            p,
            slope,
            intercept,
            slope_stderr: f64::NAN,
        });
        Ok(())
    }

    pub fn pass3(&mut self, x: f64, y: f64) {
        if let Some(f) = &self.fit {
            // Residual sum of squares summed explicitly: (1 − r²)·s_yy cancels when r → 1.
            self.sse += (y - f.intercept - f.slope * x).powi(2);
        }
    }

    /// The fit (after a successful [`TrendFit::end2`] and pass 3).
    pub fn finish(&self) -> LinearTrend {
        let mut f = self.fit.expect("end2 succeeded");
        let df = self.n as f64 - 2.0;
        f.slope_stderr = (self.sse / df / self.sxx).sqrt();
        f
    }
}

/// ln Γ(x) for x > 0 (Lanczos, g = 7, 9 terms: ~1e-15 relative).
pub fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection.
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + G + 0.5;
    for (i, &c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised incomplete beta I_x(a, b) (continued fraction, modified Lentz).
pub fn beta_inc(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let ln_front = ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln();
    // Use the symmetry that converges fast.
    if x < (a + 1.0) / (a + b + 2.0) {
        ln_front.exp() * beta_cf(a, b, x) / a
    } else {
        1.0 - ln_front.exp() * beta_cf(b, a, 1.0 - x) / b
    }
}

fn beta_cf(a: f64, b: f64, x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    if d.abs() < TINY {
        d = TINY;
    }
    d = 1.0 / d;
    let mut h = d;
    for m in 1..10_000 {
        let m = m as f64;
        let m2 = 2.0 * m;
        let aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        d = 1.0 + aa * d;
        if d.abs() < TINY {
            d = TINY;
        }
        c = 1.0 + aa / c;
        if c.abs() < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        h *= d * c;
        let aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        d = 1.0 + aa * d;
        if d.abs() < TINY {
            d = TINY;
        }
        c = 1.0 + aa / c;
        if c.abs() < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        let del = d * c;
        h *= del;
        if (del - 1.0).abs() < 1e-16 {
            break;
        }
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_gamma_and_beta_values() {
        assert!((ln_gamma(1.0)).abs() < 1e-14);
        assert!((ln_gamma(5.0) - 24f64.ln()).abs() < 1e-13);
        assert!((ln_gamma(0.5) - std::f64::consts::PI.sqrt().ln()).abs() < 1e-13);
        // I_x(1, 1) = x; I_x(a, 1) = x^a; I_0.5(a, a) = 0.5.
        assert!((beta_inc(1.0, 1.0, 0.3) - 0.3).abs() < 1e-14);
        assert!((beta_inc(3.0, 1.0, 0.4) - 0.064).abs() < 1e-14);
        assert!((beta_inc(7.5, 7.5, 0.5) - 0.5).abs() < 1e-13);
    }

    #[test]
    fn student_t_p_values_match_tables() {
        // df = 10: two-sided p of t = 2.228 is 0.05, of t = 3.169 is 0.01 (t tables).
        for (t, want) in [(2.228_138_851_986_522, 0.05), (3.169_272_672_616_951, 0.01)] {
            let df: f64 = 10.0;
            let p = beta_inc(df / 2.0, 0.5, df / (df + t * t));
            assert!((p - want).abs() / want < 1e-9, "t {t}: {p}");
        }
    }

    #[test]
    fn exact_line_and_known_correlation() {
        let x: Vec<f64> = (1..=10).map(f64::from).collect();
        let y: Vec<f64> = x.iter().map(|v| 3.0 * v - 2.0).collect();
        let t = linear_trend(&x, &y).unwrap();
        assert!((t.slope - 3.0).abs() < 1e-12 && (t.intercept + 2.0).abs() < 1e-12);
        assert_eq!((t.r, t.p), (1.0, 0.0));
        // Anscombe's first set: r = 0.81642, slope 0.5001, intercept 3.0001.
        let ax = [10.0, 8.0, 13.0, 9.0, 11.0, 14.0, 6.0, 4.0, 12.0, 7.0, 5.0];
        let ay = [
            8.04, 6.95, 7.58, 8.81, 8.33, 9.96, 7.24, 4.26, 10.84, 4.82, 5.68,
        ];
        let t = linear_trend(&ax, &ay).unwrap();
        assert!((t.r - 0.816_420_516_3).abs() < 1e-9, "{}", t.r);
        assert!((t.slope - 0.500_090_909_1).abs() < 1e-9);
        assert!((t.intercept - 3.000_090_909_1).abs() < 1e-9);
        assert!((t.p - 0.002_169_628_873).abs() < 1e-10, "{}", t.p);
    }

    #[test]
    fn degenerate_inputs_say_why() {
        assert_eq!(
            linear_trend(&[1.0, 2.0], &[1.0, 2.0]),
            Err(NoTrend::TooFew(2))
        );
        assert_eq!(
            linear_trend(&[1.0, 2.0, 3.0], &[5.0, 5.0, 5.0]),
            Err(NoTrend::Constant("y"))
        );
        assert_eq!(
            linear_trend(&[1.0, 2.0, 3.0], &[5.0, f64::NAN, 5.0]),
            Err(NoTrend::NotFinite)
        );
    }
}
