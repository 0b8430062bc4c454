//! The per-record transform: a validated [`AeRecord`] becomes one feature row.
//!
//! For each record: condition (remove the pretrigger mean), one FFT of the whole record
//! (power ratios, peak and centroid frequency), the CWT over the bins' window (the 200
//! time/frequency bins and the components the ch. 4.7 criteria need), the standard hit
//! features, and the criteria label.
//!
//! [`FeatureExtractor`] is made once per worker and reused for every record: FFT plans,
//! wavelet filters and buffers live in it, so nothing is planned or allocated per record
//! once its caches are warm (beyond the output row). [`features_table`] lists the columns;
//! adding a feature is one [`ColumnSpec`] there and one value in [`FeatureExtractor::row`].

pub mod criteria;
pub mod settings;

use crate::dsp::cwt::{Cwt, WaveletBank};
use crate::dsp::hit::hit_features;
use crate::dsp::pick::{self, PickScratch};
use crate::dsp::settings::{DspConfig, Picker};
use crate::dsp::spectrum::{band_column, power_ratios};
use crate::dsp::{condition, hit::HitFeatures};
use crate::model::columns as cols;
use crate::model::crack::{af_khz, crack_mode, ra_ms_per_v, CrackModeConfig};
use crate::model::{db_ae, AeRecord};
use crate::store::{identity_table, table::s, ColType, ColumnSpec, Identity, Row, Table, Value};
use criteria::{acquisition_fault, decide, Component, Components};
use ndarray::Array2;
use settings::{FeatureSettings, ValidateConfig};

/// Why a record cannot become a feature row (stage `validate`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FeatureError {
    #[error("record has 0 samples")]
    Empty,
    #[error("record has {samples} samples, fewer than validate.min_samples = {min}")]
    TooShort { samples: usize, min: usize },
    #[error("sample rate {0} Hz is not a positive number")]
    SampleRate(f64),
    #[error("{count} non-finite samples (NaN or inf), first at index {first} ({value})")]
    NonFinite {
        count: usize,
        first: usize,
        value: f32,
    },
    #[error("pretrigger {pretrigger} is longer than the record ({samples} samples)")]
    Pretrigger { pretrigger: u64, samples: usize },
}

/// Check a record before the transform: it must have samples, a rate, finite values and a
/// pretrigger inside it.
pub fn validate(r: &AeRecord, v: &ValidateConfig) -> Result<(), FeatureError> {
    if r.samples.is_empty() {
        return Err(FeatureError::Empty);
    }
    if r.samples.len() < v.min_samples {
        return Err(FeatureError::TooShort {
            samples: r.samples.len(),
            min: v.min_samples,
        });
    }
    if !(r.sample_rate_hz.is_finite() && r.sample_rate_hz > 0.0) {
        return Err(FeatureError::SampleRate(r.sample_rate_hz));
    }
    let count = r.samples.iter().filter(|s| !s.is_finite()).count();
    if count > 0 {
        let first = r.samples.iter().position(|s| !s.is_finite()).unwrap_or(0);
        return Err(FeatureError::NonFinite {
            count,
            first,
            value: r.samples[first],
        });
    }
    if r.pretrigger as usize > r.samples.len() {
        return Err(FeatureError::Pretrigger {
            pretrigger: r.pretrigger as u64,
            samples: r.samples.len(),
        });
    }
    Ok(())
}

/// The layout of the time/frequency bins: `n_bands` bands of `band_hz` from 0 Hz, times
/// `n_windows` windows of `window_s` from the trigger. Bin index = band · n_windows + window.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BinGrid {
    pub n_bands: usize,
    pub band_hz: f64,
    pub n_windows: usize,
    pub window_s: f64,
}

impl BinGrid {
    pub fn of(dsp: &DspConfig) -> BinGrid {
        let b = &dsp.bins;
        BinGrid {
            n_bands: (dsp.band_max_hz / b.band_hz).round() as usize,
            band_hz: b.band_hz,
            n_windows: b.n_windows,
            window_s: b.window_s,
        }
    }

