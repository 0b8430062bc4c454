//! Pictures of sources: where the events are (a histogram along the strip, or an x/y map,
//! coloured by class, with the zone and the sensors) and the damage evolution (cumulative
//! sources per class against time and load, b- and Ib-value over the test).

use super::{draw_legend, ensure_font, err, PlotError};
use crate::analysis::evolution::EvolutionRow;
use crate::config::ZoneSpec;
use crate::model::Mechanism;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use std::path::Path;

/// The classes' colours in every picture of classes (damage profile, location, evolution).
pub fn class_colour(class: &str) -> RGBColor {
    match (Mechanism::parse(class), class) {
        (Some(Mechanism::BondFailure), _) => RGBColor(31, 119, 180),
        (Some(Mechanism::FibreFailure), _) => RGBColor(214, 39, 40),
        (Some(Mechanism::Erroneous), _) => RGBColor(255, 127, 14),
        (_, crate::model::UNLIKE_REFERENCES) => RGBColor(148, 103, 189),
        (_, "all") => RGBColor(0, 0, 0),
        (_, "outside the zone") => RGBColor(190, 190, 190),
        _ => match class
            .strip_prefix("cluster ")
            .unwrap_or(class)
            .parse::<usize>()
        {
            // Cluster numbers: ten distinct colours (Tableau 10).
            Ok(c) => TAB10[c % 10],
            Err(_) => RGBColor(120, 120, 120),
        },
    }
}

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

/// Sensor positions by channel, m (`[location] sensors`).
pub type Sensors = std::collections::BTreeMap<String, Vec<f64>>;

/// One located event: where, and its class (the SOM's class of its first hit, or
/// "outside the zone" for the events the zone leaves out, which are not classified).
#[derive(Debug, Clone, PartialEq)]
pub struct LocatedSource {
    pub x_m: f64,
    pub y_m: Option<f64>,
    pub class: String,
}

/// Classes in drawing order: the mechanisms, others, then what the zone left out.
fn class_order(sources: &[LocatedSource]) -> Vec<String> {
    let mut c: Vec<String> = sources.iter().map(|s| s.class.clone()).collect();
    c.sort();
    c.dedup();
    let rank = |s: &str| match (Mechanism::parse(s), s) {
        (Some(Mechanism::BondFailure), _) => 0,
        (Some(Mechanism::FibreFailure), _) => 1,
        (Some(Mechanism::Erroneous), _) => 2,
        (_, "outside the zone") => 4,
        _ => 3,
    };
    c.sort_by_key(|s| rank(s));
    c
}

