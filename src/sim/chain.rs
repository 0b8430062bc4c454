//! Measurement chains: what stands between the sheet's surface motion and the recorded
//! volts. Every reference library is recorded through a flat sensor (pressure × a
//! sensitivity, plus noise); real AE sensors are not flat. A chain is the sensor's frequency
//! response (its resonances, each a second-order band-pass) and the preamplifier's band (a
//! second-order Butterworth high-pass and low-pass), as a causal filter: a resonant sensor
//! rings at its resonance after the wave has passed, as a real one does.
//!
//! Chains are data (`pipelines/chains.toml`, embedded), each shaped after a published
//! response and saying so in its `basis`. A chain's largest gain over the band is 1: it
//! changes the shape of what is heard, not the library's sensitivity at the sensor's best
//! frequency. `flat` is the identity (the libraries' own recording).
//!
//! The filters are the biquads of R. Bristow-Johnson's "Audio EQ Cookbook" (band-pass with
//! 0 dB peak gain; Butterworth high- and low-pass at Q = 1/√2), run in direct form II
//! transposed.

use serde::Deserialize;
use std::f64::consts::PI;

/// The chains file shipped with aepipe.
pub const CHAINS_TOML: &str = include_str!("../../pipelines/chains.toml");

/// Why a chain definition cannot be used.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ChainError {
    #[error("chains file: {0}")]
    Parse(String),
    #[error("chain {chain}: {message}")]
    Invalid { chain: String, message: String },
    #[error("no chain named {name} (the file has: {known})")]
    Unknown { name: String, known: String },
}

/// `[[chain]]` entries of a chains file.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChainFile {
    pub chain: Vec<ChainConfig>,
}

/// One chain as written.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChainConfig {
    pub name: String,
    /// Where the shape comes from (a datasheet, the thesis), in words.
    pub basis: String,
    /// The sensor's resonances; none: a flat sensor.
    #[serde(default)]
    pub resonance: Vec<Resonance>,
    /// The preamplifier's band, Hz: [high-pass corner, low-pass corner]; absent: none.
    #[serde(default)]
    pub band_hz: Option<[f64; 2]>,
}

/// A sensor resonance: a second-order band-pass of peak gain `weight` at `peak_hz`, of
/// half-power bandwidth `peak_hz / q`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Resonance {
    pub peak_hz: f64,
    pub q: f64,
    #[serde(default = "one")]
    pub weight: f64,
}

fn one() -> f64 {
    1.0
}

impl ChainFile {
    /// The shipped chains.
    pub fn shipped() -> ChainFile {
        ChainFile::parse(CHAINS_TOML).expect("the embedded chains file parses")
    }

    pub fn parse(text: &str) -> Result<ChainFile, ChainError> {
        let f: ChainFile = toml::from_str(text).map_err(|e| ChainError::Parse(e.to_string()))?;
        let mut seen = std::collections::BTreeSet::new();
        for c in &f.chain {
            if !seen.insert(c.name.as_str()) {
                return Err(ChainError::Invalid {
                    chain: c.name.clone(),
                    message: "named twice".into(),
                });
            }
        }
        Ok(f)
    }

    /// The chain called `name`.
    pub fn get(&self, name: &str) -> Result<&ChainConfig, ChainError> {
        self.chain
            .iter()
            .find(|c| c.name == name)
            .ok_or_else(|| ChainError::Unknown {
                name: name.into(),
                known: self.names().join(", "),
            })
    }

    pub fn names(&self) -> Vec<&str> {
        self.chain.iter().map(|c| c.name.as_str()).collect()
    }
}

/// A biquad's normalised coefficients (a0 = 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Biquad {
    b: [f64; 3],
    a: [f64; 2],
}

impl Biquad {
    fn new(b: [f64; 3], a0: f64, a: [f64; 2]) -> Biquad {
        Biquad {
            b: b.map(|v| v / a0),
            a: a.map(|v| v / a0),
        }
    }

    /// Band-pass of peak gain 1 at `f0` and half-power bandwidth `f0 / q`.
    pub fn band_pass(fs: f64, f0: f64, q: f64) -> Biquad {
        let w = 2.0 * PI * f0 / fs;
        let alpha = w.sin() / (2.0 * q);
        Biquad::new(
            [alpha, 0.0, -alpha],
            1.0 + alpha,
            [-2.0 * w.cos(), 1.0 - alpha],
        )
    }

    /// Second-order low-pass (Butterworth at q = 1/√2), gain 1 at DC.
    pub fn low_pass(fs: f64, f0: f64, q: f64) -> Biquad {
        let w = 2.0 * PI * f0 / fs;
        let (c, alpha) = (w.cos(), w.sin() / (2.0 * q));
        let k = (1.0 - c) / 2.0;
        Biquad::new([k, 2.0 * k, k], 1.0 + alpha, [-2.0 * c, 1.0 - alpha])
    }