    pub fn len(&self) -> usize {
        self.n_bands * self.n_windows
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The bins' description stored in the Parquet metadata (`aepipe.tf_bins`).
    pub fn describe(&self) -> String {
        serde_json::json!({
            "order": "band-major: index = band * n_windows + window",
            "n_bands": self.n_bands,
            "band_hz": self.band_hz,
            "n_windows": self.n_windows,
            "window_s": self.window_s,
            "time_origin": "trigger (first sample after the pretrigger)",
            "value": "sum of |W|^2 over the bin / sum over all bins",
        })
        .to_string()
    }
}

/// One row of `features.parquet`: the record's identity and what the DSP found in it.
pub struct FeatureRow {
    pub id: Identity,
    pub source_file: String,
    /// First threshold crossing from the trigger, s.
    pub first_crossing_s: Option<f64>,
    /// The configured picker's arrival on the acquisition's clock, s.
    pub arrival_s: Option<f64>,
    pub an: Analysis,
}

/// The columns of `features.parquet` for a configuration, each with the cell it takes from a
/// [`FeatureRow`]: the only place a feature column is declared.
pub fn features_table(dsp: &DspConfig, crack: CrackModeConfig) -> Table<FeatureRow> {
    let ra = |r: &FeatureRow| ra_ms_per_v(r.an.hit.rise_time_s, r.an.hit.amplitude_v);
    let af = |r: &FeatureRow| af_khz(r.an.hit.counts, r.an.hit.duration_s);
    let f64c =
        |name: &str, unit: &str, doc: &str| ColumnSpec::new(name, ColType::Float64, unit, doc);
    let mut t = Table::new("features")
        .embed(identity_table(), |r: &mut FeatureRow| &mut r.id)
        .col(ColumnSpec::new("source_file", ColType::Utf8, "", "file the samples were read from"), |r| s(&r.source_file))
        .col(f64c("peak_amplitude_v", "V", "largest absolute sample after removing the DC offset (the mean of the pretrigger; nothing is removed from a record without one)"), |r| Value::F64(Some(r.an.hit.amplitude_v)))
        .col(f64c(cols::PEAK_AMPLITUDE_DB.name, "dB_AE", "peak amplitude in dB re 1 µV, 20·log10(peak_amplitude_v / 1 µV)"), |r| {
            let a = r.an.hit.amplitude_v;
            Value::F64(Some(if a > 0.0 { db_ae(a) } else { f64::NEG_INFINITY }))
        })
        .col(f64c("threshold_used_v", "V", "detection threshold used for the hit features: the record's own (Vallen Thr) or dsp.hit.threshold_db"), |r| Value::F64(Some(r.an.hit.threshold_v)))
        .col(f64c("first_crossing_s", "s", "first sample with absolute value ≥ threshold, from the trigger (negative: before it); null if never reached").nullable(), |r| Value::F64(r.first_crossing_s))
        .col(f64c("rise_time_s", "s", "first threshold crossing to peak amplitude (vallenae); 0 if the threshold is never reached"), |r| Value::F64(Some(r.an.hit.rise_time_s)))
        .col(f64c("duration_s", "s", "first to last sample with absolute value ≥ threshold (ASTM E1316); 0 if never reached"), |r| Value::F64(Some(r.an.hit.duration_s)))
        .col(ColumnSpec::new("counts", ColType::Int64, "", "positive-going crossings of +threshold (vallenae)"), |r| Value::I64(Some(r.an.hit.counts)))
        .col(f64c("ra_ms_per_v", "ms/V", "RA value: rise_time_s over peak_amplitude_v (JCMS-IIIB5706); null for a record without amplitude").nullable(), move |r| Value::F64(ra(r)))
        .col(f64c("af_khz", "kHz", "average frequency: counts over duration_s; null when the threshold was never crossed (duration 0)").nullable(), move |r| Value::F64(af(r)))
        .col(ColumnSpec::new("crack_mode", ColType::Utf8, "", "tensile above the line af_khz = crack_mode.af_per_ra × ra_ms_per_v (default 1 kHz per ms/V, Ohno & Ohtsu 2010), shear on or below it; null where RA or AF is").nullable(), move |r| Value::Str(crack_mode(ra(r), af(r), crack.af_per_ra).map(|m| m.as_str().to_string())))
        .col(f64c(cols::ENERGY_EU.name, "eu", "Σx²/fs over the record, 1 eu = 1e-14 V²s (vallenae)"), |r| Value::F64(Some(r.an.hit.energy_eu)))
        .col(f64c("signal_strength_nvs", "nVs", "Σ|x|/fs over the record (vallenae)"), |r| Value::F64(Some(r.an.hit.signal_strength_nvs)))
        .col(f64c("rms_v", "V", "root mean square of the record"), |r| Value::F64(Some(r.an.hit.rms_v)))
        .col(f64c("peak_freq_hz", "Hz", "frequency of the largest power-spectrum bin (DC excluded); null for a flat record").nullable(), |r| Value::F64(r.an.peak_freq_hz))
        .col(f64c("centroid_freq_hz", "Hz", "power-weighted mean frequency of the spectrum up to fs/2; null for a flat record").nullable(), |r| Value::F64(r.an.centroid_freq_hz));
    let nb = dsp.n_ratio_bands();
    for i in 0..nb {
        let lo = i as f64 * dsp.band_hz / 1e3;
        t = t.col(
            f64c(
                &band_column(i, dsp.band_hz),
                "1",
                &format!("power ratio W_{} (Eq. 4.5.4): power in [{lo}, {}) kHz / power in [0, {}) kHz; the {nb} sum to 1; null for a flat record", i + 1, lo + dsp.band_hz / 1e3, dsp.band_max_hz / 1e3),
            )
            .nullable(),
            move |r: &FeatureRow| Value::F64(r.an.ratios.get(i).copied()),
        );
    }
    let g = BinGrid::of(dsp);
    let opt = |v: Option<Component>, f: fn(Component) -> f64| Value::F64(v.map(f));
    t.col_take(
        ColumnSpec::new(
            "tf_bins",
            ColType::FixedListF32(g.len() as i32),
            "1",
            &format!(
                "time/frequency bins (ch. 5.2): CWT |W|² summed over {} bands of {} kHz × {} windows of {} µs from the trigger, divided by their total (sum 1); index = band·{} + window; null when the window holds no power",
                g.n_bands,
                g.band_hz / 1e3,
                g.n_windows,
                g.window_s * 1e6,
                g.n_windows
            ),
        )
        .nullable(),
        |r| Value::F32s(r.an.bins.take()),
    )
    .col(ColumnSpec::of(cols::CRITERIA_LABEL, "", &format!("ch. 4.7 label: {}", mechanism_list())), |r| s(r.an.label.as_str()))
    .col(ColumnSpec::new("criteria_reason", ColType::Utf8, "", "the numbers behind the label, in words"), |r| s(&r.an.reason))
    .col(ColumnSpec::new("quality_fault", ColType::Utf8, "", &format!("the time-domain quality check's finding (ch. 5.4's erroneous data; a column beside the 200 bins, which do not carry it): {}; null when the record looks sound. The SOM stage reads the map's erroneous area by it (som.read_erroneous)", fault_list())).nullable(), |r| Value::Str(r.an.fault.map(|f| f.as_str().to_string())))
    .col(f64c("dominant_freq_hz", "Hz", "CWT frequency with the largest |W|² in the bins' window; null when the window holds no power").nullable(), move |r| opt(r.an.components.dominant, |d| d.freq_hz))
    .col(f64c("dominant_duration_s", "s", "time around its peak that the dominant component stays ≥ half its peak power").nullable(), move |r| opt(r.an.components.dominant, |d| d.duration_s))
    .col(f64c("dominant_arrival_s", "s", "first time the dominant component reaches half its peak power, from the trigger").nullable(), move |r| opt(r.an.components.dominant, |d| d.arrival_s))
    .col(f64c("cwt_onset_s", "s", "first time any CWT frequency reaches criteria.component_min_ratio of the window's largest |W|², from the trigger (where a CWT picture shows the AE start); null when the window holds no power").nullable(), |r| {
        let k = &r.an.components;
        Value::F64(k.dominant.map(|_| k.onset_s))
    })
    .col(f64c("bond_low_duration_s", "s", "half-power duration of the strongest component near criteria.bond_low_hz (≈250 kHz); null if absent").nullable(), move |r| opt(r.an.components.low, |d| d.duration_s))
    .col(f64c("bond_high_duration_s", "s", "half-power duration of the strongest component near criteria.bond_high_hz (≈750 kHz); null if absent").nullable(), move |r| opt(r.an.components.high, |d| d.duration_s))
    .col(onset_col("onset_hinkley", "Hinkley criterion (α = onset.alpha)"), |r| idx(r.an.onsets.hinkley))
    .col(onset_col("onset_aic", "Akaike information criterion"), |r| idx(r.an.onsets.aic))
    .col(onset_col("onset_er", "energy ratio (windows of onset.win samples)"), |r| idx(r.an.onsets.er))
    .col(onset_col("onset_mer", "modified energy ratio, (ER·|x|)⁴ as vallenae 0.14 computes it"), |r| idx(r.an.onsets.mer))
    .col(f64c(cols::ARRIVAL_S.name, "s", "arrival time on the acquisition's clock by onset.picker: the record's first sample (time_s − pretrigger/rate) + the pick's index / rate; null without a picker (then events use the hit time)").nullable(), |r| Value::F64(r.arrival_s))
    .pipe(crate::store::table::with_event_columns)
}

/// An onset column: the pick's 0-based sample index in the record.
fn onset_col(name: &str, what: &str) -> ColumnSpec {
    ColumnSpec::new(
        name,
        ColType::Int32,
        "samples",
        &format!("arrival by the {what} (vallenae 0.14's definition): 0-based sample index in the record, over the whole record or [onset] window; null where the record is too short for it"),
    )
    .nullable()
}

fn idx(i: Option<usize>) -> Value {
    Value::I32(i.map(|i| i as i32))
}

/// The class names the criteria give, in words for the column's documentation.
fn mechanism_list() -> String {
    words(crate::model::Mechanism::ALL.iter().map(|m| m.as_str()))
}

fn fault_list() -> String {
    words(criteria::FaultKind::ALL.iter().map(|f| f.as_str()))
}

/// "a, b or c".
fn words<'a>(items: impl ExactSizeIterator<Item = &'a str>) -> String {
    let n = items.len();
    items
        .enumerate()
        .map(|(i, m)| match i {
            0 => m.to_string(),
            i if i + 1 == n => format!(" or {m}"),
            _ => format!(", {m}"),
        })
        .collect()
}

