//! `aepipe bench transfer`: do the classes hold on a model and a sensor they were not made
//! from? Leave one model family out: for each family and each measurement chain, a map is
//! trained on the other families' reference libraries (at the libraries' own seeds, the
//! training seeds), and asked about a synthetic test made from the family left out (its
//! library simulated at an evaluation seed) and recorded through the chain. Beside the
//! map's recalls stand the ch. 4.7 criteria label's on the same hits.
//!
//! The families are the thesis's plane (the 3×3 mesh and 2×1 structure,
//! `pipelines/reference-library.toml`) and the 3-D layered network
//! (`pipelines/reference-library-3d.toml`); with two, "the other families" is the other
//! one. The chains are `pipelines/chains.toml`'s. Every library is recorded flat: the maps
//! never hear a chain, so a chain's row measures what the sensor alone does to the classes.

use super::WorkflowError;
use crate::model::Mechanism;
use crate::report::TruthScore;
use crate::sim::chain::ChainFile;
use crate::sim::reference::{LibraryDir, ReferenceConfig, ReferenceFile};
use crate::store::{ColType, ColumnSpec, Table, Value};
use std::path::{Path, PathBuf};

/// The model families, by the name the table gives them.
pub fn families() -> Vec<(&'static str, ReferenceFile)> {
    vec![
        ("plane", ReferenceFile::default_library()),
        ("3d", ReferenceFile::library_3d()),
    ]
}

/// The evaluation seeds of `aepipe bench transfer` when none are given: never used to
/// choose anything (the libraries' training seed is 2008, the demo's 2026).
pub const EVALUATION_SEEDS: [u64; 2] = [7301, 7302];

/// The tests' mechanism mix when none is given: the demo's has few fibre failures (its
/// recall would rest on a handful of hits), so a third of the sources are fibre failures.
pub const SHARES: &str = "bond_failure=0.45,fibre_failure=0.35,both=0.1,erroneous=0.1";

/// What `aepipe bench transfer` is asked.
pub struct TransferJob<'a> {
    pub out: &'a Path,
    /// Sources of each synthetic test.
    pub hits: usize,
    pub seeds: Vec<u64>,
    /// Chains by name (all of `chain_file` when empty).
    pub chains: Vec<String>,
    pub chain_file: ChainFile,
    /// Material draws per grid point of the training libraries (None: each file's own).
    pub train_variants: Option<usize>,
    /// Material draws per grid point of each test's library.
    pub test_variants: usize,
    /// The tests' mechanism mix ([`SHARES`] by default: enough fibre failures to measure
    /// their recall).
    pub shares: crate::synth::Shares,
    pub threads: usize,
    /// The reference maps' and libraries' cache (None: made anew, in a fresh `out/cache`,
    /// so that each family's map is still trained once, not once per test).
    pub cache: Option<PathBuf>,
}

/// One cell of the table: a family left out, heard through a chain, pooled over the seeds.
#[derive(Debug, Clone)]
pub struct TransferRow {
    pub family: String,
    pub chain: String,
    pub trained_on: String,
    pub seeds: String,
    /// The map's classes against the truth.
    pub map: TruthScore,
    /// The criteria label against the truth, on the same tests.
    pub criteria: TruthScore,
}

fn ratio((k, n): (usize, usize)) -> Option<f64> {
    (n > 0).then(|| k as f64 / n as f64)
}

impl TransferRow {
    pub fn novel_share(&self) -> Option<f64> {
        ratio(
            self.map
                .unlike(&[Mechanism::BondFailure, Mechanism::FibreFailure]),
        )
    }
}

