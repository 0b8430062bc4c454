//! Scoring the SOM's classes against a synthetic experiment's ground truth.

use super::*;
use crate::model::columns as cols;

/// A hit's key and a label, sortable by the key, then by which table it came from and its
/// row there (a key a table repeats keeps its file order).
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
struct Keyed {
    key: HitKey,
    /// 0: the truth's mechanism, 1: a key of the `within` table, 2: the label scored.
    from: u8,
    seq: u64,
    label: String,
}

impl crate::store::spill::Spill for Keyed {
    fn encode(&self, out: &mut Vec<u8>) {
        crate::store::spill::Enc(out)
            .str(&self.key.0)
            .i32(self.key.1)
            .i64(self.key.2)
            .u8(self.from)
            .u64(self.seq)
            .str(&self.label);
    }
    fn decode(b: &mut crate::store::spill::Dec<'_>) -> Option<Self> {
        Some(Keyed {
            key: (b.str()?, b.i32()?, b.i64()?),
            from: b.u8()?,
            seq: b.u64()?,
            label: b.str()?,
        })
    }
    fn mem_bytes(&self) -> usize {
        std::mem::size_of::<Self>() + self.key.0.len() + self.label.len()
    }
}

/// Push `(key, column)` of every row of a table, a batch at a time.
fn push_labels(
    sorter: &mut crate::store::spill::Sorter<Keyed>,
    path: &Path,
    column: &str,
    from: u8,
) -> Result<(), WorkflowError> {
    let mut seq = 0u64;
    TableScan::open(path)?.for_each_keyed_string(column, |key, label| {
        sorter.push(Keyed {
            key,
            from,
            seq,
            label,
        })?;
        seq += 1;
        Ok::<(), WorkflowError>(())
    })
}

/// The sort's `from` of the `within` table's keys: after the truth's, before the labels'.
const WITHIN: u8 = 1;

/// Compare the SOM classes with `truth.parquet`: both sorted by hit on disk and joined.
pub(super) fn score_truth(
    truth: &Path,
    classification: &Path,
) -> Result<TruthScore, WorkflowError> {
    score_labels(truth, classification, cols::SOM_LABEL.name, None)
}

/// Compare any label column of a hit table (the SOM's `som_label`, the features' ch. 4.7
/// `criteria_label`) with `truth.parquet`'s mechanism: both sorted by hit on disk and
/// joined.
///
/// With `within` (e.g. the SOM's `classification.parquet`), only the hits that table holds
/// are scored, so that two labels are compared on the same hits.
pub(super) fn score_labels(
    truth: &Path,
    table: &Path,
    column: &str,
    within: Option<&Path>,
) -> Result<TruthScore, WorkflowError> {
    let dir = table.parent().unwrap_or(Path::new("."));
    let mut sorter = crate::store::spill::Sorter::new(dir);
    push_labels(&mut sorter, truth, cols::MECHANISM.name, 0)?;
    if let Some(w) = within {
        push_labels(&mut sorter, w, cols::SOM_LABEL.name, WITHIN)?;
    }
    push_labels(&mut sorter, table, column, 2)?;
    let sorted = sorter.finish()?;
    let mut s = TruthScore {
        path: truth.to_path_buf(),
        counts: BTreeMap::new(),
        bond_fibre_total: 0,
        bond_fibre_correct: 0,
    };
    // A key's truth (the last, if a truth table repeated a key) then its classes.
    let mut mechanism: Option<(HitKey, String)> = None;
    // The last key `within` holds.
    let mut held: Option<HitKey> = None;
    for r in sorted.iter() {
        let r = r?;
        if r.from == 0 {
            mechanism = Some((r.key, r.label));
            continue;
        }
        if r.from == WITHIN {
            held = Some(r.key);
            continue;
        }
        if within.is_some() && held.as_ref() != Some(&r.key) {
            continue;
        }
        let Some((_, m)) = mechanism.as_ref().filter(|(k, _)| *k == r.key) else {
            continue;
        };
        let class = r.label;
        *s.counts.entry((class.clone(), m.clone())).or_insert(0) += 1;
        if matches!(
            crate::model::Mechanism::parse(m),
            Some(crate::model::Mechanism::BondFailure | crate::model::Mechanism::FibreFailure)
        ) {
            s.bond_fibre_total += 1;
            if &class == m {
                s.bond_fibre_correct += 1;
            }
        }
    }
    Ok(s)
}

/// Both scores of a run given a truth table: the SOM's classes (with a SOM stage) and the
/// events and locations (with an events table). `aepipe run` and `aepipe report` alike.
pub(super) fn scores(
    truth: Option<&Path>,
    som: Option<&SomStage>,
    features: &RunReport,
    cfg: &ValidConfig,
) -> Result<(Option<TruthScore>, Option<crate::report::SourceScore>), WorkflowError> {
    let Some(truth) = truth else {
        return Ok((None, None));
    };
    let classes = match som {
        Some(s) => Some(score_truth(truth, &s.classification)?),
        None => None,
    };
    let sources = if features.events_path.is_file() {
        score_sources(
            truth,
            &features.table_path,
            &features.events_path,
            cfg.source_rows(),
        )?
    } else {
        None
    };
    Ok((classes, sources))
}

