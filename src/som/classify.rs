//! Classifying every hit of feature tables with a trained map: `classification.parquet`,
//! the reading of the map's erroneous area, novelty, and the confusion report of Table 5.4.

use super::layout::ClassifyDir;
use super::novelty::NoveltyReading;
use super::settings::ReadErroneous;
use super::tables::{for_each_input, Model, Quality};
use super::SomError;
use crate::model::columns as cols;
use crate::model::{Mechanism, UNLIKE_REFERENCES};
use crate::store::{ColType, ColumnSpec, HitKey, SourceRows, Table, TableWriter, Value};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn werr(p: &Path, m: impl std::fmt::Display) -> SomError {
    SomError::Write {
        path: p.display().to_string(),
        message: m.to_string(),
    }
}

/// One classified hit: a row of `classification.parquet`.
#[derive(Debug, Clone, PartialEq)]
pub struct Classified {
    pub key: HitKey,
    pub bmu_row: usize,
    pub bmu_col: usize,
    pub bmu_distance: f64,
    /// Beyond the model's novelty threshold (`None`: the model has no calibration).
    pub novel: Option<bool>,
    pub som_label: String,
    /// The BMU's own label (what the map alone says).
    pub node_label: String,
    /// The features' quality finding (`None`: sound, or not stated).
    pub quality_fault: Option<String>,
    pub reference_label: Option<String>,
}

/// `classification.parquet`: the SOM class of every hit.
pub fn classification_table() -> Table<Classified> {
    Table::new("classification")
        .col(ColumnSpec::of(cols::EXPERIMENT, "", "experiment id"), |c: &Classified| Value::Str(Some(c.key.0.clone())))
        .col(ColumnSpec::of(cols::CHANNEL, "", "sensor channel"), |c| Value::I32(Some(c.key.1)))
        .col(ColumnSpec::of(cols::HIT, "", "hit number"), |c| Value::I64(Some(c.key.2)))
        .col(ColumnSpec::of(cols::BMU_ROW, "", "row of the best-matching unit on the map"), |c| Value::I32(Some(c.bmu_row as i32)))
        .col(ColumnSpec::of(cols::BMU_COL, "", "column of the best-matching unit"), |c| Value::I32(Some(c.bmu_col as i32)))
        .col(ColumnSpec::new("bmu_distance", ColType::Float64, "1", "Euclidean distance of the hit's vector to its BMU (in the model's, possibly standardised, units)"), |c| Value::F64(Some(c.bmu_distance)))
        .col(ColumnSpec::new("quantization_error", ColType::Float64, "1", "the hit's quantisation error (the summand of Eq. 5.4.1): its distance to its BMU, equal to bmu_distance; the novelty test reads it"), |c| Value::F64(Some(c.bmu_distance)))
        .col(ColumnSpec::new("novel", ColType::Bool, "", "quantization_error beyond the model's novelty threshold (the som.novelty_quantile conformal quantile of the distances of references held out of the map; see som::novelty): the hit is like none of the map's references and its som_label is unlike_references. Null when the model carries no calibration (a map from a .cod file, or trained on too few references)").nullable(), |c| Value::Bool(c.novel))
        .col(ColumnSpec::of(cols::SOM_LABEL, "", "the class the SOM stage assigns: unlike_references when novel; else, with som.read_erroneous = quality-check (default) on a map with an erroneous area, erroneous when quality_fault is set, else the label of the nearest node not labelled erroneous; otherwise (read_erroneous = map, or no quality_fault column in the features) node_label"), |c| Value::Str(Some(c.som_label.clone())))
        .col(ColumnSpec::of(cols::NODE_LABEL, "", "label of the BMU node: the map's own reading (ch. 5.4)"), |c| Value::Str(Some(c.node_label.clone())))
        .col(ColumnSpec::new("quality_fault", ColType::Utf8, "", "the features' time-domain quality finding (features.quality_fault); null when sound or when the features do not state it").nullable(), |c| Value::Str(c.quality_fault.clone()))
        .col(ColumnSpec::of(cols::REFERENCE_LABEL, "", "the hit's label in the reference column (e.g. criteria_label or label); null if none").nullable(), |c| Value::Str(c.reference_label.clone()))
}

/// The confusion report: for each SOM class, how its hits split over reference groups.
#[derive(Debug, Clone, Default)]
pub struct Confusion {
    /// (SOM class, reference group) → hits.
    pub counts: BTreeMap<(String, String), usize>,
    pub correct: usize,
    pub total: usize,
    /// Reference group → hits per map node (for the hit maps).
    pub hits: BTreeMap<String, Vec<f64>>,
    /// How the erroneous area was read, and what that changed.
    pub reading: Reading,
    /// The novelty threshold in force and the share of each experiment beyond it.
    pub novelty: NoveltyReading,
}

/// How [`classify_tables`] reads rows into classes (`[som] read_erroneous` and
/// `novelty_quantile`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClassifyRules {
    pub read: ReadErroneous,
    pub novelty_quantile: f64,
}

