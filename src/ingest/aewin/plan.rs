//! The order in which an AEwin test is read when a hit list lies beside it: each waveform
//! with the list row it was matched to ([`super::list::align`]), the rows no waveform has,
//! and the rate the files are read at ([`super::list::implied_rate`]), with what was decided
//! said as notes.

use super::list::{align, implied_rate, Alignment, HitList, Peek};
use super::{read_wave, WaveFile};
use crate::ingest::settings::AewinConfig;
use crate::model::{Item, Note, RecordType, Reject, Stage};
use rayon::prelude::*;

/// One step of the reading: a waveform (with its list row, when the match holds) or a list
/// row without a waveform. `order` is the hit's 1-based place in the test.
#[derive(Debug, Clone)]
pub(super) enum Step {
    Wave {
        file: WaveFile,
        row: Option<usize>,
        order: u64,
    },
    RowOnly {
        row: usize,
        order: u64,
    },
}

/// How an AEwin test is read.
pub(super) struct Plan {
    pub steps: Vec<Step>,
    /// The list whose values land, when its match holds.
    pub list: Option<HitList>,
    pub rate_hz: f64,
    /// Notes, rejects and the list's count, to hand out before the first record.
    pub first: Vec<Item>,
}

fn note(experiment: &str, file: &str, message: String, said: bool) -> Item {
    Note::item(experiment, file, message, said)
}

fn mhz(hz: f64) -> String {
    format!("{} MHz", hz / 1e6)
}

/// The plan of a test: without a hit list, its files in their order at the configured rate
/// (with the doubt said for header-less files); with one, the checked match and the rate.
pub(super) fn plan(
    experiment: &str,
    files: Vec<WaveFile>,
    hit_list: Option<&std::path::Path>,
    cfg: &AewinConfig,
    gain: f64,
) -> Plan {
    let configured = cfg.configured_rate_hz();
    let Some(path) = hit_list else {
        return without_list(experiment, files, cfg);
    };
    let file = path.display().to_string();
    let mut first = Vec::new();
    let list = match HitList::read(path) {
        Ok(l) => l,
        Err(e) => {
            first.push(Item::Reject(Reject {
                record_type: RecordType::File,
                experiment: experiment.to_string(),
                source_file: file,
                record_id: String::new(),
                stage: Stage::Read,
                reason: format!("hit list not read: {e}"),
            }));
            return Plan {
                steps: in_order(files),
                list: None,
                rate_hz: configured,
                first,
            };
        }
    };
    first.extend(list_items(experiment, &file, &list));
    let mut files = files;
    // The list is in the order the system stored the hits: by time where the names say it.
    if files.iter().all(|f| f.name_time_us.is_some()) {
        files.sort_by_key(|f| (f.name_time_us, f.hit, f.channel));
    } else {
        files.sort_by_key(|f| (f.hit, f.channel));
    }
    let (peeks, header_less) = peek_all(&files, configured, gain);
    let al = align(&list, &peeks);
    let name = path
        .file_name()
        .map_or(file.clone(), |n| n.to_string_lossy().to_string());
    let holds = al.holds() || (al.checked == 0 && list.has_time());
    first.push(match_note(experiment, &file, &name, &list, &al, holds));
    let rate_hz = if header_less && holds {
        let (rate, message, said) = rate_decision(experiment, &list, &peeks, &al, cfg);
        first.push(note(experiment, &file, message, said));
        rate
    } else {
        configured
    };
    if !holds {
        let why =
            format!("the hit list {name} does not match the waveforms: its values are not used");
        first.extend(
            list.rows
                .iter()
                .map(|r| hit_reject(experiment, &file, r.line, why.clone())),
        );
        return Plan {
            steps: in_order(files),
            list: None,
            rate_hz,
            first,
        };
    }
    Plan {
        steps: aligned(&al, files),
        list: Some(list),
        rate_hz,
        first,
    }
}

/// A test without a hit list: its files in order at the configured rate, the doubt said
/// for header-less files.
fn without_list(experiment: &str, files: Vec<WaveFile>, cfg: &AewinConfig) -> Plan {
    let configured = cfg.configured_rate_hz();
    let mut first = Vec::new();
    if files.iter().any(|f| f.header_less) {
        first.push(note(
            experiment,
            "",
            format!(
                "{experiment}: header-less waveform files and no hit list: read at {} ({}), which nothing in the files confirms",
                mhz(configured),
                if cfg.sample_rate_hz.is_some() {
                    "[ingest.aewin] sample_rate_hz"
                } else {
                    "aepipe's default; set [ingest.aewin] sample_rate_hz"
                }
            ),
            true,
        ));
    }
    Plan {
        steps: in_order(files),
        list: None,
        rate_hz: configured,
        first,
    }
}

