//! The labelled reference library: the simulator run over a grid of scenarios (bond
//! failures at different kinks and stretches, fibre failures at every break point, fibre
//! material varied within Table 4.1's spread, sensors at several distances), in parallel,
//! into one `waveforms.parquet`.

use super::model::SensorSpec;
use super::scenario::{self, Params};
use super::{output, simulate, SimError, SimOptions};
use crate::model::columns as cols;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// `pipelines/reference-library.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReferenceFile {
    pub reference: ReferenceConfig,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReferenceConfig {
    /// Seed of the material draws.
    #[serde(default = "seed")]
    pub seed: u64,
    /// Material draws per grid point: E, t and w each scaled uniformly within
    /// ±`material_spread` (ch. 4.4 uses ±10 % of Table 4.1).
    #[serde(default = "one")]
    pub variants: usize,
    #[serde(default = "spread")]
    pub material_spread: f64,
    /// Sensor cells replacing each scenario's own (on the 250 × 250 grid of 72 µm cells,
    /// (125, 100) is 1.8 mm below the centre).
    #[serde(default)]
    pub sensors: Vec<[usize; 2]>,
    /// Volts per pascal of the written samples.
    #[serde(default = "scale")]
    pub scale_v_per_pa: f64,
    /// The simulated AE system's trigger threshold and noise, dB_AE, and its pretrigger,
    /// samples (see [`output::Acquisition`]; the noise is seeded with `seed`).
    #[serde(default = "threshold_db")]
    pub threshold_db: f64,
    #[serde(default = "noise_db")]
    pub noise_db: f64,
    #[serde(default = "pretrigger")]
    pub pretrigger: usize,
    /// The fibres' material (none: Table 4.1's paper fibre); the material draws scale it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub material: Option<super::material::Material>,
    pub scenario: Vec<ScenarioGrid>,
}

impl ReferenceConfig {
    /// How the library's sensors record.
    pub fn acquisition(&self) -> output::Acquisition {
        output::Acquisition {
            scale_v_per_pa: self.scale_v_per_pa,
            threshold_db: self.threshold_db,
            noise_db: self.noise_db,
            pretrigger: self.pretrigger,
            seed: self.seed,
        }
    }
}

fn seed() -> u64 {
    2008
}
fn one() -> usize {
    1
}
fn spread() -> f64 {
    0.1
}
fn scale() -> f64 {
    output::Acquisition::default().scale_v_per_pa
}
fn threshold_db() -> f64 {
    output::Acquisition::default().threshold_db
}
fn noise_db() -> f64 {
    output::Acquisition::default().noise_db
}
fn pretrigger() -> usize {
    output::Acquisition::default().pretrigger
}

/// One scenario and the values of its parameters: every combination is run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioGrid {
    pub name: String,
    #[serde(default)]
    pub params: BTreeMap<String, Vec<f64>>,
    /// Erroneous records made from each of this scenario's simulations (ch. 5.4): run k's
    /// j-th is fault (k + j) mod 3 of triggered-before-the-front, two signals, clipped.
    #[serde(default)]
    pub erroneous: usize,
}

/// `pipelines/reference-library.toml`, embedded so that the demo and `synth-experiment` need
/// no file beside the binary.
pub const DEFAULT_TOML: &str = include_str!("../../pipelines/reference-library.toml");

/// `pipelines/reference-library-3d.toml`: the same mechanisms from the 3-D layered network,
/// embedded so that the demo can ask its map about another model's signals.
pub const LIBRARY_3D_TOML: &str = include_str!("../../pipelines/reference-library-3d.toml");

impl ReferenceFile {
    /// The 3-D library definition ([`LIBRARY_3D_TOML`]).
    pub fn library_3d() -> ReferenceFile {
        ReferenceFile::parse(
            LIBRARY_3D_TOML,
            Path::new("pipelines/reference-library-3d.toml"),
        )
        .expect("pipelines/reference-library-3d.toml is valid")
    }

    pub fn default_library() -> ReferenceFile {
        ReferenceFile::parse(DEFAULT_TOML, Path::new("pipelines/reference-library.toml"))
            .expect("pipelines/reference-library.toml is valid")
    }

