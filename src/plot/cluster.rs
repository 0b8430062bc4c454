//! Pictures of the clustering stage: the validity curves against k.

use super::{ensure_font, err, PlotError};
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

/// Ten distinct colours (Tableau 10) for cluster numbers; mechanism names keep theirs.
fn colour_of(class: &str) -> RGBColor {
    const TAB10: [RGBColor; 10] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
        RGBColor(188, 189, 34),
        RGBColor(23, 190, 207),
    ];
    match class.parse::<usize>() {
        Ok(c) => TAB10[c % 10],
        Err(_) => super::sources::class_colour(class),
    }
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
    c.configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(&e)?;
    root.present().map_err(&e)?;
    Ok(())
}
