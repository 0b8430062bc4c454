//! Continuous wavelet transform with a complex Gabor (Morlet) wavelet, computed in the
//! frequency domain.
//!
//! The wavelet at centre frequency `f` has a Gaussian envelope whose full width at half
//! maximum is `fwhm_periods / f` (AGU-Vallen's Gabor wavelet style). In the frequency domain
//! its filter is `H(ν) = 2·exp(−(ν − f)² / 2σ_f²)` for ν > 0 and 0 for ν ≤ 0 (analytic), with
//! `σ_f = 2√(2 ln 2)·f / (2π·fwhm_periods)`. The gain 2 at ν = f makes the transform
//! amplitude-preserving: a sine of amplitude A at f gives |W(t, f)| = A.
//!
//! One implementation, two paths:
//! * [`Cwt::full_power`]: |W|² at every sample × every frequency of the record (pictures,
//!   `aepipe.cwt`). A frequency whose band a grid of a quarter of the record or less holds
//!   twice over is inverse-transformed there and interpolated along time to every sample
//!   (`banded`); the wider ones (high frequencies, where σ_f spans many grid steps) are
//!   interpolated across frequency from exact anchors σ_f/5 apart (`across`). Against
//!   [`Cwt::full_power_exact`] (one full-length inverse FFT per frequency): within 1e-4 of
//!   each row's peak on broadband signals, within 5e-5 of the scalogram's peak in every case
//!   tested (a pure tone on a row's far filter tail, where that row's own peak is 1e-4 of the
//!   scalogram's or less, can be off by 1e-3–1e-2 of that row's peak); 1.7× faster than it on
//!   the peers' W1.
//! * [`Cwt::window_power`]: |W|² only over an output window `[a, b)` (the 200 feature bins
//!   need 40 µs). Each frequency then needs only the window plus its wavelet's support
//!   (±5σ_t), so it is computed from a short segment with a short FFT; frequencies that need
//!   the same segment length share one forward FFT. Where a segment would not fit inside the
//!   record (low frequencies, long wavelets) the whole record is used, exactly as the full
//!   path does, so the two paths agree.

mod across;
mod banded;

use super::settings::CwtConfig;
use rustfft::num_complex::Complex32;
use rustfft::{Fft, FftPlanner};
/// The caches' maps: keys are a few integers, hashed per frequency per record.
type HashMap<K, V> = std::collections::HashMap<K, V, rustc_hash::FxBuildHasher>;
use std::f64::consts::PI;
use std::sync::Arc;

/// 2·sqrt(2·ln 2): FWHM of a Gaussian in units of its σ.
const FWHM_SIGMAS: f64 = 2.354_820_045_030_949_4;
/// How many σ of the wavelet are kept (in frequency: filter support; in time: segment margin).
const SUPPORT_SIGMAS: f64 = 5.0;
/// Cache bounds, per engine (one per worker). Records of any length map to few padded FFT
/// lengths (3-smooth), so these are rarely reached; when one is, that cache starts afresh.
/// Plans are bounded by their summed lengths (a plan's twiddles take about 8 bytes per point),
/// not their number: a LinWave-like test meets ~66 padded record lengths plus the segment
/// lengths, forward and inverse, and a bound of 96 plans cleared the cache every few records,
/// so planning (twiddles, ~18 % of that workload) ran again and again.
const MAX_PLAN_POINTS: usize = 8 << 20;
/// And by number, for many tiny plans.
const MAX_PLANS: usize = 1024;
const MAX_GROUP_SETS: usize = 256;
/// Filter taps kept (f32 each): 8 Mi taps = 32 MiB per worker.
const MAX_FILTER_TAPS: usize = 8 << 20;
/// Interpolator weights kept, over all decimations (32 bytes each).
const MAX_PHASES: usize = 1 << 16;
/// A segment at most 1/this of the padded record is transformed on its own
/// even where it reaches past the record (read as zeros there), instead of transforming the
/// whole record: the cost of a frequency stays bounded by its wavelet, not the record.
const WHOLE_RECORD_RATIO: usize = 2;
/// Segment margin, in wavelet supports, of a filter that reaches Nyquist (its roll-off
/// widens the wavelet in time by about √2).
const CUT_MARGIN: f64 = 2.0;

/// The wavelet family and frequency grid.
#[derive(Debug, Clone, PartialEq)]
pub struct WaveletBank {
    pub freqs_hz: Vec<f64>,
    pub fwhm_periods: f64,
}

