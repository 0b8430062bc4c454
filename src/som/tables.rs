//! The SOM workflow on feature tables: inputs, the balanced training set of ch. 5.4, model
//! files, classification of every hit and the confusion report of Table 5.4.

use super::layout::{ClassifyDir, ModelDir};
use super::settings::ReadErroneous;
use super::{Init, Som, SomError, SomParams};
use crate::model::columns as cols;
use crate::model::Mechanism;
use crate::store::{ColType, ColumnSpec, HitKey, SourceRows, Table, TableScan, TableWriter, Value};
use ndarray::{Array2, ArrayView2};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Per-hit vectors read from feature tables.
#[derive(Debug, Clone)]
pub struct SomInput {
    pub keys: Vec<HitKey>,
    /// One row per kept hit.
    pub data: Array2<f64>,
    pub labels: Vec<Option<String>>,
    /// Each row's time-domain quality (`features.parquet`'s `quality_fault`).
    pub quality: Vec<Quality>,
    /// Rows left out because a feature was null or not finite (flat or empty records).
    pub skipped: usize,
}

/// A row's time-domain quality check, as its feature table states it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Quality {
    /// The table has no `quality_fault` column (written by another tool or an older aepipe).
    Unknown,
    Sound,
    /// The fault's kind (`clipped`, `two_bursts`, …).
    Fault(String),
}

impl SomInput {
    pub fn dim(&self) -> usize {
        self.data.ncols()
    }
}

fn ferr(p: &Path, m: impl std::fmt::Display) -> SomError {
    SomError::File {
        path: p.display().to_string(),
        message: m.to_string(),
    }
}

/// The store's read errors already name the file.
fn serr(e: crate::store::StoreError) -> SomError {
    match e {
        crate::store::StoreError::Read { path, message } => SomError::File { path, message },
        other => SomError::Data(other.to_string()),
    }
}

fn werr(p: &Path, m: impl std::fmt::Display) -> SomError {
    SomError::Write {
        path: p.display().to_string(),
        message: m.to_string(),
    }
}

/// `features.parquet`'s time-domain quality column, and its alias when read.
const QUALITY: &str = "quality_fault";

/// The usable rows of the tables a batch at a time ([`crate::store::read::BATCH_ROWS`] rows of a file):
/// `f` gets each batch's usable rows, in file order, so memory does not grow with the
/// table. Every batch has the same dimension (else an error naming the file).
pub fn for_each_input(
    paths: &[PathBuf],
    columns: &[String],
    label: Option<&str>,
    sources: SourceRows,
    mut f: impl FnMut(SomInput) -> Result<(), SomError>,
) -> Result<(), SomError> {
    let mut dim = None;
    for p in paths {
        let t = TableScan::open(p).map_err(serr)?.sources(sources);
        let mut need = vec![cols::EXPERIMENT.name, cols::CHANNEL.name, cols::HIT.name];
        need.extend(label);
        t.require(&need, "").map_err(serr)?;
        let names: Vec<&str> = columns.iter().map(String::as_str).collect();
        t.require(&names, "").map_err(serr)?;
        // The label may be any column, a key column included (`--label experiment`), read as
        // text; a column named twice is read once (the batch reader selects each name once).
        let mut sel: Vec<&str> = vec![cols::EXPERIMENT.name, cols::CHANNEL.name, cols::HIT.name];
        sel.extend(label);
        let has_quality = t.dtype(QUALITY).is_some();
        if has_quality {
            sel.push(QUALITY);
        }
        sel.extend(columns.iter().map(String::as_str));
        for batch in t.batches(&sel) {
            let (_, df) = batch.map_err(serr)?;
            let k = t.hit_keys(&df).map_err(serr)?;
            let l = match label {
                Some(name) => t.as_strings(&df, name).map_err(serr)?,
                None => vec![None; k.len()],
            };
            let q: Vec<Quality> = if has_quality {
                t.as_strings(&df, QUALITY)
                    .map_err(serr)?
                    .into_iter()
                    .map(|f| match f {
                        Some(f) if !f.is_empty() => Quality::Fault(f),
                        _ => Quality::Sound,
                    })
                    .collect()
            } else {
                vec![Quality::Unknown; k.len()]
            };
            let (m, keep) = t.matrix_of(&df, columns).map_err(serr)?;
            if m.nrows() > 0 {
                match dim {
                    Some(d) if d != m.ncols() => {
                        return Err(ferr(p, format!("rows of dimension {d} and {}", m.ncols())))
                    }
                    _ => dim = Some(m.ncols()),
                }
            }
            let mut input = SomInput {
                keys: Vec::with_capacity(m.nrows()),
                data: m,
                labels: Vec::with_capacity(keep.len()),
                quality: Vec::with_capacity(keep.len()),
                skipped: 0,
            };
            for (((key, lab), q), kept) in k.into_iter().zip(l).zip(q).zip(&keep) {
                if *kept {
                    input.keys.push(key);
                    input.labels.push(lab);
                    input.quality.push(q);
                } else {
                    input.skipped += 1;
                }
            }
            f(input)?;
        }
    }
    Ok(())
}

