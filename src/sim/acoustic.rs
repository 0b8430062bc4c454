//! The 2-D acoustic pressure wave equation (ch. 3.3): explicit FDTD of 2nd (Eq. 3.3.11) or
//! 4th (Eq. 3.3.13) spatial order with the non-reflecting boundaries of Eq. 3.3.21, and
//! point sources added as a pressure forcing c²·Δt²·s (ch. 3.4, Eq. 3.4.5).

use super::model::{GridSpec, Order};

/// Pressure on an nx × ny grid at three time levels. Cell (i, j) is `p[j·nx + i]`.
#[derive(Debug, Clone)]
pub struct Field {
    pub nx: usize,
    pub ny: usize,
    pub alpha: f64,
    pub order: Order,
    /// c²·Δt², the factor of a source term.
    pub src_scale: f64,
    pub prev: Vec<f64>,
    pub cur: Vec<f64>,
    next: Vec<f64>,
    /// Sources of the step being built (added to `next`).
    pub sources: Vec<f64>,
}

impl Field {
    /// `spec` must have passed [`super::model::ModelFile::check`] (stability, square cells).
    pub fn new(spec: &GridSpec) -> Field {
        let n = spec.nx * spec.ny;
        Field {
            nx: spec.nx,
            ny: spec.ny,
            alpha: spec.alpha(),
            order: spec.order,
            src_scale: spec.c * spec.c * spec.dt * spec.dt,
            prev: vec![0.0; n],
            cur: vec![0.0; n],
            next: vec![0.0; n],
            sources: vec![0.0; n],
        }
    }

    #[inline]
    pub fn idx(&self, i: usize, j: usize) -> usize {
        j * self.nx + i
    }

    /// Add a source of strength `s` (the right-hand side of ∂²p/∂t² = c²∇²p + c²·s, in
    /// Pa/m²) at cell (i, j) for the coming step.
    pub fn add_source(&mut self, i: usize, j: usize, s: f64) {
        let k = self.idx(i, j);
        self.sources[k] += s;
    }

    /// Advance one time step.
    pub fn step(&mut self) {
        let (nx, ny) = (self.nx, self.ny);
        let a2 = self.alpha * self.alpha;
        let (p, q) = (&self.cur, &self.prev);
        let out = &mut self.next;
        match self.order {
            Order::Second => {
                let c0 = 2.0 * (1.0 - 2.0 * a2);
                for j in 1..ny - 1 {
                    let row = j * nx;
                    for i in 1..nx - 1 {
                        let k = row + i;
                        out[k] =
                            c0 * p[k] - q[k] + a2 * (p[k + 1] + p[k - 1] + p[k + nx] + p[k - nx]);
                    }
                }
            }
            Order::Fourth => {
                let c0 = 2.0 - 5.0 * a2;
                let c1 = 4.0 / 3.0 * a2;
                let c2 = a2 / 12.0;
                for j in 2..ny - 2 {
                    let row = j * nx;
                    for i in 2..nx - 2 {
                        let k = row + i;
                        out[k] = c0 * p[k] - q[k]
                            + c1 * (p[k + 1] + p[k - 1] + p[k + nx] + p[k - nx])
                            - c2 * (p[k + 2] + p[k - 2] + p[k + 2 * nx] + p[k - 2 * nx]);
                    }
                }
            }
        }
        // Non-reflecting boundaries (Eq. 3.3.21): for 4th order the inner ring first, then
        // the outer ring.
        let rings: &[usize] = match self.order {
            Order::Second => &[0],
            Order::Fourth => &[1, 0],
        };
        for &b in rings {
            self.boundary_ring(b);
        }
        for (o, s) in self.next.iter_mut().zip(self.sources.iter_mut()) {
            *o += self.src_scale * *s;
            *s = 0.0;
        }
        std::mem::swap(&mut self.prev, &mut self.cur);
        std::mem::swap(&mut self.cur, &mut self.next);
    }

    /// Eq. 3.3.21 on ring `b` (0 = outermost): each cell looks one and two cells inwards.
    fn boundary_ring(&mut self, b: usize) {
        let (nx, ny, a) = (self.nx, self.ny, self.alpha);
        let (p, q) = (&self.cur, &self.prev);
        let out = &mut self.next;
        let mut set = |k: usize, k1: usize, k2: usize| {
            out[k] = p[k] + p[k1] - q[k1] + a * (p[k1] - p[k] - (q[k2] - q[k1]));
        };
        // South (j = b) and north (j = ny−1−b) rows, over the ring's extent.
        for i in b..nx - b {
            let (s, n) = (b, ny - 1 - b);
            set(s * nx + i, (s + 1) * nx + i, (s + 2) * nx + i);
            set(n * nx + i, (n - 1) * nx + i, (n - 2) * nx + i);
        }
        // West and east columns, without the corners already set.
        for j in b + 1..ny - 1 - b {
            let (w, e) = (b, nx - 1 - b);
            set(j * nx + w, j * nx + w + 1, j * nx + w + 2);
            set(j * nx + e, j * nx + e - 1, j * nx + e - 2);
        }
    }

    pub fn at(&self, i: usize, j: usize) -> f64 {
        self.cur[self.idx(i, j)]
    }

    /// Σp² over the grid (a measure of the acoustic energy left in the domain).
    pub fn energy(&self) -> f64 {
        self.cur.iter().map(|v| v * v).sum()
    }
}

