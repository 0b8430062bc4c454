//! What an export holds per transient: the columns (name, unit, meaning) and each feature
//! row's values, joined from the run's tables by (experiment, channel, hit).
//!
//! VisualAE colours and filters by numbers, so a class is written as a code whose meaning
//! the column's description spells out (`1 = bond_failure; 2 = fibre_failure; …`), the same
//! codes in every file of a run.

use crate::model::columns as cols;
use crate::model::{Mechanism, UNLIKE_REFERENCES};
use crate::store::read::{HitKey, TableScan};
use crate::store::StoreError;
use std::collections::{BTreeSet, HashMap};
use std::path::Path;

/// One column of an export and its field info.
#[derive(Debug, Clone, PartialEq)]
pub struct Column {
    pub field: String,
    /// VisualAE's unit text, in brackets (`[kHz]`), empty for none.
    pub unit: String,
    pub long_name: String,
    pub description: String,
    /// `#` for counts and codes (VisualAE's format for integers), else none.
    pub integer: bool,
}

fn col(field: &str, unit: &str, long_name: &str, description: &str, integer: bool) -> Column {
    Column {
        field: field.to_string(),
        unit: unit.to_string(),
        long_name: long_name.to_string(),
        description: description.to_string(),
        integer,
    }
}

/// The power ratios' columns of a features table, in band order (Eq. 4.5.4): every
/// `pr_<lo>_<hi>khz` column it has, so the bands are the ones the run's `[dsp] band_hz` made
/// (`dsp::spectrum::band_column`), never assumed.
pub(super) fn power_ratio_names(columns: &[String]) -> Vec<String> {
    columns
        .iter()
        .filter(|c| band_of(c).is_some())
        .cloned()
        .collect()
}

/// A power-ratio column's band, in kHz as its name gives it (`pr_250_500khz` → "250",
/// "500"; `pr_62p5_125khz` → "62.5", "125").
fn band_of(name: &str) -> Option<(String, String)> {
    let (lo, hi) = name
        .strip_prefix("pr_")?
        .strip_suffix("khz")?
        .split_once('_')?;
    let num = |s: &str| {
        let v = s.replace('p', ".");
        v.parse::<f64>().is_ok().then_some(v)
    };
    Some((num(lo)?, num(hi)?))
}

/// A hit's SOM results.
#[derive(Debug, Clone, Default)]
struct Classified {
    som: Option<String>,
    node: Option<String>,
    novel: Option<bool>,
    qe: Option<f64>,
}

/// How one column's value comes from the run's results and a features row.
type ValueOf = Box<dyn Fn(&Results, &HitKey, &FeatureRow) -> Option<f64> + Send + Sync>;

/// One column of an export, declared once: its field info and where its value comes from.
pub(super) struct Field {
    pub column: Column,
    value: ValueOf,
}

/// The run's results other than the features, by hit, and the export's columns.
pub struct Results {
    classes: Option<HashMap<HitKey, Classified>>,
    clusters: Option<HashMap<HitKey, i32>>,
    /// (experiment, event) → source position, m.
    places: Option<crate::events::table::Places>,
    /// Class name → code (1…).
    codes: HashMap<String, i64>,
    pub(super) fields: Vec<Field>,
}

const CRACK: [&str; 2] = ["tensile", "shear"];
const ZONES: [&str; 3] = ["inside", "outside", "guard"];

fn legend(names: &[&str]) -> String {
    names
        .iter()
        .enumerate()
        .map(|(k, n)| format!("{} = {n}", k + 1))
        .collect::<Vec<_>>()
        .join("; ")
}

fn code_of(names: &[&str], v: Option<&str>) -> Option<f64> {
    let v = v?;
    names.iter().position(|n| *n == v).map(|k| k as f64 + 1.0)
}