/// How the training set is drawn (ch. 5.4).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrainingSet {
    /// Share of the hits in the training set (thesis: 64 of 651 ≈ 10 %).
    pub fraction: f64,
    /// Classes left out of training (faults are not a mechanism).
    pub exclude: Vec<String>,
    /// Repeat rare classes so every class has an equal share (thesis: 4 fibre failures
    /// repeated 8 times beside 32 bond failures).
    pub balance: bool,
    pub seed: u64,
    /// After labelling the nodes with the training rows, relabel every node that wins at
    /// least one labelled input row whose class is not in `calibration_exclude` (erroneous
    /// ones included) by those rows' majority: the thesis read the map's areas with all its
    /// labelled AEs (ch. 5.4, area (4) gathered 26 of 29 erroneous ones). Nodes no
    /// calibration row reaches keep their training label. Models written before this field
    /// were labelled by their training rows only.
    #[serde(default)]
    pub calibrate: bool,
    #[serde(default)]
    pub calibration_exclude: Vec<String>,
}

impl Default for TrainingSet {
    fn default() -> Self {
        TrainingSet {
            fraction: super::defaults::FRACTION,
            exclude: [
                Mechanism::Erroneous,
                Mechanism::Unclassified,
                Mechanism::Both,
            ]
            .map(|m| m.as_str().to_string())
            .to_vec(),
            balance: true,
            seed: super::defaults::TRAINING_SEED,
            calibrate: true,
            calibration_exclude: [Mechanism::Unclassified, Mechanism::Both]
                .map(|m| m.as_str().to_string())
                .to_vec(),
        }
    }
}

/// Class → (distinct hits drawn, rows in the training set).
pub type Composition = BTreeMap<String, (usize, usize)>;

/// Indices of the training rows (with repeats when balanced) and the composition, from the
/// usable rows' labels alone (in row order): a table's training
/// set is drawn without holding its features.
pub fn draw_training_of(
    labels: &[Option<&str>],
    ts: &TrainingSet,
) -> Result<(Vec<usize>, Composition), SomError> {
    if !(ts.fraction > 0.0 && ts.fraction <= 1.0) {
        return Err(SomError::Params(format!(
            "training fraction must be in (0, 1], got {}",
            ts.fraction
        )));
    }
    let mut by_class: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
    for (i, l) in labels.iter().enumerate() {
        if let Some(l) = l {
            if !ts.exclude.iter().any(|e| e == l) {
                by_class.entry(l).or_default().push(i);
            }
        }
    }
    if by_class.is_empty() {
        return Err(SomError::Data(
            "no labelled hits to train on (after excluding erroneous/unclassified)".into(),
        ));
    }
    let total = ((ts.fraction * labels.len() as f64).round() as usize).max(by_class.len());
    let per = (total / by_class.len()).max(1);
    let n_all: usize = by_class.values().map(Vec::len).sum();
    let mut rng = crate::util::Rng::new(ts.seed);
    let mut rows = Vec::new();
    let mut comp = Composition::new();
    for (class, mut idx) in by_class {
        // Seeded Fisher–Yates shuffle: which hits of the class are drawn.
        for i in (1..idx.len()).rev() {
            let j = (rng.next_u64() % (i as u64 + 1)) as usize;
            idx.swap(i, j);
        }
        if ts.balance {
            // An equal share per class; a class with fewer hits than its share is repeated.
            let distinct = per.min(idx.len());
            rows.extend((0..per).map(|k| idx[k % distinct]));
            comp.insert(class.to_string(), (distinct, per));
        } else {
            let k = ((idx.len() as f64 / n_all as f64) * total as f64)
                .round()
                .max(1.0) as usize;
            let k = k.min(idx.len());
            rows.extend_from_slice(&idx[..k]);
            comp.insert(class.to_string(), (k, k));
        }
    }
    Ok((rows, comp))
}

/// Per-dimension mean and standard deviation (None: not standardised).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Scaling {
    pub mean: Vec<f64>,
    pub std: Vec<f64>,
}

