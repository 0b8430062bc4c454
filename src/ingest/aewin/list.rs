//! The AEwin hit list `<test>.TXT` beside a waveform folder: a header row of column names
//! (`ID PARA1 RISE COUN DURATION AMP PCNTS ABS-ENERGY`, any order, any subset) and one row
//! per hit, the acquisition system's own features.
//!
//! A list without a `TIME` column is tied to the waveform files only by order, and a test
//! may hold a waveform the list lacks (or the reverse). So the rows are *aligned* to the
//! waveforms, not zipped: an alignment that may leave a row or a waveform unpaired, scored
//! by whether the list's `AMP` equals the waveform's own peak (less the preamplifier gain)
//! within [`AMP_TOLERANCE_DB`] — the check the provenance of the real export states (27 of 29
//! within 0.5 dB). The match is taken only when most pairs agree ([`HOLDS`]); otherwise no
//! value of the list lands and each of its rows is a reject saying why. A `TIME` column (or
//! a channel column) forbids pairs that disagree on it.
//!
//! The list also tells the rate of a header-less export ([`implied_rate`]): its `RISE` is
//! microseconds from the first threshold crossing to the peak, which the waveform shows
//! in samples.

use crate::model::HitRow;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A pair agrees when the list's AMP is within this of the waveform's peak, dB.
pub const AMP_TOLERANCE_DB: f64 = 1.0;
/// The match holds when at least this share of its checked pairs agree.
pub const HOLDS: f64 = 2.0 / 3.0;
/// A TIME column pairs a row only with a waveform this close in time, s.
const TIME_TOLERANCE_S: f64 = 10e-6;
/// An unpaired row or waveform costs this; a pair that disagrees on AMP costs 1, one that
/// agrees 0, one that cannot be checked 0.5. Two gaps (3) cost more than one disagreeing
/// pair, so a lone outlier stays paired; a shift costs one gap, not a run of disagreements.
const GAP: f32 = 1.5;
/// The alignment may drift this many places beyond the count difference.
const BAND: usize = 64;
/// Rise times shorter than this (µs) are too coarse (whole µs) to tell a rate.
const MIN_RISE_US: f64 = 3.0;
/// Fewest usable rise times for an implied rate.
const MIN_RISES: usize = 5;
/// The usual rates of acquisition systems, Hz.
pub const USUAL_RATES_HZ: [f64; 7] = [1e6, 2e6, 2.5e6, 5e6, 10e6, 20e6, 40e6];

/// Where a list column lands in `hits.parquet`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Target {
    Channel,
    Time,
    Amp,
    Rise,
    Duration,
    Counts,
    CountsToPeak,
    AbsEnergy,
    Threshold,
    EnergyCounts,
    AvgFreq,
    CentroidFreq,
    PeakFreq,
    SignalStrength,
    Parametric,
    Vendor,
}

/// AEwin's column names (its hit-data listing) and where each lands; units in the name's
/// comment. The rest go to `vendor_features` under their own names.
fn target(name: &str) -> Target {
    match name.to_ascii_uppercase().as_str() {
        "ID" | "CH" | "CHAN" | "CHANNEL" => Target::Channel,
        "TIME" => Target::Time,
        "AMP" => Target::Amp,                      // dB_AE
        "RISE" => Target::Rise,                    // µs
        "DURATION" | "DURATN" => Target::Duration, // µs
        "COUN" | "COUNTS" => Target::Counts,
        "PCNTS" => Target::CountsToPeak,
        "ABS-ENERGY" => Target::AbsEnergy, // aJ
        "THR" => Target::Threshold,        // dB_AE
        "ENER" => Target::EnergyCounts,
        "A-FRQ" => Target::AvgFreq,              // kHz
        "C-FRQ" => Target::CentroidFreq,         // kHz
        "P-FRQ" => Target::PeakFreq,             // kHz
        "SIG-STRNGTH" => Target::SignalStrength, // pV·s
        n if n.starts_with("PARA") => Target::Parametric,
        _ => Target::Vendor,
    }
}