impl WaveletBank {
    /// Linear grid from `f_min_hz` to `f_max_hz` inclusive.
    pub fn from_config(c: &CwtConfig) -> WaveletBank {
        let n = c.n_freqs.max(1);
        let step = if n > 1 {
            (c.f_max_hz - c.f_min_hz) / (n - 1) as f64
        } else {
            0.0
        };
        WaveletBank {
            freqs_hz: (0..n).map(|k| c.f_min_hz + step * k as f64).collect(),
            fwhm_periods: c.fwhm_periods,
        }
    }

    /// Standard deviation of the filter in frequency, Hz.
    pub fn sigma_f(&self, f: f64) -> f64 {
        FWHM_SIGMAS * f / (2.0 * PI * self.fwhm_periods)
    }

    /// Whether the filter of `f` reaches Nyquist at `fs` and is rolled off there (see
    /// `make_band`): the filter's shape changes where this changes.
    fn cut_at_nyquist(&self, f: f64, fs: f64) -> bool {
        f + SUPPORT_SIGMAS * self.sigma_f(f) > fs / 2.0
    }

    /// Standard deviation of the envelope in time, s.
    pub fn sigma_t(&self, f: f64) -> f64 {
        self.fwhm_periods / (FWHM_SIGMAS * f)
    }
}

/// The filter of one frequency on one FFT grid: taps for bins `k0 .. k0 + taps.len()`
/// (already divided by the FFT length, so the unnormalised inverse FFT gives W).
#[derive(Debug, Default)]
struct Band {
    k0: usize,
    taps: Vec<f32>,
}

/// Frequencies that share one segment length in [`Cwt::window_power`].
#[derive(Debug)]
struct Group {
    /// Segment length (FFT size); equal to the record length for whole-record groups.
    m: usize,
    /// First sample of the segment in the record (negative, or running past the record's
    /// end, where the record is read as zeros).
    start: isize,
    whole_record: bool,
    freqs: Vec<usize>,
}

/// The spectrum a frequency's transform starts from: FFT length, sample rate, and whether it
/// is the whole record's spectrum (else the current segment's).
#[derive(Debug, Clone, Copy)]
struct Seg {
    m: usize,
    fs: f64,
    whole: bool,
}

/// The filter of frequency `fi` of `bank` on an `m`-point DFT grid at `fs`.
fn make_band(bank: &WaveletBank, fi: usize, m: usize, fs: f64) -> Band {
    let f = bank.freqs_hz[fi];
    let nyq = fs / 2.0;
    if f <= 0.0 || f > nyq {
        return Band::default(); // above Nyquist: nothing to see
    }
    let df = fs / m as f64;
    let half = m / 2;
    let s = bank.sigma_f(f);
    let lo = (((f - SUPPORT_SIGMAS * s) / df).ceil().max(1.0)) as usize;
    let hi = (((f + SUPPORT_SIGMAS * s) / df).floor() as usize).min(half);
    if hi < lo {
        return Band::default();
    }
    let cut = bank.cut_at_nyquist(f, fs);
    let taps = (lo..=hi)
        .map(|k| {
            let nu = k as f64 * df;
            let d = nu - f;
            let mut h = 2.0 * (-d * d / (2.0 * s * s)).exp();
            if cut {
                // Smooth roll-off to 0 at Nyquist (width σ_f), so the wavelet stays compact
                // in time instead of ringing from a step.
                let e = nyq - nu;
                h *= 1.0 - (-e * e / (2.0 * s * s)).exp();
            }
            (h / m as f64) as f32
        })
        .collect();
    Band { k0: lo, taps }
}

/// [`Cwt::fast_path_error`]: per frequency, and the exact scalogram's peak |W|².
#[derive(Debug, Clone)]
pub struct FastPathError {
    pub rows: Vec<RowError>,
    pub peak: f64,
}

/// One frequency's largest |fast − exact| |W|², the exact row's peak, and whether the two rows
/// are the same bits (rows computed exactly: anchors, rows in no run).
#[derive(Debug, Clone, Copy)]
pub struct RowError {
    pub err: f64,
    pub peak: f64,
    pub bit_equal: bool,
}