impl Results {
    /// Read the classification, cluster and event tables that exist; `ratios`: the features
    /// table's power-ratio columns ([`power_ratio_names`]).
    pub fn read(
        classification: Option<&Path>,
        clusters: Option<&Path>,
        events: Option<&Path>,
        ratios: &[String],
    ) -> Result<Results, StoreError> {
        let classes = classification.map(read_classes).transpose()?;
        let clusters = clusters.map(read_clusters).transpose()?;
        let places = events.map(crate::events::table::read_places).transpose()?;
        // Codes: the mechanisms in their order, then "unlike the references", then any
        // other label a map was trained on, sorted.
        let mut names: Vec<String> = Mechanism::ALL.iter().map(|m| m.to_string()).collect();
        names.push(UNLIKE_REFERENCES.to_string());
        let others: BTreeSet<String> = classes
            .iter()
            .flat_map(|c| c.values())
            .flat_map(|c| [c.som.clone(), c.node.clone()])
            .flatten()
            .filter(|n| !names.contains(n))
            .collect();
        names.extend(others);
        let codes: HashMap<String, i64> = names
            .iter()
            .enumerate()
            .map(|(k, n)| (n.clone(), k as i64 + 1))
            .collect();
        let class_legend = legend(&names.iter().map(String::as_str).collect::<Vec<_>>());
        let has = (classes.is_some(), clusters.is_some(), places.is_some());
        Ok(Results {
            classes,
            clusters,
            places,
            codes,
            fields: fields(has, &class_legend, ratios),
        })
    }

    /// The export's columns, in order.
    pub fn columns(&self) -> impl Iterator<Item = &Column> {
        self.fields.iter().map(|f| &f.column)
    }

    /// The values of the columns for one feature row (`f`: its features, by column).
    pub(super) fn values(&self, key: &HitKey, f: &FeatureRow) -> Vec<Option<f64>> {
        self.fields
            .iter()
            .map(|c| (c.value)(self, key, f))
            .collect()
    }

    fn class(&self, key: &HitKey) -> Classified {
        self.classes
            .as_ref()
            .and_then(|c| c.get(key).cloned())
            .unwrap_or_default()
    }

    fn code(&self, name: &Option<String>) -> Option<f64> {
        name.as_ref()
            .and_then(|n| self.codes.get(n))
            .map(|c| *c as f64)
    }

    /// The source position (m) of the row's event.
    fn place(&self, key: &HitKey, f: &FeatureRow) -> Option<(Option<f64>, Option<f64>)> {
        let e = f.event?;
        self.places.as_ref()?.get(&(key.0.clone(), e)).copied()
    }
}

fn field(
    column: Column,
    value: impl Fn(&Results, &HitKey, &FeatureRow) -> Option<f64> + Send + Sync + 'static,
) -> Field {
    Field {
        column,
        value: Box::new(value),
    }
}

/// The export's columns, each with its value: the SOM's, the clusters' and the locations'
/// where those tables are (`has`), the rest always, then one per power-ratio band.
fn fields(has: (bool, bool, bool), class_legend: &str, ratios: &[String]) -> Vec<Field> {
    let mut out = Vec::new();
    if has.0 {
        out.extend(som_fields(class_legend));
    }
    if has.1 {
        out.push(field(
            col(
                "Cluster",
                "",
                "aepipe cluster",
                "the hit's cluster (clusters.parquet cluster, 0-based)",
                true,
            ),
            |r, k, _| {
                r.clusters
                    .as_ref()
                    .and_then(|c| c.get(k))
                    .map(|c| *c as f64)
            },
        ));
    }
    out.extend(hit_fields());
    if has.2 {
        out.extend([
            field(
                col(
                    "X",
                    "[mm]",
                    "aepipe location x",
                    "the event's source x (events.parquet x_m, in mm)",
                    false,
                ),
                |r, k, f| r.place(k, f).and_then(|p| p.0).map(|x| x * 1e3),
            ),
            field(
                col(
                    "Y",
                    "[mm]",
                    "aepipe location y",
                    "the event's source y (events.parquet y_m, in mm)",
                    false,
                ),
                |r, k, f| r.place(k, f).and_then(|p| p.1).map(|y| y * 1e3),
            ),
        ]);
    }
    for (k, name) in ratios.iter().enumerate() {
        let (lo, hi) = band_of(name).unwrap_or_default();
        out.push(field(
            col(
                &format!("PR{:02}", k + 1),
                "[1]",
                &format!("Power ratio {lo}-{hi} kHz"),
                &format!("{name}: power in the band over the total (Eq. 4.5.4), a fraction"),
                false,
            ),
            move |_, _, f| f.ratios.get(k).copied().flatten(),
        ));
    }
    out
}