/// One data row of a hit list: its line and its cells (null where a cell cannot be read).
#[derive(Debug, Clone, PartialEq)]
pub struct ListRow {
    pub line: usize,
    pub cells: Vec<Option<f64>>,
}

/// A hit list as read: its columns, its rows, and the lines it could not read.
#[derive(Debug, Clone, PartialEq)]
pub struct HitList {
    pub path: PathBuf,
    pub names: Vec<String>,
    targets: Vec<Target>,
    pub rows: Vec<ListRow>,
    /// (line, why) of rows that are not rows of this header.
    pub bad: Vec<(usize, String)>,
    /// Cells that could not be read, by column name.
    pub unreadable: BTreeMap<String, u64>,
}

/// `12.5`, `354.814E+00`, or a clock `hh:mm:ss.fffffff` (TIME) → a number (seconds).
fn cell(s: &str) -> Option<f64> {
    if let Some(v) = crate::ingest::sniff::parse_number(s).filter(|v| v.is_finite()) {
        return Some(v);
    }
    let parts: Vec<&str> = s.split(':').collect();
    if parts.len() != 3 {
        return None;
    }
    let h: f64 = parts[0].parse().ok()?;
    let m: f64 = parts[1].parse().ok()?;
    let sec: f64 = parts[2].parse().ok()?;
    Some(h * 3600.0 + m * 60.0 + sec).filter(|v| v.is_finite())
}

impl HitList {
    pub fn read(path: &Path) -> std::io::Result<HitList> {
        let bytes = std::fs::read(path)?;
        Ok(Self::parse(path, &String::from_utf8_lossy(&bytes)))
    }

    pub fn parse(path: &Path, text: &str) -> HitList {
        let mut lines = text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty());
        let names: Vec<String> = lines
            .next()
            .map(|(_, l)| l.split_whitespace().map(str::to_string).collect())
            .unwrap_or_default();
        let targets = names.iter().map(|n| target(n)).collect();
        let mut list = HitList {
            path: path.to_path_buf(),
            names,
            targets,
            rows: Vec::new(),
            bad: Vec::new(),
            unreadable: BTreeMap::new(),
        };
        for (i, l) in lines {
            let words: Vec<&str> = l.split_whitespace().collect();
            if words.len() != list.names.len() {
                list.bad.push((
                    i + 1,
                    format!(
                        "{} cell(s) under {} column name(s)",
                        words.len(),
                        list.names.len()
                    ),
                ));
                continue;
            }
            let cells = words
                .iter()
                .zip(&list.names)
                .map(|(w, n)| {
                    let v = cell(w);
                    if v.is_none() {
                        *list.unreadable.entry(n.clone()).or_insert(0) += 1;
                    }
                    v
                })
                .collect();
            list.rows.push(ListRow { line: i + 1, cells });
        }
        list
    }

    fn value(&self, r: &ListRow, t: Target) -> Option<f64> {
        let i = self.targets.iter().position(|x| *x == t)?;
        r.cells[i]
    }

    pub fn has_time(&self) -> bool {
        self.targets.contains(&Target::Time)
    }

    pub fn amp(&self, r: &ListRow) -> Option<f64> {
        self.value(r, Target::Amp)
    }

    pub fn time_s(&self, r: &ListRow) -> Option<f64> {
        self.value(r, Target::Time)
    }

    pub fn channel(&self, r: &ListRow) -> Option<u32> {
        self.value(r, Target::Channel)
            .filter(|c| *c >= 0.0 && c.fract() == 0.0 && *c <= u32::MAX as f64)
            .map(|c| c as u32)
    }

    pub fn rise_us(&self, r: &ListRow) -> Option<f64> {
        self.value(r, Target::Rise)
    }

    pub fn threshold_db(&self, r: &ListRow) -> Option<f64> {
        self.value(r, Target::Threshold)
    }

    /// The list's values on a hit row, in SI units; the columns without a place in
    /// `hits.parquet` as a JSON object under their own names.
    pub fn fill(&self, r: &ListRow, h: &mut HitRow) {
        let mut para = BTreeMap::new();
        let mut vendor = BTreeMap::new();
        for ((name, t), v) in self.names.iter().zip(&self.targets).zip(&r.cells) {
            let Some(v) = *v else { continue };
            match t {
                Target::Channel => {}
                Target::Time => h.time_s = Some(v),
                Target::Amp => h.amplitude_db = Some(v),
                Target::Rise => h.rise_time_s = Some(v * 1e-6),
                Target::Duration => h.duration_s = Some(v * 1e-6),
                Target::Counts => h.counts = Some(v as i64),
                Target::CountsToPeak => h.counts_to_peak = Some(v as i64),
                Target::AbsEnergy => h.abs_energy_aj = Some(v),
                Target::Threshold => h.threshold_db = Some(v),
                Target::EnergyCounts => h.energy_counts = Some(v),
                Target::AvgFreq => h.avg_freq_hz = Some(v * 1e3),
                Target::CentroidFreq => h.centroid_freq_hz = Some(v * 1e3),
                Target::PeakFreq => h.peak_freq_hz = Some(v * 1e3),
                Target::SignalStrength => h.signal_strength_vs = Some(v * 1e-12),
                Target::Parametric => {
                    para.insert(name.clone(), v);
                }
                Target::Vendor => {
                    vendor.insert(name.clone(), v);
                }
            }
        }
        if !para.is_empty() {
            h.parametric = serde_json::to_string(&para).ok();
        }
        if !vendor.is_empty() {
            h.vendor_features = serde_json::to_string(&vendor).ok();
        }
    }
}

