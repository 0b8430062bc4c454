//! Synthetic AE hits with known content, made by aepipe's own code: the demo data, test
//! fixtures and the streaming benchmark's workload.
//!
//! The waveform models follow the thesis's description of the two mechanisms (ch. 4.5–4.7):
//! a bond failure rings at ~250 kHz and ~750 kHz with decay γ ≈ 5·10⁴ 1/s, the low component
//! lasting longer; a fibre failure is a short (< 5 µs) pulse above 800 kHz at the start.
//! This is a signal model, not the physical simulator (that is the `sim` room's job).

use crate::model::{AeRecord, Mechanism};
use std::f64::consts::PI;

/// SplitMix64: small, fast, seedable, good enough for test signals (no dependency).
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed ^ 0x9E37_79B9_7F4A_7C15)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }
    /// Standard normal (Box–Muller).
    pub fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
    }
}

/// Parameters of one synthetic hit.
#[derive(Debug, Clone)]
pub struct HitSpec {
    pub mechanism: Mechanism,
    pub sample_rate_hz: f64,
    pub n_samples: usize,
    pub pretrigger: usize,
    /// Peak amplitude of the main component, volts.
    pub amplitude_v: f64,
    /// Share of the bond wave's amplitude in the ~250 kHz component (the rest at ~750 kHz).
    pub low_share: f64,
    /// White noise standard deviation, volts.
    pub noise_v: f64,
}

impl HitSpec {
    pub fn new(mechanism: Mechanism) -> HitSpec {
        HitSpec {
            mechanism,
            sample_rate_hz: 10e6,
            n_samples: 4096,
            pretrigger: 500,
            amplitude_v: 0.01,
            low_share: 0.5,
            noise_v: 2e-5,
        }
    }
}

fn damped(out: &mut [f64], fs: f64, start: usize, f: f64, amp: f64, gamma: f64, phase: f64) {
    for (i, o) in out.iter_mut().enumerate().skip(start) {
        let t = (i - start) as f64 / fs;
        // Short raised-cosine onset (0.5 µs) so the front is a wave, not a step.
        let ramp = (t / 0.5e-6).min(1.0);
        let ramp = 0.5 - 0.5 * (PI * ramp).cos();
        *o += amp * ramp * (-gamma * t).exp() * (2.0 * PI * f * t + phase).sin();
    }
}

fn pulse(out: &mut [f64], fs: f64, centre: usize, f: f64, amp: f64, fwhm_s: f64) {
    let sigma = fwhm_s / 2.3548;
    for (i, o) in out.iter_mut().enumerate() {
        let t = (i as f64 - centre as f64) / fs;
        *o += amp * (-(t * t) / (2.0 * sigma * sigma)).exp() * (2.0 * PI * f * t).cos();
    }
}

/// One synthetic waveform (volts) for a spec.
pub fn waveform(spec: &HitSpec, rng: &mut Rng) -> Vec<f32> {
    let fs = spec.sample_rate_hz;
    let n = spec.n_samples;
    let mut x = vec![0.0f64; n];
    let pre = spec.pretrigger.min(n);
    let a = spec.amplitude_v;
    let bond = |x: &mut [f64], rng: &mut Rng, start: usize, scale: f64| {
        let f_lo = rng.range(235e3, 265e3);
        let f_hi = rng.range(720e3, 780e3);
        let g = 5e4 * rng.range(0.8, 1.2);
        damped(
            x,
            fs,
            start,
            f_lo,
            scale * a * spec.low_share,
            g,
            rng.range(0.0, 2.0 * PI),
        );
        // The high component decays faster (thesis: the low one lasts longer).
        damped(
            x,
            fs,
            start,
            f_hi,
            scale * a * (1.0 - spec.low_share),
            2.5 * g,
            rng.range(0.0, 2.0 * PI),
        );
    };
    let fibre = |x: &mut [f64], rng: &mut Rng, centre: usize| {
        let f = rng.range(1.0e6, 1.6e6);
        pulse(x, fs, centre, f, a, rng.range(1.5e-6, 3.0e-6));
    };
    match spec.mechanism {
        Mechanism::BondFailure => bond(&mut x, rng, pre, 1.0),
        Mechanism::FibreFailure => fibre(&mut x, rng, pre + (2e-6 * fs) as usize),
        Mechanism::Both => {
            fibre(&mut x, rng, pre + (2e-6 * fs) as usize);
            bond(&mut x, rng, pre + (6e-6 * fs) as usize, 0.8);
        }
        Mechanism::Erroneous => {
            // Two separate bursts: the second one arrives 150 µs later.
            bond(&mut x, rng, pre, 1.0);
            bond(
                &mut x,
                rng,
                (pre + (150e-6 * fs) as usize).min(n.saturating_sub(1)),
                1.0,
            );
        }
        Mechanism::Unclassified => {}
    }
    x.iter()
        .map(|v| (v + spec.noise_v * rng.normal()) as f32)
        .collect()
}

/// The load curve of a notched-strip tensile test (Fig. 4.15 shape): rises almost linearly,
/// bends over to a peak at `t_peak`, then falls as the crack grows. Newtons.
pub fn load_curve(t: f64, t_peak: f64, peak_n: f64) -> f64 {
    if t <= t_peak {
        let u = t / t_peak;
        peak_n * (1.6 * u - 0.6 * u * u)
    } else {
        let u = (t - t_peak) / t_peak;
        (peak_n * (1.0 - 2.5 * u * u)).max(0.0)
    }
}

/// A synthetic tensile test: `n` hits in time order over `duration_s`, mostly bond failures,
/// a few fibre failures, "both" and erroneous hits, load and extension at each hit.
pub struct Experiment {
    pub id: String,
    pub n_hits: usize,
    pub duration_s: f64,
    pub seed: u64,
    pub n_samples: usize,
}

