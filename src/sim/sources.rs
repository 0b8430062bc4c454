//! The acoustic field's own test cases (ch. 3.3.5–3.3.6): a monopole, a dipole (two opposite
//! monopoles one cell either side of the centre, along x) or a quadrupole (two opposite
//! dipoles, Fig. 3.23: + at (±1, ±1) cells on one diagonal, − on the other), driven by one
//! sine pulse or a continuous sine, at the centre of a 40 m × 40 m domain in the Section 3.3.6
//! medium (c = 1 m/s, ρ = 1 kg/m³), 4th order, Δh = 0.1 m (20 cells per wavelength at the
//! 2 s period), Δt = 0.05 s. The field is heard on a ring around the source.
//!
//! Each has an analytic directivity: the pressure's amplitude on a ring in the far field goes
//! as 1 (monopole), |cos θ| (dipole along x) and |sin 2θ| (the quadrupole's four lobes), θ
//! from the x axis; in 2-D it falls as 1/√r. A continuous source settles after a transient
//! (Fig. 3.27) into a sine at the drive's frequency.

use super::acoustic::Field;
use super::model::{GridSpec, Order};

/// The source's poles.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pole {
    Monopole,
    Dipole,
    Quadrupole,
}

impl Pole {
    /// The far field's analytic directivity at θ (radians from the x axis), peak 1.
    pub fn directivity(self, theta: f64) -> f64 {
        match self {
            Pole::Monopole => 1.0,
            Pole::Dipole => theta.cos().abs(),
            Pole::Quadrupole => (2.0 * theta).sin().abs(),
        }
    }

    /// Cell offsets and signs of the monopoles that make the source.
    fn monopoles(self) -> &'static [(i64, i64, f64)] {
        match self {
            Pole::Monopole => &[(0, 0, 1.0)],
            Pole::Dipole => &[(1, 0, 1.0), (-1, 0, -1.0)],
            Pole::Quadrupole => &[(1, 1, 1.0), (-1, -1, 1.0), (1, -1, -1.0), (-1, 1, -1.0)],
        }
    }
}

/// How the source is driven.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Drive {
    /// One period of sin(πt) (2 s), then silence (Figs. 3.22–3.23).
    Pulse,
    /// sin(πt) for ever (Fig. 3.27).
    Continuous,
}

/// The period of the drive, s (a wavelength of 2 m at c = 1 m/s).
pub const PERIOD_S: f64 = 2.0;
/// Where the ring is heard: 6 m (3 wavelengths) from the source.
pub const RING_M: f64 = 6.0;

/// What the ring heard.
#[derive(Debug, Clone)]
pub struct Heard {
    pub pole: Pole,
    pub drive: Drive,
    /// Directions, radians from the x axis, evenly around the ring.
    pub theta: Vec<f64>,
    /// Amplitude at each direction: the pulse's largest |p|, or the settled sine's half
    /// peak-to-peak over its last two periods, Pa.
    pub amplitude: Vec<f64>,
    /// The analytic directivity scaled to the measured peak.
    pub analytic: Vec<f64>,
    /// Pearson correlation of `amplitude` with the analytic directivity (the monopole, whose
    /// directivity is flat: 1 − (max − min)/max of its amplitudes).
    pub agreement: f64,
    /// On the strongest axis, the amplitude at 3 m over that at 6 m (2-D: √2).
    pub spreading: f64,
    /// The pressure at 6 m on the strongest axis, one value per step.
    pub on_axis: Vec<f64>,
    pub sample_rate_hz: f64,
    /// The field at the end, nx × ny, and its size.
    pub field: Vec<f64>,
    pub nx: usize,
    pub ny: usize,
}

/// The domain: 400 × 400 cells of 0.1 m, Δt 0.05 s (Courant 0.5), 4th order.
pub fn grid() -> GridSpec {
    GridSpec {
        x1: -20.0,
        x2: 20.0,
        y1: -20.0,
        y2: 20.0,
        nx: 400,
        ny: 400,
        dt: 0.05,
        rho: 1.0,
        c: 1.0,
        order: Order::Fourth,
        dipole_m: None,
        z: None,
    }
}

