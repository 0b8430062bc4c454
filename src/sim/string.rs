//! The fibre as a stiff string (§6.2, Eq. 6.2.1): the scenario `fibre-stiff-string`.
//!
//! μ·y_tt = τ·y_xx − E·I·y_xxxx − μ·α·y_t, with μ = ρπr² and I = πr⁴/4, pinned at both ends
//! (y = y_xx = 0), plucked at its centre into a triangle of `amplitude_m` and released.
//! Eq. 6.2.1 prints the bending term with a plus sign; with it every short wave grows without
//! bound (ω² = (τ/μ)k² − (EI/μ)k⁴ turns negative), so a stable string subtracts it, as here.
//! Its damping term is likewise a loss: α ≥ 0 (1/s), and every mode decays as e^(−αt/2).
//!
//! Central differences on `intervals` equal pieces (ghost points mirror the ends, so the
//! sine modes are exact eigenvectors of the discrete operator), leapfrog in time with the
//! damping centred. Stable for Δt < 2/√λ_max, λ_max = (τ/μ)·4/h² + (EI/μ)·16/h⁴ (the
//! operator's largest eigenvalue); the default step is half of that.
//!
//! Against the continuum: mode n rings at f_n = n·f_s·√(1 + B·n²), f_s = (1/2L)·√(τ/μ),
//! B = π³Er⁴/(4τL²), damped to √(f_n² − (α/4π)²).

use super::params::{scenario_params, takes_only, Params};
use super::parts::{FIBRE_E, FIBRE_RHO, FIBRE_T, FIBRE_W};
use super::{Frame, SimError};
use std::f64::consts::PI;

/// The scenario's name (a contract).
pub const NAME: &str = "fibre-stiff-string";

/// At most this many time steps (each keeps the modal coordinates and the centre: 48 bytes,
/// 240 MB at the cap) or pieces: checked before anything is allocated.
pub const MAX_STEPS: usize = 5_000_000;
pub const MAX_INTERVALS: usize = 100_000;
/// At most this many node positions in the kept frames (320 MB).
pub const MAX_FRAME_POINTS: usize = 10_000_000;

/// A pinned stiff string, checked.
#[derive(Debug, Clone, PartialEq)]
pub struct StiffString {
    pub tension_n: f64,
    pub length_m: f64,
    pub radius_m: f64,
    pub youngs_pa: f64,
    pub density_kg_m3: f64,
    /// α of Eq. 6.2.1 as a loss, 1/s.
    pub damping: f64,
    pub duration_s: f64,
    pub amplitude_m: f64,
    pub intervals: usize,
    pub dt: f64,
}

/// A run: the modal coordinates of modes 1…`MODES` at every step, and frames if kept.
#[derive(Debug, Clone)]
pub struct StringRun {
    pub dt: f64,
    pub steps: usize,
    /// `modes[n-1][k]`: the amplitude of mode n at step k (projection on sin(nπx/L)).
    pub modes: Vec<Vec<f64>>,
    /// The centre's displacement at every step.
    pub centre: Vec<f64>,
    pub frames: Vec<Frame>,
}

/// Modes whose coordinates a run keeps.
pub const MODES: usize = 5;

scenario_params! {
    /// `fibre-stiff-string`'s keys: tension (N), length, radius (m), Young's modulus (Pa),
    /// density (kg/m³), damping (1/s), duration (s), the pluck (m), the intervals of the
    /// grid and the step (s; 0: half the stable step). The defaults are
    /// [`StiffString::paper_fibre`]'s.
    pub struct StringParams {
        tension_n: f64 = StiffString::paper_fibre().tension_n,
        length_m: f64 = StiffString::paper_fibre().length_m,
        radius_m: f64 = StiffString::paper_fibre().radius_m,
        youngs_pa: f64 = StiffString::paper_fibre().youngs_pa,
        density_kg_m3: f64 = StiffString::paper_fibre().density_kg_m3,
        damping: f64 = StiffString::paper_fibre().damping,
        duration_s: f64 = StiffString::paper_fibre().duration_s,
        amplitude_m: f64 = StiffString::paper_fibre().amplitude_m,
        intervals: u32 = StiffString::paper_fibre().intervals as u32,
        dt: f64 = 0.0,
    }
}