/// What the matching needs of one waveform: its peak (dB_AE, after the preamplifier), its
/// channel and time, and where its running maximum rose (for rise times at any threshold).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Peek {
    pub amp_db: Option<f64>,
    pub channel: u32,
    pub time_s: Option<f64>,
    /// (sample, |x| there) each time |x| exceeds every earlier sample.
    steps: Vec<(u32, f32)>,
}

impl Peek {
    /// A waveform that could not be read: its place, nothing to check.
    pub fn unread(channel: u32) -> Peek {
        Peek {
            channel,
            ..Default::default()
        }
    }

    pub fn of(samples: &[f32], channel: u32, time_s: Option<f64>) -> Peek {
        let mut steps: Vec<(u32, f32)> = Vec::new();
        let mut top = 0f32;
        for (i, v) in samples.iter().enumerate() {
            let a = v.abs();
            if a > top {
                top = a;
                steps.push((i as u32, a));
            }
        }
        Peek {
            amp_db: (top > 0.0).then(|| crate::model::db_ae(top as f64)),
            channel,
            time_s,
            steps,
        }
    }

    /// Samples from the first crossing of `threshold_v` to the peak.
    pub fn rise_samples(&self, threshold_v: f64) -> Option<u32> {
        let first = self.steps.iter().find(|(_, a)| *a as f64 >= threshold_v)?;
        Some(self.steps.last()?.0 - first.0)
    }
}

/// One place of an alignment: a waveform and a row, or either alone.
pub type Pair = (Option<usize>, Option<usize>);

/// The alignment of the rows to the waveforms (both in hit order) that costs least, and how
/// many of its pairs were checked by AMP and agreed.
#[derive(Debug, Clone, PartialEq)]
pub struct Alignment {
    pub pairs: Vec<Pair>,
    pub checked: usize,
    pub agree: usize,
}

impl Alignment {
    pub fn holds(&self) -> bool {
        self.checked > 0 && self.agree as f64 >= HOLDS * self.checked as f64
    }