/// Run a source and hear it on the ring (`directions` points) and on its strongest axis.
pub fn run(pole: Pole, drive: Drive, directions: usize) -> Heard {
    let g = grid();
    let mut f = Field::new(&g);
    let h = g.dx();
    let centre = (g.nx / 2) as i64;
    let axis = match pole {
        Pole::Quadrupole => std::f64::consts::FRAC_PI_4,
        _ => 0.0,
    };
    let cell = |r: f64, th: f64| {
        let (x, y) = (r * th.cos(), r * th.sin());
        g.cell(x, y).expect("the ring lies inside")
    };
    let theta: Vec<f64> = (0..directions)
        .map(|k| 2.0 * std::f64::consts::PI * k as f64 / directions as f64)
        .collect();
    let ring: Vec<(usize, usize)> = theta.iter().map(|&t| cell(RING_M, t)).collect();
    let (near, far) = (cell(0.5 * RING_M, axis), cell(RING_M, axis));
    // A pulse has passed the ring after (R + 3 wavelengths)/c; a continuous source is
    // measured over two periods after four have settled at the ring.
    let settle = RING_M / g.c + 4.0 * PERIOD_S;
    let total = match drive {
        Drive::Pulse => RING_M / g.c + 4.0 * PERIOD_S,
        Drive::Continuous => settle + 2.0 * PERIOD_S,
    };
    let steps = (total / g.dt).round() as usize;
    let from = match drive {
        Drive::Pulse => 0,
        Drive::Continuous => (settle / g.dt).round() as usize,
    };
    let mut hi = vec![f64::NEG_INFINITY; directions + 2];
    let mut lo = vec![f64::INFINITY; directions + 2];
    let mut on_axis = Vec::with_capacity(steps);
    for n in 0..steps {
        let t = n as f64 * g.dt;
        let s = match drive {
            Drive::Pulse if t >= PERIOD_S => 0.0,
            _ => (2.0 * std::f64::consts::PI * t / PERIOD_S).sin() / (h * h),
        };
        for &(di, dj, sign) in pole.monopoles() {
            f.add_source((centre + di) as usize, (centre + dj) as usize, sign * s);
        }
        f.step();
        on_axis.push(f.at(far.0, far.1));
        if n >= from {
            for (k, &(i, j)) in ring.iter().chain([&near, &far]).enumerate() {
                let p = f.at(i, j);
                hi[k] = hi[k].max(p);
                lo[k] = lo[k].min(p);
            }
        }
    }
    let amp: Vec<f64> = (0..directions + 2)
        .map(|k| match drive {
            Drive::Pulse => hi[k].abs().max(lo[k].abs()),
            Drive::Continuous => 0.5 * (hi[k] - lo[k]),
        })
        .collect();
    let amplitude = amp[..directions].to_vec();
    let top = amplitude.iter().fold(0.0f64, |a, &v| a.max(v));
    let analytic: Vec<f64> = theta.iter().map(|&t| top * pole.directivity(t)).collect();
    let agreement = match pole {
        Pole::Monopole => {
            let low = amplitude.iter().fold(f64::INFINITY, |a, &v| a.min(v));
            1.0 - (top - low) / top
        }
        _ => correlation(&amplitude, &analytic),
    };
    Heard {
        pole,
        drive,
        theta,
        amplitude,
        analytic,
        agreement,
        spreading: amp[directions] / amp[directions + 1],
        on_axis,
        sample_rate_hz: 1.0 / g.dt,
        field: f.cur.clone(),
        nx: g.nx,
        ny: g.ny,
    }
}

/// Pearson's r of two equally long series.
pub fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    sab / (saa * sbb).sqrt()
}

/// How pure a sine at `f_hz` a signal is: the share of its power (about its mean) that the
/// least-squares sine at that frequency explains (1: a pure sine). The signal should hold
/// whole periods.
pub fn sine_share(x: &[f64], fs: f64, f_hz: f64) -> f64 {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let w = 2.0 * std::f64::consts::PI * f_hz / fs;
    let (mut a, mut b) = (0.0, 0.0);
    for (k, v) in x.iter().enumerate() {
        a += (v - mean) * (w * k as f64).sin();
        b += (v - mean) * (w * k as f64).cos();
    }
    let (a, b) = (2.0 * a / n, 2.0 * b / n);
    let (mut resid, mut all) = (0.0, 0.0);
    for (k, v) in x.iter().enumerate() {
        let fit = a * (w * k as f64).sin() + b * (w * k as f64).cos();
        resid += (v - mean - fit).powi(2);
        all += (v - mean).powi(2);
    }
    if all > 0.0 {
        1.0 - resid / all
    } else {
        0.0
    }
}
