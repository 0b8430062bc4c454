//! What the SOM's folders hold, by name: a model folder (`aepipe som train --out`, a run's
//! `som/model/`) and a classification folder (`aepipe som classify --out`, a run's `som/`).

use std::path::{Path, PathBuf};

/// A trained model's folder.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ModelDir(PathBuf);

impl ModelDir {
    pub fn new(p: impl Into<PathBuf>) -> ModelDir {
        ModelDir(p.into())
    }
    pub fn path(&self) -> &Path {
        &self.0
    }
    /// The model: map, columns, scaling, training set, node labels.
    pub fn json(&self) -> PathBuf {
        self.0.join("model.json")
    }
    /// The codebook in SOM_PAK's format.
    pub fn cod(&self) -> PathBuf {
        self.0.join("model.cod")
    }
    /// The training set in SOM_PAK's format.
    pub fn train_dat(&self) -> PathBuf {
        self.0.join("train.dat")
    }
    pub fn u_matrix(&self) -> PathBuf {
        self.0.join("u_matrix.png")
    }
}

/// A classification's folder.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ClassifyDir(PathBuf);

impl ClassifyDir {
    pub fn new(p: impl Into<PathBuf>) -> ClassifyDir {
        ClassifyDir(p.into())
    }
    pub fn path(&self) -> &Path {
        &self.0
    }
    pub fn classification(&self) -> PathBuf {
        self.0.join("classification.parquet")
    }
    pub fn hit_maps(&self) -> PathBuf {
        self.0.join("hit_maps.png")
    }
    pub fn u_matrix(&self) -> PathBuf {
        self.0.join("u_matrix.png")
    }
    pub fn damage_profile(&self) -> PathBuf {
        self.0.join("damage_profile.parquet")
    }
    /// The Fig. 6.1 picture of one experiment × channel (the id made file-safe).
    pub fn damage_profile_png(&self, experiment: &str, channel: i32) -> PathBuf {
        self.0.join(format!(
            "damage_profile_{}_ch{channel}.png",
            crate::util::file_safe(experiment)
        ))
    }
    /// The damage evolution (`analysis::evolution`).
    pub fn evolution(&self) -> PathBuf {
        self.0.join("evolution.parquet")
    }
    /// The load cycles, Felicity ratios and Kaiser flags (`analysis::cycles`).
    pub fn cycles(&self) -> PathBuf {
        self.0.join("cycles.parquet")
    }
    pub fn evolution_png(&self, experiment: &str) -> PathBuf {
        self.0.join(format!(
            "evolution_{}.png",
            crate::util::file_safe(experiment)
        ))
    }
    /// Where one experiment's events are (histogram along the strip, or x/y map).
    pub fn location_png(&self, experiment: &str) -> PathBuf {
        self.0.join(format!(
            "location_{}.png",
            crate::util::file_safe(experiment)
        ))
    }
}

/// The cache entry of a run's map: its key, and whether the run reused it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MapCache {
    pub key: String,
    pub reused: bool,
}

impl std::fmt::Display for MapCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.reused {
            true => write!(f, "cached map {}", self.key),
            false => write!(f, "map {} made and cached", self.key),
        }
    }
}
