//! The tables `aepipe schema` prints.

use super::*;

/// The tables whose columns `aepipe schema` prints.
pub const TABLES: &[&str] = &[
    "features",
    "waveforms",
    "rejects",
    "hits",
    "parametric",
    "markers",
    "events",
    "trend",
    "classification",
    "damage_profile",
    "evolution",
    "cycles",
    "sim_waveforms",
    "sim_trajectories",
    "sim_trajectories_3d",
    "sim_sweep",
    "sim_tension",
    "sim_energy",
    "sim_convergence",
    "truth",
    "truth_cycles",
    "clusters",
    "validity",
    "statistics",
    "series",
    "transfer",
];

/// The schema of a written table by name (one of [`TABLES`]).
pub fn table_schema(name: &str, cfg: &PipelineConfig) -> Option<crate::store::TableSchema> {
    Some(match name {
        "features" => crate::features::features_table(&cfg.dsp, cfg.crack_mode).schema(),
        "waveforms" => crate::store::waveforms_table().schema(),
        "rejects" => crate::store::rejects_table().schema(),
        "hits" => crate::store::hits_table(Default::default()).schema(),
        "parametric" => crate::store::parametric_table().schema(),
        "markers" => crate::store::markers_table().schema(),
        "events" => crate::events::events_table().schema(),
        "trend" => crate::analysis::trend::trend_table().schema(),
        "classification" => crate::som::classify::classification_table().schema(),
        "damage_profile" => crate::som::profile::profile_table().schema(),
        "evolution" => crate::analysis::evolution::evolution_table().schema(),
        "cycles" => crate::analysis::cycles::cycles_table().schema(),
        "sim_waveforms" => crate::sim::output::sim_waveforms_table().schema(),
        "sim_trajectories" => crate::sim::output::trajectory_table().schema(),
        "sim_trajectories_3d" => crate::sim::output::trajectory_table_3d().schema(),
        // The fixed columns; a sweep adds one per swept key.
        "sim_sweep" => crate::sim::sweep::SweepTable::default().schema(),
        "sim_tension" => crate::sim::output::tension_table().schema(),
        "sim_energy" => crate::sim::output::energy_table().schema(),
        "sim_convergence" => crate::sim::convergence::table().schema(),
        "truth" => crate::synth::truth_table().schema(),
        "truth_cycles" => crate::synth::loading::cycle_truth_table().schema(),
        "clusters" => crate::cluster::stage::clusters_table().schema(),
        "validity" => crate::cluster::stage::validity_table().schema(),
        "statistics" => crate::analysis::powerlaw::statistics_table().schema(),
        // The classes of the default reference map; a run has one column per class of its map.
        "series" => {
            crate::analysis::series::series_table(&crate::analysis::series::default_classes(), true)
                .schema()
        }
        "transfer" => super::transfer::transfer_table().schema(),
        _ => return None,
    })
}