    pub fn read(path: &Path) -> Result<ReferenceFile, SimError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| SimError::Read(format!("{}: {e}", path.display())))?;
        ReferenceFile::parse(&text, path)
    }

    pub fn parse(text: &str, path: &Path) -> Result<ReferenceFile, SimError> {
        let f: ReferenceFile = toml::from_str(text).map_err(|e| SimError::Parse {
            path: path.display().to_string(),
            line: e
                .span()
                .map(|s| text[..s.start].matches('\n').count() + 1)
                .unwrap_or(0),
            message: e.message().to_string(),
        })?;
        for g in &f.reference.scenario {
            if !scenario::model_names().any(|k| k == g.name) {
                return Err(SimError::Model(format!(
                    "{}: unknown scenario {:?}; known: {}",
                    path.display(),
                    g.name,
                    scenario::model_names().collect::<Vec<_>>().join(", ")
                )));
            }
        }
        if let Some(m) = &f.reference.material {
            m.check()
                .map_err(|e| SimError::Model(format!("{}: {e}", path.display())))?;
        }
        if !(0.0..0.5).contains(&f.reference.material_spread) || f.reference.variants == 0 {
            return Err(SimError::Model(format!(
                "{}: need variants ≥ 1 and 0 ≤ material_spread < 0.5",
                path.display()
            )));
        }
        Ok(f)
    }
}

/// Every run of the library: scenario name, parameters, and how many erroneous records to
/// make from it (its grid's `erroneous`).
pub fn expand(cfg: &ReferenceConfig) -> Vec<(String, Params, usize)> {
    let mut rng = crate::util::Rng::new(cfg.seed);
    let mut runs = Vec::new();
    for g in &cfg.scenario {
        let mut combos: Vec<Vec<(String, f64)>> = vec![vec![]];
        for (k, vs) in &g.params {
            combos = combos
                .into_iter()
                .flat_map(|c| {
                    vs.iter().map(move |v| {
                        let mut c = c.clone();
                        c.push((k.clone(), *v));
                        c
                    })
                })
                .collect();
        }
        for c in combos {
            for v in 0..cfg.variants {
                let mut p = c.clone();
                let mut scales: Vec<(&str, f64)> = match &cfg.material {
                    Some(m) => m.scales().to_vec(),
                    None => Vec::new(),
                };
                if v > 0 || cfg.variants > 1 {
                    let s = cfg.material_spread;
                    for key in ["e_scale", "t_scale", "w_scale"] {
                        let draw = rng.range(1.0 - s, 1.0 + s);
                        match scales.iter_mut().find(|(k, _)| *k == key) {
                            Some((_, base)) => *base *= draw,
                            None => scales.push((key, draw)),
                        }
                    }
                }
                p.extend(scales.into_iter().map(|(k, v)| (k.to_string(), v)));
                runs.push((g.name.clone(), Params(p), g.erroneous));
            }
        }
    }
    runs
}

/// The plucked paper fibre's fundamental (Table 3.8 as simulated, 1 mm at 1 %), Hz: a
/// material's fibres ring near this times [`super::material::Material::frequency_ratio`].
const PAPER_FIBRE_HZ: f64 = 243.04e3;

/// Refuse a material whose fibres ring too slowly for the run to hold three of their periods
/// (a library of silence): the rubber band's 1.5 kHz in 60 µs, say.
fn audible_in_time(
    mat: &super::material::Material,
    m: &super::model::ModelFile,
) -> Result<(), SimError> {
    let f = PAPER_FIBRE_HZ * mat.frequency_ratio();
    let dur = m.system.dt * m.system.iterations as f64;
    if f * dur < 3.0 {
        return Err(SimError::Model(format!(
            "material {:?}: its fibres ring near {:.3e} Hz (√(E/ρ) against the paper fibre's), \
             and {} runs {:.1e} s — {:.2} periods, not a signal; give the scenario \
             `iterations` for at least {:.1e} s (and a grid that resolves it)",
            mat.name,
            f,
            m.name,
            dur,
            f * dur,
            3.0 / f
        )));
    }
    Ok(())
}

/// The library's sensor cells on a scenario's grid: its own cells, or on a grid refined by
/// `grid_um` the cells holding the same points (outside: cells the model's check refuses).
pub fn library_sensors(cells: &[[usize; 2]], g: &super::model::GridSpec) -> Vec<SensorSpec> {
    cells
        .iter()
        .map(|&[i, j]| {
            let (i, j) = g.original_cell(i, j).unwrap_or((usize::MAX, usize::MAX));
            SensorSpec { i, j, k: None }
        })
        .collect()
}