/// Run `plan` in place on `buf`, growing the caller's scratch to what the plan needs.
fn transform(plan: &Arc<dyn Fft<f32>>, buf: &mut [Complex32], scratch: &mut Vec<Complex32>) {
    let need = plan.get_inplace_scratch_len();
    if scratch.len() < need {
        scratch.resize(need, Complex32::default());
    }
    plan.process_with_scratch(buf, &mut scratch[..need]);
}

/// Per-worker CWT engine: plans, filters and buffers, reused across records.
pub struct Cwt {
    bank: WaveletBank,
    plans: HashMap<(usize, bool), Arc<dyn Fft<f32>>>,
    /// Summed lengths of `plans` (their memory bound).
    plan_points: usize,
    filters: HashMap<(usize, u64, usize), Arc<Band>>,
    /// Filter taps held by `filters` (their memory bound).
    filter_taps: usize,
    groups: HashMap<(usize, u64, usize, usize), Arc<Vec<Group>>>,
    /// The banded path's interpolator weights per decimation, and their count (bound).
    phases: HashMap<usize, Arc<Vec<[f32; banded::TAPS]>>>,
    phase_count: usize,
    banded: banded::Scratch,
    /// Spectrum of the whole record loaded by [`Cwt::load`], zero-padded to a fast length.
    full: Vec<Complex32>,
    /// (record length, padded length, sample rate bits) of the loaded record.
    loaded: Option<(usize, usize, u64)>,
    seg: Vec<Complex32>,
    work: Vec<Complex32>,
    scratch: Vec<Complex32>,
    row: Vec<f32>,
}

impl Cwt {
    pub fn new(bank: WaveletBank) -> Cwt {
        Cwt {
            bank,
            plans: HashMap::default(),
            plan_points: 0,
            filters: HashMap::default(),
            filter_taps: 0,
            groups: HashMap::default(),
            phases: HashMap::default(),
            phase_count: 0,
            banded: banded::Scratch::default(),
            full: Vec::new(),
            loaded: None,
            seg: Vec::new(),
            work: Vec::new(),
            scratch: Vec::new(),
            row: Vec::new(),
        }
    }

    pub fn bank(&self) -> &WaveletBank {
        &self.bank
    }

    /// The plan of an `m`-point FFT. Each length is planned by a fresh planner: RustFFT's
    /// planner rebuilds a new length on the largest step it already holds, so a shared one
    /// makes the plan (and the last bits of every result) depend on which lengths a worker
    /// met before. A fresh one gives each length the same plan on every worker, thread
    /// count and shard: the tables are byte-identical however the batch is split.
    fn plan(&mut self, m: usize, inverse: bool) -> Arc<dyn Fft<f32>> {
        if let Some(p) = self.plans.get(&(m, inverse)) {
            return p.clone();
        }
        if self.plans.len() >= MAX_PLANS || self.plan_points + m > MAX_PLAN_POINTS {
            self.plans.clear();
            self.plan_points = 0;
        }
        let mut planner = FftPlanner::new();
        let plan = if inverse {
            planner.plan_fft_inverse(m)
        } else {
            planner.plan_fft_forward(m)
        };
        self.plan_points += m;
        self.plans.insert((m, inverse), plan.clone());
        plan
    }

    /// The filter of frequency `fi` on an `m`-point grid at `fs`, made on first use (only the
    /// frequencies a grid is used for get taps there).
    fn band(&mut self, fi: usize, m: usize, fs: f64) -> Arc<Band> {
        let key = (m, fs.to_bits(), fi);
        if let Some(b) = self.filters.get(&key) {
            return b.clone();
        }
        if self.filter_taps > MAX_FILTER_TAPS {
            self.filters.clear();
            self.filter_taps = 0;
        }
        let band = Arc::new(make_band(&self.bank, fi, m, fs));
        self.filter_taps += band.taps.len();
        self.filters.insert(key, band.clone());
        band
    }

    /// Forward FFT of `x[start .. start + m]` into the segment buffer, reading the record as
    /// zeros outside `0..x.len()`.
    fn forward_segment(&mut self, x: &[f32], start: isize, m: usize) {
        let plan = self.plan(m, false);
        self.seg.clear();
        // The part of the segment inside the record, with zeros before and after it.
        let lo = start.clamp(0, x.len() as isize) as usize;
        let hi = (start + m as isize).clamp(0, x.len() as isize) as usize;
        let before = (lo as isize - start) as usize;
        self.seg.resize(before, Complex32::default());
        self.seg
            .extend(x[lo..hi].iter().map(|&v| Complex32::new(v, 0.0)));
        self.seg.resize(m, Complex32::default());
        transform(&plan, &mut self.seg, &mut self.scratch);
    }

