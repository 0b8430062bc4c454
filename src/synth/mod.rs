//! Synthetic AE hits with known content, made by aepipe's own code: the demo data, test
//! fixtures and the streaming benchmark's workload.
//!
//! The waveform models follow the thesis's description of the two mechanisms (ch. 4.5–4.7):
//! a bond failure rings at ~250 kHz and ~750 kHz with decay γ ≈ 5·10⁴ 1/s, the low component
//! lasting longer; a fibre failure is a short (< 5 µs) pulse above 800 kHz at the start.
//! This is a signal model, not the physical simulator (that is the `sim` room's job).

use crate::model::columns as cols;
use crate::model::{AeRecord, Mechanism};

pub mod loading;
pub mod strip;
pub use crate::util::Rng;
pub use loading::{Shape, Shares};
pub use strip::{SourceKind, Strip, SynthHit};

/// Why a synthetic experiment could not be made.
#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    /// The reference library is unusable (missing, or without both mechanisms).
    #[error("{path}: {message}")]
    Library { path: String, message: String },
    #[error(transparent)]
    Sim(#[from] crate::sim::SimError),
    #[error("{path}: cannot write the Vallen pair: {message}")]
    Vallen { path: String, message: String },
    #[error(transparent)]
    Store(#[from] crate::store::StoreError),
    /// `--cycles` or `--energy-exponent` out of range.
    #[error("{0}")]
    Shape(String),
}

impl crate::util::HasKind for SynthError {
    fn kind(&self) -> crate::util::ErrorKind {
        match self {
            SynthError::Library { .. } => crate::util::ErrorKind::Usage,
            SynthError::Sim(s) => s.kind(),
            SynthError::Vallen { .. } => crate::util::ErrorKind::Failed,
            SynthError::Store(s) => s.kind(),
            SynthError::Shape(_) => crate::util::ErrorKind::Usage,
        }
    }
}
use std::f64::consts::PI;

/// The synthetic tests' sample rate (the demo's Vallen acquisition), Hz.
pub const SAMPLE_RATE_HZ: f64 = 10e6;

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
            sample_rate_hz: SAMPLE_RATE_HZ,
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

/// Add `amp · sig` into `x` from index `at` (clipped at the end).
fn add_at(x: &mut [f64], sig: &[f64], at: usize, amp: f64) {
    for (k, v) in sig.iter().enumerate() {
        if let Some(o) = x.get_mut(at + k) {
            *o += amp * v;
        }
    }
}

/// A hit made of reference-library signals: a drawn signal of the mechanism placed at the
/// trigger with up to 1 µs of arrival jitter, bond hits re-weighted between their parts
/// below and above 500 kHz by `low_share` (the designed ch. 4.5.5 shift), distance
/// attenuation (a source 0–5 mm away, 20 %/mm), the sensor band 100–2500 kHz, and noise.
/// "Both" is a fibre pulse followed 4 µs later by a bond wave; erroneous hits are the
/// library's erroneous records (triggered before the front, two signals, clipped — a
/// clipped one is clipped again after the band and noise, as an ADC would), or, from a
/// library without them, two bursts 150 µs apart or a burst that starts before the trigger.
/// Returns the samples, the signals' sources, and whether the hit was clipped (a clipped
/// library record: a caller that adds its own noise afterwards clips again, as the ADC would).
fn from_library(lib: &Library, spec: &HitSpec, rng: &mut Rng) -> (Vec<f32>, String, bool) {
    let fs = spec.sample_rate_hz;
    let n = spec.n_samples;
    let pre = spec.pretrigger.min(n);
    let mut x = vec![0.0f64; n];
    let mut sources = Vec::new();
    let pick = |set: &[LibrarySignal], rng: &mut Rng| (rng.next_u64() % set.len() as u64) as usize;
    let lead = (2e-6 * fs) as usize;
    let bond = |x: &mut [f64], rng: &mut Rng, at: usize, amp: f64, sources: &mut Vec<String>| {
        let s = &lib.bond[pick(&lib.bond, rng)];
        let w: Vec<f64> = s
            .low
            .iter()
            .zip(&s.high)
            .map(|(l, h)| 2.0 * (spec.low_share * l + (1.0 - spec.low_share) * h))
            .collect();
        add_at(x, &w, at.saturating_sub(lead), amp);
        sources.push(format!("bond: {}", s.source));
    };
    let fibre = |x: &mut [f64], rng: &mut Rng, at: usize, amp: f64, sources: &mut Vec<String>| {
        let s = &lib.fibre[pick(&lib.fibre, rng)];
        add_at(x, &s.samples, at.saturating_sub(lead), amp);
        sources.push(format!("fibre: {}", s.source));
    };
    let distance_mm = rng.range(0.0, 5.0);
    let a = spec.amplitude_v * (-0.2 * distance_mm).exp();
    let mut clip = false;
    let at = pre + (rng.uniform() * 1e-6 * fs) as usize;
    match spec.mechanism {
        Mechanism::BondFailure => bond(&mut x, rng, at, a, &mut sources),
        Mechanism::FibreFailure => fibre(&mut x, rng, at, a, &mut sources),
        Mechanism::Both => {
            fibre(&mut x, rng, at, a, &mut sources);
            bond(
                &mut x,
                rng,
                at + (4e-6 * fs) as usize,
                0.8 * a,
                &mut sources,
            );
        }
        Mechanism::Erroneous if !lib.erroneous.is_empty() => {
            // One of the library's faulty records (triggered before the front, two
            // signals, clipped), placed with its own trigger at the hit's.
            let s = &lib.erroneous[pick(&lib.erroneous, rng)];
            add_at(&mut x, &s.samples, at.saturating_sub(lead), a);
            sources.push(format!("erroneous: {}", s.source));
            clip = s.clipped;
        }
        Mechanism::Erroneous => {
            if rng.uniform() < 0.5 {
                bond(&mut x, rng, at, a, &mut sources);
                bond(&mut x, rng, at + (150e-6 * fs) as usize, a, &mut sources);
            } else {
                // Early trigger: the burst is already under way at the start of the record.
                bond(&mut x, rng, (pre / 10).max(lead), a, &mut sources);
            }
        }
        Mechanism::Unclassified => {}
    }
    let x = band_pass(&x, fs, 100e3, 2500e3);
    let mut out: Vec<f32> = x
        .iter()
        .map(|v| (v + spec.noise_v * rng.normal()) as f32)
        .collect();
    if clip {
        // The ADC's range: 90 % of what the sensor delivered.
        let range = 0.9 * out.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        out.iter_mut().for_each(|v| *v = v.clamp(-range, range));
    }
    (out, sources.join("; "), clip)
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
    /// Simulated reference signals to build the hits from (else analytic waveforms).
    pub library: Option<Library>,
    /// Sensors on a strip: every source is heard at each, with its delay and attenuation
    /// ([`strip`]); `n_hits` then counts sources. None: one sensor, one hit per source.
    pub strip: Option<Strip>,
    /// Load cycles ([`loading`]): 0 or 1, a monotonic test to failure; N ≥ 2, a
    /// load–unload–reload test of N cycles.
    pub cycles: usize,
    /// The exponent the hits' energies follow ([`loading::power_law_amplitude`]); None:
    /// the demo's amplitude spread.
    pub energy_exponent: Option<f64>,
    /// The sources' mechanism mix.
    pub shares: loading::Shares,
    /// The measurement chain every sensor hears through (None: the libraries' flat one).
    /// Applied to the source's waveform before each sensor's attenuation and noise: the
    /// sensor shapes the wave, its own noise is added after.
    pub chain: Option<crate::sim::chain::Chain>,
}

/// Reference-library signals by mechanism, each cut to start a little before its trigger.
#[derive(Debug, Clone, Default)]
pub struct Library {
    pub bond: Vec<LibrarySignal>,
    pub fibre: Vec<LibrarySignal>,
    /// Erroneous records (acquisition faults made from simulated signals); may be empty.
    pub erroneous: Vec<LibrarySignal>,
}

#[derive(Debug, Clone)]
pub struct LibrarySignal {
    /// Samples from 2 µs before the trigger, peak-normalised, at `sample_rate_hz`.
    pub samples: Vec<f64>,
    /// The part below 500 kHz and the rest (for the designed spectral shift of bond hits).
    pub low: Vec<f64>,
    pub high: Vec<f64>,
    /// Which simulation (its `sim_params`), for the truth table.
    pub source: String,
    /// The record sits at its extreme value for 3 or more samples: the ADC clipped it, and
    /// a hit made from it is clipped again after the synthetic sensor band and noise.
    pub clipped: bool,
}

impl Library {
    /// Read a simulated `waveforms.parquet` (from `aepipe reference`): bond- and
    /// fibre-failure signals sampled at `fs`.
    pub fn read(path: &std::path::Path, fs: f64) -> Result<Library, SynthError> {
        let cfg = crate::config::ValidConfig::default();
        let d = crate::ingest::discover(&[path.to_path_buf()], &cfg.ingest);
        let mut lib = Library::default();
        for src in &d.sources {
            for it in crate::ingest::open(src, cfg.read_settings(), &cfg.load) {
                let crate::model::Item::Record(r) = it else {
                    continue;
                };
                if (r.sample_rate_hz - fs).abs() > 1e-6 * fs {
                    continue;
                }
                let start = (r.pretrigger as usize).saturating_sub((2e-6 * fs) as usize);
                let x: Vec<f64> = r.samples[start..].iter().map(|&v| v as f64).collect();
                let peak = x.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                if peak <= 0.0 {
                    continue;
                }
                let clipped = x.iter().filter(|v| v.abs() == peak).count() >= 3;
                let x: Vec<f64> = x.iter().map(|v| v / peak).collect();
                let (low, high) = split_band(&x, fs, 500e3);
                let sig = LibrarySignal {
                    samples: x,
                    low,
                    high,
                    source: format!("{} hit {} ch {}", r.experiment, r.hit, r.channel),
                    clipped,
                };
                match r.label.as_deref().and_then(Mechanism::parse) {
                    Some(Mechanism::BondFailure) => lib.bond.push(sig),
                    Some(Mechanism::FibreFailure) => lib.fibre.push(sig),
                    Some(Mechanism::Erroneous) => lib.erroneous.push(sig),
                    _ => {}
                }
            }
        }
        if lib.bond.is_empty() || lib.fibre.is_empty() {
            return Err(SynthError::Library {
                path: path.display().to_string(),
                message: format!(
                    "the library needs bond_failure and fibre_failure signals at {} MHz (found {} and {})",
                    fs / 1e6,
                    lib.bond.len(),
                    lib.fibre.len()
                ),
            });
        }
        Ok(lib)
    }
}

/// Split a signal at `cut_hz` with an FFT mask: (below, at and above).
pub fn split_band(x: &[f64], fs: f64, cut_hz: f64) -> (Vec<f64>, Vec<f64>) {
    let (lo, hi) = (band_pass(x, fs, 0.0, cut_hz), band_pass(x, fs, cut_hz, fs));
    (lo, hi)
}

/// Keep [lo, hi) Hz of a signal (FFT mask with 50 kHz cosine edges, no padding).
pub fn band_pass(x: &[f64], fs: f64, lo: f64, hi: f64) -> Vec<f64> {
    let edge = 50e3;
    let gain = |f: f64| {
        let up = if lo <= 0.0 {
            1.0
        } else {
            (((f - lo) / edge) + 0.5).clamp(0.0, 1.0)
        };
        let down = (((hi - f) / edge) + 0.5).clamp(0.0, 1.0);
        let g = up.min(down);
        0.5 - 0.5 * (PI * g).cos()
    };
    crate::dsp::filter::zero_phase(x, x.len(), fs, gain)
}

impl Experiment {
    pub fn new(id: &str, n_hits: usize, seed: u64) -> Experiment {
        Experiment {
            id: id.into(),
            n_hits,
            duration_s: 60.0,
            seed,
            n_samples: 4096,
            library: None,
            strip: None,
            cycles: 0,
            energy_exponent: None,
            shares: loading::Shares::default(),
            chain: None,
        }
    }

    /// The designed cycles (none for a monotonic test).
    pub fn cycle_design(&self) -> Vec<loading::CycleDesign> {
        match self.cycles {
            0 | 1 => vec![],
            n => loading::design(n, self.duration_s),
        }
    }

    /// The test machine's load at `t`, N.
    pub fn load_at(&self, design: &[loading::CycleDesign], t: f64) -> f64 {
        match design.is_empty() {
            true => load_curve(t, 0.8 * self.duration_s, loading::PEAK_N),
            false => loading::cyclic_load(design, t),
        }
    }

    /// The test machine's extension at `t`, m.
    pub fn extension_at(&self, design: &[loading::CycleDesign], t: f64) -> f64 {
        match design.is_empty() {
            true => 1e-3 * t / self.duration_s,
            false => loading::cyclic_extension(design, t),
        }
    }

    /// The sources' times, sorted. A monotonic test's activity grows towards the peak
    /// load: times ~ duration · u^(1/2.5).
    pub(super) fn source_times(&self, design: &[loading::CycleDesign], rng: &mut Rng) -> Vec<f64> {
        if !design.is_empty() {
            return loading::cyclic_times(design, self.n_hits, rng);
        }
        let mut times: Vec<f64> = (0..self.n_hits)
            .map(|_| self.duration_s * rng.uniform().powf(0.4))
            .collect();
        times.sort_by(f64::total_cmp);
        times
    }

    /// A source's peak amplitude, V.
    pub(super) fn amplitude(&self, rng: &mut Rng) -> f64 {
        match self.energy_exponent {
            Some(alpha) => loading::power_law_amplitude(alpha, rng),
            None => 0.003 * (1.0 + 9.0 * rng.uniform().powi(3)),
        }
    }

    /// The waveforms' ADC step, mV per count: 1 µV (±32.8 mV), or 10 µV for power-law
    /// amplitudes (up to `loading::A_MAX_V`).
    fn tr_mv(&self) -> f64 {
        match self.energy_exponent {
            Some(_) => 1e-2,
            None => 1e-3,
        }
    }

    /// Mechanism of the next source (deterministic given the seed), drawn from the test's
    /// mix (by default ~84 % bond, 2 % fibre, 10 % both, 4 % erroneous).
    pub(super) fn mechanism(&self, rng: &mut Rng) -> Mechanism {
        self.shares.draw(rng.uniform())
    }

    /// The hits, lazily (one waveform in memory at a time), labelled with their mechanism.
    pub fn records(&self) -> impl Iterator<Item = AeRecord> + Send + '_ {
        self.hits().map(|(r, _)| r)
    }

    /// The hits with, for each, the reference signal(s) it was built from ("" for analytic
    /// waveforms).
    pub fn hits(&self) -> impl Iterator<Item = (AeRecord, String)> + Send + '_ {
        self.synth_hits().map(|h| (h.rec, h.reference))
    }

    /// The hits with what made each (source, position, kind): one per source and sensor
    /// on a [`Strip`], else one per source.
    pub fn synth_hits(&self) -> Box<dyn Iterator<Item = SynthHit> + Send + '_> {
        match &self.strip {
            Some(s) => Box::new(strip::strip_hits(self, s).into_iter()),
            None => Box::new(self.one_sensor_hits().map(|(rec, reference)| SynthHit {
                source: rec.hit,
                source_x_m: None,
                kind: SourceKind::Specimen,
                rec,
                reference,
            })),
        }
    }

    /// `x` as the experiment's measurement chain delivers it (unchanged without one).
    pub(crate) fn heard(&self, x: Vec<f32>) -> Vec<f32> {
        match &self.chain {
            Some(c) if !c.is_flat() => {
                let y: Vec<f64> = x.iter().map(|&v| v as f64).collect();
                c.apply(&y).into_iter().map(|v| v as f32).collect()
            }
            _ => x,
        }
    }

    fn one_sensor_hits(&self) -> impl Iterator<Item = (AeRecord, String)> + Send + '_ {
        let mut rng = Rng::new(self.seed);
        let design = self.cycle_design();
        let times = self.source_times(&design, &mut rng);
        times.into_iter().enumerate().map(move |(i, t)| {
            let mech = self.mechanism(&mut rng);
            let progress = i as f64 / self.n_hits.max(1) as f64;
            let mut spec = HitSpec::new(mech);
            spec.n_samples = self.n_samples;
            // 500 samples (50 µs) of pretrigger as in the thesis' records, less for short ones.
            spec.pretrigger = (self.n_samples / 8).min(500);
            spec.amplitude_v = self.amplitude(&mut rng);
            // Damage shifts power from ~750 to ~250 kHz as the test goes on (ch. 4.5.5).
            spec.low_share = 0.3 + 0.4 * progress;
            let (samples, source, _) = match &self.library {
                Some(lib) => from_library(lib, &spec, &mut rng),
                None => (waveform(&spec, &mut rng), String::new(), false),
            };
            // One sensor: its record, noise included, is heard through the chain.
            let samples = self.heard(samples);
            let rec = AeRecord {
                kind: crate::model::RecordKind::Hit,
                experiment: self.id.clone(),
                channel: 1,
                hit: i as u64 + 1,
                time_s: Some(t),
                sample_rate_hz: spec.sample_rate_hz,
                pretrigger: spec.pretrigger as u32,
                samples,
                load_n: Some(self.load_at(&design, t)),
                extension_m: Some(self.extension_at(&design, t)),
                label: Some(mech.as_str().to_string()),
                threshold_v: None,
                source_file: String::new(),
            };
            (rec, source)
        })
    }

    /// Write the experiment as a Vallen `.pridb`/`.tradb` pair in `dir` (load on PA0 in mV
    /// at 1 N/mV, extension on PA1 at 1 µm/mV, sampled at 10 Hz like a test machine).
    pub fn write_vallen(
        &self,
        dir: &std::path::Path,
    ) -> rusqlite::Result<(std::path::PathBuf, std::path::PathBuf)> {
        let recs: Vec<AeRecord> = self.records().collect();
        self.write_vallen_records(dir, &recs)
    }

    fn write_vallen_records(
        &self,
        dir: &std::path::Path,
        recs: &[AeRecord],
    ) -> rusqlite::Result<(std::path::PathBuf, std::path::PathBuf)> {
        std::fs::create_dir_all(dir)
            .map_err(|e| rusqlite::Error::ToSqlConversionFailure(Box::new(e)))?;
        let design = self.cycle_design();
        let steps = (self.duration_s * 10.0) as usize;
        let par: Vec<(f64, f64, f64)> = (0..=steps)
            .map(|k| {
                let t = k as f64 / 10.0;
                (
                    t,
                    self.load_at(&design, t),
                    1e6 * self.extension_at(&design, t),
                )
            })
            .collect();
        let hits = recs.iter().map(|r| crate::ingest::vallen::HitToWrite {
            channel: r.channel,
            trai: r.hit,
            time_s: r.time_s.unwrap_or(0.0),
            sample_rate_hz: r.sample_rate_hz,
            pretrigger: r.pretrigger,
            samples_v: &r.samples,
            restart: false,
            transient: true,
        });
        crate::ingest::vallen::write_pair(&dir.join(&self.id), hits, &par, self.tr_mv(), 1e-4)
    }
}