/// Extra Parquet metadata of `features.parquet`: the bin layout and the CWT.
pub fn features_metadata(dsp: &DspConfig) -> Vec<(String, String)> {
    vec![
        ("aepipe.tf_bins".into(), BinGrid::of(dsp).describe()),
        (
            "aepipe.cwt".into(),
            serde_json::json!({
                "wavelet": "complex Gabor (Morlet), analytic, amplitude-preserving",
                "fwhm_periods": dsp.cwt.fwhm_periods,
                "f_min_hz": dsp.cwt.f_min_hz,
                "f_max_hz": dsp.cwt.f_max_hz,
                "n_freqs": dsp.cwt.n_freqs,
            })
            .to_string(),
        ),
    ]
}

/// The strongest frequency in `lo..=hi` Hz whose peak power is a local maximum along
/// frequency: a real component, not the flank of a stronger neighbour.
fn strongest_peak(freqs: &[f64], peaks: &[f32], lo: f64, hi: f64) -> Option<usize> {
    (0..peaks.len())
        .filter(|&i| freqs[i] >= lo && freqs[i] <= hi && peaks[i] > 0.0)
        .filter(|&i| {
            (i == 0 || peaks[i] >= peaks[i - 1])
                && (i + 1 == peaks.len() || peaks[i] >= peaks[i + 1])
        })
        .max_by(|&a, &b| peaks[a].total_cmp(&peaks[b]))
}