impl Default for ClassifyRules {
    /// `[som]`'s defaults: the quality-check reading, novelty at the 0.99 quantile.
    fn default() -> Self {
        ClassifyRules {
            read: ReadErroneous::default(),
            novelty_quantile: super::settings::som_defaults::NOVELTY_QUANTILE,
        }
    }
}

impl ClassifyRules {
    /// The rules of a run's `[som]`.
    pub fn of(c: &super::settings::SomConfig) -> ClassifyRules {
        ClassifyRules {
            read: c.read_erroneous,
            novelty_quantile: c.novelty_quantile,
        }
    }
}

/// What reading the map's erroneous area by the quality check did in one classification.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Reading {
    /// The reading in force: `quality-check` or `map` (the configured one, or `map` when the
    /// map has no erroneous area).
    pub rule: String,
    /// Hits the quality check called erroneous.
    pub faults: usize,
    /// Hits the map alone called erroneous and the quality check found sound (read as
    /// their nearest other class).
    pub reread: usize,
    /// Hits whose features did not state their quality (read by the map alone).
    pub unknown: usize,
}

impl Reading {
    /// One sentence for the terminal and the report.
    pub fn describe(&self) -> String {
        if self.rule != ReadErroneous::QualityCheck.as_str() {
            return "erroneous read by the map alone (the BMU's label, as the thesis)".into();
        }
        let mut s = format!(
            "erroneous read by the time-domain quality check: {} hits with a quality_fault; {} sound hits on erroneous nodes read as their nearest other node's class",
            self.faults, self.reread
        );
        if self.unknown > 0 {
            s += &format!(
                "; {} hits without quality_fault read by the map alone",
                self.unknown
            );
        }
        s
    }
}

impl Confusion {
    pub fn accuracy(&self) -> Option<f64> {
        (self.total > 0).then(|| self.correct as f64 / self.total as f64)
    }

    /// Table 5.4 orientation: rows = SOM class, columns = reference group, cells = share of
    /// the SOM class's hits (and the count), plus the overall accuracy.
    pub fn format(&self) -> String {
        let som: Vec<&String> = self
            .counts
            .keys()
            .map(|k| &k.0)
            .collect::<std::collections::BTreeSet<_>>()
            .into_iter()
            .collect();
        let refs: Vec<&String> = self
            .counts
            .keys()
            .map(|k| &k.1)
            .collect::<std::collections::BTreeSet<_>>()
            .into_iter()
            .collect();
        let mut s = format!("{:<16}", "SOM class");
        for r in &refs {
            s.push_str(&format!(" {:>18}", r));
        }
        s.push('\n');
        for c in &som {
            let n: usize = refs
                .iter()
                .map(|r| {
                    self.counts
                        .get(&((*c).clone(), (*r).clone()))
                        .copied()
                        .unwrap_or(0)
                })
                .sum();
            s.push_str(&format!("{:<16}", c));
            for r in &refs {
                let k = self
                    .counts
                    .get(&((*c).clone(), (*r).clone()))
                    .copied()
                    .unwrap_or(0);
                s.push_str(&format!(
                    " {:>10.2}% ({:>4})",
                    100.0 * k as f64 / n.max(1) as f64,
                    k
                ));
            }
            s.push('\n');
        }
        if let Some(a) = self.accuracy() {
            s.push_str(&format!(
                "overall accuracy: {}/{} = {:.2}%\n",
                self.correct,
                self.total,
                100.0 * a
            ));
        }
        s
    }
}

/// Each row's BMU and distance and, where the quality check re-reads it (`gate`, a sound
/// hit on an erroneous node), its nearest node of another class: independent per row, so
/// computed in parallel.
fn find_nodes(
    model: &Model,
    inp: &super::tables::SomInput,
    gate: bool,
) -> Vec<(usize, f64, Option<usize>)> {
    use rayon::prelude::*;
    let erroneous = Mechanism::Erroneous.as_str();
    let labels = &model.som.labels;
    let other = |j: usize| {
        labels
            .get(j)
            .is_some_and(|l| !l.is_empty() && l != erroneous)
    };
    (0..inp.keys.len())
        .into_par_iter()
        .map_init(
            || vec![0.0; inp.dim()],
            |x, i| {
                x.iter_mut().zip(inp.data.row(i)).for_each(|(a, b)| *a = *b);
                if let Some(s) = &model.scaling {
                    s.apply(x);
                }
                let (b, d, node) = model.som.classify(x);
                let reread = (gate && inp.quality[i] == Quality::Sound && node == Some(erroneous))
                    .then(|| model.som.bmu_among(x, other).map(|(j, _)| j))
                    .flatten();
                (b, d, reread)
            },
        )
        .collect()
}

