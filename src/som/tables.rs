//! The SOM workflow on feature tables: inputs, the balanced training set of ch. 5.4, model
//! files, classification of every hit and the confusion report of Table 5.4.

use super::layout::ModelDir;
use super::{Init, Som, SomError, SomParams};
use crate::model::columns as cols;
use crate::model::Mechanism;
use crate::store::SourceRows;
use ndarray::{Array2, ArrayView2};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Per-hit vectors read from feature tables (the store's [`HitMatrix`]).
pub type SomInput = crate::store::HitMatrix;
pub use crate::store::Quality;

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

/// The usable rows of the tables a batch at a time ([`crate::store::for_each_matrix`]), the
/// reading's errors in the SOM's words.
pub fn for_each_input(
    paths: &[PathBuf],
    columns: &[String],
    label: Option<&str>,
    sources: SourceRows,
    f: impl FnMut(SomInput) -> Result<(), SomError>,
) -> Result<(), SomError> {
    crate::store::for_each_matrix(paths, columns, label, sources, serr, f)
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
        rng.shuffle(&mut idx);
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
    /// The held-out distances the novelty threshold is read from (`None`: a map written
    /// before novelty, trained on fewer than `novelty::MIN_ROWS` distinct rows, or read
    /// from a SOM_PAK codebook, which replaced the map the calibration measured).
    #[serde(default)]
    pub novelty: Option<super::novelty::Novelty>,
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
    let (mut data, group) = read_drawn(paths, o, &rows, dim)?;
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
    // Held-out distances for the novelty threshold (the same parameters and seed, fold by
    // fold; the map above is not changed by it).
    let novelty = super::novelty::Novelty::calibrate(&params, data.view(), &rows, &group, o.seed)?;
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
        novelty,
        tool_version: env!("CARGO_PKG_VERSION").into(),
    };
    save_model(&model, out, Some((data.view(), &labels)))?;
    Ok(model)
}

/// Pass 2 of [`train`]: the drawn rows' features, in the draw's order (a row drawn twice is
/// twice), and each drawn row's source, (experiment, hit) numbered: a library's sensors
/// record one simulated source each, and the novelty calibration holds a source's rows out
/// together.
fn read_drawn(
    paths: &[PathBuf],
    o: &TrainOptions,
    rows: &[usize],
    dim: usize,
) -> Result<(Array2<f64>, Vec<usize>), SomError> {
    let mut wanted: Vec<(usize, usize)> =
        rows.iter().enumerate().map(|(pos, &i)| (i, pos)).collect();
    wanted.sort_unstable();
    let mut data = Array2::<f64>::zeros((rows.len(), dim));
    let mut sources: BTreeMap<(String, i64), usize> = BTreeMap::new();
    let mut group = vec![0usize; rows.len()];
    let (mut next, mut base) = (0usize, 0usize);
    for_each_input(paths, &o.columns, None, o.sources, |b| {
        let n = b.keys.len();
        while next < wanted.len() && wanted[next].0 < base + n {
            let (i, pos) = wanted[next];
            data.row_mut(pos).assign(&b.data.row(i - base));
            let (e, _, h) = &b.keys[i - base];
            let k = sources.len();
            group[pos] = *sources.entry((e.clone(), *h)).or_insert(k);
            next += 1;
        }
        base += n;
        Ok(())
    })?;
    Ok((data, group))
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
        // The calibration measured aepipe's map, not this one.
        m.novelty = None;
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
    if let Some(n) = &m.novelty {
        n.check().map_err(|e| ferr(src, e))?;
    }
    Ok(m)
}