/// The sum of `row[edges[w]..edges[w + 1]]` for each window `w` into `sums[w]`, each in
/// ascending sample order (the f32 result of the plain loop, bit for bit), but the windows'
/// sums advance together: one add chain per window instead of one long chain, which is what
/// bounded this loop's speed (f32 add latency).
// The index loop is the point: sample j of every lane in turn, eight chains in flight.
#[allow(clippy::needless_range_loop)]
fn window_sums(row: &[f32], edges: &[usize], sums: &mut [f32; 64]) {
    const LANES: usize = 8;
    let nw = edges.len() - 1;
    for w0 in (0..nw).step_by(LANES) {
        let k_n = (nw - w0).min(LANES);
        let len = |k: usize| edges[w0 + k + 1] - edges[w0 + k];
        let common = (0..k_n).map(len).min().unwrap_or(0);
        // Lanes past the last window read the first `common` samples into a sum nobody keeps.
        let lane: [&[f32]; LANES] = std::array::from_fn(|k| {
            let start = if k < k_n { edges[w0 + k] } else { 0 };
            &row[start..start + common]
        });
        let mut acc = [0.0f32; LANES];
        for j in 0..common {
            for k in 0..LANES {
                acc[k] += lane[k][j];
            }
        }
        for k in 0..k_n {
            for &v in &row[edges[w0 + k] + common..edges[w0 + k + 1]] {
                acc[k] += v;
            }
            sums[w0 + k] = acc[k];
        }
    }
}