impl StiffString {
    /// The paper fibre of Table 3.8 as a stiff string: 1 mm, the cross-section 2.8 × 35 µm as
    /// a circle of the same area, E 35 GPa, 1.5 g/cm³, stretched 1 % (τ = E·A·0.01).
    pub fn paper_fibre() -> StiffString {
        let area = FIBRE_T * FIBRE_W;
        StiffString {
            tension_n: FIBRE_E * area * 0.01,
            length_m: 1e-3,
            radius_m: (area / PI).sqrt(),
            youngs_pa: FIBRE_E,
            density_kg_m3: FIBRE_RHO,
            damping: 0.0,
            duration_s: 40e-6,
            amplitude_m: 1e-5,
            intervals: 200,
            dt: 0.0,
        }
    }

    /// The stiff string of §6.2 from its parameters ([`StringParams`]); the defaults are
    /// the paper fibre of Table 3.8 as a string. A key it does not take is refused by name.
    pub fn from_params(p: &Params) -> Result<StiffString, SimError> {
        takes_only(NAME, p, &[StringParams::KEYS])?;
        let s = StringParams::read(p)?;
        StiffString {
            tension_n: s.tension_n,
            length_m: s.length_m,
            radius_m: s.radius_m,
            youngs_pa: s.youngs_pa,
            density_kg_m3: s.density_kg_m3,
            damping: s.damping,
            duration_s: s.duration_s,
            amplitude_m: s.amplitude_m,
            intervals: s.intervals as usize,
            dt: s.dt,
        }
        .checked()
    }

