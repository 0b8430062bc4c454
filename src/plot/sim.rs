//! Pictures of a simulator sweep (`aepipe simulate --sweep`): the dominant frequency and the
//! decay constant against the swept value (Figs. 4.7 and 4.17), and the envelopes with
//! their exponential fits (Figs. 3.17–3.18).

use super::{boxed_legend, ensure_font, err, PlotError};
use crate::sim::sweep::{SweepRow, SweepTable};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use std::path::Path;

/// Curves per picture at most (sensors or values of a second swept key); the rest are left
/// out and the caption says so.
const MAX_CURVES: usize = 10;

/// The rows' curves: one per sensor for a one-key sweep, one per value of the second key
/// (first sensor) for a two-key sweep; each (name, rows sorted by the first key).
fn curves(t: &SweepTable) -> Vec<(String, Vec<&SweepRow>)> {
    let mut out: Vec<(String, Vec<&SweepRow>)> = Vec::new();
    let first_sensor = t.rows.iter().map(|r| r.sensor).min().unwrap_or(0);
    for r in &t.rows {
        let name = if t.keys.len() >= 2 {
            if r.sensor != first_sensor {
                continue;
            }
            t.keys[1..]
                .iter()
                .zip(&r.values[1..])
                .map(|(k, v)| format!("{k} = {}", short(*v)))
                .collect::<Vec<_>>()
                .join(", ")
        } else if r.sensor == 0 {
            "node".to_string()
        } else {
            format!("sensor {}", r.sensor)
        };
        match out.iter_mut().find(|(n, _)| *n == name) {
            Some((_, v)) => v.push(r),
            None => out.push((name, vec![r])),
        }
    }
    for (_, v) in &mut out {
        v.sort_by(|a, b| a.values[0].total_cmp(&b.values[0]));
    }
    out
}

/// The simulator pictures' frame on `area`: caption at `font` px, a 10 px margin, label
/// areas of 35 (x) and 70 (y) px, linear axes over `x` × `y`, the mesh drawn with its axis
/// descriptions (an empty one is left out).
#[allow(clippy::too_many_arguments)]
fn framed<'a, DB: DrawingBackend + 'a>(
    area: &'a DrawingArea<DB, plotters::coord::Shift>,
    caption: &str,
    font: u32,
    x: std::ops::Range<f64>,
    y: std::ops::Range<f64>,
    x_desc: &str,
    y_desc: &str,
    path: &Path,
) -> Result<ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>, PlotError> {
    let e = err(path);
    let mut c = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", font))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(70)
        .build_cartesian_2d(x, y)
        .map_err(&e)?;
    let mut mesh = c.configure_mesh();
    mesh.x_desc(x_desc);
    if !y_desc.is_empty() {
        mesh.y_desc(y_desc);
    }
    mesh.draw().map_err(&e)?;
    Ok(c)
}

/// Dominant frequency (kHz) and γ (1/s) against the first swept key, side by side.
pub fn sweep_png(path: &Path, t: &SweepTable) -> Result<(), PlotError> {
    ensure_font()?;
    let e = err(path);
    let root = BitMapBackend::new(path, (1100, 420)).into_drawing_area();
    root.fill(&WHITE).map_err(&e)?;
    let areas = root.split_evenly((1, 2));
    let all = curves(t);
    let left_out = all.len().saturating_sub(MAX_CURVES);
    let shown = &all[..all.len().min(MAX_CURVES)];
    let key = t.keys.first().map(String::as_str).unwrap_or("value");
    type Get = fn(&SweepRow) -> Option<f64>;
    let panels: [(&str, Get); 2] = [
        ("dominant frequency, kHz", |r| {
            Some(r.dominant_frequency_hz / 1e3)
        }),
        ("decay constant γ, 1/s (Eq. 3.5.1)", |r| {
            r.decay.as_ref().map(|d| d.gamma_hz)
        }),
    ];
    for ((title, get), area) in panels.iter().zip(&areas) {
        let pts: Vec<Vec<(f64, f64)>> = shown
            .iter()
            .map(|(_, rows)| {
                rows.iter()
                    .filter_map(|r| get(r).map(|v| (r.values[0], v)))
                    .collect()
            })
            .collect();
        let (x, y) = bounds(pts.iter().flatten().copied());
        let caption = if left_out > 0 {
            format!("{title} ({left_out} curves not drawn)")
        } else {
            title.to_string()
        };
        let mut c = framed(area, &caption, 14, x.0..x.1, y.0..y.1, key, "", path)?;
        for (i, ((name, _), p)) in shown.iter().zip(&pts).enumerate() {
            let col = Palette99::pick(i).to_rgba();
            c.draw_series(LineSeries::new(p.iter().copied(), col.stroke_width(2)))
                .map_err(&e)?
                .label(name.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 16, y)], col.stroke_width(2))
                });
            c.draw_series(p.iter().map(|q| Circle::new(*q, 3, col.filled())))
                .map_err(&e)?;
        }
        boxed_legend(&mut c, SeriesLabelPosition::UpperRight, path)?;
    }
    root.present().map_err(&e)?;
    Ok(())
}