/// Linear location: a stacked histogram of the events along the strip (1 mm bins, or finer
/// for short spans), the zone shaded and the sensors marked. Planar: an x/y map of the events,
/// the zone's polygon and the sensors.
pub fn location_png(
    path: &Path,
    title: &str,
    sources: &[LocatedSource],
    zone: Option<&ZoneSpec>,
    sensors: &Sensors,
) -> Result<(), PlotError> {
    ensure_font()?;
    if sources.iter().any(|s| s.y_m.is_some()) || sensors.iter().any(|s| s.1.len() > 1) {
        return planar_png(path, title, sources, zone, sensors);
    }
    let e = err(path);
    let mm = |x: f64| x * 1e3;
    let xs = sensors
        .iter()
        .filter_map(|s| s.1.first().copied())
        .chain(sources.iter().map(|s| s.x_m));
    let (lo, hi) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
        (a.min(x), b.max(x))
    });
    let (lo, hi) = if lo.is_finite() {
        (mm(lo) - 3.0, mm(hi) + 3.0)
    } else {
        (-1.0, 1.0)
    };
    let width = if hi - lo > 40.0 { 1.0 } else { 0.5 };
    let nb = ((hi - lo) / width).ceil().max(1.0) as usize;
    let classes = class_order(sources);
    let mut counts = vec![vec![0u32; nb]; classes.len()];
    for s in sources {
        let b = (((mm(s.x_m) - lo) / width).floor().max(0.0) as usize).min(nb - 1);
        let k = classes.iter().position(|c| *c == s.class).unwrap_or(0);
        counts[k][b] += 1;
    }
    let tops: Vec<u32> = (0..nb).map(|b| counts.iter().map(|c| c[b]).sum()).collect();
    let ymax = (*tops.iter().max().unwrap_or(&1)).max(1) as f64 * 1.15;
    let root = BitMapBackend::new(path, (1000, 420)).into_drawing_area();
    root.fill(&WHITE).map_err(&e)?;
    let mut c = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(lo..hi, 0.0..ymax)
        .map_err(&e)?;
    c.configure_mesh()
        .x_desc(format!("position along the strip (mm), {width} mm bins"))
        .y_desc("events")
        .draw()
        .map_err(&e)?;
    if let Some(ZoneSpec::Interval([a, b])) = zone {
        c.draw_series([Rectangle::new(
            [(mm(*a), 0.0), (mm(*b), ymax)],
            RGBColor(60, 170, 60).mix(0.10).filled(),
        )])
        .map_err(&e)?
        .label(format!("zone {:.0} to {:.0} mm", mm(*a), mm(*b)))
        .legend(|(x, y)| {
            Rectangle::new(
                [(x, y - 5), (x + 20, y + 5)],
                RGBColor(60, 170, 60).mix(0.3).filled(),
            )
        });
    }
    draw_stacked_bars(&mut c, path, &classes, &counts, nb, lo, width)?;
    for (ch, pos) in sensors {
        if let Some(&x) = pos.first() {
            c.draw_series([TriangleMarker::new((mm(x), ymax * 0.03), 9, BLACK.filled())])
                .map_err(&e)?;
            c.draw_series([Text::new(
                format!("ch{ch}"),
                (mm(x) + 0.4, ymax * 0.08),
                ("sans-serif", 14),
            )])
            .map_err(&e)?;
        }
    }
    draw_legend(&mut c, SeriesLabelPosition::UpperRight, path)?;
    root.present().map_err(&e)?;
    Ok(())
}

/// Each class's bars (`counts[class][bin]`) stacked on the ones before, one legend entry each.
fn draw_stacked_bars(
    c: &mut ChartContext<'_, BitMapBackend<'_>, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    path: &Path,
    classes: &[String],
    counts: &[Vec<u32>],
    nb: usize,
    lo: f64,
    width: f64,
) -> Result<(), PlotError> {
    let e = err(path);
    let mut base = vec![0u32; nb];
    for (k, class) in classes.iter().enumerate() {
        let colour = class_colour(class);
        let bars: Vec<Rectangle<(f64, f64)>> = (0..nb)
            .filter(|&b| counts[k][b] > 0)
            .map(|b| {
                let x0 = lo + b as f64 * width;
                let r = Rectangle::new(
                    [
                        (x0, base[b] as f64),
                        (x0 + width, (base[b] + counts[k][b]) as f64),
                    ],
                    colour.filled(),
                );
                base[b] += counts[k][b];
                r
            })
            .collect();
        let total: u32 = counts[k].iter().sum();
        c.draw_series(bars)
            .map_err(&e)?
            .label(format!("{class} ({total})"))
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 20, y + 5)], colour.filled()));
    }
    Ok(())
}

