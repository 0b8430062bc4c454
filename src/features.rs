//! The per-record transform: a validated [`AeRecord`] becomes one feature row.
//!
//! [`FeatureExtractor`] is made once per worker and reused for every record (the place where
//! FFT plans and scratch buffers live), so the hot path allocates nothing per record beyond
//! the output row. [`features_table`] lists the columns; adding a feature is one
//! [`ColumnSpec`] there and one value in [`FeatureExtractor::row`].

use crate::config::PipelineConfig;
use crate::model::{db_ae, AeRecord};
use crate::store::{
    identity_columns, identity_values, ColType, ColumnSpec, Row, TableSchema, Value,
};

/// Why a record cannot become a feature row (stage `validate`).
pub fn validate(r: &AeRecord, cfg: &PipelineConfig) -> Result<(), String> {
    if r.samples.is_empty() {
        return Err("record has 0 samples".into());
    }
    if r.samples.len() < cfg.validate.min_samples {
        return Err(format!(
            "record has {} samples, fewer than validate.min_samples = {}",
            r.samples.len(),
            cfg.validate.min_samples
        ));
    }
    if !(r.sample_rate_hz.is_finite() && r.sample_rate_hz > 0.0) {
        return Err(format!(
            "sample rate {} Hz is not a positive number",
            r.sample_rate_hz
        ));
    }
    let bad = r.samples.iter().filter(|s| !s.is_finite()).count();
    if bad > 0 {
        let first = r.samples.iter().position(|s| !s.is_finite()).unwrap_or(0);
        return Err(format!(
            "{bad} non-finite samples (NaN or inf), first at index {first} ({})",
            r.samples[first]
        ));
    }
    if r.pretrigger as usize > r.samples.len() {
        return Err(format!(
            "pretrigger {} is longer than the record ({} samples)",
            r.pretrigger,
            r.samples.len()
        ));
    }
    Ok(())
}

/// The columns of `features.parquet` for a configuration.
pub fn features_table(_cfg: &PipelineConfig) -> TableSchema {
    let mut columns = identity_columns();
    columns.push(ColumnSpec::new(
        "source_file",
        ColType::Utf8,
        "",
        "file the samples were read from",
    ));
    columns.push(ColumnSpec::new(
        "peak_amplitude_v",
        ColType::Float64,
        "V",
        "largest absolute sample after removing the DC offset (mean of the pretrigger, or of the record without one)",
    ));
    columns.push(ColumnSpec::new(
        "peak_amplitude_db",
        ColType::Float64,
        "dB_AE",
        "peak amplitude in dB re 1 µV, 20·log10(peak_amplitude_v / 1 µV)",
    ));
    TableSchema {
        name: "features".into(),
        columns,
    }
}

/// Per-worker state for computing feature rows.
pub struct FeatureExtractor {
    cfg: PipelineConfig,
    /// Conditioned (DC-free) samples of the current record; reused.
    scratch: Vec<f64>,
}

impl FeatureExtractor {
    pub fn new(cfg: &PipelineConfig) -> FeatureExtractor {
        FeatureExtractor {
            cfg: cfg.clone(),
            scratch: Vec::new(),
        }
    }

    pub fn config(&self) -> &PipelineConfig {
        &self.cfg
    }

    /// Remove the DC offset (mean of the pretrigger; of the whole record when there is no
    /// pretrigger) into the scratch buffer.
    fn condition(&mut self, r: &AeRecord) {
        let pre = (r.pretrigger as usize).min(r.samples.len());
        let base = if pre > 0 {
            &r.samples[..pre]
        } else {
            &r.samples[..]
        };
        let dc = base.iter().map(|&s| s as f64).sum::<f64>() / base.len().max(1) as f64;
        self.scratch.clear();
        self.scratch
            .extend(r.samples.iter().map(|&s| s as f64 - dc));
    }

    /// The feature row of a validated record, in [`features_table`] order.
    pub fn row(&mut self, r: &AeRecord) -> Result<Row, String> {
        self.condition(r);
        let peak = self.scratch.iter().fold(0.0f64, |m, &s| m.max(s.abs()));
        let mut row = identity_values(r);
        row.push(Value::Str(Some(r.source_file.clone())));
        row.push(Value::F64(Some(peak)));
        row.push(Value::F64(Some(if peak > 0.0 {
            db_ae(peak)
        } else {
            f64::NEG_INFINITY
        })));
        Ok(row)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rec(samples: Vec<f32>, pre: u32) -> AeRecord {
        AeRecord {
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
            source_file: "f".into(),
        }
    }

    #[test]
    fn peak_is_measured_from_the_pretrigger_baseline() {
        let cfg = PipelineConfig::default();
        let mut s = vec![0.5f32; 100];
        s[60] = 0.5 + 0.01; // 10 mV above a 0.5 V offset
        s[70] = 0.5 - 0.02; // 20 mV below
        let row = FeatureExtractor::new(&cfg).row(&rec(s, 50)).unwrap();
        let t = features_table(&cfg);
        let Value::F64(Some(p)) = row[t.index_of("peak_amplitude_v").unwrap()] else {
            panic!()
        };
        assert!((p - 0.02).abs() < 1e-6, "{p}");
        let Value::F64(Some(db)) = row[t.index_of("peak_amplitude_db").unwrap()] else {
            panic!()
        };
        assert!((db - 86.0206).abs() < 1e-3, "{db}");
        assert_eq!(row.len(), t.columns.len());
    }

    #[test]
    fn validation_catches_bad_records() {
        let cfg = PipelineConfig::default();
        assert!(validate(&rec(vec![], 0), &cfg)
            .unwrap_err()
            .contains("0 samples"));
        assert!(validate(&rec(vec![0.0; 4], 0), &cfg)
            .unwrap_err()
            .contains("fewer than"));
        let mut s = vec![0.0f32; 64];
        s[9] = f32::NAN;
        s[20] = f32::INFINITY;
        let e = validate(&rec(s, 0), &cfg).unwrap_err();
        assert!(e.contains("2 non-finite") && e.contains("index 9"), "{e}");
        assert!(validate(&rec(vec![0.0; 64], 100), &cfg)
            .unwrap_err()
            .contains("pretrigger"));
        assert!(validate(&rec(vec![0.0; 64], 10), &cfg).is_ok());
    }
}
