//! A fibre material for the reference library (§6.2: "different well defined paper types …
//! cloth"): Young's modulus, section, Poisson's ratio and density, applied to the thesis's
//! structures as scale factors of Table 4.1's paper fibre (the scenarios' `e_scale`,
//! `t_scale`, `w_scale`, `rho_scale` and `nu`). Presets with their sources are in
//! `pipelines/materials/`.

use super::parts::{FIBRE_E, FIBRE_NU, FIBRE_RHO, FIBRE_T, FIBRE_W};
use super::SimError;
use serde::{Deserialize, Serialize};

/// `[reference.material]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// What it is, for the reader.
    pub name: String,
    /// Where the values come from.
    pub source: String,
    pub youngs_pa: f64,
    /// The fibre's section in the model's plane: thickness and width, m.
    pub thickness_m: f64,
    pub width_m: f64,
    pub poisson: f64,
    pub density_kg_m3: f64,
}

impl Material {
    /// Table 4.1's paper fibre, the thesis's material.
    pub fn thesis_paper() -> Material {
        Material {
            name: "paper fibre (thesis, Table 4.1)".into(),
            source: "thesis Table 4.1".into(),
            youngs_pa: FIBRE_E,
            thickness_m: FIBRE_T,
            width_m: FIBRE_W,
            poisson: FIBRE_NU,
            density_kg_m3: FIBRE_RHO,
        }
    }

    /// Every value finite and in its physical range.
    pub fn check(&self) -> Result<(), SimError> {
        let bad = |w: String| SimError::Model(format!("material {:?}: {w}", self.name));
        for (k, v) in [
            ("youngs_pa", self.youngs_pa),
            ("thickness_m", self.thickness_m),
            ("width_m", self.width_m),
            ("density_kg_m3", self.density_kg_m3),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(bad(format!("{k} must be > 0, got {v}")));
            }
        }
        if !(self.poisson.is_finite() && (0.0..0.5).contains(&self.poisson)) {
            return Err(bad(format!(
                "poisson must be in [0, 0.5), got {}",
                self.poisson
            )));
        }
        Ok(())
    }

    /// The scenario parameters that make Table 4.1's fibre this material.
    pub fn scales(&self) -> [(&'static str, f64); 5] {
        [
            ("e_scale", self.youngs_pa / FIBRE_E),
            ("t_scale", self.thickness_m / FIBRE_T),
            ("w_scale", self.width_m / FIBRE_W),
            ("rho_scale", self.density_kg_m3 / FIBRE_RHO),
            ("nu", self.poisson),
        ]
    }

    /// The plucked fibre's fundamental relative to the paper fibre's: √((E/ρ)/(E₀/ρ₀)) at the
    /// same strain and length (the tension E·A·ε over the mass ρ·A·L: the section cancels).
    pub fn frequency_ratio(&self) -> f64 {
        ((self.youngs_pa / self.density_kg_m3) / (FIBRE_E / FIBRE_RHO)).sqrt()
    }
}