fn planar_png(
    path: &Path,
    title: &str,
    sources: &[LocatedSource],
    zone: Option<&ZoneSpec>,
    sensors: &Sensors,
) -> Result<(), PlotError> {
    let e = err(path);
    let pts = sensors
        .iter()
        .filter(|s| s.1.len() >= 2)
        .map(|s| (s.1[0], s.1[1]))
        .chain(sources.iter().map(|s| (s.x_m, s.y_m.unwrap_or(0.0))));
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for (x, y) in pts {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    if !x0.is_finite() {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    let pad = 0.05 * (x1 - x0).max(y1 - y0).max(1e-3);
    let root = BitMapBackend::new(path, (760, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(&e)?;
    let mut c = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d((x0 - pad)..(x1 + pad), (y0 - pad)..(y1 + pad))
        .map_err(&e)?;
    c.configure_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .draw()
        .map_err(&e)?;
    if let Some(ZoneSpec::Polygon(p)) = zone {
        let mut ring: Vec<(f64, f64)> = p.iter().map(|v| (v[0], v[1])).collect();
        ring.extend(ring.first().copied());
        c.draw_series(LineSeries::new(ring, RGBColor(60, 170, 60).stroke_width(2)))
            .map_err(&e)?
            .label("zone")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], RGBColor(60, 170, 60)));
    }
    for class in class_order(sources) {
        let colour = class_colour(&class);
        let n = sources.iter().filter(|s| s.class == class).count();
        c.draw_series(
            sources
                .iter()
                .filter(|s| s.class == class)
                .map(|s| Circle::new((s.x_m, s.y_m.unwrap_or(0.0)), 4, colour.filled())),
        )
        .map_err(&e)?
        .label(format!("{class} ({n})"))
        .legend(move |(x, y)| Circle::new((x + 10, y), 4, colour.filled()));
    }
    for (ch, pos) in sensors.iter().filter(|s| s.1.len() >= 2) {
        c.draw_series([TriangleMarker::new((pos[0], pos[1]), 9, BLACK.filled())])
            .map_err(&e)?;
        c.draw_series([Text::new(
            format!("ch{ch}"),
            (pos[0], pos[1]),
            ("sans-serif", 14),
        )])
        .map_err(&e)?;
    }
    draw_legend(&mut c, SeriesLabelPosition::UpperRight, path)?;
    root.present().map_err(&e)?;
    Ok(())
}

/// The damage evolution of one experiment: cumulative sources of each class against time
/// (top) and against load (middle), and the b- and Ib-value of all sources over the test
/// (bottom), the peak load marked.
pub fn evolution_png(
    path: &Path,
    experiment: &str,
    rows: &[&EvolutionRow],
    window: usize,
    peak_time_s: Option<f64>,
    every: usize,
) -> Result<(), PlotError> {
    let sampled = if every > 1 {
        format!(" (every {every}th source drawn)")
    } else {
        String::new()
    };
    ensure_font()?;
    let e = err(path);
    let mut classes: Vec<&str> = rows.iter().map(|r| r.class.as_str()).collect();
    classes.sort_unstable();
    classes.dedup();
    let tmax = rows.iter().filter_map(|r| r.time_s).fold(1e-9, f64::max);
    let lmax = rows.iter().filter_map(|r| r.load_n).fold(0.0, f64::max);
    let nmax = rows.iter().map(|r| r.cum_sources).max().unwrap_or(1).max(1) as f64 * 1.05;
    let root = BitMapBackend::new(path, (1000, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(&e)?;
    let parts = root.split_evenly((3, 1));
    let cumulative = Cumulative {
        experiment,
        sampled: &sampled,
        rows,
        classes: &classes,
        tmax,
        lmax,
        nmax,
        peak_time_s,
    };
    // (1) against time, (2) against load.
    for (k, area) in parts.iter().take(2).enumerate() {
        let against_load = k == 1;
        cumulative_panel(area, path, &cumulative, against_load)?;
    }
    // (3) b and Ib of all sources.
    let all = class_series(rows, "all");
    b_value_panel(&parts[2], path, &all, window, tmax, peak_time_s)?;
    root.present().map_err(&e)?;
    Ok(())
}

/// The rows of one class, in order: one line of a panel ("all": the b- and Ib-values).
fn class_series<'a>(rows: &[&'a EvolutionRow], c: &str) -> Vec<&'a EvolutionRow> {
    rows.iter().filter(|r| r.class == c).copied().collect()
}

/// What both cumulative panels of [`evolution_png`] share: rows, classes, axes, peak time.
struct Cumulative<'a> {
    experiment: &'a str,
    /// The captions' note that only every n-th source is drawn (empty when all are).
    sampled: &'a str,
    rows: &'a [&'a EvolutionRow],
    classes: &'a [&'a str],
    tmax: f64,
    lmax: f64,
    nmax: f64,
    peak_time_s: Option<f64>,
}