/// Run the library into `out/waveforms.parquet`. Returns (runs, signals, seconds).
pub fn build_library(
    cfg: &ReferenceConfig,
    out: &Path,
    progress: bool,
) -> Result<(usize, u64, f64), SimError> {
    build_library_part(cfg, out, None, progress)
}

/// The experiment id of every signal of a reference library (and its Hive partition).
pub const LIBRARY_EXPERIMENT: &str = "reference";

/// What a library's folder holds, by name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LibraryDir(std::path::PathBuf);

impl LibraryDir {
    pub fn new(p: impl Into<std::path::PathBuf>) -> LibraryDir {
        LibraryDir(p.into())
    }
    pub fn path(&self) -> &Path {
        &self.0
    }
    /// The whole library (`aepipe reference`, `aepipe merge` of library shards).
    pub fn waveforms(&self) -> std::path::PathBuf {
        self.0.join("waveforms.parquet")
    }
    /// Shard K's signals (`waveforms/experiment=reference/part-K.parquet`).
    pub fn part(&self, k: u32) -> std::path::PathBuf {
        crate::store::shard::hive_file(&self.0, "waveforms", LIBRARY_EXPERIMENT, k)
    }
}

/// What a library shard's manifest (`shards/shard-K-of-N.json`, kind `reference_library`)
/// records besides its header (whose `keys` are the grid indices it simulated).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct LibraryShard {
    pub signals: u64,
}

fn definition_hash(cfg: &ReferenceConfig) -> String {
    let text = toml::to_string(&ReferenceFile {
        reference: cfg.clone(),
    })
    .unwrap_or_default();
    crate::util::sha256_hex(text.as_bytes())
}

/// The library, or with `shard` = K/N only the grid points whose index hashes to K (the
/// material draws are made for the whole grid first, so every point is the same in any
/// layout), written to `OUT/waveforms/experiment=reference/part-K.parquet` with
/// `OUT/shards/shard-K-of-N.json` (kind `reference_library`); [`merge_library`] joins the N.
pub fn build_library_part(
    cfg: &ReferenceConfig,
    out: &Path,
    shard: Option<crate::util::Shard>,
    progress: bool,
) -> Result<(usize, u64, f64), SimError> {
    build_library_controlled(cfg, out, shard, progress, None)
}