/// The SOM stage's columns (classes as codes of `class_legend`).
fn som_fields(class_legend: &str) -> [Field; 4] {
    [
        field(
            col(
                "SOM_Class",
                "",
                "aepipe SOM class",
                &format!("the SOM stage's class (som_label): {class_legend}"),
                true,
            ),
            |r, k, _| r.code(&r.class(k).som),
        ),
        field(
            col(
                "SOM_Node",
                "",
                "aepipe SOM node class",
                &format!("the class of the hit's best-matching node (node_label): {class_legend}"),
                true,
            ),
            |r, k, _| r.code(&r.class(k).node),
        ),
        field(
            col(
                "Novel",
                "",
                "aepipe unlike the references",
                "1: farther from the map than its novelty threshold (novel); 0: not",
                true,
            ),
            |r, k, _| r.class(k).novel.map(|b| b as i64 as f64),
        ),
        field(
            col(
                "QE",
                "",
                "aepipe quantization error",
                "distance to the best-matching node (quantization_error, Eq. 5.4.1)",
                false,
            ),
            |r, k, _| r.class(k).qe,
        ),
    ]
}

/// The columns every export has: the criteria label, crack mode, RA, AF, event and zone.
fn hit_fields() -> [Field; 6] {
    let mech = Mechanism::ALL.map(Mechanism::as_str);
    [
        field(
            col(
                "Criteria",
                "",
                "aepipe ch. 4.7 label",
                &format!("criteria_label: {}", legend(&mech)),
                true,
            ),
            move |_, _, f| code_of(&mech, f.criteria.as_deref()),
        ),
        field(
            col(
                "CrackMode",
                "",
                "aepipe RA-AF crack mode",
                &format!("crack_mode: {}", legend(&CRACK)),
                true,
            ),
            |_, _, f| code_of(&CRACK, f.crack.as_deref()),
        ),
        field(
            col(
                "RA",
                "[ms/V]",
                "RA value",
                "rise time over peak amplitude (ra_ms_per_v)",
                false,
            ),
            |_, _, f| f.ra,
        ),
        field(
            col(
                "AF",
                "[kHz]",
                "Average frequency",
                "counts over duration (af_khz)",
                false,
            ),
            |_, _, f| f.af,
        ),
        field(
            col(
                "Event",
                "",
                "aepipe event",
                "1-based event of the experiment (event)",
                true,
            ),
            |_, _, f| f.event.map(|e| e as f64),
        ),
        field(
            col(
                "Zone",
                "",
                "aepipe zone",
                &format!("zone: {}", legend(&ZONES)),
                true,
            ),
            |_, _, f| code_of(&ZONES, f.zone.as_deref()),
        ),
    ]
}

/// What an export takes from one features row.
#[derive(Debug, Clone, Default)]
pub(super) struct FeatureRow {
    pub source_file: String,
    pub criteria: Option<String>,
    pub crack: Option<String>,
    pub ra: Option<f64>,
    pub af: Option<f64>,
    pub event: Option<i64>,
    pub zone: Option<String>,
    pub ratios: Vec<Option<f64>>,
}

fn read_classes(path: &Path) -> Result<HashMap<HitKey, Classified>, StoreError> {
    let t = TableScan::open(path)?;
    let df = t.columns(&[
        cols::EXPERIMENT.name,
        cols::CHANNEL.name,
        cols::HIT.name,
        cols::SOM_LABEL.name,
        cols::NODE_LABEL.name,
        "novel",
        "quantization_error",
    ])?;
    let keys = t.hit_keys(&df)?;
    let som = t.texts(&df, cols::SOM_LABEL)?;
    let node = t.texts(&df, cols::NODE_LABEL)?;
    let novel = t.bools(&df, "novel")?;
    let qe = t.f64s(&df, "quantization_error")?;
    Ok(keys
        .into_iter()
        .enumerate()
        .map(|(i, k)| {
            let c = Classified {
                som: som[i].clone(),
                node: node[i].clone(),
                novel: novel[i],
                qe: qe[i],
            };
            (k, c)
        })
        .collect())
}

fn read_clusters(path: &Path) -> Result<HashMap<HitKey, i32>, StoreError> {
    let t = TableScan::open(path)?;
    let df = t.columns(&[
        cols::EXPERIMENT.name,
        cols::CHANNEL.name,
        cols::HIT.name,
        "cluster",
    ])?;
    let keys = t.hit_keys(&df)?;
    let c = t.f64s(&df, "cluster")?;
    Ok(keys
        .into_iter()
        .zip(c)
        .filter_map(|(k, c)| Some((k, c? as i32)))
        .collect())
}