/// Per-worker state for computing feature rows.
pub struct FeatureExtractor {
    cfg: FeatureSettings,
    picks: PickScratch,
    /// The table the rows are made for (its columns depend on the configuration).
    table: Table<FeatureRow>,
    grid: BinGrid,
    cwt: Cwt,
    cond: Vec<f32>,
    ratios: Vec<f64>,
    bins: Vec<f64>,
    /// The CWT frequency grid (a copy of the bank's, to borrow beside the engine).
    freqs: Vec<f64>,
    /// Peak |W|² of each CWT frequency over the window.
    peaks: Vec<f32>,
    /// Largest |W|² over the frequencies at each sample of the window.
    env: Vec<f32>,
    row: Vec<f32>,
}

/// What the DSP found in one record (everything the row needs).
pub struct Analysis {
    pub hit: HitFeatures,
    pub peak_freq_hz: Option<f64>,
    pub centroid_freq_hz: Option<f64>,
    /// Power ratios (empty: flat record).
    pub ratios: Vec<f64>,
    /// Normalised time/frequency bins (None: no power in the window).
    pub bins: Option<Vec<f32>>,
    pub components: Components,
    pub label: crate::model::Mechanism,
    pub reason: String,
    /// The time-domain quality check's finding (then `label` is erroneous).
    pub fault: Option<criteria::FaultKind>,
    /// The four pickers' arrivals, 0-based sample index in the record.
    pub onsets: Onsets,
}

/// Where each picker puts the arrival (0-based sample index in the record; `None` where the
/// record, or its window, is too short for the picker).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Onsets {
    pub hinkley: Option<usize>,
    pub aic: Option<usize>,
    pub er: Option<usize>,
    pub mer: Option<usize>,
}

impl Onsets {
    /// Run the four pickers of `[onset]` on the record's own samples (as recorded, volts:
    /// the input vallenae's pickers see), over the whole record or the configured window.
    pub fn pick(
        r: &AeRecord,
        cfg: &crate::dsp::settings::OnsetConfig,
        s: &mut PickScratch,
    ) -> Onsets {
        let n = r.samples.len();
        let (a, b) = match (cfg.window_before_s, cfg.window_after_s) {
            (Some(before), Some(after)) => {
                let t = r.pretrigger as f64;
                let fs = r.sample_rate_hz;
                let a = (t - before * fs).round().max(0.0) as usize;
                let b = ((t + after * fs).round().max(0.0) as usize).min(n);
                (a.min(b), b)
            }
            _ => (0, n),
        };
        let x = &r.samples[a..b];
        let at = |p: Option<usize>| p.map(|i| i + a);
        let [hinkley, aic, er, mer] = pick::pick_all(x, cfg.alpha, cfg.win, s);
        Onsets {
            hinkley: at(hinkley),
            aic: at(aic),
            er: at(er),
            mer: at(mer),
        }
    }
}

impl FeatureExtractor {
    /// A worker for the settings (those of a checked pipeline: `&ValidConfig` converts).
    pub fn new(settings: impl Into<FeatureSettings>) -> FeatureExtractor {
        let cfg: FeatureSettings = settings.into();
        let bank = WaveletBank::from_config(&cfg.dsp.cwt);
        FeatureExtractor {
            freqs: bank.freqs_hz.clone(),
            table: features_table(&cfg.dsp, cfg.crack_mode),
            picks: PickScratch::default(),
            grid: BinGrid::of(&cfg.dsp),
            cwt: Cwt::new(bank),
            cond: Vec::new(),
            ratios: vec![0.0; cfg.dsp.n_ratio_bands()],
            bins: Vec::new(),
            peaks: Vec::new(),
            env: Vec::new(),
            row: Vec::new(),
            cfg,
        }
    }

    pub fn config(&self) -> &FeatureSettings {
        &self.cfg
    }

    /// The full-resolution CWT power of a record (n_freqs × n_samples, row-major) after
    /// conditioning, with the frequency grid: for pictures.
    pub fn full_cwt(&mut self, r: &AeRecord) -> (Vec<f64>, Array2<f32>) {
        condition(&r.samples, r.pretrigger as usize, &mut self.cond);
        self.cwt.load(&self.cond, r.sample_rate_hz);
        let shape = (self.cwt.bank().freqs_hz.len(), self.cond.len());
        let mut out = Array2::zeros(shape);
        let slice = out.as_slice_mut().expect("a new array is contiguous");
        self.cwt.full_power(&self.cond, r.sample_rate_hz, slice);
        (self.cwt.bank().freqs_hz.clone(), out)
    }