/// Score the events and their locations against the truth's sources: which aepipe events
/// hold which sources' hits (through `features.parquet`'s `event`), how far each located
/// specimen event lies from its source, and which sources the zone and guards keep out of
/// the counts.
pub(super) fn score_sources(
    truth: &Path,
    features: &Path,
    events: &Path,
    rows: crate::store::SourceRows,
) -> Result<Option<crate::report::SourceScore>, WorkflowError> {
    let Some(sources) = truth_sources(truth)? else {
        return Ok(None);
    };
    let hit = feature_hits(features, rows)?;
    let event = event_sizes(events)?;
    let mut s = crate::report::SourceScore {
        sources: sources.len(),
        events: event.len(),
        ..Default::default()
    };
    let mut errors = Vec::new();
    for ((exp, _), (x_true, kind, hits)) in &sources {
        let specimen = kind == "specimen";
        if specimen {
            s.specimen += 1;
        } else {
            s.grip += 1;
        }
        let of: Vec<(Option<i64>, bool)> =
            hits.iter().filter_map(|k| hit.get(k).copied()).collect();
        let counted = of.iter().any(|(_, c)| *c);
        match (specimen, counted) {
            (true, false) => s.specimen_lost += 1,
            (false, false) => s.grip_removed += 1,
            _ => {}
        }
        let evs: std::collections::BTreeSet<Option<i64>> = of.iter().map(|(e, _)| *e).collect();
        if let [Some(ev)] = evs.into_iter().collect::<Vec<_>>()[..] {
            if let Some((x, n)) = event.get(&(exp.clone(), ev)) {
                if *n == hits.len() {
                    s.found += 1;
                    if let (true, Some(x), Some(xt)) = (specimen, x, x_true) {
                        errors.push((x - xt).abs());
                    }
                }
            }
        }
    }
    errors.sort_by(f64::total_cmp);
    s.located = errors.len();
    let q = |p: f64| {
        (!errors.is_empty()).then(|| errors[((errors.len() - 1) as f64 * p).round() as usize])
    };
    s.median_error_m = q(0.5);
    s.p90_error_m = q(0.9);
    Ok(Some(s))
}

/// Source → (x, kind, its hits).
/// (experiment, source) → (source_x_m, source_kind, its hits)
type Truths = BTreeMap<(String, i64), (Option<f64>, String, Vec<HitKey>)>;

/// The truth's sources with their position, kind and hits; None when the truth table has
/// no source columns (nothing to score the events against).
fn truth_sources(truth: &Path) -> Result<Option<Truths>, WorkflowError> {
    let t = TableScan::open(truth)?;
    if t.require(
        &[
            cols::EVENT.name,
            cols::SOURCE_X_M.name,
            cols::SOURCE_KIND.name,
        ],
        "",
    )
    .is_err()
    {
        return Ok(None);
    }
    let df = t.columns(&[
        cols::EXPERIMENT.name,
        cols::CHANNEL.name,
        cols::HIT.name,
        cols::EVENT.name,
        cols::SOURCE_X_M.name,
        cols::SOURCE_KIND.name,
    ])?;
    let keys = t.hit_keys(&df)?;
    let src = t.i64s(&df, cols::EVENT)?;
    let sx = t.floats(&df, cols::SOURCE_X_M)?;
    let kind = t.texts(&df, cols::SOURCE_KIND)?;
    let mut sources: Truths = BTreeMap::new();
    for (i, k) in keys.into_iter().enumerate() {
        let id = (k.0.clone(), src[i].unwrap_or(0));
        let e = sources
            .entry(id)
            .or_insert_with(|| (sx[i], kind[i].clone().unwrap_or_default(), Vec::new()));
        e.2.push(k);
    }
    Ok(Some(sources))
}

/// Each hit of `features.parquet`: its aepipe event and whether it counts (`rows`), to
/// follow a source's hits into the events.
fn feature_hits(
    features: &Path,
    rows: crate::store::SourceRows,
) -> Result<BTreeMap<HitKey, (Option<i64>, bool)>, WorkflowError> {
    let f = TableScan::open(features)?;
    f.require(
        &[cols::EVENT.name, cols::EVENT_FIRST.name, cols::ZONE.name],
        "",
    )?;
    let df = f.columns(&[
        cols::EXPERIMENT.name,
        cols::CHANNEL.name,
        cols::HIT.name,
        cols::EVENT.name,
        cols::EVENT_FIRST.name,
        cols::ZONE.name,
    ])?;
    let fk = f.hit_keys(&df)?;
    let fev = f.i64s(&df, cols::EVENT)?;
    let counts = f.counted(&df, rows)?;
    Ok(fk
        .into_iter()
        .enumerate()
        .map(|(i, k)| (k, (fev[i], counts[i])))
        .collect())
}

/// (experiment, event) → (x_m, n_hits)
type EventSizes = BTreeMap<(String, i64), (Option<f64>, usize)>;

/// Each event of `events.parquet` by (experiment, event): its position and number of hits,
/// to tell whether it holds exactly one source's hits and where it was located.
fn event_sizes(events: &Path) -> Result<EventSizes, WorkflowError> {
    let e = TableScan::open(events)?;
    let df = e.columns(&[
        cols::EXPERIMENT.name,
        cols::EVENT.name,
        cols::X_M.name,
        cols::N_HITS.name,
    ])?;
    let eexp = e.texts(&df, cols::EXPERIMENT)?;
    let eev = e.i64s(&df, cols::EVENT)?;
    let ex = e.floats(&df, cols::X_M)?;
    let en = e.i32s(&df, cols::N_HITS)?;
    Ok((0..df.height())
        .map(|i| {
            (
                (eexp[i].clone().unwrap_or_default(), eev[i].unwrap_or(0)),
                (ex[i], en[i].unwrap_or(0) as usize),
            )
        })
        .collect())
}