    /// Second-order high-pass (Butterworth at q = 1/√2), gain 1 at fs/2.
    pub fn high_pass(fs: f64, f0: f64, q: f64) -> Biquad {
        let w = 2.0 * PI * f0 / fs;
        let (c, alpha) = (w.cos(), w.sin() / (2.0 * q));
        let k = (1.0 + c) / 2.0;
        Biquad::new([k, -2.0 * k, k], 1.0 + alpha, [-2.0 * c, 1.0 - alpha])
    }

    /// The complex response at `f` (Hz) for sample rate `fs`, as (re, im).
    pub fn response(&self, f: f64, fs: f64) -> (f64, f64) {
        let w = 2.0 * PI * f / fs;
        // z^-1 = e^{-jw}
        let (c1, s1, c2, s2) = (w.cos(), -w.sin(), (2.0 * w).cos(), -(2.0 * w).sin());
        let (nr, ni) = (
            self.b[0] + self.b[1] * c1 + self.b[2] * c2,
            self.b[1] * s1 + self.b[2] * s2,
        );
        let (dr, di) = (
            1.0 + self.a[0] * c1 + self.a[1] * c2,
            self.a[0] * s1 + self.a[1] * s2,
        );
        let d = dr * dr + di * di;
        ((nr * dr + ni * di) / d, (ni * dr - nr * di) / d)
    }

    /// `x` filtered, from rest (direct form II transposed).
    pub fn run(&self, x: &[f64], out: &mut [f64]) {
        let (mut z1, mut z2) = (0.0, 0.0);
        for (o, &v) in out.iter_mut().zip(x) {
            let y = self.b[0] * v + z1;
            z1 = self.b[1] * v - self.a[0] * y + z2;
            z2 = self.b[2] * v - self.a[1] * y;
            *o = y;
        }
    }
}

/// A checked chain at one sample rate: the sensor's resonances in parallel, then the band's
/// high- and low-pass in series, scaled so the largest gain over the band is 1.
#[derive(Debug, Clone, PartialEq)]
pub struct Chain {
    pub name: String,
    sensor: Vec<(f64, Biquad)>,
    band: Vec<Biquad>,
    scale: f64,
    fs: f64,
}

/// Frequencies the chain's largest gain is sought over: 1 kHz to 0.45·fs, log-spaced.
const GAIN_GRID: usize = 4000;

impl ChainConfig {
    /// Checked once into a [`Chain`] for sample rate `fs`.
    pub fn check(&self, fs: f64) -> Result<Chain, ChainError> {
        let bad = |m: String| ChainError::Invalid {
            chain: self.name.clone(),
            message: m,
        };
        let nyquist = fs / 2.0;
        if !(fs.is_finite() && fs > 0.0) {
            return Err(bad(format!("sample rate {fs} Hz")));
        }
        let mut sensor = Vec::new();
        for r in &self.resonance {
            if !(r.peak_hz > 0.0 && r.peak_hz < nyquist) {
                return Err(bad(format!(
                    "resonance at {} Hz: must lie in (0, {nyquist}) Hz",
                    r.peak_hz
                )));
            }
            if !(r.q.is_finite() && r.q > 0.0 && r.weight.is_finite() && r.weight > 0.0) {
                return Err(bad(format!(
                    "resonance at {} Hz: q {} and weight {} must be positive",
                    r.peak_hz, r.q, r.weight
                )));
            }
            sensor.push((r.weight, Biquad::band_pass(fs, r.peak_hz, r.q)));
        }
        let mut band = Vec::new();
        if let Some([lo, hi]) = self.band_hz {
            if !(lo > 0.0 && lo < hi && hi < nyquist) {
                return Err(bad(format!(
                    "band [{lo}, {hi}] Hz: must be 0 < low < high < {nyquist}"
                )));
            }
            let q = std::f64::consts::FRAC_1_SQRT_2;
            band.push(Biquad::high_pass(fs, lo, q));
            band.push(Biquad::low_pass(fs, hi, q));
        }
        let mut c = Chain {
            name: self.name.clone(),
            sensor,
            band,
            scale: 1.0,
            fs,
        };
        if !c.is_flat() {
            let peak = (0..GAIN_GRID)
                .map(|k| {
                    let f = 1e3 * (0.45 * fs / 1e3).powf(k as f64 / (GAIN_GRID - 1) as f64);
                    c.gain(f)
                })
                .fold(0.0f64, f64::max);
            c.scale = 1.0 / peak;
        }
        Ok(c)
    }
}

impl Chain {
    /// The identity: no resonance and no band.
    pub fn is_flat(&self) -> bool {
        self.sensor.is_empty() && self.band.is_empty()
    }