    /// Run the DSP of a validated record.
    pub fn analyse(&mut self, r: &AeRecord) -> Analysis {
        let fs = r.sample_rate_hz;
        let n = r.samples.len();
        let pre = r.pretrigger as usize;
        condition(&r.samples, pre, &mut self.cond);
        let thr = match r.threshold_v {
            Some(t) if self.cfg.dsp.hit.use_record_threshold && t > 0.0 => t,
            _ => crate::model::db_to_v(self.cfg.dsp.hit.threshold_db),
        };
        let hit = hit_features(&self.cond, fs, thr);

        // Spectrum: one FFT of the whole record (zero-padded to a fast length, so the band
        // powers of Eq. 4.5.4 stay those of the whole hit), shared with the whole-record CWT.
        self.cwt.load(&self.cond, fs);
        let spec = power_ratios(
            self.cwt.spectrum(),
            self.cwt.padded_len(),
            fs,
            self.cfg.dsp.band_hz,
            &mut self.ratios,
        );

        // CWT over the bins' window.
        let g = self.grid;
        let a = pre.min(n);
        let edge = |w: usize| (a + (w as f64 * g.window_s * fs).round() as usize).min(n);
        let b = edge(g.n_windows);
        self.bins.clear();
        self.bins.resize(g.len(), 0.0);
        let freqs = &self.freqs;
        self.peaks.clear();
        self.peaks.resize(freqs.len(), 0.0);
        let band_max = g.band_hz * g.n_bands as f64;
        self.env.clear();
        self.env.resize(b - a, 0.0);
        let bins = &mut self.bins;
        let peaks = &mut self.peaks;
        let env = &mut self.env;
        // Window edges relative to the trigger, computed once per record.
        let mut edges = [0usize; 65];
        let n_edges = (g.n_windows + 1).min(edges.len());
        for (w, e) in edges.iter_mut().enumerate().take(n_edges) {
            *e = edge(w) - a;
        }
        let edges = &edges[..n_edges];
        self.cwt.window_power(&self.cond, fs, a, b, |fi, row| {
            let f = freqs[fi];
            if f <= band_max {
                let band = ((f / g.band_hz) as usize).min(g.n_bands - 1);
                let mut sums = [0.0f32; 64];
                window_sums(row, edges, &mut sums);
                for (w, &sum) in sums[..n_edges - 1].iter().enumerate() {
                    bins[band * g.n_windows + w] += sum as f64;
                }
            }
            peaks[fi] = crate::dsp::max_from_zero(row, |v| v);
            for (e, &v) in env.iter_mut().zip(row) {
                *e = e.max(v);
            }
        });
        let total: f64 = self.bins.iter().sum();
        let bins = (total > 0.0 && total.is_finite())
            .then(|| self.bins.iter().map(|&v| (v / total) as f32).collect());
        let crit = self.cfg.criteria.clone();
        let tol = crit.bond_tolerance_hz;
        let mut component = |lo: f64, hi: f64| {
            let fi = strongest_peak(freqs, &self.peaks, lo, hi)?;
            self.cwt.window_row(&self.cond, fs, a, b, fi, &mut self.row);
            Component::from_row(freqs[fi], &self.row, fs)
        };
        let top = self.env.iter().fold(0.0f32, |m, &v| m.max(v));
        let visible = (crit.component_min_ratio * top as f64) as f32;
        let onset = self
            .env
            .iter()
            .position(|&v| top > 0.0 && v >= visible)
            .unwrap_or(0);
        let components = Components {
            onset_s: onset as f64 / fs,
            dominant: component(f64::NEG_INFINITY, f64::INFINITY),
            low: component(crit.bond_low_hz - tol, crit.bond_low_hz + tol),
            high: component(crit.bond_high_hz - tol, crit.bond_high_hz + tol),
            fibre: component(crit.fibre_min_hz + 1e-9, f64::INFINITY),
        };
        let fault = acquisition_fault(&r.samples, &self.cond, fs, pre, &hit, &crit);
        let (label, reason) = match &fault {
            Some(f) => (crate::model::Mechanism::Erroneous, f.reason.clone()),
            None => {
                let d = decide(&components, &crit);
                (d.label, d.reason)
            }
        };
        let onsets = Onsets::pick(r, &self.cfg.onset, &mut self.picks);
        Analysis {
            onsets,
            hit,
            peak_freq_hz: spec.map(|s| s.peak_freq_hz),
            centroid_freq_hz: spec.map(|s| s.centroid_freq_hz),
            ratios: if spec.is_some() {
                self.ratios.clone()
            } else {
                Vec::new()
            },
            bins,
            components,
            label,
            reason,
            fault: fault.map(|f| f.kind),
        }
    }