/// [`build_library_part`] with a caller's stop request and progress count (one per
/// simulation run): a stopped build returns [`SimError::Cancelled`] and writes nothing.
pub fn build_library_controlled(
    cfg: &ReferenceConfig,
    out: &Path,
    shard: Option<crate::util::Shard>,
    progress: bool,
    control: Option<&crate::util::JobControl>,
) -> Result<(usize, u64, f64), SimError> {
    let t0 = std::time::Instant::now();
    std::fs::create_dir_all(out).map_err(|e| SimError::Io(format!("{}: {e}", out.display())))?;
    let all = expand(cfg);
    let keep: Vec<usize> = (0..all.len())
        .filter(|k| shard.is_none_or(|s| s.owns(&k.to_string())))
        .collect();
    let runs: Vec<(usize, (String, Params, usize))> =
        keep.iter().map(|&k| (k, all[k].clone())).collect();
    let pb = if progress {
        let pb = indicatif::ProgressBar::new(runs.len() as u64);
        pb.set_style(
            indicatif::ProgressStyle::with_template(
                "simulating {bar:30} {pos}/{len} runs {elapsed}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        pb
    } else {
        indicatif::ProgressBar::hidden()
    };
    if let Some(mat) = &cfg.material {
        for (_, (name, p, _)) in &runs {
            audible_in_time(mat, &scenario::build(name, p)?)?;
        }
    }
    let results: Vec<_> = runs
        .par_iter()
        .map(|(_, (name, p, _))| {
            if control.is_some_and(|c| c.is_cancelled()) {
                return Err(SimError::Cancelled);
            }
            let mut m = scenario::build(name, p)?;
            if let (false, Some(g)) = (cfg.sensors.is_empty(), m.grid.as_ref()) {
                // The library's cells are the scenario's own grid's: on a grid refined by
                // `grid_um`, the cells holding the same points (outside: refused by check).
                m.sensors = library_sensors(&cfg.sensors, g);
                m.check()?;
            }
            m.name = LIBRARY_EXPERIMENT.into();
            let o = simulate(&m, &SimOptions::default())?;
            pb.inc(1);
            if let Some(c) = control {
                c.add(1);
            }
            Ok((m, o, format!("scenario:{name}"), p.to_json()))
        })
        .collect::<Result<Vec<_>, SimError>>()?;
    pb.finish_and_clear();
    let acq = cfg.acquisition();
    let rows: Vec<output::Run> = results
        .iter()
        .enumerate()
        .map(|(j, (m, o, src, json))| output::Run {
            model: m,
            out: o,
            source: src.clone(),
            params: json.clone(),
            hit: runs[j].0 as u64 + 1,
            acq: &acq,
            faults: (0..runs[j].1 .2)
                .map(|e| output::Fault::ALL[(runs[j].0 + e) % output::Fault::ALL.len()])
                .collect(),
        })
        .collect();
    let Some(sh) = shard else {
        let n = output::write_waveforms(&LibraryDir::new(out).waveforms(), &rows)?;
        return Ok((runs.len(), n, t0.elapsed().as_secs_f64()));
    };
    let dir = LibraryDir::new(out);
    let part = dir.part(sh.k);
    let folder = part.parent().expect("a part has a folder");
    std::fs::create_dir_all(folder)
        .map_err(|e| SimError::Io(format!("{}: {e}", folder.display())))?;
    let n = output::write_waveforms(&part, &rows)?;
    let file = crate::store::shard::published(out, &part)?;
    let m = crate::store::shard::ShardFile {
        header: crate::store::shard::ShardHeader {
            kind: crate::store::shard::ShardKind::ReferenceLibrary,
            tool_version: env!("CARGO_PKG_VERSION").into(),
            definition_sha256: definition_hash(cfg),
            k: sh.k,
            n: sh.n,
            keys: keep.iter().map(|k| k.to_string()).collect(),
            files: vec![file],
        },
        payload: LibraryShard { signals: n },
    };
    crate::store::shard::write_manifest(out, &m).map_err(|e| SimError::Io(e.to_string()))?;
    Ok((runs.len(), n, t0.elapsed().as_secs_f64()))
}

/// Join the N shards of a library in `dir` into `out` (`waveforms.parquet`), the signals in
/// grid order as `aepipe reference` writes them. Refuses (naming them) shards that are
/// missing or were made from another definition or tool version.
pub fn merge_library(dir: &Path, out: &Path) -> Result<u64, SimError> {
    let bad = |m: String| SimError::Model(format!("{}: {m}", dir.display()));
    let shards: Vec<crate::store::shard::ShardFile<LibraryShard>> =
        crate::store::shard::read_shards(dir, crate::store::shard::ShardKind::ReferenceLibrary)?;
    let first = shards[0].header.clone();
    let src = LibraryDir::new(dir);
    // Every part's rows, then in grid order (hit, channel).
    let mut batches = Vec::new();
    let mut schema = None;
    for m in &shards {
        let p = src.part(m.header.k);
        let (sch, _, b) =
            crate::store::read_parquet(&p).map_err(|e| SimError::Read(e.to_string()))?;
        schema.get_or_insert(sch);
        batches.extend(b);
    }
    let schema = schema.ok_or_else(|| bad("the shards hold no signals".into()))?;
    let joined =
        arrow::compute::concat_batches(&schema, &batches).map_err(|e| bad(e.to_string()))?;
    let key = |name: &str| -> Result<arrow::compute::SortColumn, SimError> {
        Ok(arrow::compute::SortColumn {
            values: joined
                .column_by_name(name)
                .ok_or_else(|| bad(format!("the library shards have no {name} column")))?
                .clone(),
            options: None,
        })
    };
    let order =
        arrow::compute::lexsort_to_indices(&[key(cols::HIT.name)?, key(cols::CHANNEL.name)?], None)
            .map_err(|e| bad(e.to_string()))?;
    let all = arrow::compute::take_record_batch(&joined, &order).map_err(|e| bad(e.to_string()))?;
    std::fs::create_dir_all(out).map_err(|e| SimError::Io(format!("{}: {e}", out.display())))?;
    let meta = [(
        "aepipe.config_sha256".to_string(),
        first.definition_sha256.clone(),
    )];
    let mut w = crate::store::TableWriter::create(
        &LibraryDir::new(out).waveforms(),
        output::sim_waveforms_table().schema(),
        &meta,
        256,
    )
    .map_err(|e| SimError::Io(e.to_string()))?;
    let n = w
        .push_batch(&all)
        .map_err(|e| SimError::Io(e.to_string()))?;
    w.finish().map_err(|e| SimError::Io(e.to_string()))?;
    Ok(n)
}
