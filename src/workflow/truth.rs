//! Scoring the SOM's classes against a synthetic experiment's ground truth.

use super::*;

/// Compare the SOM classes with `truth.parquet`.
pub fn score_truth(truth: &Path, classification: &Path) -> Result<TruthScore, WorkflowError> {
    let t: BTreeMap<_, _> = TableScan::open(truth)?
        .keyed_strings("mechanism")?
        .into_iter()
        .collect();
    let mut s = TruthScore {
        path: truth.to_path_buf(),
        counts: BTreeMap::new(),
        bond_fibre_total: 0,
        bond_fibre_correct: 0,
    };
    for (key, class) in TableScan::open(classification)?.keyed_strings("som_label")? {
        let Some(m) = t.get(&key) else { continue };
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