    /// The feature row of a validated record, in [`features_table`] order.
    pub fn row(&mut self, r: &AeRecord) -> Row {
        let an = self.analyse(r);
        let fs = r.sample_rate_hz;
        let first_crossing_s = an
            .hit
            .first_crossing
            .map(|i| (i as f64 - r.pretrigger as f64) / fs);
        let o = an.onsets;
        let index = match self.cfg.onset.picker {
            Picker::None => None,
            Picker::Threshold => an.hit.first_crossing,
            Picker::Aic => o.aic,
            Picker::Hinkley => o.hinkley,
            Picker::Er => o.er,
            Picker::Mer => o.mer,
        };
        // The record's first sample is `pretrigger` samples before its trigger time.
        let arrival_s = match (r.time_s, index) {
            (Some(t), Some(i)) => Some(t + (i as f64 - r.pretrigger as f64) / fs),
            _ => None,
        };
        self.table.row(FeatureRow {
            id: Identity::of(r),
            source_file: r.source_file.clone(),
            first_crossing_s,
            arrival_s,
            an,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{PipelineConfig, ValidConfig};
    use crate::model::Mechanism;
    use crate::synth::{waveform, HitSpec, Rng};

    fn rec(samples: Vec<f32>, pre: u32) -> AeRecord {
        AeRecord {
            kind: crate::model::RecordKind::Hit,
            experiment: "e".into(),
            channel: 1,
            hit: 1,
            time_s: Some(0.0),
            sample_rate_hz: 10e6,
            pretrigger: pre,
            samples,
            load_n: None,
            extension_m: None,
            label: None,
            threshold_v: None,
            source_file: "f".into(),
        }
    }

    fn get(row: &Row, t: &crate::store::TableSchema, name: &str) -> Value {
        row[t.index_of(name).unwrap_or_else(|| panic!("{name}"))].clone()
    }

    #[test]
    fn row_matches_the_table_and_sums_to_one() {
        let cfg = ValidConfig::default();
        let t = features_table(&cfg.dsp, cfg.crack_mode).schema();
        let spec = HitSpec::new(Mechanism::BondFailure);
        let r = rec(waveform(&spec, &mut Rng::new(1)), spec.pretrigger as u32);
        let row = FeatureExtractor::new(&cfg).row(&r);
        assert_eq!(row.cells().len(), t.columns.len());
        let ratios: f64 = (0..25)
            .map(|i| match get(&row, &t, &band_column(i, 100e3)) {
                Value::F64(Some(v)) => v,
                _ => panic!(),
            })
            .sum();
        assert!((ratios - 1.0).abs() < 1e-6, "{ratios}");
        let Value::F32s(Some(bins)) = get(&row, &t, "tf_bins") else {
            panic!()
        };
        assert_eq!(bins.len(), 200);
        assert!((bins.iter().map(|&v| v as f64).sum::<f64>() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn peak_is_measured_from_the_pretrigger_baseline() {
        let cfg = ValidConfig::default();
        let mut s = vec![0.5f32; 100];
        s[60] = 0.5 + 0.01;
        s[70] = 0.5 - 0.02;
        let row = FeatureExtractor::new(&cfg).row(&rec(s, 50));
        let t = features_table(&cfg.dsp, cfg.crack_mode).schema();
        let Value::F64(Some(p)) = get(&row, &t, "peak_amplitude_v") else {
            panic!()
        };
        assert!((p - 0.02).abs() < 1e-6, "{p}");
        let Value::F64(Some(db)) = get(&row, &t, "peak_amplitude_db") else {
            panic!()
        };
        assert!((db - 86.0206).abs() < 1e-3, "{db}");
    }

    fn label_of(m: Mechanism, seed: u64) -> (Mechanism, String) {
        let cfg = ValidConfig::default();
        let spec = HitSpec::new(m);
        let r = rec(waveform(&spec, &mut Rng::new(seed)), spec.pretrigger as u32);
        let a = FeatureExtractor::new(&cfg).analyse(&r);
        (a.label, a.reason)
    }

    #[test]
    fn synthetic_mechanisms_get_their_labels() {
        for seed in 1..=40 {
            for m in [
                Mechanism::BondFailure,
                Mechanism::FibreFailure,
                Mechanism::Both,
                Mechanism::Erroneous,
            ] {
                let (got, why) = label_of(m, seed);
                assert_eq!(got, m, "seed {seed}: {m} labelled {got}: {why}");
            }
        }
    }

    #[test]
    fn early_trigger_and_clipping_are_erroneous() {
        let cfg = ValidConfig::default();
        let mut spec = HitSpec::new(Mechanism::BondFailure);
        spec.pretrigger = 50; // the wave starts 450 samples (45 µs) before the trigger
        let mut w = waveform(&spec, &mut Rng::new(3));
        let r = rec(w.clone(), 500);
        let a = FeatureExtractor::new(&cfg).analyse(&r);
        assert_eq!(a.label, Mechanism::Erroneous);
        assert!(a.reason.starts_with("triggered early"), "{}", a.reason);
        assert_eq!(a.fault, Some(criteria::FaultKind::TriggeredEarly));
        // Clip the normal record at 40 % of its peak.
        spec.pretrigger = 500;
        w = waveform(&spec, &mut Rng::new(3));
        let lim = 0.4 * w.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let clipped: Vec<f32> = w.iter().map(|v| v.clamp(-lim, lim)).collect();
        let a = FeatureExtractor::new(&cfg).analyse(&rec(clipped, 500));
        assert_eq!(a.label, Mechanism::Erroneous);
        assert!(a.reason.starts_with("clipped"), "{}", a.reason);
        assert_eq!(a.fault, Some(criteria::FaultKind::Clipped));
        // Pure noise below the threshold is empty.
        let mut rng = Rng::new(4);
        let noise: Vec<f32> = (0..4096).map(|_| (1e-5 * rng.normal()) as f32).collect();
        let a = FeatureExtractor::new(&cfg).analyse(&rec(noise, 500));
        assert!(a.reason.starts_with("empty"), "{}", a.reason);
        assert_eq!(a.fault, Some(criteria::FaultKind::Empty));
    }

    /// Sum a full-resolution CWT into the bins the way the thesis describes (independently of
    /// the windowed path).
    fn bins_from_full(cfg: &ValidConfig, r: &AeRecord) -> Vec<f64> {
        let g = BinGrid::of(&cfg.dsp);
        let (freqs, p) = FeatureExtractor::new(cfg).full_cwt(r);
        let n = r.samples.len();
        let fs = r.sample_rate_hz;
        let t0 = r.pretrigger as f64 / fs;
        let mut bins = vec![0.0f64; g.len()];
        for (fi, &f) in freqs.iter().enumerate() {
            if f > g.band_hz * g.n_bands as f64 {
                continue;
            }
            let band = ((f / g.band_hz) as usize).min(g.n_bands - 1);
            for i in 0..n {
                let t = i as f64 / fs - t0;
                let w = (t / g.window_s + 1e-9).floor();
                if w >= 0.0 && (w as usize) < g.n_windows {
                    bins[band * g.n_windows + w as usize] += p[[fi, i]] as f64;
                }
            }
        }
        let total: f64 = bins.iter().sum();
        bins.iter().map(|b| b / total).collect()
    }

    #[test]
    fn feature_path_equals_full_resolution_summed_into_bins() {
        for (fs, len) in [(10e6, 4096usize), (5e6, 2048)] {
            let mut cfg = PipelineConfig::default();
            cfg.dsp.hit.threshold_db = 30.0;
            let cfg = cfg.check().unwrap();
            for (k, m) in [
                Mechanism::BondFailure,
                Mechanism::FibreFailure,
                Mechanism::Both,
                Mechanism::Erroneous,
            ]
            .into_iter()
            .enumerate()
            {
                let mut spec = HitSpec::new(m);
                spec.sample_rate_hz = fs;
                spec.n_samples = len;
                let mut r = rec(
                    waveform(&spec, &mut Rng::new(k as u64 + 10)),
                    spec.pretrigger as u32,
                );
                r.sample_rate_hz = fs;
                let fast = FeatureExtractor::new(&cfg).analyse(&r).bins.unwrap();
                let slow = bins_from_full(&cfg, &r);
                let big = slow.iter().cloned().fold(0.0, f64::max);
                for (i, (a, b)) in fast.iter().zip(&slow).enumerate() {
                    let (a, b) = (*a as f64, *b);
                    // Relative to the bin where the bin matters; absolute (to the largest bin)
                    // for bins that hold almost nothing.
                    let err = (a - b).abs() / b.max(1e-3 * big);
                    assert!(
                        err < 1e-3,
                        "{m} at {fs} Hz, bin {i}: windowed {a} vs full {b}"
                    );
                }
            }
        }
    }
}