/// What the grid carries: below `pass_hz` waves travel at close to the speed of sound, above
/// `stop_hz` they hardly travel at all. From the scheme's dispersion relation along a grid
/// axis (the worst direction), sin²(ωΔt/2) = α²·S(kΔh) with S(θ) = sin²(θ/2) (2nd order) or
/// (4/3)·sin²(θ/2) − (1/12)·sin²θ (4th order): `pass_hz` is the frequency whose group
/// velocity is 20 % below c, `stop_hz` the one 50 % below. For the Appendix-A grid (72 µm,
/// 0.1 µs, air, 4th order) they are 1.51 and 1.77 MHz (3.2 and 2.7 cells per wavelength);
/// the highest frequency the grid can hold along an axis is 1.90 MHz, where the group
/// velocity is zero: energy put there stays where it was made and rings (the "1950–2000 kHz"
/// components simulated bond failures used to show).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BandLimit {
    pub pass_hz: f64,
    pub stop_hz: f64,
}

/// [`BandLimit`] of a grid (checked: stable Courant number).
pub fn band_limit(g: &GridSpec) -> BandLimit {
    let h = g.dx();
    let a = g.alpha();
    let s = |th: f64| match g.order {
        Order::Second => (th / 2.0).sin().powi(2),
        Order::Fourth => 4.0 / 3.0 * (th / 2.0).sin().powi(2) - (th.sin().powi(2)) / 12.0,
    };
    let omega = |k: f64| 2.0 / g.dt * (a * s(k * h).max(0.0).sqrt()).min(1.0).asin();
    let n = 20_000;
    let dk = std::f64::consts::PI / h / n as f64;
    let mut pass = None;
    for i in 1..n {
        let k = i as f64 * dk;
        let vg = (omega(k + 0.5 * dk) - omega(k - 0.5 * dk)) / dk;
        if pass.is_none() && vg <= 0.8 * g.c {
            pass = Some(omega(k) / (2.0 * std::f64::consts::PI));
        }
        if vg <= 0.5 * g.c {
            let stop = omega(k) / (2.0 * std::f64::consts::PI);
            return BandLimit {
                pass_hz: pass.unwrap_or(stop),
                stop_hz: stop,
            };
        }
    }
    let top = omega(std::f64::consts::PI / h) / (2.0 * std::f64::consts::PI);
    BandLimit {
        pass_hz: pass.unwrap_or(top),
        stop_hz: top,
    }
}

/// Zero-phase low-pass by FFT mask: gain 1 up to `pass_hz`, a raised cosine down to 0 at
/// `stop_hz`. Zero phase keeps every passed component where the grid put it. (A causal,
/// minimum-phase version of the same magnitude was tried: its group delay near the edge
/// held 1.4–1.5 MHz fibre pulses back by 2–4 µs, past "the start of the record". The price
/// of zero phase is a ripple ahead of a sharp front: for an impulse, 4 % of its peak 2 µs
/// ahead and 0.2 % 5 µs ahead; on simulated signals it moves a 40 dB_AE trigger under a
/// 90 dB_AE hit up to ~1 µs early.) The
/// signal is zero-padded to twice its length so the filter's tails do not wrap round.
pub fn low_pass(x: &[f64], fs: f64, pass_hz: f64, stop_hz: f64) -> Vec<f64> {
    if x.is_empty() || fs <= 0.0 {
        return x.to_vec();
    }
    let n = (2 * x.len()).next_power_of_two();
    let width = (stop_hz - pass_hz).max(f64::MIN_POSITIVE);
    crate::dsp::filter::zero_phase(x, n, fs, |f| {
        if f <= pass_hz {
            1.0
        } else if f >= stop_hz {
            0.0
        } else {
            0.5 + 0.5 * (std::f64::consts::PI * (f - pass_hz) / width).cos()
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_appendix_a_grid_carries_up_to_about_1_5_mhz() {
        let b = band_limit(&crate::sim::scenario::paper_grid());
        assert!((1.45e6..1.55e6).contains(&b.pass_hz), "{b:?}");
        assert!((1.70e6..1.82e6).contains(&b.stop_hz), "{b:?}");
        // Twice as fine a grid (same Courant number) carries twice the band.
        let mut g = crate::sim::scenario::paper_grid();
        g.nx *= 2;
        g.ny *= 2;
        g.dt /= 2.0;
        let b2 = band_limit(&g);
        assert!((b2.pass_hz / b.pass_hz - 2.0).abs() < 0.01, "{b2:?}");
    }

    #[test]
    fn low_pass_keeps_the_pass_band_and_removes_the_stop_band() {
        let fs = 10e6;
        let tone = |f: f64| -> Vec<f64> {
            (0..4000)
                .map(|i| (2.0 * std::f64::consts::PI * f * i as f64 / fs).sin())
                .collect()
        };
        let rms = |x: &[f64]| (x[1000..3000].iter().map(|v| v * v).sum::<f64>() / 2000.0).sqrt();
        let lo = low_pass(&tone(500e3), fs, 1.5e6, 1.76e6);
        let hi = low_pass(&tone(1.9e6), fs, 1.5e6, 1.76e6);
        assert!((rms(&lo) / rms(&tone(500e3)) - 1.0).abs() < 1e-3);
        assert!(rms(&hi) < 1e-3 * rms(&tone(1.9e6)));
        // Zero phase: an impulse stays where it was, and its ripple (an impulse is all
        // edge) is below 0.2 % of the peak 5 µs away.
        let mut imp = vec![0.0; 2000];
        imp[1000] = 1.0;
        let y = low_pass(&imp, fs, 1.5e6, 1.76e6);
        let top = (0..y.len()).max_by(|&a, &b| y[a].total_cmp(&y[b])).unwrap();
        assert_eq!(top, 1000);
        let far = y[..950]
            .iter()
            .chain(&y[1051..])
            .fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(far < 2e-3 * y[1000], "{far}");
    }
}