    /// Check the values and fix the step (`dt` 0: half the stable limit).
    pub fn checked(mut self) -> Result<StiffString, SimError> {
        let bad = |what: &str| SimError::Model(format!("{NAME}: {what}"));
        for (k, v) in [
            ("tension_n", self.tension_n),
            ("length_m", self.length_m),
            ("radius_m", self.radius_m),
            ("density_kg_m3", self.density_kg_m3),
            ("duration_s", self.duration_s),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(bad(&format!("{k} must be > 0, got {v}")));
            }
        }
        for (k, v) in [
            ("youngs_pa", self.youngs_pa),
            ("damping", self.damping),
            ("dt", self.dt),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(&format!("{k} must be ≥ 0, got {v}")));
            }
        }
        if !(4..=MAX_INTERVALS).contains(&self.intervals) {
            return Err(bad(&format!(
                "intervals must be 4…{MAX_INTERVALS}, got {}",
                self.intervals
            )));
        }
        let limit = self.stable_dt();
        if self.dt == 0.0 {
            self.dt = 0.5 * limit;
        } else if self.dt >= limit {
            return Err(bad(&format!(
                "dt = {:e} s is not below the stable step {limit:e} s (2/√λ_max)",
                self.dt
            )));
        }
        let steps = self.duration_s / self.dt;
        if steps > MAX_STEPS as f64 {
            return Err(bad(&format!(
                "{steps:.3e} steps of {:e} s exceed {MAX_STEPS}",
                self.dt
            )));
        }
        Ok(self)
    }

    /// Refuse trajectories of more than [`MAX_FRAME_POINTS`] node positions (32 bytes each)
    /// before the run, so that `--trajectories` cannot outgrow memory either.
    pub fn check_frames(&self, every: Option<usize>) -> Result<(), SimError> {
        let Some(e) = every.filter(|e| *e > 0) else {
            return Ok(());
        };
        let steps = (self.duration_s / self.dt).round() as usize;
        let points = (steps / e + 1).saturating_mul(self.intervals + 1);
        if points > MAX_FRAME_POINTS {
            return Err(SimError::Model(format!(
                "{NAME}: --trajectories {e} keeps {points} node positions, more than \
                 {MAX_FRAME_POINTS}; keep every {}th step or fewer",
                (steps + 1) * (self.intervals + 1) / MAX_FRAME_POINTS + 1
            )));
        }
        Ok(())
    }

    /// Mass per length μ = ρπr², kg/m.
    pub fn mu(&self) -> f64 {
        self.density_kg_m3 * PI * self.radius_m.powi(2)
    }

    /// Bending stiffness E·I, I = πr⁴/4.
    pub fn ei(&self) -> f64 {
        self.youngs_pa * PI * self.radius_m.powi(4) / 4.0
    }

    /// The flexible string's fundamental f_s = (1/2L)·√(τ/μ), Hz.
    pub fn f_s(&self) -> f64 {
        (self.tension_n / self.mu()).sqrt() / (2.0 * self.length_m)
    }

    /// The inharmonicity B = π³Er⁴/(4τL²).
    pub fn b(&self) -> f64 {
        PI.powi(3) * self.youngs_pa * self.radius_m.powi(4)
            / (4.0 * self.tension_n * self.length_m.powi(2))
    }

    /// Mode n of the continuum, undamped: n·f_s·√(1 + B·n²), Hz.
    pub fn mode_hz(&self, n: usize) -> f64 {
        let n = n as f64;
        n * self.f_s() * (1.0 + self.b() * n * n).sqrt()
    }

    /// Mode n of the continuum with the damping: √(f_n² − (α/4π)²), Hz.
    pub fn damped_mode_hz(&self, n: usize) -> f64 {
        (self.mode_hz(n).powi(2) - (self.damping / (4.0 * PI)).powi(2))
            .max(0.0)
            .sqrt()
    }

    /// The largest step the scheme is stable at, s.
    pub fn stable_dt(&self) -> f64 {
        let h = self.length_m / self.intervals as f64;
        let mu = self.mu();
        let lmax = self.tension_n / mu * 4.0 / (h * h) + self.ei() / mu * 16.0 / h.powi(4);
        2.0 / lmax.sqrt()
    }

    /// Run it, keeping a frame every `every` steps (none: no frames).
    pub fn run(&self, every: Option<usize>) -> StringRun {
        let n = self.intervals;
        let h = self.length_m / n as f64;
        let dt = self.dt;
        let steps = (self.duration_s / dt).round() as usize;
        let (c2, k2) = (
            self.tension_n / self.mu() / (h * h),
            self.ei() / self.mu() / h.powi(4),
        );
        let x = |i: usize| i as f64 * h;
        let mut y: Vec<f64> = (0..=n)
            .map(|i| self.amplitude_m * (1.0 - (2.0 * x(i) / self.length_m - 1.0).abs()))
            .collect();
        y[0] = 0.0;
        y[n] = 0.0;
        // The discrete operator with mirrored ghosts (y₋₁ = −y₁, y_{n+1} = −y_{n−1}).
        let op = |y: &[f64], out: &mut [f64]| {
            let at = |i: isize| -> f64 {
                if i < 0 {
                    -y[(-i) as usize]
                } else if i as usize > n {
                    -y[2 * n - i as usize]
                } else {
                    y[i as usize]
                }
            };
            out[0] = 0.0;
            out[n] = 0.0;
            for i in 1..n {
                let i = i as isize;
                let d2 = at(i - 1) - 2.0 * at(i) + at(i + 1);
                let d4 = at(i - 2) - 4.0 * at(i - 1) + 6.0 * at(i) - 4.0 * at(i + 1) + at(i + 2);
                out[i as usize] = c2 * d2 - k2 * d4;
            }
        };
        let shapes: Vec<Vec<f64>> = (1..=MODES)
            .map(|m| {
                (0..=n)
                    .map(|i| (m as f64 * PI * x(i) / self.length_m).sin() * 2.0 / n as f64)
                    .collect()
            })
            .collect();
        let mut run = StringRun {
            dt,
            steps,
            modes: (0..MODES).map(|_| Vec::with_capacity(steps + 1)).collect(),
            centre: Vec::with_capacity(steps + 1),
            frames: Vec::new(),
        };
        let mut acc = vec![0.0; n + 1];
        let (a_plus, a_minus) = (1.0 + 0.5 * self.damping * dt, 1.0 - 0.5 * self.damping * dt);
        let mid = n / 2;
        // prev = y^(k−1), y = y^k, next = y^(k+1); released at rest.
        let mut prev = y.clone();
        let mut next = vec![0.0; n + 1];
        for k in 0..=steps {
            for (m, s) in shapes.iter().enumerate() {
                run.modes[m].push(y.iter().zip(s).map(|(a, b)| a * b).sum());
            }
            run.centre.push(if n.is_multiple_of(2) {
                y[mid]
            } else {
                0.5 * (y[mid] + y[mid + 1])
            });
            if every.is_some_and(|e| e > 0 && k % e == 0) {
                run.frames.push(Frame {
                    t: k as f64 * dt,
                    r: (0..=n)
                        .map(|i| [x(i) - 0.5 * self.length_m, y[i], 0.0])
                        .collect(),
                    u: (0..=n).map(|i| [0.0, (y[i] - prev[i]) / dt, 0.0]).collect(),
                    tension: Vec::new(),
                    energy: None,
                });
            }
            if k == steps {
                break;
            }
            op(&y, &mut acc);
            for i in 1..n {
                next[i] = if k == 0 {
                    // y¹ = y⁰ + ½Δt²·L y⁰: zero initial velocity.
                    y[i] + 0.5 * dt * dt * acc[i]
                } else {
                    (2.0 * y[i] - a_minus * prev[i] + dt * dt * acc[i]) / a_plus
                };
            }
            std::mem::swap(&mut prev, &mut y);
            std::mem::swap(&mut y, &mut next);
        }
        run
    }
}

