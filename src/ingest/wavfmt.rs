//! WAV files, one hit per file; each channel of the file is one record (channel 1, 2, …).
//! Integer samples are scaled to ±1 V full scale, float samples are taken as volts; then
//! `[ingest] gain_db` is divided out. The rate comes from the header.

use super::{gain_factor, Source};
use crate::ingest::settings::ReadSettings;
use crate::model::{AeRecord, Item, Reject, Stage};
use std::path::Path;

fn read_wav(path: &Path, max_samples: u64) -> Result<(f64, Vec<Vec<f32>>), String> {
    let mut r =
        hound::WavReader::open(path).map_err(|e| format!("not a readable WAV file: {e}"))?;
    let spec = r.spec();
    let ch = spec.channels.max(1) as usize;
    // The header's length is a claim: check it against the file and the limit first.
    let file_len = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    let bytes = (spec.bits_per_sample as u64).div_ceil(8).max(1) * ch as u64;
    let promised = r.duration() as u64;
    if promised > file_len / bytes {
        return Err(format!(
            "header promises {promised} samples per channel; the file of {file_len} bytes holds at most {}",
            file_len / bytes
        ));
    }
    if promised > max_samples {
        return Err(format!(
            "{promised} samples per channel exceed ingest.max_samples_per_record = {max_samples}"
        ));
    }
    let mut chans = vec![Vec::with_capacity(promised as usize); ch];
    match spec.sample_format {
        hound::SampleFormat::Float => {
            for (i, s) in r.samples::<f32>().enumerate() {
                chans[i % ch].push(s.map_err(|e| format!("sample {i}: {e}"))?);
            }
        }
        hound::SampleFormat::Int => {
            let full = 2f64.powi(spec.bits_per_sample as i32 - 1);
            for (i, s) in r.samples::<i32>().enumerate() {
                chans[i % ch]
                    .push((s.map_err(|e| format!("sample {i}: {e}"))? as f64 / full) as f32);
            }
        }
    }
    Ok((spec.sample_rate as f64, chans))
}

/// WAV files, one hit per file, numbered by their place in the folder.
pub(crate) const FORMAT: crate::ingest::FormatSpec = crate::ingest::FormatSpec {
    name: "wav",
    one_hit_per_file: true,
    numbered_by_place: true,
    follow: crate::ingest::Follow::PerFile,
    open,
};

pub fn open(src: &Source, cfg: &ReadSettings) -> Box<dyn Iterator<Item = Item> + Send> {
    let experiment = src.id.clone();
    let gain = gain_factor(cfg.gain_db) as f32;
    let pre = cfg.pretrigger_samples;
    let max_samples = cfg.max_samples_per_record;
    let files = src.files.clone();
    let counter = super::stream::HitCounter::new(src.first_hit.into());
    let cfg = cfg.clone();
    Box::new(files.into_iter().flat_map(move |p| {
        // A WAV that `[detect]` cuts is a stream, read block by block.
        if let Ok(l) = super::stream::wav_layout(&p) {
            if cfg.detect().cuts(l.frames) {
                let c = counter.clone();
                return super::stream::open_layout(Ok(l), &p, experiment.clone(), c, &cfg);
            }
        }
        let hit = counter.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        let items: Vec<Item> = match read_wav(&p, max_samples) {
            Ok((rate, chans)) => chans
                .into_iter()
                .enumerate()
                .map(|(c, mut s)| {
                    s.iter_mut().for_each(|x| *x *= gain);
                    Item::Record(AeRecord {
                        kind: crate::model::RecordKind::Hit,
                        experiment: experiment.clone(),
                        channel: c as u32 + 1,
                        hit,
                        time_s: None,
                        sample_rate_hz: rate,
                        pretrigger: pre,
                        samples: s,
                        load_n: None,
                        extension_m: None,
                        label: None,
                        threshold_v: None,
                        source_file: p.display().to_string(),
                    })
                })
                .collect(),
            Err(reason) => vec![Item::Reject(Reject {
                record_type: crate::model::RecordType::Transient,
                experiment: experiment.clone(),
                source_file: p.display().to_string(),
                record_id: format!("hit {hit}"),
                stage: Stage::Read,
                reason,
            })],
        };
        Box::new(items.into_iter())
    }))
}

/// Write one hit as a 32-bit float WAV (volts), e.g. for fixtures and exports.
pub fn write_wav_f32(
    path: &Path,
    sample_rate_hz: u32,
    samples: &[f32],
) -> Result<(), hound::Error> {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: sample_rate_hz,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(path, spec)?;
    for &s in samples {
        w.write_sample(s)?;
    }
    w.finalize()
}
