//! The labelled reference library: the simulator run over a grid of scenarios (bond
//! failures at different kinks and stretches, fibre failures at every break point, fibre
//! material varied within Table 4.1's spread, sensors at several distances), in parallel,
//! into one `waveforms.parquet`.

use super::model::SensorSpec;
use super::scenario::{self, Params};
use super::{output, simulate, SimError, SimOptions};
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
    pub scenario: Vec<ScenarioGrid>,
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
    1e-3
}

/// One scenario and the values of its parameters: every combination is run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScenarioGrid {
    pub name: String,
    #[serde(default)]
    pub params: BTreeMap<String, Vec<f64>>,
}

/// `pipelines/reference-library.toml`, embedded so that the demo and `synth-experiment` need
/// no file beside the binary.
pub const DEFAULT_TOML: &str = include_str!("../../pipelines/reference-library.toml");

impl ReferenceFile {
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
            if !scenario::NAMES.contains(&g.name.as_str()) {
                return Err(SimError::Model(format!(
                    "{}: unknown scenario {:?}; known: {}",
                    path.display(),
                    g.name,
                    scenario::NAMES.join(", ")
                )));
            }
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

/// Every run of the library: scenario name and parameters.
pub fn expand(cfg: &ReferenceConfig) -> Vec<(String, Params)> {
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
                if v > 0 || cfg.variants > 1 {
                    let s = cfg.material_spread;
                    for key in ["e_scale", "t_scale", "w_scale"] {
                        p.push((key.to_string(), rng.range(1.0 - s, 1.0 + s)));
                    }
                }
                runs.push((g.name.clone(), Params(p)));
            }
        }
    }
    runs
}

/// Run the library into `out/waveforms.parquet`. Returns (runs, signals, seconds).
pub fn build_library(
    cfg: &ReferenceConfig,
    out: &Path,
    progress: bool,
) -> Result<(usize, u64, f64), SimError> {
    let t0 = std::time::Instant::now();
    std::fs::create_dir_all(out).map_err(|e| SimError::Io(format!("{}: {e}", out.display())))?;
    let runs = expand(cfg);
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
    let results: Vec<_> = runs
        .par_iter()
        .map(|(name, p)| {
            let mut m = scenario::build(name, p)?;
            if !cfg.sensors.is_empty() && m.grid.is_some() {
                m.sensors = cfg
                    .sensors
                    .iter()
                    .map(|&[i, j]| SensorSpec { i, j })
                    .collect();
                m.check()?;
            }
            m.name = "reference".into();
            let o = simulate(&m, &SimOptions::default())?;
            pb.inc(1);
            Ok((m, o, format!("scenario:{name}"), p.to_json()))
        })
        .collect::<Result<Vec<_>, SimError>>()?;
    pb.finish_and_clear();
    let rows: Vec<output::Run> = results
        .iter()
        .enumerate()
        .map(|(k, (m, o, src, json))| output::Run {
            model: m,
            out: o,
            source: src.clone(),
            params: json.clone(),
            hit: k as u64 + 1,
            scale_v_per_pa: cfg.scale_v_per_pa,
        })
        .collect();
    let n = output::write_waveforms(&out.join("waveforms.parquet"), &rows)?;
    Ok((runs.len(), n, t0.elapsed().as_secs_f64()))
}