impl Experiment {
    pub fn new(id: &str, n_hits: usize, seed: u64) -> Experiment {
        Experiment {
            id: id.into(),
            n_hits,
            duration_s: 60.0,
            seed,
            n_samples: 4096,
        }
    }

    /// Mechanism of hit `i` (deterministic given the seed): ~84 % bond, 2 % fibre, 10 % both,
    /// 4 % erroneous.
    fn mechanism(rng: &mut Rng) -> Mechanism {
        let u = rng.uniform();
        if u < 0.02 {
            Mechanism::FibreFailure
        } else if u < 0.12 {
            Mechanism::Both
        } else if u < 0.16 {
            Mechanism::Erroneous
        } else {
            Mechanism::BondFailure
        }
    }

    /// The hits, lazily (one waveform in memory at a time), labelled with their mechanism.
    pub fn records(&self) -> impl Iterator<Item = AeRecord> + Send + '_ {
        let mut rng = Rng::new(self.seed);
        let t_peak = 0.8 * self.duration_s;
        // AE activity grows towards the peak load: times ~ duration · u^(1/2.5).
        let mut times: Vec<f64> = (0..self.n_hits)
            .map(|_| self.duration_s * rng.uniform().powf(0.4))
            .collect();
        times.sort_by(f64::total_cmp);
        times.into_iter().enumerate().map(move |(i, t)| {
            let mech = Self::mechanism(&mut rng);
            let progress = i as f64 / self.n_hits.max(1) as f64;
            let mut spec = HitSpec::new(mech);
            spec.n_samples = self.n_samples;
            // 500 samples (50 µs) of pretrigger as in the thesis' records, less for short ones.
            spec.pretrigger = (self.n_samples / 8).min(500);
            spec.amplitude_v = 0.003 * (1.0 + 9.0 * rng.uniform().powi(3));
            // Damage shifts power from ~750 to ~250 kHz as the test goes on (ch. 4.5.5).
            spec.low_share = 0.3 + 0.4 * progress;
            AeRecord {
                experiment: self.id.clone(),
                channel: 1,
                hit: i as u64 + 1,
                time_s: Some(t),
                sample_rate_hz: spec.sample_rate_hz,
                pretrigger: spec.pretrigger as u32,
                samples: waveform(&spec, &mut rng),
                load_n: Some(load_curve(t, t_peak, 60.0)),
                extension_m: Some(1e-3 * t / self.duration_s),
                label: Some(mech.as_str().to_string()),
                threshold_v: None,
                source_file: String::new(),
            }
        })
    }

    /// Write the experiment as a Vallen `.pridb`/`.tradb` pair in `dir` (load on PA0 in mV
    /// at 1 N/mV, extension on PA1 at 1 µm/mV, sampled at 10 Hz like a test machine).
    pub fn write_vallen(
        &self,
        dir: &std::path::Path,
    ) -> rusqlite::Result<(std::path::PathBuf, std::path::PathBuf)> {
        std::fs::create_dir_all(dir)
            .map_err(|e| rusqlite::Error::ToSqlConversionFailure(Box::new(e)))?;
        let t_peak = 0.8 * self.duration_s;
        let steps = (self.duration_s * 10.0) as usize;
        let par: Vec<(f64, f64, f64)> = (0..=steps)
            .map(|k| {
                let t = k as f64 / 10.0;
                (t, load_curve(t, t_peak, 60.0), 1e3 * t / self.duration_s)
            })
            .collect();
        let recs: Vec<AeRecord> = self.records().collect();
        let hits = recs.iter().map(|r| crate::ingest::vallen::HitToWrite {
            channel: r.channel,
            trai: r.hit,
            time_s: r.time_s.unwrap_or(0.0),
            sample_rate_hz: r.sample_rate_hz,
            pretrigger: r.pretrigger,
            samples_v: &r.samples,
        });
        crate::ingest::vallen::write_pair(&dir.join(&self.id), hits, &par, 1e-3, 1e-4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rng_is_seedable_and_roughly_uniform_and_normal() {
        let mut a = Rng::new(7);
        let mut b = Rng::new(7);
        assert_eq!(a.next_u64(), b.next_u64());
        let mut r = Rng::new(1);
        let n = 20000;
        let mean_u = (0..n).map(|_| r.uniform()).sum::<f64>() / n as f64;
        assert!((mean_u - 0.5).abs() < 0.01, "{mean_u}");
        let xs: Vec<f64> = (0..n).map(|_| r.normal()).collect();
        let m = xs.iter().sum::<f64>() / n as f64;
        let v = xs.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / n as f64;
        assert!(m.abs() < 0.03 && (v - 1.0).abs() < 0.05, "{m} {v}");
    }

    #[test]
    fn load_curve_peaks_at_t_peak() {
        let peak = load_curve(8.0, 8.0, 60.0);
        assert!((peak - 60.0).abs() < 1e-9);
        assert!(load_curve(4.0, 8.0, 60.0) < peak && load_curve(9.0, 8.0, 60.0) < peak);
        assert_eq!(load_curve(0.0, 8.0, 60.0), 0.0);
    }

    #[test]
    fn bond_wave_starts_after_the_pretrigger() {
        let mut spec = HitSpec::new(Mechanism::BondFailure);
        spec.noise_v = 0.0;
        let w = waveform(&spec, &mut Rng::new(3));
        assert!(w[..spec.pretrigger].iter().all(|v| *v == 0.0));
        assert!(w[spec.pretrigger + 50..].iter().any(|v| v.abs() > 1e-3));
    }
}