impl StringRun {
    /// Mode n's frequency (zero crossings of its coordinate) and decay (Eq. 3.5.1 fit).
    pub fn mode(&self, n: usize) -> Option<(f64, Option<super::decay::Decay>)> {
        let q = self.modes.get(n.checked_sub(1)?)?;
        let t: Vec<f64> = (0..q.len()).map(|k| k as f64 * self.dt).collect();
        let f = super::zero_crossing_frequency(&t, q)?;
        Some((f, super::decay::fit(q, self.dt, 1.0 / f)))
    }
}

/// `aepipe simulate --scenario fibre-stiff-string`: one run per sweep value; the lines to
/// print, `trajectories[_N].parquet` with `--trajectories`, `sweep.parquet` for a sweep.
pub(super) fn run_job(job: &super::SimJob) -> Result<super::SimReport, SimError> {
    use super::sweep::{SweepRow, SweepTable};
    if job.solver.is_some() || job.run.snapshot_every.is_some() {
        return Err(SimError::Model(format!(
            "{NAME} has its own scheme (leapfrog) and no acoustic grid: --solver and \
             --snapshots do not apply"
        )));
    }
    let io = |e: std::io::Error| SimError::Io(format!("{}: {e}", job.out.display()));
    std::fs::create_dir_all(&job.out).map_err(io)?;
    let grid = super::params::sweep_grid(&job.sweep);
    // Every run's string is built (and checked) before the first runs.
    let mut strings = Vec::new();
    for v in &grid {
        let mut p = job.params.clone();
        p.0.extend(v.iter().cloned());
        let s = StiffString::from_params(&p)?;
        s.check_frames(job.run.trajectory_every)?;
        strings.push((s, p.to_json()));
    }
    let mut lines = Vec::new();
    let mut table = SweepTable::of(&job.sweep);
    for (k, (s, json)) in strings.iter().enumerate() {
        let t0 = std::time::Instant::now();
        let run = s.run(job.run.trajectory_every);
        let run_s = t0.elapsed().as_secs_f64();
        lines.push(format!(
            "{NAME} {json}: {} pieces, {} steps of {:.3e} s (stable below {:.3e} s) in {:.2} s; \
             f_s {:.2} kHz, B {:.3e}",
            s.intervals,
            run.steps,
            s.dt,
            s.stable_dt(),
            run_s,
            s.f_s() / 1e3,
            s.b()
        ));
        // Modes 1, 3 and 5 (a centre pluck excites odd modes only), measured once.
        let modes: Vec<_> = [1, 3, 5].into_iter().map(|n| (n, run.mode(n))).collect();
        for (n, measured) in &modes {
            let n = *n;
            let want = s.damped_mode_hz(n);
            match measured {
                Some((f, d)) => lines.push(format!(
                    "  mode {n}: {:.3} kHz against n·f_s·√(1+Bn²) {:.3} kHz ({:+.3} %){}",
                    f / 1e3,
                    want / 1e3,
                    (f / want - 1.0) * 100.0,
                    match d {
                        Some(d) => format!(
                            ", decay γ {:.4e} 1/s against α/2 {:.4e}",
                            d.gamma_hz,
                            0.5 * s.damping
                        ),
                        None => String::new(),
                    }
                )),
                None => lines.push(format!("  mode {n}: too few oscillations to measure")),
            }
        }
        super::write_trajectories(job, k, strings.len() > 1, &run.frames, 2, &mut lines)?;
        if let (false, (_, Some((f, decay)))) = (job.sweep.is_empty(), &modes[0]) {
            table.rows.push(SweepRow {
                hit: k as u64 + 1,
                values: grid[k].iter().map(|(_, v)| *v).collect(),
                params: json.clone(),
                sensor: 0,
                dominant_frequency_hz: *f,
                peak: run.centre.iter().fold(0.0f64, |a, v| a.max(v.abs())),
                decay: decay.clone(),
                damping_kg_s: None,
                run_s,
            });
        }
    }
    super::finish(job, table, lines)
}