/// The demo's pipeline definition, `pipelines/demo.toml` (the strip this module builds, read
/// as a Vallen test), embedded in the binary so that `aepipe demo` and `aepipe bench
/// analysis` need no file beside them.
pub fn demo_config() -> crate::config::ValidConfig {
    crate::config::PipelineConfig::from_toml(include_str!("../../pipelines/demo.toml"))
        .expect("pipelines/demo.toml is valid")
}

/// `aepipe synth-experiment`: a library-built experiment in `dir` (the library built from the
/// embedded definition into `dir/reference` unless given). Returns a summary line.
pub fn synth_experiment(
    dir: &std::path::Path,
    id: &str,
    hits: usize,
    seed: u64,
    library: Option<&std::path::Path>,
    progress: bool,
) -> Result<String, SynthError> {
    synth_test(dir, id, hits, seed, Shape::default(), library, progress)
}

/// `aepipe synth-experiment` with a test's shape: its load cycles and energy law.
pub fn synth_test(
    dir: &std::path::Path,
    id: &str,
    hits: usize,
    seed: u64,
    shape: Shape,
    library: Option<&std::path::Path>,
    progress: bool,
) -> Result<String, SynthError> {
    synth_test_through(dir, id, hits, seed, shape, library, None, progress)
}

/// [`synth_test`] heard through a measurement chain (`synth-experiment --chain NAME`; None:
/// flat, as the libraries are recorded).
#[allow(clippy::too_many_arguments)]
pub fn synth_test_through(
    dir: &std::path::Path,
    id: &str,
    hits: usize,
    seed: u64,
    shape: Shape,
    library: Option<&std::path::Path>,
    chain: Option<&crate::sim::chain::Chain>,
    progress: bool,
) -> Result<String, SynthError> {
    let shape = shape.check()?;
    let t0 = std::time::Instant::now();
    let lib_path = match library {
        Some(p) => p.to_path_buf(),
        None => {
            // The embedded library definition with the experiment's seed for the material
            // draws: its signals differ from those of a library built for training
            // (seed 2008), so a classifier trained on that one is tested on unseen fibres.
            let mut f = crate::sim::reference::ReferenceFile::default_library();
            f.reference.seed = seed;
            let out = dir.join("reference");
            crate::sim::reference::build_library(&f.reference, &out, progress)?;
            out.join("waveforms.parquet")
        }
    };
    let lib = Library::read(&lib_path, SAMPLE_RATE_HZ)?;
    let mut e = Experiment::new(id, hits, seed);
    e.library = Some(lib);
    e.strip = Some(Strip::demo());
    e.cycles = shape.cycles;
    e.energy_exponent = shape.energy_exponent;
    e.shares = shape.shares;
    e.chain = chain.cloned();
    let data = dir.join("data");
    let truth = dir.join("truth.parquet");
    let n_hits = e.write_with_truth(&data, &truth)?;
    let mut stated = String::new();
    if e.cycles >= 2 {
        stated += &format!(
            "; {} load cycles (designed Felicity ratios in {})",
            e.cycles,
            truth.with_file_name("truth_cycles.parquet").display()
        );
    }
    if let Some(a) = e.energy_exponent {
        stated += &format!("; energies ∝ E^-{a}");
    }
    if e.shares != loading::Shares::default() {
        stated += &format!("; mechanisms drawn as {}", e.shares);
    }
    if let Some(c) = &e.chain {
        stated += &format!("; heard through the {} chain", c.name);
    }
    Ok(format!(
        "{hits} sources, {n_hits} hits (seed {seed}) from {} → {} (.pridb/.tradb) and {} in {:.1} s{stated}",
        lib_path.display(),
        data.join(id).display(),
        truth.display(),
        t0.elapsed().as_secs_f64()
    ))
}

