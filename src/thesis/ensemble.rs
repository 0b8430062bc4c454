//! Fig. 4.12 (§4.5.4): the CWT of the ensemble-average AE. The thesis averages the measured
//! AEs of a notched paper test — bond failures, mostly — and reads "two dominant frequency
//! components at around 250 kHz and 750 kHz". No paper test is at hand, so the entry averages
//! what aepipe says a bond failure is: the 3×3 mesh's bond failure (1) heard at sensor 1,
//! over the material draws of Fig. 4.7 (Young's modulus ×0.9 … ×1.1), sample by sample from
//! the failure on; then the CWT of the average, its power summed over time per frequency, and
//! the strongest peak of that marginal above 500 kHz (the upper component) compared.

use super::ThesisError;
use crate::dsp::cwt::{Cwt, WaveletBank};
use crate::dsp::settings::CwtConfig;
use crate::sim::scenario::{build, Params};
use crate::sim::{simulate, SimError, SimOptions};
use std::path::Path;

/// The draws of Young's modulus averaged (Table 4.1's ±10 %).
const E_SCALES: [f64; 5] = [0.9, 0.95, 1.0, 1.05, 1.1];

/// The ensemble average at sensor 1 (band-limited pressure, Pa) and its sampling rate.
pub fn ensemble() -> Result<(Vec<f64>, f64), SimError> {
    let mut sum: Vec<f64> = Vec::new();
    let mut fs = 0.0;
    for e in E_SCALES {
        let m = build(
            "mesh3x3-bond-failure",
            &Params(vec![("t2".into(), -1.0), ("e_scale".into(), e)]),
        )?;
        let out = simulate(&m, &SimOptions::default())?;
        let g = m.grid.as_ref().expect("the mesh has a grid");
        let p = crate::sim::output::band_limited(&out.sensors[0], g);
        sum.resize(p.len().max(sum.len()), 0.0);
        for (s, v) in sum.iter_mut().zip(&p) {
            *s += v;
        }
        fs = out.sample_rate_hz;
    }
    let n = E_SCALES.len() as f64;
    Ok((sum.into_iter().map(|v| v / n).collect(), fs))
}

/// The local maxima of a marginal (index, value), strongest first.
fn peaks(m: &[f64]) -> Vec<(usize, f64)> {
    let mut p: Vec<(usize, f64)> = (1..m.len().saturating_sub(1))
        .filter(|&k| m[k] > m[k - 1] && m[k] >= m[k + 1])
        .map(|k| (k, m[k]))
        .collect();
    p.sort_by(|a, b| b.1.total_cmp(&a.1));
    p
}

/// The entry: writes `marginal.parquet` (frequency, the average's CWT power summed over time,
/// for both components) and `cwt.png`; returns the upper component's frequency, kHz.
pub fn fig_4_12(dir: &Path) -> Result<f64, ThesisError> {
    let (avg, fs) = ensemble()?;
    let cfg = CwtConfig::default();
    let bank = WaveletBank::from_config(&cfg);
    let freqs = bank.freqs_hz.clone();
    let mut cwt = Cwt::new(bank);
    let x: Vec<f32> = avg.iter().map(|v| *v as f32).collect();
    let mut power = vec![0f32; freqs.len() * x.len()];
    cwt.load(&x, fs);
    cwt.full_power(&x, fs, &mut power);
    let marginal: Vec<f64> = power
        .chunks(x.len())
        .map(|row| row.iter().map(|v| *v as f64).sum())
        .collect();
    super::write_floats(
        &dir.join("marginal.parquet"),
        "thesis_fig_4_12",
        [
            ("frequency_hz", "Hz", "CWT frequency"),
            ("power", "Pa²", "the average AE's |W|² summed over time"),
        ],
        freqs.iter().zip(&marginal).map(|(f, p)| [*f, *p]),
    )?;
    // Drawn as a sensor records it: the pressure × the default sensitivity, volts.
    let scale = crate::sim::output::Acquisition::default().scale_v_per_pa as f32;
    let rec = crate::model::AeRecord {
        experiment: "ensemble of bond failures".into(),
        channel: 1,
        hit: 1,
        time_s: Some(0.0),
        sample_rate_hz: fs,
        pretrigger: 0,
        samples: x.iter().map(|v| v * scale).collect(),
        load_n: None,
        extension_m: None,
        label: Some(crate::model::Mechanism::BondFailure.as_str().into()),
        threshold_v: None,
        source_file: "aepipe thesis fig-4.12".into(),
        kind: crate::model::RecordKind::Hit,
    };
    let view = ndarray::ArrayView2::from_shape((freqs.len(), x.len()), &power)
        .map_err(|e| SimError::Io(e.to_string()))?;
    crate::plot::cwt_png(
        &dir.join("cwt.png"),
        &rec,
        &freqs,
        view,
        "Fig. 4.12: CWT of the average of 5 simulated bond failures (E ×0.9…×1.1), sensor 1 at 30 µV/Pa",
    )?;
    peaks(&marginal)
        .into_iter()
        .find(|(k, _)| freqs[*k] > 500e3)
        .map(|(k, _)| freqs[k] / 1e3)
        .ok_or(ThesisError::Measure {
            id: "fig-4.12",
            message: "the average's CWT has no peak above 500 kHz".into(),
        })
}