    pub fn paired(&self) -> usize {
        self.pairs
            .iter()
            .filter(|p| p.0.is_some() && p.1.is_some())
            .count()
    }
}

/// A pair's cost, `None` where the pair is impossible (another channel, another time).
fn pair_cost(list: &HitList, w: &Peek, r: &ListRow) -> Option<f32> {
    if let Some(c) = list.channel(r) {
        if c != w.channel {
            return None;
        }
    }
    if let (Some(a), Some(b)) = (list.time_s(r), w.time_s) {
        if (a - b).abs() > TIME_TOLERANCE_S {
            return None;
        }
    }
    Some(match (list.amp(r), w.amp_db) {
        (Some(a), Some(b)) if (a - b).abs() <= AMP_TOLERANCE_DB => 0.0,
        (Some(_), Some(_)) => 1.0,
        _ => 0.5,
    })
}

/// The least-cost alignment (edit distance with [`GAP`] and [`pair_cost`]), kept to a band
/// around the diagonal so a list of n rows costs O(n·band), not O(n²).
pub fn align(list: &HitList, waves: &[Peek]) -> Alignment {
    let (n, m) = (waves.len(), list.rows.len());
    let lo = (m as i64 - n as i64).min(0) - BAND as i64;
    let hi = (m as i64 - n as i64).max(0) + BAND as i64;
    let width = (hi - lo + 1) as usize;
    // Cell (i, j) of the table at i·width + (j − i − lo); outside the band: unreachable.
    let at = |i: usize, j: usize| -> Option<usize> {
        let d = j as i64 - i as i64;
        (lo..=hi)
            .contains(&d)
            .then(|| i * width + (d - lo) as usize)
    };
    let mut cost = vec![f32::INFINITY; (n + 1) * width];
    // 0: diagonal (a pair), 1: waveform alone, 2: row alone.
    let mut from = vec![0u8; (n + 1) * width];
    for i in 0..=n {
        for j in 0..=m {
            let Some(k) = at(i, j) else { continue };
            if i == 0 && j == 0 {
                cost[k] = 0.0;
                continue;
            }
            let mut best = (f32::INFINITY, 0u8);
            if i > 0 && j > 0 {
                if let (Some(p), Some(c)) = (
                    at(i - 1, j - 1),
                    pair_cost(list, &waves[i - 1], &list.rows[j - 1]),
                ) {
                    best = best.min_by_cost((cost[p] + c, 0));
                }
            }
            if i > 0 {
                if let Some(p) = at(i - 1, j) {
                    best = best.min_by_cost((cost[p] + GAP, 1));
                }
            }
            if j > 0 {
                if let Some(p) = at(i, j - 1) {
                    best = best.min_by_cost((cost[p] + GAP, 2));
                }
            }
            cost[k] = best.0;
            from[k] = best.1;
        }
    }
    let mut pairs = Vec::with_capacity(n.max(m));
    let (mut i, mut j) = (n, m);
    while i > 0 || j > 0 {
        let k = at(i, j).expect("the path stays in the band");
        match from[k] {
            0 => {
                pairs.push((Some(i - 1), Some(j - 1)));
                i -= 1;
                j -= 1;
            }
            1 => {
                pairs.push((Some(i - 1), None));
                i -= 1;
            }
            _ => {
                pairs.push((None, Some(j - 1)));
                j -= 1;
            }
        }
    }
    pairs.reverse();
    let (mut checked, mut agree) = (0, 0);
    for (w, r) in &pairs {
        if let (Some(w), Some(r)) = (w, r) {
            if let (Some(a), Some(b)) = (list.amp(&list.rows[*r]), waves[*w].amp_db) {
                checked += 1;
                agree += usize::from((a - b).abs() <= AMP_TOLERANCE_DB);
            }
        }
    }
    Alignment {
        pairs,
        checked,
        agree,
    }
}