/// One cumulative panel, against time or against load (a note when no load was recorded).
fn cumulative_panel(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    path: &Path,
    p: &Cumulative<'_>,
    against_load: bool,
) -> Result<(), PlotError> {
    let e = err(path);
    let (experiment, sampled, nmax) = (p.experiment, p.sampled, p.nmax);
    if against_load && p.lmax <= 0.0 {
        area.draw(&Text::new(
            "no load recorded: nothing to draw against load",
            (20, 40),
            ("sans-serif", 16),
        ))
        .map_err(&e)?;
        return Ok(());
    }
    let xmax = if against_load { p.lmax * 1.02 } else { p.tmax };
    let mut c = ChartBuilder::on(area)
        .caption(
            if against_load {
                format!("{experiment}: cumulative sources against load{sampled}")
            } else {
                format!("{experiment}: cumulative sources against time{sampled}")
            },
            ("sans-serif", 16),
        )
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..xmax, 0.0..nmax)
        .map_err(&e)?;
    c.configure_mesh()
        .x_desc(if against_load { "load (N)" } else { "time (s)" })
        .y_desc("sources")
        .draw()
        .map_err(&e)?;
    for class in p.classes {
        let colour = class_colour(class);
        let s = class_series(p.rows, class);
        let last = s
            .last()
            .map(|r| (r.cum_sources, r.cum_hits))
            .unwrap_or((0, 0));
        let pts: Vec<(f64, f64)> = s
            .iter()
            .filter_map(|r| {
                let x = if against_load { r.load_n } else { r.time_s };
                x.map(|x| (x, r.cum_sources as f64))
            })
            .collect();
        c.draw_series(LineSeries::new(pts, colour.stroke_width(2)))
            .map_err(&e)?
            .label(format!("{class}: {} sources, {} hits", last.0, last.1))
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], colour.stroke_width(2)));
    }
    if let (false, Some(t)) = (against_load, p.peak_time_s) {
        c.draw_series(LineSeries::new([(t, 0.0), (t, nmax)], BLACK.mix(0.5)))
            .map_err(&e)?
            .label("peak load")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLACK.mix(0.5)));
    }
    draw_legend(&mut c, SeriesLabelPosition::UpperLeft, path)?;
    Ok(())
}

/// The b- and Ib-value of all sources over time (a note when too few), the peak load marked.
fn b_value_panel(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    path: &Path,
    all: &[&EvolutionRow],
    window: usize,
    tmax: f64,
    peak_time_s: Option<f64>,
) -> Result<(), PlotError> {
    let e = err(path);
    let vals = all
        .iter()
        .flat_map(|r| [r.b_value, r.ib_value])
        .flatten()
        .filter(|v| v.is_finite());
    let (vlo, vhi) = vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    if !vlo.is_finite() {
        area.draw(&Text::new(
            format!("fewer than {window} sources: no b-value window"),
            (20, 40),
            ("sans-serif", 16),
        ))
        .map_err(&e)?;
    } else {
        let pad = 0.1 * (vhi - vlo).max(0.1);
        let mut c = ChartBuilder::on(area)
            .caption(
                format!("b-value (Aki) and Ib-value (Shiotani), windows of {window} sources"),
                ("sans-serif", 16),
            )
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..tmax, (vlo - pad).max(0.0)..(vhi + pad))
            .map_err(&e)?;
        c.configure_mesh()
            .x_desc("time (s)")
            .y_desc("value")
            .draw()
            .map_err(&e)?;
        for (name, colour, get) in [
            (
                "b-value",
                RGBColor(31, 119, 180),
                (|r: &EvolutionRow| r.b_value) as fn(&EvolutionRow) -> Option<f64>,
            ),
            ("Ib-value", RGBColor(44, 160, 44), |r: &EvolutionRow| {
                r.ib_value
            }),
        ] {
            let pts: Vec<(f64, f64)> = all
                .iter()
                .filter_map(|r| Some((r.time_s?, get(r)?)))
                .collect();
            c.draw_series(LineSeries::new(pts, colour.stroke_width(2)))
                .map_err(&e)?
                .label(name)
                .legend(move |(x, y)| {
                    PathElement::new([(x, y), (x + 20, y)], colour.stroke_width(2))
                });
        }
        if let Some(t) = peak_time_s {
            c.draw_series(LineSeries::new(
                [(t, (vlo - pad).max(0.0)), (t, vhi + pad)],
                BLACK.mix(0.5),
            ))
            .map_err(&e)?;
        }
        draw_legend(&mut c, SeriesLabelPosition::UpperLeft, path)?;
    }
    Ok(())
}