    /// |H(f)|, the chain's gain at `f` Hz (its largest over the band is 1).
    pub fn gain(&self, f: f64) -> f64 {
        let (mut re, mut im) = if self.sensor.is_empty() {
            (1.0, 0.0)
        } else {
            self.sensor.iter().fold((0.0, 0.0), |(r, i), (w, b)| {
                let (br, bi) = b.response(f, self.fs);
                (r + w * br, i + w * bi)
            })
        };
        for b in &self.band {
            let (br, bi) = b.response(f, self.fs);
            (re, im) = (re * br - im * bi, re * bi + im * br);
        }
        self.scale * (re * re + im * im).sqrt()
    }

    /// `x` as the chain delivers it, from rest; the flat chain returns it unchanged.
    pub fn apply(&self, x: &[f64]) -> Vec<f64> {
        if self.is_flat() {
            return x.to_vec();
        }
        let mut y = vec![0.0; x.len()];
        if self.sensor.is_empty() {
            y.copy_from_slice(x);
        } else {
            let mut part = vec![0.0; x.len()];
            for (w, b) in &self.sensor {
                b.run(x, &mut part);
                y.iter_mut().zip(&part).for_each(|(o, p)| *o += w * p);
            }
        }
        let mut tmp = vec![0.0; x.len()];
        for b in &self.band {
            b.run(&y, &mut tmp);
            std::mem::swap(&mut y, &mut tmp);
        }
        y.iter_mut().for_each(|v| *v *= self.scale);
        y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FS: f64 = 10e6;

    fn shipped(name: &str) -> Chain {
        ChainFile::shipped().get(name).unwrap().check(FS).unwrap()
    }

    /// The cookbook's closed forms: the band-pass's gain is 1 at its peak and
    /// 1/√(1 + q²(f/f0 − f0/f)²) elsewhere; the Butterworth corners are at −3.01 dB.
    #[test]
    fn the_biquads_have_their_closed_form_responses() {
        let mag = |b: &Biquad, f: f64| {
            let (r, i) = b.response(f, FS);
            (r * r + i * i).sqrt()
        };
        let (f0, q) = (150e3, 3.0);
        let bp = Biquad::band_pass(FS, f0, q);
        assert!((mag(&bp, f0) - 1.0).abs() < 1e-9);
        // The digital band-pass is the bilinear transform of the analogue one: at
        // frequencies well below fs the two agree closely.
        for f in [50e3, 100e3, 250e3, 400e3] {
            let analogue = 1.0 / (1.0 + q * q * (f / f0 - f0 / f).powi(2)).sqrt();
            assert!((mag(&bp, f) / analogue - 1.0).abs() < 0.01, "{f}");
        }
        let q = std::f64::consts::FRAC_1_SQRT_2;
        let lp = Biquad::low_pass(FS, 1.2e6, q);
        let hp = Biquad::high_pass(FS, 20e3, q);
        assert!((mag(&lp, 0.0) - 1.0).abs() < 1e-12);
        assert!((mag(&hp, FS / 2.0) - 1.0).abs() < 1e-9);
        for (b, f) in [(lp, 1.2e6), (hp, 20e3)] {
            assert!((20.0 * mag(&b, f).log10() + 3.0103).abs() < 0.01);
        }
    }

    /// What the filter does in time is what its response says: a long sinusoid comes out,
    /// after the transient, at |H(f)| of its amplitude, for the shipped resonant chain.
    #[test]
    fn a_sinusoid_comes_out_at_the_chains_gain() {
        let c = shipped("resonant-150k");
        for f in [60e3, 150e3, 250e3, 750e3] {
            let n = 200_000;
            let x: Vec<f64> = (0..n)
                .map(|i| (2.0 * PI * f * i as f64 / FS).sin())
                .collect();
            let y = c.apply(&x);
            // The amplitude by correlation over the second half (the transient gone).
            let (mut a, mut b) = (0.0, 0.0);
            for (i, v) in y.iter().enumerate().skip(n / 2) {
                let ph = 2.0 * PI * f * i as f64 / FS;
                a += v * ph.sin();
                b += v * ph.cos();
            }
            let amp = 2.0 * (a * a + b * b).sqrt() / (n - n / 2) as f64;
            assert!(
                (amp / c.gain(f) - 1.0).abs() < 0.005,
                "{f}: {amp} vs {}",
                c.gain(f)
            );
        }
    }

    /// A resonant sensor rings: struck by an impulse, the shipped 150 kHz resonance (alone,
    /// without the band's corners) has its spectral peak at 150 kHz and its crests decay as
    /// exp(−π·f0·t/q), the band-pass pole's damping.
    #[test]
    fn a_resonant_sensor_rings_at_its_resonance_and_decays_at_its_q() {
        let mut cfg = ChainFile::shipped().get("resonant-150k").unwrap().clone();
        let r = cfg.resonance[0];
        cfg.band_hz = None;
        let c = cfg.check(FS).unwrap();
        let n = 1 << 15;
        let mut x = vec![0.0; n];
        x[0] = 1.0;
        let y = c.apply(&x);
        let spec = crate::dsp::filter::spectrum(&y, n);
        let k = (1..n / 2)
            .max_by(|&a, &b| spec[a].norm().total_cmp(&spec[b].norm()))
            .unwrap();
        let bin = FS / n as f64;
        assert!(
            (k as f64 * bin - r.peak_hz).abs() <= bin,
            "{}",
            k as f64 * bin
        );
        // ln of each crest (a positive local maximum) in the first 100 µs against its time:
        // a least-squares line whose slope is −π·f0/q.
        let crests: Vec<(f64, f64)> = (1..1000)
            .filter(|&i| y[i] > 0.0 && y[i] >= y[i - 1] && y[i] > y[i + 1])
            .map(|i| (i as f64 / FS, y[i].ln()))
            .collect();
        assert!(crests.len() >= 12, "{} crests", crests.len());
        let m = crests.len() as f64;
        let (mt, ml) = crests
            .iter()
            .fold((0.0, 0.0), |(a, b), (t, l)| (a + t / m, b + l / m));
        let (sxy, sxx) = crests.iter().fold((0.0, 0.0), |(a, b), (t, l)| {
            (a + (t - mt) * (l - ml), b + (t - mt) * (t - mt))
        });
        let measured = -sxy / sxx;
        let expected = PI * r.peak_hz / r.q;
        assert!(
            (measured / expected - 1.0).abs() < 0.01,
            "{measured} vs {expected}"
        );
    }

    /// The shipped chains' shapes are the ones their basis states: the resonant sensor's
    /// stated operating range 50–400 kHz lies 12–20 dB below its peak, the wideband
    /// sensor's 500–800 kHz within 3 dB of its best and its 100 and 2 500 kHz edges below
    /// −10 dB; each chain's largest gain is 1; the flat chain is the identity.
    #[test]
    fn the_shipped_chains_have_the_shapes_their_basis_states() {
        let db = |c: &Chain, f: f64| 20.0 * c.gain(f).log10();
        let r = shipped("resonant-150k");
        assert!(db(&r, 150e3).abs() < 0.1);
        for f in [50e3, 400e3] {
            assert!((-20.0..=-12.0).contains(&db(&r, f)), "{f}: {}", db(&r, f));
        }
        let w = shipped("wideband-650k");
        for f in [500e3, 650e3, 800e3] {
            assert!(db(&w, f) > -3.0, "{f}: {}", db(&w, f));
        }
        for f in [100e3, 2.5e6] {
            assert!(db(&w, f) < -10.0, "{f}: {}", db(&w, f));
        }
        let flat = shipped("flat");
        assert!(flat.is_flat());
        let x = [0.5, -1.0, 2.0];
        assert_eq!(flat.apply(&x), x);
        for c in [&r, &w] {
            let g = (0..GAIN_GRID)
                .map(|k| c.gain(1e3 * 4500f64.powf(k as f64 / (GAIN_GRID - 1) as f64)))
                .fold(0.0f64, f64::max);
            assert!((g - 1.0).abs() < 1e-9, "{}: {g}", c.name);
        }
    }

    /// Bad definitions are errors naming the chain and the value: a resonance above
    /// Nyquist, a q of 0, a band upside down, a name twice, an unknown key, an unknown
    /// chain.
    #[test]
    fn bad_chains_are_errors_that_say_why() {
        let one = |body: &str| {
            ChainFile::parse(&format!("[[chain]]\nname = \"x\"\nbasis = \"b\"\n{body}"))
                .and_then(|f| f.chain[0].check(FS).map(|_| ()))
                .unwrap_err()
                .to_string()
        };
        assert!(one("resonance = [{ peak_hz = 6e6, q = 2 }]").contains("6000000 Hz"));
        assert!(one("resonance = [{ peak_hz = 1e5, q = 0 }]").contains("q 0"));
        assert!(one("band_hz = [1e6, 1e5]").contains("band [1000000, 100000]"));
        assert!(one("gain = 2").contains("unknown field"));
        let twice =
            "[[chain]]\nname = \"x\"\nbasis = \"b\"\n[[chain]]\nname = \"x\"\nbasis = \"c\"";
        assert!(ChainFile::parse(twice)
            .unwrap_err()
            .to_string()
            .contains("named twice"));
        let e = ChainFile::shipped().get("r15").unwrap_err().to_string();
        assert!(
            e.contains("no chain named r15") && e.contains("flat"),
            "{e}"
        );
    }
}
