//! After the classification: the damage evolution (`evolution.parquet` and a picture per
//! experiment) and where the classified events are (a location picture per experiment).

use super::*;
use crate::analysis::evolution::{evolve, EvolutionParams, EvolutionRow, Source};
use crate::plot::sources::LocatedSource;
use crate::som::layout::ClassifyDir;
use crate::som::profile::{ProfileRow, ProfileSummary};
use polars::prelude::col;

/// `evolution.parquet` from the damage profile's rows (the classified sources, in time order
/// per series) and one picture per experiment. Returns the table and the pictures.
pub(super) fn evolution_stage(
    cfg: &ValidConfig,
    rows: &[ProfileRow],
    summaries: &[ProfileSummary],
    som_dir: &ClassifyDir,
) -> Result<(PathBuf, Vec<(String, PathBuf)>), WorkflowError> {
    let p = EvolutionParams::of(&cfg.evolution);
    let mut by_exp: BTreeMap<&str, Vec<&ProfileRow>> = BTreeMap::new();
    for r in rows {
        by_exp.entry(r.key.0.as_str()).or_default().push(r);
    }
    let mut out: Vec<EvolutionRow> = Vec::new();
    let mut spans = Vec::new();
    for (exp, mut rs) in by_exp {
        // Channels' series (no events built) merge into the experiment's, by time.
        rs.sort_by(|a, b| {
            let (ta, tb) = (a.time_s.unwrap_or(f64::NAN), b.time_s.unwrap_or(f64::NAN));
            ta.total_cmp(&tb).then(a.key.2.cmp(&b.key.2))
        });
        let sources: Vec<Source> = rs
            .iter()
            .map(|r| Source {
                key: r.key.clone(),
                time_s: r.time_s,
                load_n: r.load_n,
                amplitude_db: r.amplitude_db,
                energy_eu: r.energy_eu,
                hits: r.source_hits,
                class: r.class.clone(),
            })
            .collect();
        let start = out.len();
        out.extend(evolve(exp, &sources, &p));
        spans.push((exp.to_string(), start..out.len()));
    }
    let table = som_dir.evolution();
    crate::analysis::evolution::write(&table, &out, &cfg.hash())?;
    let mut plots = Vec::new();
    for (exp, span) in spans {
        let rows: Vec<&EvolutionRow> = out[span].iter().collect();
        let peak = summaries
            .iter()
            .filter(|s| s.experiment == exp)
            .find_map(|s| s.peak_time_s);
        let png = som_dir.evolution_png(&exp);
        crate::plot::sources::evolution_png(&png, &exp, &rows, p.window, peak)?;
        plots.push((exp, png));
    }
    Ok((table, plots))
}

/// A location picture per experiment with located events: each event coloured by its first
/// hit's SOM class (from the damage profile's `rows`, the classified hits), "outside the
/// zone" for those the zone leaves out (which the SOM does not classify with
/// `exclude_outside`).
pub(super) fn location_stage(
    cfg: &ValidConfig,
    rows: &[ProfileRow],
    events: &Path,
    som_dir: &ClassifyDir,
) -> Result<Vec<(String, PathBuf)>, WorkflowError> {
    if !events.is_file() {
        return Ok(Vec::new());
    }
    let ev = TableScan::open(events)?;
    let df = ev.select(vec![
        col("experiment"),
        col("event"),
        col("x_m"),
        col("y_m"),
        col("zone"),
    ])?;
    let exps = ev.strings(&df, "experiment")?;
    let numbers = ev.f64s(&df, "event")?;
    let (xs, ys) = (ev.f64s(&df, "x_m")?, ev.f64s(&df, "y_m")?);
    let zones = ev.strings(&df, "zone")?;
    if xs.iter().all(Option::is_none) {
        return Ok(Vec::new());
    }
    // (experiment, event) → the SOM's class of its first hit.
    let class_of: BTreeMap<(&str, i64), &str> = rows
        .iter()
        .filter_map(|r| Some(((r.key.0.as_str(), r.event?), r.class.as_str())))
        .collect();
    let mut per_exp: BTreeMap<String, Vec<LocatedSource>> = BTreeMap::new();
    for i in 0..df.height() {
        let (Some(exp), Some(n), Some(x)) = (&exps[i], numbers[i], xs[i]) else {
            continue;
        };
        let class = if zones[i].as_deref() == Some("outside") {
            "outside the zone"
        } else {
            class_of
                .get(&(exp.as_str(), n as i64))
                .copied()
                .unwrap_or("unclassified")
        };
        per_exp.entry(exp.clone()).or_default().push(LocatedSource {
            x_m: x,
            y_m: ys[i],
            class: class.to_string(),
        });
    }
    let mut plots = Vec::new();
    for (exp, located) in per_exp {
        let png = som_dir.location_png(&exp);
        let title = format!("{exp}: where the events are ({} located)", located.len());
        crate::plot::sources::location_png(
            &png,
            &title,
            &located,
            cfg.location.zone.as_ref(),
            &cfg.location.sensors,
        )?;
        plots.push((exp, png));
    }
    Ok(plots)
}