trait MinByCost {
    fn min_by_cost(self, o: Self) -> Self;
}

impl MinByCost for (f32, u8) {
    /// The cheaper step; on a tie the earlier kind (a pair before a gap).
    fn min_by_cost(self, o: Self) -> Self {
        if o.0 < self.0 {
            o
        } else {
            self
        }
    }
}

/// What the rise times say of the rate: samples per list-µs (the median over the usable
/// pairs), how many pairs were usable, and the usual rate they clearly agree on.
#[derive(Debug, Clone, PartialEq)]
pub struct ImpliedRate {
    pub samples_per_us: f64,
    pub used: usize,
    /// `None`: no candidate rate is clearly nearest.
    pub rate_hz: Option<f64>,
}

/// The rate the list's `RISE` implies: for each pair whose rise is at least [`MIN_RISE_US`],
/// the waveform's samples from the first crossing of the threshold (the list's `THR`, else
/// its lowest `AMP`: no hit is below the threshold) to the peak, per list-µs. A candidate
/// (the usual rates and `configured`) is clearly agreed on when the median is within 25 % of
/// it and every other candidate is at least twice as far (in ratio).
pub fn implied_rate(
    list: &HitList,
    waves: &[Peek],
    al: &Alignment,
    configured: f64,
) -> Option<ImpliedRate> {
    let pairs: Vec<(&Peek, &ListRow)> = al
        .pairs
        .iter()
        .filter_map(|p| Some((&waves[p.0?], &list.rows[p.1?])))
        .collect();
    let lowest_amp = pairs
        .iter()
        .filter_map(|(_, r)| list.amp(r))
        .fold(f64::INFINITY, f64::min);
    let mut ratios: Vec<f64> = pairs
        .iter()
        .filter_map(|(w, r)| {
            let rise = list.rise_us(r).filter(|v| *v >= MIN_RISE_US)?;
            let thr_db = list
                .threshold_db(r)
                .or(lowest_amp.is_finite().then_some(lowest_amp))?;
            let thr_v = 1e-6 * 10f64.powf(thr_db / 20.0);
            Some(w.rise_samples(thr_v)? as f64 / rise)
        })
        .collect();
    if ratios.len() < MIN_RISES {
        return None;
    }
    ratios.sort_by(f64::total_cmp);
    let k = ratios.len();
    let median = if k % 2 == 1 {
        ratios[k / 2]
    } else {
        0.5 * (ratios[k / 2 - 1] + ratios[k / 2])
    };
    Some(ImpliedRate {
        samples_per_us: median,
        used: k,
        rate_hz: clear_rate(median, configured, CLEAR),
    })
}

/// When a median of samples per list-µs clearly agrees on a candidate rate.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Clearly {
    /// The median is within this ratio of the candidate (1.25: 25 %)…
    within: f64,
    /// …and every other candidate is at least this many times as far, in log ratio…
    apart: f64,
    /// …where the nearest's distance counts as at least this (so two candidates a few
    /// percent apart, e.g. a configured 5.2 MHz beside 5 MHz, are never told apart).
    floor: f64,
}

const CLEAR: Clearly = Clearly {
    within: 1.25,
    apart: 2.0,
    floor: 0.05,
};