/// Each run's envelope at its first sensor (points) and its fit y₀·e^(−γt) (line), on a
/// log axis: Figs. 3.17–3.18 for a sweep over the damping b.
pub fn envelopes_png(path: &Path, t: &SweepTable) -> Result<(), PlotError> {
    ensure_font()?;
    let e = err(path);
    let first_sensor = t.rows.iter().map(|r| r.sensor).min().unwrap_or(0);
    let runs: Vec<&SweepRow> = t
        .rows
        .iter()
        .filter(|r| r.sensor == first_sensor && r.decay.is_some())
        .collect();
    let left_out = runs.len().saturating_sub(MAX_CURVES);
    let runs = &runs[..runs.len().min(MAX_CURVES)];
    let pts = runs
        .iter()
        .flat_map(|r| r.decay.iter().flat_map(|d| d.points.iter().copied()));
    let (x, y) = bounds(pts.map(|(t, v)| (t * 1e6, v)));
    let root = BitMapBackend::new(path, (800, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(&e)?;
    let caption = format!(
        "envelope (points) and its fit y0·exp(−γt) (lines), {}{}",
        if first_sensor == 0 {
            "node displacement".to_string()
        } else {
            format!("sensor {first_sensor}")
        },
        if left_out > 0 {
            format!(" ({left_out} runs not drawn)")
        } else {
            String::new()
        }
    );
    let lo = y.0.max(y.1 * 1e-4).max(f64::MIN_POSITIVE);
    let mut c = ChartBuilder::on(&root)
        .caption(caption, ("sans-serif", 14))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(70)
        .build_cartesian_2d(x.0..x.1, (lo..y.1 * 1.5).log_scale())
        .map_err(&e)?;
    c.configure_mesh()
        .x_desc("time, µs")
        .y_desc(if first_sensor == 0 {
            "envelope, m"
        } else {
            "envelope, Pa"
        })
        .draw()
        .map_err(&e)?;
    for (i, r) in runs.iter().enumerate() {
        let Some(d) = &r.decay else { continue };
        let col = Palette99::pick(i).to_rgba();
        let label = format!(
            "{}γ = {:.3e} 1/s",
            t.keys
                .iter()
                .zip(&r.values)
                .map(|(k, v)| format!("{k} = {}, ", short(*v)))
                .collect::<String>(),
            d.gamma_hz
        );
        c.draw_series(
            d.points
                .iter()
                .map(|&(t, v)| Cross::new((t * 1e6, v), 3, col.stroke_width(1))),
        )
        .map_err(&e)?;
        let (t0, t1) = (d.points[0].0, d.points[d.points.len() - 1].0);
        let line = (0..=50).map(|k| {
            let t = t0 + (t1 - t0) * k as f64 / 50.0;
            (t * 1e6, d.at(t).max(lo))
        });
        c.draw_series(LineSeries::new(line, col.stroke_width(2)))
            .map_err(&e)?
            .label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], col.stroke_width(2)));
    }
    boxed_legend(&mut c, SeriesLabelPosition::UpperRight, path)?;
    root.present().map_err(&e)?;
    Ok(())
}