impl Scaling {
    pub fn fit(data: ArrayView2<f64>) -> Scaling {
        let dim = data.ncols();
        let n = data.nrows().max(1) as f64;
        let mut mean = vec![0.0; dim];
        for x in data.rows() {
            for k in 0..dim {
                mean[k] += x[k] / n;
            }
        }
        let mut var = vec![0.0f64; dim];
        for x in data.rows() {
            for k in 0..dim {
                var[k] += (x[k] - mean[k]).powi(2) / n;
            }
        }
        Scaling {
            mean,
            std: var
                .into_iter()
                .map(|v| if v > 0.0 { v.sqrt() } else { 1.0 })
                .collect(),
        }
    }
    pub fn apply(&self, x: &mut [f64]) {
        for (k, v) in x.iter_mut().enumerate() {
            *v = (*v - self.mean[k % self.mean.len()]) / self.std[k % self.std.len()];
        }
    }

    /// [`Scaling::apply`] to every row of a matrix (in standard layout).
    pub fn apply_rows(&self, data: &mut Array2<f64>) {
        for mut x in data.rows_mut() {
            self.apply(x.as_slice_mut().expect("standard layout"));
        }
    }
}

/// Everything saved in `MODEL_DIR/model.json`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Model {
    pub som: Som,
    pub columns: Vec<String>,
    pub label_column: String,
    pub scaling: Option<Scaling>,
    pub training: TrainingSet,
    pub composition: Composition,
    /// Class → rows that labelled the nodes (empty: the training rows did).
    #[serde(default)]
    pub calibration: Composition,
    pub tool_version: String,
}

/// Options of `aepipe som train`.
#[derive(Debug, Clone)]
pub struct TrainOptions {
    pub columns: Vec<String>,
    pub label: String,
    pub standardise: bool,
    pub rows: usize,
    pub cols: usize,
    pub seed: u64,
    pub init: Init,
    pub training: TrainingSet,
    /// Which rows count: with events built, one hit per event (`[location] exclude_outside`
    /// also leaves out the zone's outside).
    pub sources: SourceRows,
}

impl Default for TrainOptions {
    fn default() -> Self {
        TrainOptions {
            columns: vec!["tf_bins".into()],
            label: cols::CRITERIA_LABEL.name.into(),
            standardise: false,
            rows: super::defaults::ROWS,
            cols: super::defaults::COLS,
            seed: super::defaults::SEED,
            init: Init::Samples,
            training: TrainingSet::default(),
            sources: SourceRows::default(),
        }
    }
}