/// A row's class before novelty: its node's, unless the quality check reads the map's
/// erroneous area (`gate`): a fault is erroneous, a sound hit on an erroneous node takes
/// its nearest other node's class (`reread`). Counts what it did in `reading`.
fn read_class(
    quality: &Quality,
    gate: bool,
    node: &str,
    reread: Option<usize>,
    labels: &[String],
    reading: &mut Reading,
) -> String {
    let erroneous = Mechanism::Erroneous.as_str();
    match (quality, gate) {
        (_, false) => node.to_string(),
        (Quality::Unknown, true) => {
            reading.unknown += 1;
            node.to_string()
        }
        (Quality::Fault(_), true) => {
            reading.faults += 1;
            erroneous.to_string()
        }
        (Quality::Sound, true) if node == erroneous => match reread {
            Some(j) => {
                reading.reread += 1;
                labels[j].clone()
            }
            None => node.to_string(),
        },
        (Quality::Sound, true) => node.to_string(),
    }
}

/// Classify every hit of the feature tables; write `DIR/classification.parquet`. Reads a
/// batch of rows at a time ([`for_each_input`]) and classifies its rows in parallel, so
/// memory stays bounded whatever the table's size; rows are written in file order.
pub fn classify_tables(
    model: &Model,
    paths: &[PathBuf],
    reference: Option<&str>,
    out: &Path,
    sources: SourceRows,
    rules: ClassifyRules,
) -> Result<Confusion, SomError> {
    let read = rules.read;
    let threshold = model
        .novelty
        .as_ref()
        .map(|n| n.threshold(rules.novelty_quantile));
    std::fs::create_dir_all(out).map_err(|e| werr(out, e))?;
    let path = ClassifyDir::new(out).classification();
    let table = classification_table();
    let mut w =
        TableWriter::create(&path, table.schema(), &[], 4096).map_err(|e| werr(&path, e))?;
    let erroneous = Mechanism::Erroneous.as_str();
    let labels = &model.som.labels;
    // The quality check reads the map's erroneous area only where the map has one (a map
    // labelled by experiment or channel is read as it is).
    let gate = read == ReadErroneous::QualityCheck && labels.iter().any(|l| l == erroneous);
    let mut conf = Confusion {
        reading: Reading {
            rule: if gate { read } else { ReadErroneous::Map }.as_str().into(),
            ..Default::default()
        },
        novelty: NoveltyReading {
            threshold,
            quantile: rules.novelty_quantile,
            calibrated_on: model.novelty.as_ref().map_or(0, |n| n.rows),
            per_experiment: BTreeMap::new(),
        },
        ..Default::default()
    };
    let mut rows = 0usize;
    for_each_input(paths, &model.columns, reference, sources, |inp| {
        if inp.keys.is_empty() {
            return Ok(());
        }
        if inp.dim() != model.som.dim {
            return Err(SomError::Data(format!(
                "feature dimension {} differs from the model's {}",
                inp.dim(),
                model.som.dim
            )));
        }
        rows += inp.keys.len();
        let found = find_nodes(model, &inp, gate);
        for (i, (b, d, reread)) in found.into_iter().enumerate() {
            let node = labels.get(b).map(String::as_str).unwrap_or("").to_string();
            let quality_fault = match &inp.quality[i] {
                Quality::Fault(f) => Some(f.clone()),
                _ => None,
            };
            let l = read_class(
                &inp.quality[i],
                gate,
                &node,
                reread,
                labels,
                &mut conf.reading,
            );
            // A hit like none of the references is no mechanism, whatever its node.
            let novel = threshold.map(|t| d > t);
            let l = if novel == Some(true) {
                UNLIKE_REFERENCES.to_string()
            } else {
                l
            };
            // The experiment's name is copied once, not per row.
            let per = &mut conf.novelty.per_experiment;
            if !per.contains_key(&inp.keys[i].0) {
                per.insert(inp.keys[i].0.clone(), (0, 0));
            }
            let tally = per.get_mut(&inp.keys[i].0).expect("inserted above");
            tally.0 += usize::from(novel == Some(true));
            tally.1 += 1;
            if let Some(r) = &inp.labels[i] {
                conf.hits
                    .entry(r.clone())
                    .or_insert_with(|| vec![0.0; model.som.nodes()])[b] += 1.0;
                *conf.counts.entry((l.clone(), r.clone())).or_default() += 1;
                conf.total += 1;
                if &l == r {
                    conf.correct += 1;
                }
            }
            w.push(table.row(Classified {
                key: inp.keys[i].clone(),
                bmu_row: b / model.som.cols,
                bmu_col: b % model.som.cols,
                bmu_distance: d,
                novel,
                som_label: l,
                node_label: node,
                quality_fault,
                reference_label: inp.labels[i].clone(),
            }))
            .map_err(|e| werr(&path, e))?;
        }
        Ok(())
    })?;
    if rows == 0 {
        return Err(SomError::NoUsableRows);
    }
    w.finish().map_err(|e| werr(&path, e))?;
    Ok(conf)
}
