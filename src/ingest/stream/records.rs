//! Cut hits as rows and records, and records other readers read whole (a Vallen TR
//! record, a long row of `waveforms.parquet`) cut in memory.

use crate::detect::{Cut, Detector, ValidDetect};
use crate::model::{
    db_ae, AeRecord, HitRow, HitSource, Item, RecordType, Reject, Stage, StreamTally, Tally,
};

/// Where cut hits come from: their experiment, file and rate.
pub struct Cutting<'a> {
    pub experiment: &'a str,
    pub file: &'a str,
    pub rate_hz: f64,
}

impl Cutting<'_> {
    /// A cut hit's row of `hits.parquet` (the detector's features) and its record.
    pub fn items(&self, channel: u32, hit: u64, c: Cut) -> (HitRow, AeRecord) {
        let rate = self.rate_hz;
        let t = |k: u64| k as f64 / rate;
        let ended = if c.at_stream_end {
            "stream_end"
        } else if c.by_max_duration {
            "max_duration"
        } else {
            "ddt"
        };
        let row = HitRow {
            experiment: self.experiment.to_string(),
            acquisition: 1,
            channel,
            hit,
            time_s: Some(t(c.first)),
            amplitude_db: (c.peak_v > 0.0).then(|| db_ae(c.peak_v)),
            threshold_db: (c.threshold_v > 0.0).then(|| db_ae(c.threshold_v)),
            rise_time_s: Some(t(c.peak - c.first)),
            duration_s: Some(t(c.last - c.first)),
            counts: Some(c.counts),
            energy_eu: Some(c.energy_eu),
            transient: Some(hit),
            vendor_features: Some(format!(
                "{{\"two_bursts\": {}, \"ended_by\": \"{ended}\", \"first_sample\": {}, \"last_sample\": {}}}",
                c.two_bursts, c.first, c.last
            )),
            source: HitSource::Detected,
            source_file: self.file.to_string(),
            ..Default::default()
        };
        let rec = AeRecord {
            kind: crate::model::RecordKind::Hit,
            experiment: self.experiment.to_string(),
            channel,
            hit,
            time_s: Some(t(c.first)),
            sample_rate_hz: rate,
            pretrigger: (c.first - c.start) as u32,
            samples: c.samples,
            load_n: None,
            extension_m: None,
            label: None,
            threshold_v: Some(c.threshold_v),
            source_file: self.file.to_string(),
        };
        (row, rec)
    }

    /// Cut channels held in memory (volts, one slice per channel, channel k + 1): the hits
    /// in order of their first crossing, numbered 1…, as a stream file's would be.
    pub fn cut_channels(
        &self,
        channels: &[&[f32]],
        detect: &ValidDetect,
    ) -> Vec<(HitRow, AeRecord)> {
        let p = detect.at_rate(self.rate_hz);
        let mut cuts: Vec<(u32, Cut)> = Vec::new();
        for (k, x) in channels.iter().enumerate() {
            let mut d = Detector::<f32>::new(p, 1.0, self.rate_hz);
            let mut out = Vec::new();
            for b in x.chunks(detect.block_samples) {
                d.push(b, &mut out);
            }
            d.finish(&mut out);
            cuts.extend(out.into_iter().map(|c| (k as u32 + 1, c)));
        }
        cuts.sort_by_key(|(ch, c)| (c.first, *ch));
        cuts.into_iter()
            .enumerate()
            .map(|(i, (ch, c))| self.items(ch, i as u64 + 1, c))
            .collect()
    }
}