/// The table `transfer.parquet` (data-schema/transfer.md).
pub fn transfer_table() -> Table<TransferRow> {
    let s = |name: &str, doc: &str| ColumnSpec::new(name, ColType::Utf8, "", doc);
    let f = |name: &str, doc: &str| ColumnSpec::new(name, ColType::Float64, "1", doc).nullable();
    let i = |name: &str, doc: &str| ColumnSpec::new(name, ColType::Int64, "hits", doc);
    let rec = |t: &TruthScore, m| Value::F64(ratio(t.recall(m)));
    Table::new("transfer")
        .col(s("family", "the model family left out: the test's signals come from it (plane: the thesis's 3×3 mesh and 2×1 structure; 3d: the layered network)"), |r: &TransferRow| Value::Str(Some(r.family.clone())))
        .col(s("chain", "the measurement chain the test was recorded through (pipelines/chains.toml)"), |r| Value::Str(Some(r.chain.clone())))
        .col(s("trained_on", "the families the map was trained on (all but the one left out), each recorded flat"), |r| Value::Str(Some(r.trained_on.clone())))
        .col(s("seeds", "the evaluation seeds pooled (each a test library's material draws and the test's own draws)"), |r| Value::Str(Some(r.seeds.clone())))
        .col(i("bond_fibre_hits", "hits whose truth is a bond or a fibre failure"), |r| Value::I64(Some((r.map.recall(Mechanism::BondFailure).1 + r.map.recall(Mechanism::FibreFailure).1) as i64)))
        .col(f("balanced_accuracy", "the map: the mean of the bond and fibre recalls"), |r| Value::F64(r.map.balanced_accuracy()))
        .col(f("bond_recall", "the map: true bond failures called bond_failure"), move |r| rec(&r.map, Mechanism::BondFailure))
        .col(f("fibre_recall", "the map: true fibre failures called fibre_failure"), move |r| rec(&r.map, Mechanism::FibreFailure))
        .col(f("erroneous_recognised", "the map: true erroneous records labelled erroneous or unlike_references"), |r| Value::F64(ratio(r.map.erroneous_recall())))
        .col(f("novel_share", "the map: share of true bond and fibre failures called unlike_references"), |r| Value::F64(r.novel_share()))
        .col(f("criteria_balanced_accuracy", "the ch. 4.7 criteria label on the same hits: the mean of its bond and fibre recalls"), |r| Value::F64(r.criteria.balanced_accuracy()))
        .col(f("criteria_bond_recall", "the criteria label: true bond failures labelled bond_failure"), move |r| rec(&r.criteria, Mechanism::BondFailure))
        .col(f("criteria_fibre_recall", "the criteria label: true fibre failures labelled fibre_failure"), move |r| rec(&r.criteria, Mechanism::FibreFailure))
}

/// Two scores of the same kind pooled.
fn pool(a: &mut TruthScore, b: TruthScore) {
    for (k, v) in b.counts {
        *a.counts.entry(k).or_insert(0) += v;
    }
    a.bond_fibre_total += b.bond_fibre_total;
    a.bond_fibre_correct += b.bond_fibre_correct;
}