    /// Load a record: one forward FFT of the whole record, kept for the spectrum features
    /// and for the whole-record CWT. Must precede [`full_power`](Self::full_power) and
    /// [`window_power`](Self::window_power) for the same record.
    pub fn load(&mut self, x: &[f32], fs: f64) {
        let n = x.len();
        let padded = super::next_fast_len(n);
        let plan = self.plan(padded, false);
        self.full.clear();
        self.full.extend(x.iter().map(|&v| Complex32::new(v, 0.0)));
        self.full.resize(padded, Complex32::default());
        transform(&plan, &mut self.full, &mut self.scratch);
        self.loaded = Some((n, padded, fs.to_bits()));
    }

    /// Length of the loaded record's spectrum: the record zero-padded to the next 2^a·3^b
    /// (the record itself when its length is one), so any record length maps to few FFT
    /// sizes and plans.
    pub fn padded_len(&self) -> usize {
        self.loaded.map_or(0, |l| l.1)
    }

    /// The whole (padded) record's spectrum (unnormalised DFT), after [`load`](Self::load).
    pub fn spectrum(&self) -> &[Complex32] {
        &self.full
    }

    /// |W|² of frequency `fi` from a spectrum of length `m`, for outputs `lo..hi` of the
    /// segment, into `out` (length `hi − lo`).
    fn band_power(&mut self, fi: usize, seg: Seg, lo: usize, hi: usize, out: &mut [f32]) {
        if !self.band_transform(fi, seg) {
            out.fill(0.0);
            return;
        }
        for (o, w) in out.iter_mut().zip(&self.work[lo..hi]) {
            *o = w.norm_sqr();
        }
    }

    /// W of frequency `fi` over the whole segment (complex, unnormalised inverse FFT of the
    /// filtered spectrum) into `self.work`; false (and nothing computed) where its filter is
    /// empty (above Nyquist).
    fn band_transform(&mut self, fi: usize, seg: Seg) -> bool {
        let Seg {
            m,
            fs,
            whole: from_full,
        } = seg;
        let band = self.band(fi, m, fs);
        if band.taps.is_empty() {
            return false;
        }
        let plan = self.plan(m, true);
        self.work.clear();
        self.work.resize(m, Complex32::default());
        let spec = if from_full { &self.full } else { &self.seg };
        let taps = band.k0..band.k0 + band.taps.len();
        for ((w, &v), &t) in self.work[taps.clone()]
            .iter_mut()
            .zip(&spec[taps])
            .zip(&band.taps)
        {
            *w = v * t;
        }
        transform(&plan, &mut self.work, &mut self.scratch);
        true
    }

    fn check_loaded(&self, x: &[f32], fs: f64) {
        assert_eq!(
            self.loaded.map(|l| (l.0, l.2)),
            Some((x.len(), fs.to_bits())),
            "Cwt::load must be called with this record first"
        );
    }

    /// Full resolution: |W(t, f)|² for every frequency (rows) × every sample (columns),
    /// row-major into `out`, which must hold `n_freqs · x.len()` values. Interpolated along
    /// time (`banded`) or across frequency (`across`) where that is cheaper than a full-length
    /// transform: within 5e-5 of the scalogram's peak of
    /// [`full_power_exact`](Self::full_power_exact), and within 1e-4 of each row's peak on
    /// broadband signals (see the module notes).
    pub fn full_power(&mut self, x: &[f32], fs: f64, out: &mut [f32]) {
        self.full_rows(x, fs, out, true);
    }

    /// As [`full_power`](Self::full_power), with one inverse FFT of the whole padded record
    /// per frequency: the reference the fast path is measured against.
    pub fn full_power_exact(&mut self, x: &[f32], fs: f64, out: &mut [f32]) {
        self.full_rows(x, fs, out, false);
    }