/// Train a model on feature tables and write `model.json`, `model.cod` and `train.dat`.
///
/// The tables are read a batch at a time, three times: the usable rows' labels (the draw
/// needs only those), the drawn rows' features (the training set, `fraction` of the rows),
/// and, to calibrate, every labelled row once more, voting as it passes. Memory holds the
/// training set and ~30 bytes per row for the draw (a label id, the shuffled indices),
/// never the tables.
pub fn train(paths: &[PathBuf], out: &Path, o: &TrainOptions) -> Result<Model, SomError> {
    // Pass 1: every usable row's label, interned.
    let mut names: Vec<String> = Vec::new();
    let mut ids: BTreeMap<String, u32> = BTreeMap::new();
    let mut row_labels: Vec<Option<u32>> = Vec::new();
    let mut dim = 0;
    for_each_input(paths, &o.columns, Some(&o.label), o.sources, |b| {
        if !b.keys.is_empty() {
            dim = b.dim();
        }
        for l in b.labels {
            row_labels.push(l.map(|l| match ids.get(&l) {
                Some(&i) => i,
                None => {
                    let i = names.len() as u32;
                    ids.insert(l.clone(), i);
                    names.push(l);
                    i
                }
            }));
        }
        Ok(())
    })?;
    if row_labels.is_empty() {
        return Err(SomError::NoUsableRows);
    }
    let (rows, comp) = {
        let as_str: Vec<Option<&str>> = row_labels
            .iter()
            .map(|l| l.map(|i| names[i as usize].as_str()))
            .collect();
        draw_training_of(&as_str, &o.training)?
    };
    // Pass 2: the drawn rows' features, in the draw's order (a row drawn twice is twice).
    let mut wanted: Vec<(usize, usize)> =
        rows.iter().enumerate().map(|(pos, &i)| (i, pos)).collect();
    wanted.sort_unstable();
    let mut data = Array2::<f64>::zeros((rows.len(), dim));
    let (mut next, mut base) = (0usize, 0usize);
    for_each_input(paths, &o.columns, None, o.sources, |b| {
        let n = b.keys.len();
        while next < wanted.len() && wanted[next].0 < base + n {
            let (i, pos) = wanted[next];
            data.row_mut(pos).assign(&b.data.row(i - base));
            next += 1;
        }
        base += n;
        Ok(())
    })?;
    let labels: Vec<String> = rows
        .iter()
        .map(|&i| names[row_labels[i].expect("training rows are labelled") as usize].clone())
        .collect();
    let scaling = o.standardise.then(|| Scaling::fit(data.view()));
    if let Some(s) = &scaling {
        s.apply_rows(&mut data);
    }
    let params = SomParams {
        rows: o.rows,
        cols: o.cols,
        seed: o.seed,
        init: o.init.clone(),
        // The Table 5.2 stages.
        ..SomParams::default()
    }
    .check()?;
    let mut som = Som::fit(&params, data.view())?;
    som.label_nodes(data.view(), &labels)?;
    let mut calibration = Composition::new();
    if o.training.calibrate {
        // Pass 3: every labelled row not excluded votes, class-balanced, in row order.
        let counted = |i: &u32| !o.training.calibration_exclude.contains(&names[*i as usize]);
        let mut sizes: BTreeMap<String, usize> = BTreeMap::new();
        for l in row_labels.iter().flatten().filter(|i| counted(i)) {
            *sizes.entry(names[*l as usize].clone()).or_default() += 1;
        }
        for (l, n) in &sizes {
            calibration.insert(l.clone(), (*n, *n));
        }
        let mut votes = super::Votes::new(&som, sizes);
        let mut at = 0usize;
        let mut x = vec![0.0; dim];
        for_each_input(paths, &o.columns, None, o.sources, |b| {
            for r in 0..b.keys.len() {
                if let Some(l) = row_labels[at].filter(counted) {
                    x.iter_mut().zip(b.data.row(r)).for_each(|(a, v)| *a = *v);
                    if let Some(s) = &scaling {
                        s.apply(&mut x);
                    }
                    votes.add(&som, &x, &names[l as usize]);
                }
                at += 1;
            }
            Ok(())
        })?;
        som.relabel_with(votes)?;
    }
    let model = Model {
        som,
        columns: o.columns.clone(),
        label_column: o.label.clone(),
        scaling,
        training: o.training.clone(),
        composition: comp,
        calibration,
        tool_version: env!("CARGO_PKG_VERSION").into(),
    };
    save_model(&model, out, Some((data.view(), &labels)))?;
    Ok(model)
}

/// Write a model folder: `model.json` (everything `load_model` reads), `model.cod` (the
/// SOM_PAK codebook) and, when the training rows are given, `train.dat` (SOM_PAK's input
/// format, scaled as the map saw them, with their labels). The one writer of a model folder
/// (`aepipe som train`, `aepipe run`, the Python package's `Som.save`).
pub fn save_model(
    model: &Model,
    out: &Path,
    training: Option<(ArrayView2<f64>, &[String])>,
) -> Result<(), SomError> {
    std::fs::create_dir_all(out).map_err(|e| werr(out, e))?;
    let dir = ModelDir::new(out);
    let w = |p: PathBuf, text: String| {
        crate::util::write_atomic(&p, text.as_bytes()).map_err(|e| werr(&p, e))
    };
    w(dir.json(), serde_json::to_string(model).expect("json"))?;
    w(dir.cod(), model.som.to_cod())?;
    if let Some((data, labels)) = training {
        let mut dat = format!("{}\n", data.ncols());
        for (x, l) in data.rows().into_iter().zip(labels) {
            dat.push_str(
                &x.iter()
                    .map(|v| format!("{v:e}"))
                    .collect::<Vec<_>>()
                    .join(" "),
            );
            dat.push(' ');
            dat.push_str(l);
            dat.push('\n');
        }
        w(dir.train_dat(), dat)?;
    }
    Ok(())
}

/// Load a model: a model folder, its `model.json`, or a SOM_PAK codebook (`.cod`) beside a
/// `model.json`. A `.cod` replaces the map (weights, size, node labels): a codebook trained
/// or relabelled with SOM_PAK on the `train.dat` aepipe wrote classifies with aepipe's
/// columns and scaling. Everything read is checked before use.
pub fn load_model(path: &Path) -> Result<Model, SomError> {
    let is_cod = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("cod"));
    let json = if path.is_dir() {
        ModelDir::new(path).json()
    } else if is_cod {
        ModelDir::new(path.parent().unwrap_or(Path::new(""))).json()
    } else {
        path.to_path_buf()
    };
    let text = std::fs::read_to_string(&json).map_err(|e| ferr(&json, e))?;
    let mut m: Model = serde_json::from_str(&text).map_err(|e| ferr(&json, e))?;
    if is_cod {
        let cod = std::fs::read_to_string(path).map_err(|e| ferr(path, e))?;
        let som = Som::from_cod(&cod).map_err(|e| ferr(path, e))?;
        if som.labels.is_empty() {
            return Err(ferr(path, "the codebook's nodes carry no labels"));
        }
        m.som = Som {
            params: m.som.params.clone(),
            log: None,
            ..som
        };
    }
    let src = if is_cod { path } else { json.as_path() };
    m.som.check().map_err(|e| ferr(src, e))?;
    if let Some(s) = &m.scaling {
        if s.mean.len() != m.som.dim || s.std.len() != m.som.dim {
            return Err(ferr(src, "the scaling does not match the nodes' length"));
        }
        if s.std.iter().chain(&s.mean).any(|v| !v.is_finite()) || s.std.contains(&0.0) {
            return Err(ferr(src, "the scaling holds a zero or non-finite value"));
        }
    }
    Ok(m)
}