/// The candidate (the usual rates and `configured`) a median of `samples_per_us` clearly
/// agrees on by `rule`; `None` when none does.
fn clear_rate(samples_per_us: f64, configured: f64, rule: Clearly) -> Option<f64> {
    let mut cands: Vec<f64> = USUAL_RATES_HZ.to_vec();
    if !cands.contains(&configured) {
        cands.push(configured);
    }
    let far = |c: f64| (samples_per_us * 1e6 / c).ln().abs();
    cands.sort_by(|a, b| far(*a).total_cmp(&far(*b)));
    let (best, next) = (
        far(cands[0]),
        cands.get(1).map_or(f64::INFINITY, |c| far(*c)),
    );
    let clear = best <= rule.within.ln() && next >= rule.apart * best.max(rule.floor);
    clear.then_some(cands[0])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn list(text: &str) -> HitList {
        HitList::parse(Path::new("t.TXT"), text)
    }

    fn wave(amp_db: f64) -> Peek {
        let peak = 1e-6 * 10f64.powf(amp_db / 20.0);
        Peek::of(&[0.0, (peak * 0.5) as f32, peak as f32], 1, None)
    }

    #[test]
    fn columns_land_by_name_in_any_order() {
        let l = list("\n AMP  ID RISE  X-Y\n 58 2 17 3.5\n 61 2 4 bad\n 1 2\n");
        assert_eq!(l.rows.len(), 2);
        assert_eq!(l.bad, vec![(5, "2 cell(s) under 4 column name(s)".into())]);
        assert_eq!(l.unreadable.get("X-Y"), Some(&1));
        let mut h = HitRow::default();
        l.fill(&l.rows[0], &mut h);
        assert_eq!(h.amplitude_db, Some(58.0));
        assert_eq!(h.rise_time_s, Some(17e-6));
        assert_eq!(l.channel(&l.rows[0]), Some(2));
        assert_eq!(h.vendor_features.as_deref(), Some(r#"{"X-Y":3.5}"#));
        assert_eq!(cell("00:01:02.5"), Some(62.5));
    }

    #[test]
    fn a_missing_row_is_a_gap_not_a_shift() {
        let amps = [50.0, 60.0, 70.0, 55.0, 65.0, 75.0, 52.0, 62.0];
        let waves: Vec<Peek> = amps.iter().map(|a| wave(*a)).collect();
        // The list lacks the fourth hit.
        let text: String = std::iter::once(" ID AMP\n".to_string())
            .chain(
                amps.iter()
                    .enumerate()
                    .filter(|(i, _)| *i != 3)
                    .map(|(_, a)| format!(" 1 {a}\n")),
            )
            .collect();
        let l = list(&text);
        let al = align(&l, &waves);
        assert!(al.holds());
        assert_eq!((al.checked, al.agree), (7, 7));
        assert_eq!(al.pairs[3], (Some(3), None));
        assert_eq!(al.pairs[4], (Some(4), Some(3)));
    }

    #[test]
    fn unrelated_amplitudes_do_not_hold() {
        let waves: Vec<Peek> = [50.0, 60.0, 70.0, 80.0].iter().map(|a| wave(*a)).collect();
        let l = list(" ID AMP\n 1 90\n 1 40\n 1 85\n 1 45\n");
        assert!(!align(&l, &waves).holds());
    }

    /// A waveform whose running maximum holds `below` V, then rises from `start` V by 10 µV a
    /// sample for `r` samples: `r` samples from the first crossing of any threshold in
    /// (`below`, `start`] to the peak.
    fn ramp(below: f32, start: f32, r: u32) -> Peek {
        let mut v = vec![below, 0.0, 0.0];
        v.extend((0..=r).map(|i| start + 1e-5 * i as f32));
        Peek::of(&v, 1, None)
    }

    /// Every row paired with the waveform at its place.
    fn paired(n: usize) -> Alignment {
        Alignment {
            pairs: (0..n).map(|i| (Some(i), Some(i))).collect(),
            checked: 0,
            agree: 0,
        }
    }

    /// A list (`THR 40` dB_AE = 100 µV, `AMP 60`) of one row per (samples, rise µs), and
    /// waveforms rising that many samples above 100 µV from 60 µV below it.
    fn rises(cases: &[(u32, f64)]) -> (HitList, Vec<Peek>, Alignment) {
        let text: String = std::iter::once(" ID THR AMP RISE\n".to_string())
            .chain(cases.iter().map(|(_, us)| format!(" 1 40 60 {us}\n")))
            .collect();
        let waves = cases.iter().map(|(r, _)| ramp(6e-5, 2e-4, *r)).collect();
        (list(&text), waves, paired(cases.len()))
    }

    fn implied(cases: &[(u32, f64)], configured: f64) -> Option<ImpliedRate> {
        let (l, w, al) = rises(cases);
        implied_rate(&l, &w, &al, configured)
    }

    /// Six usable ratios 4.5, 4.8, 5.0, 5.2, 5.4, 9.0 samples/µs: the median is 5.1 (the mean,
    /// 5.65, would be off), nearest 5 MHz by 2 %, every other rate ≥ 2× as far: 5 MHz. Rises
    /// under 3 µs, rows without a waveform and waveforms without a row are not used; the
    /// threshold is the list's THR, so the 60 µV step below it does not count (it would add
    /// 3 samples to each rise).
    #[test]
    fn the_median_rise_ratio_tells_a_clear_rate() {
        let mut cases = vec![(45, 10.0), (48, 10.0), (50, 10.0), (52, 10.0), (54, 10.0)];
        cases.extend([(90, 10.0), (20, 2.0), (29, 2.9)]);
        let (mut l, mut w, mut al) = rises(&cases);
        w.push(ramp(6e-5, 2e-4, 500));
        l.rows.push(ListRow {
            line: 99,
            cells: vec![Some(1.0), Some(40.0), Some(60.0), Some(100.0)],
        });
        al.pairs.push((Some(cases.len()), None));
        al.pairs.push((None, Some(cases.len())));
        let got = implied_rate(&l, &w, &al, 5e6).unwrap();
        assert_eq!(got.used, 6);
        assert!((got.samples_per_us - 5.1).abs() < 1e-12, "{got:?}");
        assert_eq!(got.rate_hz, Some(5e6));
        // Without a THR column the threshold is the lowest AMP (60 dB_AE = 1 mV): the step
        // of 0.5 mV below it does not count, the first sample at 1.5 mV does.
        let text: String = std::iter::once(" ID AMP RISE\n".to_string())
            .chain((0..5).map(|k| format!(" 1 {} 10\n", 60 + k)))
            .collect();
        let w: Vec<Peek> = (0..5).map(|_| ramp(5e-4, 1.5e-3, 100)).collect();
        let got = implied_rate(&list(&text), &w, &paired(5), 5e6).unwrap();
        assert_eq!((got.samples_per_us, got.rate_hz), (10.0, Some(10e6)));
    }

    /// Five rises of at least 3 µs tell a rate; four do not, however many shorter ones (or
    /// rows without a RISE) stand beside them.
    #[test]
    fn too_few_rise_times_tell_no_rate() {
        let short = [(20, 2.0), (29, 2.9), (10, 1.0)];
        let mut four: Vec<(u32, f64)> = vec![(50, 10.0); 4];
        four.extend(short);
        assert_eq!(implied(&four, 5e6), None);
        let (mut l, mut w, _) = rises(&four);
        l.rows.push(ListRow {
            line: 99,
            cells: vec![Some(1.0), Some(40.0), Some(60.0), None],
        });
        w.push(ramp(6e-5, 2e-4, 50));
        assert_eq!(implied_rate(&l, &w, &paired(w.len()), 5e6), None);
        four.push((50, 10.0));
        let five = implied(&four, 5e6).unwrap();
        assert_eq!((five.used, five.rate_hz), (5, Some(5e6)));
    }

    /// Through the whole computation: a median of √5 = 2.236 samples/µs is equally near 2 and
    /// 2.5 MHz (none is clearly nearest); 6.27 is 25.4 % above 5 MHz (too far from every
    /// usual rate, though 10 MHz is more than twice as far); 3.0 is a configured 3 MHz, and
    /// 2.5 MHz (20 % off, 2 MHz 2.2× as far) when the configured rate is 5 MHz.
    #[test]
    fn an_ambiguous_or_distant_median_tells_no_rate_and_the_configured_rate_is_a_candidate() {
        let ambiguous = implied(&[(559, 250.0); 5], 5e6).unwrap();
        assert!((ambiguous.samples_per_us - 2.236).abs() < 1e-12);
        assert_eq!(ambiguous.rate_hz, None);
        let far = implied(&[(627, 100.0); 5], 5e6).unwrap();
        assert_eq!((far.samples_per_us, far.rate_hz), (6.27, None));
        assert_eq!(implied(&[(30, 10.0); 5], 3e6).unwrap().rate_hz, Some(3e6));
        assert_eq!(implied(&[(30, 10.0); 5], 5e6).unwrap().rate_hz, Some(2.5e6));
    }

    /// (median samples/µs, configured Hz, the rate it clearly tells) on both sides of each
    /// boundary, worked out by hand: within 25 % of 5 MHz (6.2 and 4.05 are, 6.27 and 3.95
    /// are not); every other rate ≥ 2× as far in log ratio (2.15: ln(2.5/2.15) = 0.151 ≥
    /// 2·ln(1.075) = 0.145, 2.16: 0.146 < 0.154); √5 equally near 2 and 2.5 MHz; the
    /// configured rate a candidate (3 MHz) and, a few percent from a usual rate, never told
    /// apart from it (5.2 MHz: ln 1.04 = 0.039 < 2·0.05; 5.6 MHz: ln 1.12 = 0.113 ≥ 0.1).
    const BOUNDARIES: [(f64, f64, Option<f64>); 13] = [
        (5.0, 5e6, Some(5e6)),
        (6.2, 5e6, Some(5e6)),
        (6.27, 5e6, None),
        (4.05, 5e6, Some(5e6)),
        (3.95, 5e6, None),
        (2.15, 5e6, Some(2e6)),
        (2.16, 5e6, None),
        (2.236_067_977_5, 5e6, None),
        (3.0, 3e6, Some(3e6)),
        (3.0, 5e6, Some(2.5e6)),
        (5.0, 5.2e6, None),
        (5.0, 5.6e6, Some(5e6)),
        (20.0, 5e6, Some(20e6)),
    ];

    /// The cases of [`BOUNDARIES`] a decision gets wrong.
    fn wrong(decide: &dyn Fn(f64, f64) -> Option<f64>) -> Vec<(f64, f64, Option<f64>)> {
        BOUNDARIES
            .iter()
            .filter(|(m, c, want)| decide(*m, *c) != *want)
            .copied()
            .collect()
    }

    /// The decision agrees with every hand-worked boundary case. Plants: copies of it with
    /// the 25 % rule at 30 % or 20 %, the 2× rule at 1.5× or 3×, no floor or a 0.06 floor, or
    /// the configured rate left out of the candidates, each get a case wrong.
    #[test]
    fn the_rate_decision_holds_on_both_sides_of_each_boundary() {
        assert_eq!(wrong(&|m, c| clear_rate(m, c, CLEAR)), vec![]);
        let with = |r: Clearly| move |m: f64, c: f64| clear_rate(m, c, r);
        let plants = [
            Clearly {
                within: 1.3,
                ..CLEAR
            },
            Clearly {
                within: 1.2,
                ..CLEAR
            },
            Clearly {
                apart: 1.5,
                ..CLEAR
            },
            Clearly {
                apart: 3.0,
                ..CLEAR
            },
            Clearly {
                floor: 0.0,
                ..CLEAR
            },
            Clearly {
                floor: 0.06,
                ..CLEAR
            },
        ];
        for p in plants {
            assert!(!wrong(&with(p)).is_empty(), "plant {p:?} passed");
        }
        // The configured rate ignored: a usual rate in its place adds no candidate.
        assert!(!wrong(&|m, _| clear_rate(m, 5e6, CLEAR)).is_empty());
    }
}