    fn full_rows(&mut self, x: &[f32], fs: f64, out: &mut [f32], fast: bool) {
        self.check_loaded(x, fs);
        let n = x.len();
        let nf = self.bank.freqs_hz.len();
        assert_eq!(
            out.len(),
            nf * n,
            "full_power needs n_freqs × n_samples outputs"
        );
        if n == 0 {
            return;
        }
        let padded = self.padded_len();
        let whole = Seg {
            m: padded,
            fs,
            whole: true,
        };
        if !fast {
            for (fi, row) in out.chunks_exact_mut(n).enumerate() {
                self.band_power(fi, whole, 0, n, row);
            }
            return;
        }
        // Rows that no grid of a quarter of the record holds are taken across frequency where
        // they come in ascending runs of one filter shape (a run ends where the roll-off at
        // Nyquist sets in: the filters change abruptly there); the rest along time on their
        // shorter grid.
        let wide: Vec<bool> = (0..nf)
            .map(|fi| {
                self.decimation(fi, padded, fs)
                    .is_some_and(|d| d <= across::MAX_DECIMATION)
            })
            .collect();
        let freqs = self.bank.freqs_hz.clone();
        let mut fi = 0;
        while fi < nf {
            let mut end = fi + 1;
            let same_shape =
                |a: f64, b: f64| self.bank.cut_at_nyquist(a, fs) == self.bank.cut_at_nyquist(b, fs);
            // A gap wider than an anchor spacing ends a run too (a user's grid with a hole).
            let close =
                |a: f64, b: f64| b > a && b - a <= self.bank.sigma_f(a) / across::ANCHORS_PER_SIGMA;
            while wide[fi]
                && end < nf
                && wide[end]
                && close(freqs[end - 1], freqs[end])
                && same_shape(freqs[end], freqs[fi])
            {
                end += 1;
            }
            if wide[fi] && self.across_run(fi..end, whole, n, out) {
                fi = end;
                continue;
            }
            for i in fi..end {
                let row = &mut out[i * n..(i + 1) * n];
                if !self.banded_row(i, padded, fs, row) {
                    self.band_power(i, whole, 0, n, row);
                }
            }
            fi = end;
        }
    }

    /// How far [`full_power`](Self::full_power) is from
    /// [`full_power_exact`](Self::full_power_exact) on the loaded record (the tests' and
    /// `aepipe bench cwt`'s measure).
    pub fn fast_path_error(&mut self, x: &[f32], fs: f64) -> FastPathError {
        let (n, nf) = (x.len(), self.bank.freqs_hz.len());
        let (mut exact, mut fast) = (vec![0f32; nf * n], vec![0f32; nf * n]);
        self.full_power_exact(x, fs, &mut exact);
        self.full_power(x, fs, &mut fast);
        let peak_of = |r: &[f32]| r.iter().fold(0f32, |m, &v| m.max(v)) as f64;
        let rows = exact
            .chunks_exact(n.max(1))
            .zip(fast.chunks_exact(n.max(1)))
            .map(|(e, f)| {
                let err = e
                    .iter()
                    .zip(f)
                    .map(|(a, b)| (*a as f64 - *b as f64).abs())
                    .fold(0.0, f64::max);
                RowError {
                    err,
                    peak: peak_of(e),
                    bit_equal: e == f,
                }
            })
            .collect();
        FastPathError {
            rows,
            peak: peak_of(&exact),
        }
    }

    /// Frequency `fi`'s filter on the whole padded grid, its peak bin and the decimation
    /// `banded` gives it (None: an empty filter, nothing to compute).
    fn banded_plan(
        &mut self,
        fi: usize,
        padded: usize,
        fs: f64,
    ) -> Option<(Arc<Band>, usize, usize)> {
        let band = self.band(fi, padded, fs);
        if band.taps.is_empty() {
            return None;
        }
        let len = band.taps.len();
        let c = banded::centre(self.bank.freqs_hz[fi], fs / padded as f64, band.k0, len);
        let d = banded::decimation(padded, band.k0, len, c);
        Some((band, c, d))
    }

    /// The decimation `banded` would give frequency `fi` (None: nothing to compute there).
    fn decimation(&mut self, fi: usize, padded: usize, fs: f64) -> Option<usize> {
        self.banded_plan(fi, padded, fs).map(|p| p.2)
    }