/// One classified hit: a row of `classification.parquet`.
#[derive(Debug, Clone, PartialEq)]
pub struct Classified {
    pub key: HitKey,
    pub bmu_row: usize,
    pub bmu_col: usize,
    pub bmu_distance: f64,
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
        .col(ColumnSpec::new("bmu_row", ColType::Int32, "", "row of the best-matching unit on the map"), |c| Value::I32(Some(c.bmu_row as i32)))
        .col(ColumnSpec::new("bmu_col", ColType::Int32, "", "column of the best-matching unit"), |c| Value::I32(Some(c.bmu_col as i32)))
        .col(ColumnSpec::new("bmu_distance", ColType::Float64, "1", "Euclidean distance of the hit's vector to its BMU (in the model's, possibly standardised, units)"), |c| Value::F64(Some(c.bmu_distance)))
        .col(ColumnSpec::of(cols::SOM_LABEL, "", "the class the SOM stage assigns: with som.read_erroneous = quality-check (default) on a map with an erroneous area, erroneous when quality_fault is set, else the label of the nearest node not labelled erroneous; otherwise (read_erroneous = map, or no quality_fault column in the features) node_label"), |c| Value::Str(Some(c.som_label.clone())))
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

/// Classify every hit of the feature tables; write `DIR/classification.parquet`. Reads a
/// batch of rows at a time ([`for_each_input`]) and classifies its rows in parallel, so
/// memory stays bounded whatever the table's size; rows are written in file order.
pub fn classify_tables(
    model: &Model,
    paths: &[PathBuf],
    reference: Option<&str>,
    out: &Path,
    sources: SourceRows,
    read: ReadErroneous,
) -> Result<Confusion, SomError> {
    use rayon::prelude::*;
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
    let other = |j: usize| {
        labels
            .get(j)
            .is_some_and(|l| !l.is_empty() && l != erroneous)
    };
    let mut conf = Confusion {
        reading: Reading {
            rule: if gate { read } else { ReadErroneous::Map }.as_str().into(),
            ..Default::default()
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
        // Each row's BMU (and, where the quality check re-reads it, its nearest node of
        // another class): independent per row, so computed in parallel.
        let found: Vec<(usize, f64, Option<usize>)> = (0..inp.keys.len())
            .into_par_iter()
            .map_init(
                || vec![0.0; inp.dim()],
                |x, i| {
                    x.iter_mut().zip(inp.data.row(i)).for_each(|(a, b)| *a = *b);
                    if let Some(s) = &model.scaling {
                        s.apply(x);
                    }
                    let (b, d, node) = model.som.classify(x);
                    let reread =
                        (gate && inp.quality[i] == Quality::Sound && node == Some(erroneous))
                            .then(|| model.som.bmu_among(x, other).map(|(j, _)| j))
                            .flatten();
                    (b, d, reread)
                },
            )
            .collect();
        for (i, (b, d, reread)) in found.into_iter().enumerate() {
            let node = labels.get(b).map(String::as_str).unwrap_or("").to_string();
            let quality_fault = match &inp.quality[i] {
                Quality::Fault(f) => Some(f.clone()),
                _ => None,
            };
            let l = match (&inp.quality[i], gate) {
                (_, false) => node.clone(),
                (Quality::Unknown, true) => {
                    conf.reading.unknown += 1;
                    node.clone()
                }
                (Quality::Fault(_), true) => {
                    conf.reading.faults += 1;
                    erroneous.to_string()
                }
                (Quality::Sound, true) if node == erroneous => match reread {
                    Some(j) => {
                        conf.reading.reread += 1;
                        labels[j].clone()
                    }
                    None => node.clone(),
                },
                (Quality::Sound, true) => node.clone(),
            };
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