/// One hit's ground truth: a row of `truth.parquet`.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthRow {
    pub experiment: String,
    pub channel: u32,
    pub hit: u64,
    pub time_s: Option<f64>,
    pub mechanism: Mechanism,
    pub reference_signals: String,
    /// The source the hit belongs to (1-based; one per hit without a strip).
    pub event: u64,
    pub source_x_m: Option<f64>,
    pub source_kind: SourceKind,
}

/// `truth.parquet`: the ground truth of a synthetic experiment.
pub fn truth_table() -> crate::store::Table<TruthRow> {
    use crate::store::{ColType, ColumnSpec, Value};
    let classes: Vec<&str> = Mechanism::ALL
        .iter()
        .filter(|m| **m != Mechanism::Unclassified)
        .map(|m| m.as_str())
        .collect();
    crate::store::Table::new("truth")
        .col(
            ColumnSpec::new(
                cols::EXPERIMENT.name,
                ColType::Utf8,
                "",
                "experiment id (the Vallen file stem)",
            ),
            |t: &TruthRow| Value::Str(Some(t.experiment.clone())),
        )
        .col(
            ColumnSpec::of(cols::CHANNEL, "", "sensor channel"),
            |t| Value::I32(Some(t.channel as i32)),
        )
        .col(
            ColumnSpec::of(cols::HIT, "", "hit number (Vallen TRAI)"),
            |t| Value::I64(Some(t.hit as i64)),
        )
        .col(
            ColumnSpec::of(cols::TIME_S, "s", "hit time"),
            |t| Value::F64(t.time_s),
        )
        .col(
            ColumnSpec::new(
                cols::MECHANISM.name,
                ColType::Utf8,
                "",
                &format!("what made the hit: {}", classes.join(", ")),
            ),
            |t| Value::Str(Some(t.mechanism.as_str().to_string())),
        )
        .col(
            ColumnSpec::new(
                "reference_signals",
                ColType::Utf8,
                "",
                "the reference-library signals the hit was built from (empty: analytic waveform)",
            ),
            |t| Value::Str(Some(t.reference_signals.clone())),
        )
        .col(
            ColumnSpec::new(
                cols::EVENT.name,
                ColType::Int64,
                "",
                "the source the hit belongs to, 1-based in time order: the hits of one source at the test's sensors share it (the truth behind events.parquet)",
            ),
            |t| Value::I64(Some(t.event as i64)),
        )
        .col(
            ColumnSpec::new(
                cols::SOURCE_X_M.name,
                ColType::Float64,
                "m",
                "where the source is along the strip (the notch at 0; the sensors' coordinates of the pipeline's [location]); null: a one-sensor test",
            )
            .nullable(),
            |t| Value::F64(t.source_x_m),
        )
        .col(
            ColumnSpec::new(
                cols::SOURCE_KIND.name,
                ColType::Utf8,
                "",
                "specimen (paper damage in the gauge section) or grip (grip and machine noise beyond the sensors)",
            ),
            |t| Value::Str(Some(t.source_kind.as_str().to_string())),
        )
}