    /// Rows `rows` (ascending frequencies) from exact anchors and interpolation across
    /// frequency between them; false (nothing written) where the run is too short for it.
    fn across_run(
        &mut self,
        rows: std::ops::Range<usize>,
        whole: Seg,
        n: usize,
        out: &mut [f32],
    ) -> bool {
        let f = &self.bank.freqs_hz[rows.clone()];
        let bank = &self.bank;
        let anchors = across::anchors(f, |x| bank.sigma_f(x));
        if anchors.len() < across::TAPS || anchors.len() == f.len() {
            return false;
        }
        let f = f.to_vec();
        // Anchors' complex W (real parts, then imaginary), computed when a stencil first needs them
        // and dropped once no later stencil does: at most TAPS + 1 records' worth.
        let mut held: std::collections::VecDeque<(usize, Vec<f32>)> = Default::default();
        let mut spare: Vec<Vec<f32>> = Vec::new();
        for i in 0..f.len() {
            let row = &mut out[(rows.start + i) * n..(rows.start + i + 1) * n];
            let s = across::stencil_start(&anchors, i);
            while held.front().is_some_and(|h| h.0 < s) {
                spare.extend(held.pop_front().map(|h| h.1));
            }
            while held.back().map_or(s, |h| h.0 + 1) < s + across::TAPS {
                let k = held.back().map_or(s, |h| h.0 + 1);
                let mut buf = spare.pop().unwrap_or_default();
                buf.clear();
                buf.resize(2 * n, 0.0);
                if self.band_transform(rows.start + anchors[k], whole) {
                    let (re, im) = buf.split_at_mut(n);
                    for ((r, i), w) in re.iter_mut().zip(im).zip(&self.work[..n]) {
                        *r = w.re;
                        *i = w.im;
                    }
                }
                held.push_back((k, buf));
            }
            if let Some(h) = held.iter().find(|h| anchors[h.0] == i) {
                let (re, im) = h.1.split_at(n);
                for ((o, r), i) in row.iter_mut().zip(re).zip(im) {
                    *o = r * r + i * i;
                }
                continue;
            }
            let nodes: [f64; across::TAPS] = std::array::from_fn(|t| f[anchors[s + t]]);
            let w = across::weights(&nodes, f[i]);
            let stencil: [&[f32]; across::TAPS] = std::array::from_fn(|t| &held[t].1[..]);
            across::interpolate_power(stencil, &w, row);
        }
        true
    }

    /// |W|² of frequency `fi` over the whole record from a decimated grid, into `row`; false
    /// (nothing written) where the band is too wide to decimate.
    fn banded_row(&mut self, fi: usize, padded: usize, fs: f64, row: &mut [f32]) -> bool {
        let Some((band, c, d)) = self.banded_plan(fi, padded, fs) else {
            return false;
        };
        if d == 1 {
            return false;
        }
        let m = padded / d;
        let plan = self.plan(m, true);
        // The band shifted so that bin c lands on 0: bins below it wrap to the grid's end.
        self.work.clear();
        self.work.resize(m, Complex32::default());
        let (len, split) = (band.taps.len(), c - band.k0);
        let (spec_below, spec_from) = self.full[band.k0..band.k0 + len].split_at(split);
        let (taps_below, taps_from) = band.taps.split_at(split);
        for ((w, &v), &t) in self.work[m - split..]
            .iter_mut()
            .zip(spec_below)
            .zip(taps_below)
        {
            *w = v * t;
        }
        for ((w, &v), &t) in self.work[..len - split]
            .iter_mut()
            .zip(spec_from)
            .zip(taps_from)
        {
            *w = v * t;
        }
        transform(&plan, &mut self.work, &mut self.scratch);
        let weights = self.phases(d);
        banded::interpolate_power(&self.work, d, &weights, &mut self.banded, row);
        true
    }

    /// The interpolator's weights for decimation `d`, made on first use.
    fn phases(&mut self, d: usize) -> Arc<Vec<[f32; banded::TAPS]>> {
        if let Some(w) = self.phases.get(&d) {
            return w.clone();
        }
        if self.phase_count + d > MAX_PHASES {
            self.phases.clear();
            self.phase_count = 0;
        }
        let w = Arc::new(banded::phases(d));
        self.phase_count += d;
        self.phases.insert(d, w.clone());
        w
    }