/// Records that other readers read whole (a Vallen TR record of the continuous mode, a long
/// row of `waveforms.parquet`, …) cut when `[detect]` says so: each cut hit is numbered
/// `record hit × 10⁶ + k` (traceable to its record, unique), timed from the record's first
/// sample, and a hit row and record of its own. A cut record counts as the transients it
/// became (a tally of the extra ones); one with no hit is a reject saying so. WAV and
/// stream files are cut by their own readers, block by block.
pub(crate) fn cut_long_records(
    items: crate::ingest::Items,
    cfg: &crate::ingest::settings::ReadSettings,
) -> crate::ingest::Items {
    if cfg.detect().mode == crate::detect::DetectMode::Off {
        return items;
    }
    let detect = cfg.detect().clone();
    // A record just cut from a stream (its detected hit row right before it) is not cut
    // again.
    let mut cut: Option<(u32, u64)> = None;
    Box::new(items.flat_map(move |it| match it {
        Item::Hit(h) => {
            cut = (h.source == HitSource::Detected).then_some((h.channel, h.hit));
            vec![Item::Hit(h)]
        }
        Item::Record(r) => {
            let fresh = cut.take() != Some((r.channel, r.hit));
            if fresh && detect.cuts(r.samples.len() as u64) {
                cut_record(r, &detect)
            } else {
                vec![Item::Record(r)]
            }
        }
        other => vec![other],
    }))
}

/// The hits of one record held in memory.
fn cut_record(r: AeRecord, detect: &ValidDetect) -> Vec<Item> {
    let rate = r.sample_rate_hz;
    let at = Cutting {
        experiment: &r.experiment,
        file: &r.source_file,
        rate_hz: rate,
    };
    let p = detect.at_rate(rate);
    let mut d = Detector::<f32>::new(p, 1.0, rate);
    let mut cuts = Vec::new();
    for b in r.samples.chunks(detect.block_samples) {
        d.push(b, &mut cuts);
    }
    d.finish(&mut cuts);
    // Hit numbers record hit × 10⁶ + k stay unique below 10⁶ hits a record.
    const MAX_CUTS: usize = 999_999;
    let dropped = cuts.len().saturating_sub(MAX_CUTS);
    cuts.truncate(MAX_CUTS);
    // The record's first sample; a record without a time starts at 0 s, as a stream does.
    let t0 = r.time_s.map_or(0.0, |t| t - r.pretrigger as f64 / rate);
    let mut tally = StreamTally {
        experiment: r.experiment.clone(),
        file: format!("{} (ch{} hit {})", r.source_file, r.channel, r.hit),
        channels: 1,
        sample_rate_hz: rate,
        samples_read: r.samples.len() as u64,
        samples_promised: r.samples.len() as u64,
        ..Default::default()
    };
    let mut out = Vec::with_capacity(2 * cuts.len() + 1);
    let m = cuts.len() as u64;
    for (k, c) in cuts.into_iter().enumerate() {
        tally.hits_cut += 1;
        tally.samples_in_hits += c.last - c.first + 1;
        tally.two_bursts += c.two_bursts as u64;
        let hit = r.hit.saturating_mul(1_000_000).saturating_add(k as u64 + 1);
        let (mut row, mut rec) = at.items(r.channel, hit, c);
        row.time_s = row.time_s.map(|t| t0 + t);
        rec.time_s = row.time_s;
        (row.load_n, row.extension_m) = (r.load_n, r.extension_m);
        (rec.load_n, rec.extension_m) = (r.load_n, r.extension_m);
        out.push(Item::Hit(Box::new(row)));
        out.push(Item::Record(rec));
    }
    if dropped > 0 {
        out.push(Item::Note(crate::model::Note {
        said: false,
            experiment: r.experiment.clone(),
            source_file: r.source_file.clone(),
            message: format!(
                "ch{} hit {}: {dropped} hits beyond the {MAX_CUTS} a record can number were not cut",
                r.channel, r.hit
            ),
        }));
    }
    if m == 0 {
        out.push(Item::Reject(Reject {
            experiment: r.experiment.clone(),
            source_file: r.source_file.clone(),
            record_id: format!("ch{} hit {}", r.channel, r.hit),
            stage: Stage::Read,
            reason: format!(
                "a continuous record of {} samples with no hit at [detect]'s threshold",
                r.samples.len()
            ),
            record_type: RecordType::Transient,
        }));
    }
    let added = [
        (RecordType::Transient, m.saturating_sub(1)),
        (RecordType::Hit, m),
    ];
    out.push(Item::Tally(Tally {
        experiment: r.experiment.clone(),
        added: added.into_iter().filter(|(_, n)| *n > 0).collect(),
        stream: Some(Box::new(tally)),
        ..Default::default()
    }));
    out
}