/// The list's bad lines (rejects), its unreadable cells (notes) and its count of rows.
fn list_items(experiment: &str, file: &str, list: &HitList) -> Vec<Item> {
    let mut out: Vec<Item> = list
        .bad
        .iter()
        .map(|(line, why)| hit_reject(experiment, file, *line, why.clone()))
        .collect();
    for (col, n) in &list.unreadable {
        out.push(note(
            experiment,
            file,
            format!("hit list column {col}: {n} cell(s) are not numbers: null"),
            false,
        ));
    }
    out.push(Item::Tally(crate::model::Tally {
        experiment: experiment.to_string(),
        read: [(RecordType::Hit, (list.rows.len() + list.bad.len()) as u64)].into(),
        ..Default::default()
    }));
    out
}

/// What the match needs of every waveform (read in parallel), and whether the test is
/// header-less (no readable file carries its own rate).
fn peek_all(files: &[WaveFile], rate: f64, gain: f64) -> (Vec<Peek>, bool) {
    let peeks: Vec<(Peek, bool)> = files
        .par_iter()
        .map(|f| match read_wave(f, rate) {
            Ok(r) => {
                let v: Vec<f32> = r.samples.iter().map(|v| (v * gain) as f32).collect();
                (Peek::of(&v, f.channel, r.time_s), r.from_header)
            }
            Err(_) => (Peek::unread(f.channel), false),
        })
        .collect();
    let header_less = peeks.iter().all(|(p, h)| !h || p.amp_db.is_none());
    (peeks.into_iter().map(|p| p.0).collect(), header_less)
}

/// The steps of a match that holds: each place of the alignment in order.
fn aligned(al: &Alignment, files: Vec<WaveFile>) -> Vec<Step> {
    let mut files: Vec<Option<WaveFile>> = files.into_iter().map(Some).collect();
    al.pairs
        .iter()
        .enumerate()
        .map(|(k, (w, r))| {
            let order = k as u64 + 1;
            match w {
                Some(w) => Step::Wave {
                    file: files[*w].take().expect("each waveform once"),
                    row: *r,
                    order,
                },
                None => Step::RowOnly {
                    row: r.expect("a place holds a waveform or a row"),
                    order,
                },
            }
        })
        .collect()
}

fn in_order(files: Vec<WaveFile>) -> Vec<Step> {
    files
        .into_iter()
        .map(|file| Step::Wave {
            order: file.hit,
            file,
            row: None,
        })
        .collect()
}

fn hit_reject(experiment: &str, file: &str, line: usize, reason: String) -> Item {
    Item::Reject(Reject {
        record_type: RecordType::Hit,
        experiment: experiment.to_string(),
        source_file: file.to_string(),
        record_id: format!("line {line}"),
        stage: Stage::Read,
        reason,
    })
}

/// What the match found: how many pairs, how many agree on AMP, and each row or waveform
/// left alone (the first few by name).
fn match_note(
    experiment: &str,
    file: &str,
    name: &str,
    list: &HitList,
    al: &Alignment,
    holds: bool,
) -> Item {
    let alone_waves = al.pairs.iter().filter(|p| p.1.is_none()).count();
    let alone_rows = al.pairs.iter().filter(|p| p.0.is_none()).count();
    let how = if list.has_time() {
        "by time"
    } else {
        "in hit order"
    };
    let check = if al.checked > 0 {
        format!(
            "AMP within {} dB of the waveform's peak (less the preamplifier gain) for {} of {}",
            super::list::AMP_TOLERANCE_DB,
            al.agree,
            al.checked
        )
    } else {
        "not checked by AMP (the list has no AMP column, or no waveform could be read)".into()
    };
    let mut m = if holds {
        format!(
            "{experiment}: hit list {name} matched {how}: {} of {} row(s) paired with waveforms, {check}",
            al.paired(),
            list.rows.len()
        )
    } else {
        format!(
            "{experiment}: hit list {name} does not match the waveforms in any order: at best {check}; its values are not used"
        )
    };
    if holds && alone_waves + alone_rows > 0 {
        let places: Vec<String> = al
            .pairs
            .iter()
            .enumerate()
            .filter(|(_, p)| p.0.is_none() || p.1.is_none())
            .take(5)
            .map(|(k, p)| match p {
                (None, Some(r)) => format!(
                    "hit {} (line {}) has no waveform",
                    k + 1,
                    list.rows[*r].line
                ),
                _ => format!("hit {} has no list row", k + 1),
            })
            .collect();
        m += &format!(
            "; {alone_waves} waveform(s) without a row, {alone_rows} row(s) without a waveform: {}{}",
            places.join(", "),
            if alone_waves + alone_rows > 5 { ", …" } else { "" }
        );
    }
    let said = !holds || alone_waves + alone_rows > 0;
    note(experiment, file, m, said)
}