    /// How the frequencies of a window `a..b` of a record padded to `padded` samples are
    /// computed: frequencies that need the same segment length share one forward FFT of a
    /// segment centred on the window. A segment that fits inside the record is used as it
    /// is; one that reaches past the record reads zeros there if it is at most half the
    /// padded record, else the whole (padded) record is used, as the full path computes it.
    /// So no frequency costs more than its wavelet. Filters that reach Nyquist roll off
    /// smoothly there (see `make_band`) and get `CUT_MARGIN` times the support.
    fn groups(&mut self, padded: usize, fs: f64, a: usize, b: usize) -> Arc<Vec<Group>> {
        if self.groups.len() >= MAX_GROUP_SETS
            && !self.groups.contains_key(&(padded, fs.to_bits(), a, b))
        {
            self.groups.clear();
        }
        let bank = &self.bank;
        self.groups
            .entry((padded, fs.to_bits(), a, b))
            .or_insert_with(|| {
                let w = b - a;
                let mut by_m: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
                let mut whole = Vec::new();
                for (fi, &f) in bank.freqs_hz.iter().enumerate() {
                    if f <= 0.0 || f > fs / 2.0 {
                        continue;
                    }
                    let cut_at_nyquist = bank.cut_at_nyquist(f, fs);
                    // A filter cut at Nyquist is not compact in time: its segment keeps
                    // CUT_MARGIN times the support, where the ringing has died down.
                    let k = if cut_at_nyquist { CUT_MARGIN } else { 1.0 };
                    let t = (k * SUPPORT_SIGMAS * bank.sigma_t(f) * fs).ceil() as usize;
                    let m = super::next_fast_segment_len(w + 2 * t);
                    let margin = (m - w) / 2;
                    let inside = a >= margin && a - margin + m <= padded;
                    let short = m * WHOLE_RECORD_RATIO <= padded;
                    if inside || short {
                        by_m.entry(m).or_default().push(fi);
                    } else {
                        whole.push(fi);
                    }
                }
                let mut gs: Vec<Group> = by_m
                    .into_iter()
                    .map(|(m, freqs)| Group {
                        m,
                        start: a as isize - ((m - w) / 2) as isize,
                        whole_record: false,
                        freqs,
                    })
                    .collect();
                if !whole.is_empty() {
                    gs.push(Group {
                        m: padded,
                        start: 0,
                        whole_record: true,
                        freqs: whole,
                    });
                }
                Arc::new(gs)
            })
            .clone()
    }

    /// |W|² over the output window `a..b` only: `visit(freq_index, power)` is called once for
    /// each frequency below Nyquist, with `power.len() == b − a`. Frequencies above Nyquist
    /// are not visited (their power is zero).
    pub fn window_power(
        &mut self,
        x: &[f32],
        fs: f64,
        a: usize,
        b: usize,
        mut visit: impl FnMut(usize, &[f32]),
    ) {
        self.check_loaded(x, fs);
        let n = x.len();
        assert!(
            a <= b && b <= n,
            "window {a}..{b} outside a record of {n} samples"
        );
        if a == b {
            return;
        }
        let groups = self.groups(self.padded_len(), fs, a, b);
        let mut row = std::mem::take(&mut self.row);
        row.resize(b - a, 0.0);
        for g in groups.iter() {
            self.load_group(g, x);
            for &fi in &g.freqs {
                self.group_row(g, fs, a, fi, &mut row);
                visit(fi, &row);
            }
        }
        self.row = row;
    }

    /// The spectrum group `g`'s frequencies start from: its segment's forward FFT (the whole
    /// record's is already loaded).
    fn load_group(&mut self, g: &Group, x: &[f32]) {
        if !g.whole_record {
            self.forward_segment(x, g.start, g.m);
        }
    }

    /// |W|² of frequency `fi` of group `g` (loaded) over the window from sample `a`, into `out`
    /// (the window's length).
    fn group_row(&mut self, g: &Group, fs: f64, a: usize, fi: usize, out: &mut [f32]) {
        let lo = (a as isize - g.start) as usize;
        let seg = Seg {
            m: g.m,
            fs,
            whole: g.whole_record,
        };
        self.band_power(fi, seg, lo, lo + out.len(), out);
    }

    /// |W|² of one frequency over the output window `a..b` into `out` (as
    /// [`window_power`](Self::window_power) computes it for that frequency).
    pub fn window_row(
        &mut self,
        x: &[f32],
        fs: f64,
        a: usize,
        b: usize,
        fi: usize,
        out: &mut Vec<f32>,
    ) {
        self.check_loaded(x, fs);
        out.clear();
        out.resize(b - a, 0.0);
        let groups = self.groups(self.padded_len(), fs, a, b);
        if let Some(g) = groups.iter().find(|g| g.freqs.contains(&fi)) {
            self.load_group(g, x);
            self.group_row(g, fs, a, fi, out);
        }
    }
}

#[cfg(test)]
mod tests;
