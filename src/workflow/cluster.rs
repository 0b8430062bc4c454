//! The clustering stage of a run (`[cluster] enabled`), and the RA–AF pictures the report
//! shows by cluster and by SOM class.

use super::*;
use crate::model::columns as cols;
use crate::report::{ClusterStage, SomStage};
use std::collections::HashMap;

/// Points drawn in an RA–AF scatter at most (a larger table is thinned evenly; the
/// picture's caption says so).
pub const RA_AF_POINTS: usize = 20_000;

/// Cluster the run's feature rows into `dir`; draw the validity curves and the RA–AF
/// scatter by cluster (and by SOM class when the SOM ran).
pub(super) fn cluster_stage(
    cfg: &ValidConfig,
    feats: &[PathBuf],
    written: &crate::pipeline::RunReport,
    dir: &Path,
    som: Option<&SomStage>,
) -> Result<ClusterStage, WorkflowError> {
    let report =
        crate::cluster::cluster_tables(feats, dir, cfg.cluster(), cfg.source_rows(), &cfg.hash())?;
    let validity_png = dir.join("validity.png");
    crate::plot::validity_png(&validity_png, &report.validity)?;
    let slope = cfg.crack_mode.af_per_ra;
    let mut ra_af_pngs = Vec::new();
    let png = dir.join("ra_af_cluster.png");
    if ra_af_picture(
        &feats[0],
        &report.clusters,
        "cluster",
        "cluster",
        &png,
        slope,
    )? {
        ra_af_pngs.push(("RA against AF by cluster".to_string(), png));
    }
    // The SOM stage draws its own by class; the clusters' section shows it beside.
    if let Some(p) = som.and_then(|s| s.ra_af_plot.clone()) {
        ra_af_pngs.push(("RA against AF by SOM class".to_string(), p));
    }
    let views = super::cluster_views::cluster_views(cfg, feats, &report.clusters, written, dir)?;
    Ok(ClusterStage {
        report,
        validity_png,
        ra_af_pngs,
        cumulative_pngs: views.cumulative,
        distributions_png: views.distributions,
        location_pngs: views.locations,
        pictured: views.joined,
        evolution_pngs: views.evolution_plots,
        reloads: views.reloads,
    })
}

/// Draw RA against AF of the rows of `classes` coloured by `column` into `png`, with the
/// crack-mode line; false (nothing drawn) when no row has both RA and AF.
pub fn ra_af_picture(
    features: &Path,
    classes: &Path,
    column: &str,
    what: &str,
    png: &Path,
    slope: f64,
) -> Result<bool, WorkflowError> {
    let (pts, every) = ra_af_points(features, classes, column, RA_AF_POINTS)?;
    if pts.is_empty() {
        return Ok(false);
    }
    crate::plot::ra_af_png(png, &pts, slope, what, every)?;
    Ok(true)
}

/// RA, AF and class of one hit drawn in a scatter.
pub type RaAfPoint = (f64, f64, String);

/// (RA, AF, class) of the rows of `classes` (keyed by hit; class read from `column` as
/// text), every `every`-th row so that at most `max` are kept; rows without RA or AF are
/// left out.
pub fn ra_af_points(
    features: &Path,
    classes: &Path,
    column: &str,
    max: usize,
) -> Result<(Vec<RaAfPoint>, usize), WorkflowError> {
    let t = TableScan::open(classes)?;
    let every = t.file_rows().div_ceil(max.max(1)).max(1);
    let mut want: HashMap<HitKey, String> = HashMap::new();
    let sel = [
        cols::EXPERIMENT.name,
        cols::CHANNEL.name,
        cols::HIT.name,
        column,
    ];
    let mut at = 0usize;
    for b in t.batches(&sel) {
        let (_, df) = b?;
        let keys = t.hit_keys(&df)?;
        let labels = t.as_strings(&df, column)?;
        for (k, l) in keys.into_iter().zip(labels) {
            if at.is_multiple_of(every) {
                want.insert(k, l.unwrap_or_default());
            }
            at += 1;
        }
    }
    let f = TableScan::open(features)?;
    let mut pts = Vec::with_capacity(want.len());
    if f.dtype("ra_ms_per_v").is_none() || f.dtype("af_khz").is_none() {
        return Ok((pts, every));
    }
    let sel = [
        cols::EXPERIMENT.name,
        cols::CHANNEL.name,
        cols::HIT.name,
        "ra_ms_per_v",
        "af_khz",
    ];
    for b in f.batches(&sel) {
        let (_, df) = b?;
        let keys = f.hit_keys(&df)?;
        let ra = f.f64s(&df, "ra_ms_per_v")?;
        let af = f.f64s(&df, "af_khz")?;
        for ((k, r), a) in keys.iter().zip(ra).zip(af) {
            if let (Some(l), Some(r), Some(a)) = (want.get(k), r, a) {
                pts.push((r, a, l.clone()));
            }
        }
    }
    Ok((pts, every))
}