impl Experiment {
    /// Write the experiment as a Vallen pair in `dir` and its ground truth to `truth` (kept
    /// out of `dir`, which an ingest run reads whole). Returns the number of hits written
    /// (one per sensor that heard a source).
    pub fn write_with_truth(
        &self,
        dir: &std::path::Path,
        truth: &std::path::Path,
    ) -> Result<usize, SynthError> {
        use crate::store::TableWriter;
        let hits: Vec<SynthHit> = self.synth_hits().collect();
        let recs: Vec<AeRecord> = hits.iter().map(|h| h.rec.clone()).collect();
        self.write_vallen_records(dir, &recs)
            .map_err(|e| SynthError::Vallen {
                path: dir.display().to_string(),
                message: e.to_string(),
            })?;
        let path = truth.to_path_buf();
        let n_hits = hits.len();
        let table = truth_table();
        let mut w = TableWriter::create(
            &path,
            table.schema(),
            &[("aepipe.config_sha256".into(), format!("{:064x}", self.seed))],
            65_536,
        )?;
        let design = self.cycle_design();
        let mut cycle_truth: Vec<loading::CycleTruth> = design
            .iter()
            .map(|d| loading::CycleTruth {
                experiment: self.id.clone(),
                design: d.clone(),
                first_hit_s: None,
                first_hit_load_n: None,
            })
            .collect();
        for h in hits.iter().filter(|h| h.kind == SourceKind::Specimen) {
            let Some(t) = h.rec.time_s else { continue };
            if let Some(c) = cycle_truth.iter_mut().rfind(|c| c.design.start_s <= t) {
                if c.first_hit_s.is_none_or(|f| t < f) {
                    c.first_hit_s = Some(t);
                    c.first_hit_load_n = Some(self.load_at(&design, t));
                }
            }
        }
        for (r, h) in recs.iter().zip(hits) {
            let mechanism = r
                .label
                .as_deref()
                .and_then(Mechanism::parse)
                .expect("every synthetic hit is labelled with its mechanism");
            w.push(table.row(TruthRow {
                experiment: r.experiment.clone(),
                channel: r.channel,
                hit: r.hit,
                time_s: r.time_s,
                mechanism,
                reference_signals: h.reference,
                event: h.source,
                source_x_m: h.source_x_m,
                source_kind: h.kind,
            }))?;
        }
        w.finish()?;
        if !cycle_truth.is_empty() {
            let table = loading::cycle_truth_table();
            let path = truth.with_file_name("truth_cycles.parquet");
            let meta = [("aepipe.config_sha256".into(), format!("{:064x}", self.seed))];
            let mut w = TableWriter::create(&path, table.schema(), &meta, 1024)?;
            for c in cycle_truth {
                w.push(table.row(c))?;
            }
            w.finish()?;
        }
        Ok(n_hits)
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