/// The whole table, written to `out/transfer.parquet`; each test and run under `out/`.
pub fn transfer(job: &TransferJob) -> Result<Vec<TransferRow>, WorkflowError> {
    let input = |m: String| WorkflowError::Input {
        path: job.out.display().to_string(),
        message: m,
    };
    if job.seeds.is_empty() || job.hits == 0 || job.test_variants == 0 {
        return Err(input("at least one seed, one hit and one variant".into()));
    }
    let names: Vec<String> = if job.chains.is_empty() {
        job.chain_file
            .names()
            .iter()
            .map(|n| n.to_string())
            .collect()
    } else {
        job.chains.clone()
    };
    let chains = names
        .iter()
        .map(|n| {
            job.chain_file
                .get(n)
                .and_then(|c| c.check(crate::synth::SAMPLE_RATE_HZ))
                .map_err(|e| input(e.to_string()))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let cache = match &job.cache {
        Some(c) => c.clone(),
        None => {
            let c = job.out.join("cache");
            if c.exists() {
                std::fs::remove_dir_all(&c).map_err(|e| input(format!("{}: {e}", c.display())))?;
            }
            c
        }
    };
    let fams = families();
    // Each family's training library, simulated (or copied from the cache) once.
    let mut training: Vec<PathBuf> = Vec::new();
    for (name, f) in &fams {
        let mut def: ReferenceConfig = f.reference.clone();
        if let Some(v) = job.train_variants {
            def.variants = v;
        }
        let dir = LibraryDir::new(job.out.join("libraries").join(name));
        super::mapcache::library(Some(&cache), &def, &dir, false)?;
        training.push(dir.waveforms());
    }
    let mut rows = Vec::new();
    for (k, (name, f)) in fams.iter().enumerate() {
        let others: Vec<usize> = (0..fams.len()).filter(|&j| j != k).collect();
        // With two families, the other one's library is the training set.
        let [other] = others[..] else {
            return Err(input(
                "leaving one out of more than two families is not built".into(),
            ));
        };
        let cell_dir = job.out.join(format!("{name}-left-out"));
        let mut cells: Vec<(TruthScore, TruthScore)> = Vec::new();
        for &seed in &job.seeds {
            let mut def = f.reference.clone();
            def.seed = seed;
            def.variants = job.test_variants;
            let lib = LibraryDir::new(cell_dir.join(format!("library-{seed}")));
            super::mapcache::library(Some(&cache), &def, &lib, false)?;
            for (c, chain) in chains.iter().enumerate() {
                let test = cell_dir.join(format!("{}-{seed}", chain.name));
                crate::synth::synth_test_through(
                    &test,
                    &format!("{name}_{}_{seed}", chain.name.replace('-', "_")),
                    job.hits,
                    seed,
                    crate::synth::Shape {
                        shares: job.shares,
                        ..Default::default()
                    },
                    Some(&lib.waveforms()),
                    Some(chain),
                    false,
                )?;
                let (map, criteria) = score(job, &cache, &test, &training[other])?;
                match cells.get_mut(c) {
                    Some((m, cr)) => {
                        pool(m, map);
                        pool(cr, criteria);
                    }
                    None => cells.push((map, criteria)),
                }
            }
        }
        for (chain, (map, criteria)) in chains.iter().zip(cells) {
            rows.push(TransferRow {
                family: name.to_string(),
                chain: chain.name.clone(),
                trained_on: fams[other].0.to_string(),
                seeds: job
                    .seeds
                    .iter()
                    .map(|s| s.to_string())
                    .collect::<Vec<_>>()
                    .join(","),
                map,
                criteria,
            });
        }
    }
    let path = job.out.join("transfer.parquet");
    let meta = [(
        "aepipe.config_sha256".to_string(),
        settings_digest(job, &names),
    )];
    transfer_table()
        .write_all(&path, &meta, 1024, rows.iter().cloned())
        .map_err(|e| input(e.to_string()))?;
    Ok(rows)
}

/// What the table depends on, hashed (the role a pipeline's configuration hash plays for
/// the other tables): the demo pipeline the tests run through, the families' library
/// definitions, the chains as defined, and the job's sizes, seeds and mix.
fn settings_digest(job: &TransferJob, chains: &[String]) -> String {
    let mut text = crate::synth::demo_config().hash();
    for (name, f) in families() {
        text += &format!("|{name}:{:?}", f.reference);
    }
    for c in chains {
        text += &format!("|{:?}", job.chain_file.get(c).ok());
    }
    text += &format!(
        "|{} {:?} {:?} {} {}",
        job.hits, job.seeds, job.train_variants, job.test_variants, job.shares
    );
    crate::util::sha256_hex(text.as_bytes())
}

/// The demo's pipeline on `test` with a map trained on `library`: the map's and the
/// criteria label's scores against the test's truth.
fn score(
    job: &TransferJob,
    cache: &Path,
    test: &Path,
    library: &Path,
) -> Result<(TruthScore, TruthScore), WorkflowError> {
    let mut cfg = crate::synth::demo_config().into_inner();
    cfg.som.reference_library = Some(library.to_path_buf());
    cfg.report.enabled = false;
    let cfg = cfg.check()?;
    let truth = test.join("truth.parquet");
    let data = test.join("data");
    let run = super::run(&super::RunJob {
        truth: Some(&truth),
        progress: false,
        cache: Some(cache.to_path_buf()),
        ..super::RunJob::new(
            &cfg,
            std::slice::from_ref(&data),
            &test.join("run"),
            job.threads,
        )
    })?;
    let map = run.truth.ok_or_else(|| WorkflowError::Input {
        path: truth.display().to_string(),
        message: "the run scored no hit against the truth".into(),
    })?;
    // The criteria label on the hits the map classified (the events' first hits in the
    // zone), so that both are scored on the same hits.
    let classification = run.som.as_ref().map(|s| s.classification.clone());
    let criteria = super::truth::score_labels(
        &truth,
        &run.features.table_path,
        crate::model::columns::CRITERIA_LABEL.name,
        classification.as_deref(),
    )?;
    Ok((map, criteria))
}

/// The table as the terminal shows it.
pub fn format(rows: &[TransferRow]) -> String {
    let pct = |v: Option<f64>| v.map_or("—".into(), |v| format!("{:.1} %", 100.0 * v));
    let rec = |t: &TruthScore, m| {
        let (k, n) = t.recall(m);
        format!("{k}/{n}")
    };
    let mut s = String::from(
        "left out  chain           trained on  map: balanced  bond      fibre    erroneous  novel    criteria: balanced  bond      fibre\n",
    );
    for r in rows {
        let (ek, en) = r.map.erroneous_recall();
        s += &format!(
            "{:<9} {:<15} {:<11} {:>14}  {:<9} {:<8} {:<10} {:<8} {:>19}  {:<9} {}\n",
            r.family,
            r.chain,
            r.trained_on,
            pct(r.map.balanced_accuracy()),
            rec(&r.map, Mechanism::BondFailure),
            rec(&r.map, Mechanism::FibreFailure),
            format!("{ek}/{en}"),
            pct(r.novel_share()),
            pct(r.criteria.balanced_accuracy()),
            rec(&r.criteria, Mechanism::BondFailure),
            rec(&r.criteria, Mechanism::FibreFailure),
        );
    }
    s
}
