//! Pictures of the clustering stage: the validity curves against k, RA against AF, the
//! cumulative hits per cluster against time and load, and the feature distributions.

use super::{boxed_legend, ensure_font, err, PlotError};
use crate::cluster::ValidityRow;
use plotters::prelude::*;
use std::path::Path;

/// One panel per index (Davies–Bouldin, silhouette, Calinski–Harabasz, and BIC for a
/// mixture) against k; the chosen k marked.
pub fn validity_png(path: &Path, rows: &[ValidityRow]) -> Result<(), PlotError> {
    ensure_font()?;
    let e = err(path);
    type Get = fn(&ValidityRow) -> Option<f64>;
    let mut panels: Vec<(&str, Get)> = vec![
        ("Davies–Bouldin (lower is better)", |r| r.davies_bouldin),
        ("silhouette (higher is better)", |r| r.silhouette),
        ("Calinski–Harabasz (higher is better)", |r| {
            r.calinski_harabasz
        }),
    ];
    if rows.iter().any(|r| r.bic.is_some()) {
        panels.push(("BIC (lower is better)", |r| r.bic));
    }
    let root = BitMapBackend::new(path, (300 * panels.len() as u32, 320)).into_drawing_area();
    root.fill(&WHITE).map_err(&e)?;
    let areas = root.split_evenly((1, panels.len()));
    let method = rows.first().map(|r| r.method.as_str()).unwrap_or("");
    let (k0, k1) = rows
        .iter()
        .fold((usize::MAX, 0), |(a, b), r| (a.min(r.k), b.max(r.k)));
    for ((title, get), area) in panels.iter().zip(&areas) {
        let pts: Vec<(f64, f64)> = rows
            .iter()
            .filter_map(|r| get(r).map(|v| (r.k as f64, v)))
            .collect();
        let (lo, hi) = pts
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                (a.min(p.1), b.max(p.1))
            });
        let pad = if hi > lo { 0.08 * (hi - lo) } else { 1.0 };
        let (lo, hi) = if pts.is_empty() {
            (0.0, 1.0)
        } else {
            (lo - pad, hi + pad)
        };
        let mut c = ChartBuilder::on(area)
            .caption(format!("{method}: {title}"), ("sans-serif", 13))
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(55)
            .build_cartesian_2d(k0 as f64 - 0.5..k1 as f64 + 0.5, lo..hi)
            .map_err(&e)?;
        c.configure_mesh()
            .x_desc("k")
            .x_labels(k1 - k0 + 2)
            .draw()
            .map_err(&e)?;
        c.draw_series(LineSeries::new(pts.iter().copied(), BLUE.stroke_width(2)))
            .map_err(&e)?;
        c.draw_series(pts.iter().map(|p| Circle::new(*p, 3, BLUE.filled())))
            .map_err(&e)?;
        let chosen = rows
            .iter()
            .filter(|r| r.chosen)
            .filter_map(|r| get(r).map(|v| (r.k as f64, v)));
        c.draw_series(chosen.map(|p| Circle::new(p, 7, RED.stroke_width(2))))
            .map_err(&e)?;
    }
    root.present().map_err(&e)?;
    Ok(())
}

/// A cluster number's colour (mechanism names keep theirs).
fn colour_of(class: &str) -> RGBColor {
    super::sources::class_colour(class)
}