/// A swept value as a legend shows it: plain for everyday sizes, else in e-notation.
fn short(v: f64) -> String {
    if v == 0.0 || (1e-3..1e5).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// Axis ranges around points, padded; (0, 1) for none.
fn bounds(pts: impl Iterator<Item = (f64, f64)>) -> ((f64, f64), (f64, f64)) {
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for (x, y) in pts.filter(|p| p.0.is_finite() && p.1.is_finite()) {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    if x0 > x1 {
        return ((0.0, 1.0), (0.0, 1.0));
    }
    let pad = |a: f64, b: f64| {
        let p = if b > a {
            0.06 * (b - a)
        } else {
            a.abs().max(1.0) * 0.1
        };
        (a - p, b + p)
    };
    (pad(x0, x1), pad(y0, y1))
}

/// A source heard on a ring (`aepipe thesis fig-3.23`, `fig-3.27`): its amplitude against
/// direction with the analytic directivity, and its pressure on the strongest axis.
pub fn directivity_png(path: &Path, h: &crate::sim::sources::Heard) -> Result<(), PlotError> {
    ensure_font()?;
    let e = err(path);
    let root = BitMapBackend::new(path, (1100, 420)).into_drawing_area();
    root.fill(&WHITE).map_err(&e)?;
    let areas = root.split_evenly((1, 2));
    let deg: Vec<f64> = h.theta.iter().map(|t| t.to_degrees()).collect();
    let top = h
        .amplitude
        .iter()
        .fold(0.0f64, |a, &v| a.max(v))
        .max(1e-300);
    let caption = format!(
        "{:?} ({:?}) on the ring: measured (points), analytic (line)",
        h.pole, h.drive
    );
    let mut c = framed(
        &areas[0],
        &caption,
        14,
        0.0..360.0,
        0.0..1.1 * top,
        "direction θ from the x axis, degrees",
        "amplitude, Pa",
        path,
    )?;
    c.draw_series(LineSeries::new(
        deg.iter().copied().zip(h.analytic.iter().copied()),
        BLUE.stroke_width(2),
    ))
    .map_err(&e)?;
    c.draw_series(
        deg.iter()
            .zip(&h.amplitude)
            .map(|(x, y)| Circle::new((*x, *y), 3, RED.filled())),
    )
    .map_err(&e)?;
    let t: Vec<f64> = (0..h.on_axis.len())
        .map(|k| (k + 1) as f64 / h.sample_rate_hz)
        .collect();
    let (x, y) = bounds(t.iter().copied().zip(h.on_axis.iter().copied()));
    let mut c = framed(
        &areas[1],
        "pressure 6 m out on the strongest axis",
        14,
        x.0..x.1,
        y.0..y.1,
        "time, s",
        "pressure, Pa",
        path,
    )?;
    c.draw_series(LineSeries::new(
        t.iter().copied().zip(h.on_axis.iter().copied()),
        BLACK.stroke_width(1),
    ))
    .map_err(&e)?;
    root.present().map_err(&e)?;
    Ok(())
}

/// Named curves on one chart: the first drawn as points, the rest as lines.
pub fn curves_png(
    path: &Path,
    title: &str,
    x_desc: &str,
    y_desc: &str,
    curves: &[(&str, Vec<(f64, f64)>)],
) -> Result<(), PlotError> {
    ensure_font()?;
    let e = err(path);
    let root = BitMapBackend::new(path, (800, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(&e)?;
    let (x, y) = bounds(curves.iter().flat_map(|(_, p)| p.iter().copied()));
    let mut c = framed(&root, title, 15, x.0..x.1, y.0..y.1, x_desc, y_desc, path)?;
    for (i, (name, p)) in curves.iter().enumerate() {
        let col = Palette99::pick(i).to_rgba();
        if i == 0 {
            c.draw_series(p.iter().map(|q| Circle::new(*q, 4, col.filled())))
                .map_err(&e)?
                .label(*name)
                .legend(move |(x, y)| Circle::new((x + 8, y), 4, col.filled()));
        } else {
            c.draw_series(LineSeries::new(p.iter().copied(), col.stroke_width(2)))
                .map_err(&e)?
                .label(*name)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 16, y)], col.stroke_width(2))
                });
        }
    }
    boxed_legend(&mut c, SeriesLabelPosition::UpperRight, path)?;
    root.present().map_err(&e)?;
    Ok(())
}