/// The rate to read a header-less test at, the note saying why, and whether the terminal
/// says it too (whenever the rate is not the one the list confirms).
fn rate_decision(
    experiment: &str,
    list: &HitList,
    peeks: &[Peek],
    al: &Alignment,
    cfg: &AewinConfig,
) -> (f64, String, bool) {
    let configured = cfg.configured_rate_hz();
    let Some(imp) = implied_rate(list, peeks, al, configured) else {
        return (
            configured,
            format!(
                "{experiment}: {} as configured; the hit list holds too few rise times (≥ 3 µs) to check it",
                mhz(configured)
            ),
            true,
        );
    };
    let by = format!(
        "{:.1} samples per list-µs over {} hits",
        imp.samples_per_us, imp.used
    );
    match (imp.rate_hz, cfg.sample_rate_hz) {
        (None, _) => (
            configured,
            format!(
                "{experiment}: {} as configured; the hit list's rise times imply no usual rate clearly ({by})",
                mhz(configured)
            ),
            true,
        ),
        (Some(r), _) if r == configured => (
            r,
            format!(
                "{experiment}: {}, as the hit list's rise times imply ({by})",
                mhz(r)
            ),
            false,
        ),
        (Some(r), Some(set)) => (
            set,
            format!(
                "{experiment}: {} as set in the pipeline file, though the hit list's rise times imply {} ({by})",
                mhz(set),
                mhz(r)
            ),
            true,
        ),
        (Some(r), None) => (
            r,
            format!(
                "{experiment}: {}, implied by the hit list's rise times (configured {}; {by})",
                mhz(r),
                mhz(configured)
            ),
            true,
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` rows (THR 40 dB_AE = 100 µV, RISE `us` µs) paired with waveforms that rise `r`
    /// samples from 200 µV (above the threshold) to their peak.
    fn case(n: usize, r: u32, us: f64) -> (HitList, Vec<Peek>, Alignment) {
        let text: String = std::iter::once(" ID THR AMP RISE\n".to_string())
            .chain((0..n).map(|_| format!(" 1 40 60 {us}\n")))
            .collect();
        let mut v = vec![0f32; 3];
        v.extend((0..=r).map(|i| 2e-4 + 1e-5 * i as f32));
        let al = Alignment {
            pairs: (0..n).map(|i| (Some(i), Some(i))).collect(),
            checked: 0,
            agree: 0,
        };
        let list = HitList::parse(std::path::Path::new("EXP.TXT"), &text);
        (list, vec![Peek::of(&v, 1, None); n], al)
    }

    fn decide(c: (HitList, Vec<Peek>, Alignment), set: Option<f64>) -> (f64, String, bool) {
        let cfg = AewinConfig {
            sample_rate_hz: set,
            ..Default::default()
        };
        rate_decision("EXP", &c.0, &c.1, &c.2, &cfg)
    }

    /// Each branch of the decision on a header-less test, the rate read and what is said:
    /// four rises are too few to check the configured 5 MHz (five are enough: the same rows
    /// with one more reach the next branch); a median of 2.236 samples/µs, equally near 2
    /// and 2.5 MHz, implies no rate clearly; 5.0 confirms 5 MHz (a manifest note, not a
    /// terminal line); 10.0 implies 10 MHz when no rate is set, and is said against a set
    /// 5 MHz, which is kept.
    #[test]
    fn each_rate_decision_reads_at_the_rate_it_says() {
        assert_eq!(
            decide(case(4, 50, 10.0), None),
            (5e6, "EXP: 5 MHz as configured; the hit list holds too few rise times (≥ 3 µs) to check it".into(), true)
        );
        assert_eq!(
            decide(case(5, 559, 250.0), None),
            (5e6, "EXP: 5 MHz as configured; the hit list's rise times imply no usual rate clearly (2.2 samples per list-µs over 5 hits)".into(), true)
        );
        assert_eq!(
            decide(case(5, 50, 10.0), None),
            (5e6, "EXP: 5 MHz, as the hit list's rise times imply (5.0 samples per list-µs over 5 hits)".into(), false)
        );
        assert_eq!(
            decide(case(5, 100, 10.0), None),
            (10e6, "EXP: 10 MHz, implied by the hit list's rise times (configured 5 MHz; 10.0 samples per list-µs over 5 hits)".into(), true)
        );
        assert_eq!(
            decide(case(6, 100, 10.0), Some(5e6)),
            (5e6, "EXP: 5 MHz as set in the pipeline file, though the hit list's rise times imply 10 MHz (10.0 samples per list-µs over 6 hits)".into(), true)
        );
    }
}