/// RA (ms/V) against AF (kHz), both on log axes, coloured by `by` (a cluster number or a
/// class name), with the crack-mode line AF = `slope` × RA; `every` > 1 says the points
/// were thinned. Points with RA or AF of 0 cannot sit on a log axis and are counted in the
/// caption.
pub fn ra_af_png(
    path: &Path,
    pts: &[(f64, f64, String)],
    slope: f64,
    by: &str,
    every: usize,
) -> Result<(), PlotError> {
    ensure_font()?;
    let e = err(path);
    let pos: Vec<&(f64, f64, String)> = pts.iter().filter(|p| p.0 > 0.0 && p.1 > 0.0).collect();
    let zero = pts.len() - pos.len();
    let range = |f: fn(&&(f64, f64, String)) -> f64| {
        let (lo, hi) = pos
            .iter()
            .map(f)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
        if lo.is_finite() {
            (lo / 1.5, hi * 1.5)
        } else {
            (1e-3, 1.0)
        }
    };
    let (x0, x1) = range(|p| p.0);
    let (y0, y1) = range(|p| p.1);
    // The line is drawn across the RA range: the AF axis takes it in.
    let (y0, y1) = (y0.min(slope * x0), y1.max(slope * x1));
    let root = BitMapBackend::new(path, (820, 620)).into_drawing_area();
    root.fill(&WHITE).map_err(&e)?;
    let mut note = String::new();
    if every > 1 {
        note += &format!("; every {every}th hit");
    }
    if zero > 0 {
        note += &format!("; {zero} with RA or AF 0 not drawn");
    }
    let mut c = ChartBuilder::on(&root)
        .caption(format!("RA against AF by {by}{note}"), ("sans-serif", 16))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(&e)?;
    c.configure_mesh()
        .x_desc("RA (ms/V)")
        .y_desc("AF (kHz)")
        .draw()
        .map_err(&e)?;
    let mut classes: Vec<&str> = pos.iter().map(|p| p.2.as_str()).collect();
    classes.sort_unstable();
    classes.dedup();
    for cl in classes {
        let col = colour_of(cl);
        let n = pos.iter().filter(|p| p.2 == cl).count();
        c.draw_series(
            pos.iter()
                .filter(|p| p.2 == cl)
                .map(|p| Circle::new((p.0, p.1), 2, col.mix(0.6).filled())),
        )
        .map_err(&e)?
        .label(format!("{cl} ({n})"))
        .legend(move |(x, y)| Circle::new((x + 8, y), 4, col.filled()));
    }
    c.draw_series(LineSeries::new(
        [(x0, slope * x0), (x1, slope * x1)],
        BLACK.stroke_width(2),
    ))
    .map_err(&e)?
    .label(format!("AF = {slope} × RA: tensile above, shear below"))
    .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLACK));
    boxed_legend(&mut c, SeriesLabelPosition::LowerRight, path)?;
    root.present().map_err(&e)?;
    Ok(())
}

/// One cluster's cumulative hits of one experiment, thinned: (time s, load N, count).
pub type CumulativePoint = (f64, Option<f64>, u64);

/// Cumulative hits per cluster of one experiment against time and, when the test has a
/// load, against load (`no_load` says why not, and the panel is left out).
pub fn cumulative_png(
    path: &Path,
    title: &str,
    series: &std::collections::BTreeMap<usize, Vec<CumulativePoint>>,
    no_load: Option<&str>,
) -> Result<(), PlotError> {
    ensure_font()?;
    let e = err(path);
    let panels = if no_load.is_some() { 1 } else { 2 };
    let root = BitMapBackend::new(path, (460 * panels as u32, 360)).into_drawing_area();
    root.fill(&WHITE).map_err(&e)?;
    let (head, body) = root.split_vertically(24);
    head.draw_text(title, &("sans-serif", 14).into_text_style(&head), (10, 4))
        .map_err(&e)?;
    let areas = body.split_evenly((1, panels));
    let top = series
        .values()
        .filter_map(|v| v.last())
        .map(|p| p.2)
        .max()
        .unwrap_or(1);
    for (k, area) in areas.iter().enumerate() {
        let x_of = |p: &CumulativePoint| if k == 0 { Some(p.0) } else { p.1 };
        let (x0, x1) = series
            .values()
            .flatten()
            .filter_map(x_of)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
        let (x0, x1) = if x0 < x1 { (x0, x1) } else { (0.0, 1.0) };
        let mut c = ChartBuilder::on(area)
            .margin(8)
            .x_label_area_size(32)
            .y_label_area_size(55)
            .build_cartesian_2d(x0..x1, 0.0..top as f64 * 1.05)
            .map_err(&e)?;
        c.configure_mesh()
            .x_desc(if k == 0 { "time (s)" } else { "load (N)" })
            .y_desc("cumulative hits")
            .draw()
            .map_err(&e)?;
        for (cl, pts) in series {
            let col = colour_of(&cl.to_string());
            let line: Vec<(f64, f64)> = pts
                .iter()
                .filter_map(|p| x_of(p).map(|x| (x, p.2 as f64)))
                .collect();
            let n = pts.last().map_or(0, |p| p.2);
            let drawn = if k == 0 {
                c.draw_series(LineSeries::new(line, col.stroke_width(2)))
            } else {
                // Against load the curve doubles back where the load falls: points.
                c.draw_series(LineSeries::new(line, col.stroke_width(1)))
            };
            drawn
                .map_err(&e)?
                .label(format!("cluster {cl} ({n})"))
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], col.stroke_width(2)));
        }
        boxed_legend(&mut c, SeriesLabelPosition::UpperLeft, path)?;
    }
    root.present().map_err(&e)?;
    Ok(())
}

/// A feature drawn in the distributions: its name, axis label and whether on log₁₀.
pub struct Distribution {
    pub column: &'static str,
    pub label: &'static str,
    pub scale: f64,
    pub log10: bool,
}

/// One panel per feature: each cluster's histogram (40 bins over the samples' 1–99 %
/// range, as a share of the cluster's sampled hits), from a sample of each cluster.
pub fn distributions_png(
    path: &Path,
    title: &str,
    features: &[Distribution],
    samples: &std::collections::BTreeMap<usize, Vec<Vec<f64>>>,
) -> Result<(), PlotError> {
    ensure_font()?;
    let e = err(path);
    let cols = 3usize;
    let rows = features.len().div_ceil(cols);
    let root = BitMapBackend::new(path, (1200, 24 + 300 * rows as u32)).into_drawing_area();
    root.fill(&WHITE).map_err(&e)?;
    let (head, body) = root.split_vertically(24);
    head.draw_text(title, &("sans-serif", 14).into_text_style(&head), (10, 4))
        .map_err(&e)?;
    let areas = body.split_evenly((rows, cols));
    const BINS: usize = 40;
    for (f, (d, area)) in features.iter().zip(&areas).enumerate() {
        let value = |r: &Vec<f64>| {
            let v = r[f] * d.scale;
            let v = if d.log10 { v.log10() } else { v };
            v.is_finite().then_some(v)
        };
        let mut all: Vec<f64> = samples.values().flatten().filter_map(value).collect();
        if all.is_empty() {
            continue;
        }
        all.sort_by(f64::total_cmp);
        let q = |p: f64| all[((all.len() - 1) as f64 * p).round() as usize];
        let (lo, hi) = (q(0.01), q(0.99));
        let (lo, hi) = if hi > lo {
            (lo, hi)
        } else {
            (lo - 0.5, lo + 0.5)
        };
        let w = (hi - lo) / BINS as f64;
        let hists: Vec<(usize, Vec<f64>)> = samples
            .iter()
            .map(|(cl, rows)| {
                let mut h = vec![0.0; BINS];
                let vals: Vec<f64> = rows.iter().filter_map(value).collect();
                for v in &vals {
                    let b = ((v - lo) / w).floor();
                    if b >= 0.0 && (b as usize) < BINS {
                        h[b as usize] += 1.0;
                    }
                }
                let n = vals.len().max(1) as f64;
                h.iter_mut().for_each(|x| *x /= n);
                (*cl, h)
            })
            .collect();
        let top = hists
            .iter()
            .flat_map(|(_, h)| h.iter().copied())
            .fold(0.0f64, f64::max)
            .max(1e-9);
        let mut c = ChartBuilder::on(area)
            .margin(8)
            .x_label_area_size(32)
            .y_label_area_size(45)
            .build_cartesian_2d(lo..hi, 0.0..top * 1.1)
            .map_err(&e)?;
        c.configure_mesh()
            .x_desc(if d.log10 {
                format!("log10 {}", d.label)
            } else {
                d.label.to_string()
            })
            .y_desc("share of hits")
            .draw()
            .map_err(&e)?;
        for (cl, h) in &hists {
            let col = colour_of(&cl.to_string());
            // A step line over the bins.
            let steps: Vec<(f64, f64)> = h
                .iter()
                .enumerate()
                .flat_map(|(b, y)| {
                    let x = lo + b as f64 * w;
                    [(x, *y), (x + w, *y)]
                })
                .collect();
            c.draw_series(LineSeries::new(steps, col.stroke_width(2)))
                .map_err(&e)?
                .label(format!("cluster {cl}"))
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], col.stroke_width(2)));
        }
        if f == 0 {
            boxed_legend(&mut c, SeriesLabelPosition::UpperRight, path)?;
        }
    }
    root.present().map_err(&e)?;
    Ok(())
}
