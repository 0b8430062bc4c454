//! Pictures (PNG, plotters' bitmap backend): the waveform + CWT of a hit the way AE engineers
//! read them (time in µs, frequency in kHz, colour scale of |W|).
//!
//! Text is drawn with plotters' pure-Rust `ab_glyph` renderer and a TrueType font found on the
//! machine (DejaVu Sans or Liberation Sans; `AEPIPE_FONT` names another), so no system font
//! library is linked. The font is loaded once per process.

pub mod sim;
pub mod sources;

mod cluster;
use crate::model::AeRecord;
pub use cluster::{
    cumulative_png, distributions_png, ra_af_png, validity_png, CumulativePoint, Distribution,
};
use ndarray::ArrayView2;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::colors::colormaps::ViridisRGB;
use std::path::Path;
use std::sync::OnceLock;

/// Why a picture was not drawn.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("AEPIPE_FONT={path}: {message}")]
    Font { path: String, message: String },
    #[error("{path}: {message}")]
    Draw { path: String, message: String },
}

impl crate::util::HasKind for PlotError {
    fn kind(&self) -> crate::util::ErrorKind {
        match self {
            PlotError::Font { .. } => crate::util::ErrorKind::Usage,
            PlotError::Draw { .. } => crate::util::ErrorKind::Failed,
        }
    }
}

/// The series' legend in a box at `at`.
pub(crate) fn boxed_legend<'a, DB: DrawingBackend + 'a, CT: plotters::coord::CoordTranslate>(
    c: &mut ChartContext<'a, DB, CT>,
    at: SeriesLabelPosition,
    path: &Path,
) -> Result<(), PlotError> {
    c.configure_series_labels()
        .position(at)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(err(path))
}

/// Register the sans-serif font with plotters once: the file `AEPIPE_FONT` names, else
/// DejaVu Sans embedded in the binary (the `dejavu` crate), so pictures never depend on the
/// machine's fonts.
pub fn ensure_font() -> Result<(), PlotError> {
    static DONE: OnceLock<Result<(), (String, String)>> = OnceLock::new();
    DONE.get_or_init(|| {
        let (name, bytes): (String, &'static [u8]) = match std::env::var("AEPIPE_FONT") {
            Ok(p) if !p.is_empty() => match std::fs::read(&p) {
                Ok(b) => (p, Box::leak(b.into_boxed_slice())),
                Err(e) => return Err((p, e.to_string())),
            },
            _ => ("(embedded DejaVu Sans)".into(), dejavu::sans::regular()),
        };
        plotters::style::register_font("sans-serif", FontStyle::Normal, bytes)
            .map_err(|_| (name, "not a TrueType font".to_string()))
    })
    .clone()
    .map_err(|(path, message)| PlotError::Font { path, message })
}

fn err<E: std::fmt::Display>(path: &Path) -> impl Fn(E) -> PlotError + '_ {
    move |e| PlotError::Draw {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

/// The series legend every chart of ours draws: a white box with a black border, 14 px text.
fn draw_legend<'a, DB: DrawingBackend + 'a>(
    c: &mut ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    position: SeriesLabelPosition,
    path: &Path,
) -> Result<(), PlotError> {
    c.configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(err(path))
}

/// Draw a record's waveform (top) and CWT magnitude (bottom) into a PNG.
/// `power` is |W|², `freqs.len()` rows × `rec.samples.len()` columns.
pub fn cwt_png(
    path: &Path,
    rec: &AeRecord,
    freqs: &[f64],
    power: ArrayView2<f32>,
    title: &str,
) -> Result<(), PlotError> {
    cwt_window_png(path, rec, freqs, power, title, 0..rec.samples.len())
}

/// [`cwt_png`] of the samples `window` only (clamped to the record; the CWT is the whole
/// record's, so the window's edges are the transform's, not a cut signal's), the colour scale
/// relative to the window's largest |W|. Times stay on the record's axis (trigger at 0).
pub fn cwt_window_png(
    path: &Path,
    rec: &AeRecord,
    freqs: &[f64],
    power: ArrayView2<f32>,
    title: &str,
    window: std::ops::Range<usize>,
) -> Result<(), PlotError> {
    ensure_font()?;
    let n_all = rec.samples.len();
    let nf = freqs.len();
    assert_eq!(power.dim(), (nf, n_all), "power is freqs × samples");
    let (a, b) = (window.start.min(n_all), window.end.min(n_all));
    let (a, b) = if b > a + 1 { (a, b) } else { (0, n_all) };
    let power = power.slice(ndarray::s![.., a..b]);
    let power = power.as_standard_layout();
    let power = power.as_slice().expect("standard layout");
    let samples = &rec.samples[a..b];
    let n = b - a;
    let fs = rec.sample_rate_hz;
    let t0 = (a as f64 - rec.pretrigger as f64) / fs * 1e6; // µs, trigger at 0
    let t1 = t0 + n as f64 / fs * 1e6;
    let (w, h) = (1100u32, 760u32);
    let root = BitMapBackend::new(path, (w, h)).into_drawing_area();
    let e = err(path);
    root.fill(&WHITE).map_err(&e)?;
    let root = root.titled(title, ("sans-serif", 20)).map_err(&e)?;
    let (top, bottom) = root.split_vertically(230);

    // Waveform, mV.
    let vmax = samples.iter().fold(0f32, |m, v| m.max(v.abs())).max(1e-12) as f64 * 1e3 * 1.05;
    let mut c = ChartBuilder::on(&top)
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(70)
        .build_cartesian_2d(t0..t1, -vmax..vmax)
        .map_err(&e)?;
    c.configure_mesh()
        .x_desc("time (µs)")
        .y_desc("mV")
        .light_line_style(WHITE)
        .draw()
        .map_err(&e)?;
    c.draw_series(LineSeries::new(
        samples
            .iter()
            .enumerate()
            .map(|(i, &v)| (t0 + i as f64 / fs * 1e6, v as f64 * 1e3)),
        BLUE.stroke_width(1),
    ))
    .map_err(&e)?;

    // CWT |W| as an image: each pixel of the plotting area takes its nearest cell.
    let (cwt_area, bar_area) = bottom.split_horizontally(w - 110);
    let (f0, f1) = (freqs[0] / 1e3, freqs[nf - 1] / 1e3);
    let mut c = ChartBuilder::on(&cwt_area)
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(70)
        .build_cartesian_2d(t0..t1, f0..f1)
        .map_err(&e)?;
    c.configure_mesh()
        .x_desc("time (µs)")
        .y_desc("frequency (kHz)")
        .disable_mesh()
        .draw()
        .map_err(&e)?;
    let amax = power.iter().fold(0f32, |m, &v| m.max(v)).sqrt().max(1e-30);
    let area = c.plotting_area();
    let (xr, yr) = area.get_pixel_range();
    let (pw, ph) = ((xr.end - xr.start).max(1), (yr.end - yr.start).max(1));
    for py in 0..ph {
        // top pixel row = highest frequency
        let fi =
            (((ph - 1 - py) as f64 / (ph - 1).max(1) as f64) * (nf - 1) as f64).round() as usize;
        for px in 0..pw {
            let ti = ((px as f64 / (pw - 1).max(1) as f64) * (n - 1) as f64).round() as usize;
            let a = power[fi * n + ti].sqrt() / amax;
            let col = ViridisRGB::get_color(a as f64);
            cwt_area
                .draw_pixel(
                    (
                        xr.start + px - cwt_area.get_base_pixel().0,
                        yr.start + py - cwt_area.get_base_pixel().1,
                    ),
                    &col,
                )
                .map_err(&e)?;
        }
    }
    // Colour bar: |W| relative to its maximum.
    let mut cb = ChartBuilder::on(&bar_area)
        .margin_top(10)
        .margin_bottom(45)
        .margin_right(30)
        .y_label_area_size(45)
        .build_cartesian_2d(0.0..1.0, 0.0..1.0)
        .map_err(&e)?;
    cb.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_labels(6)
        .y_desc("|W| / max")
        .y_label_style(("sans-serif", 13))
        .axis_desc_style(("sans-serif", 13))
        .y_label_formatter(&|v| format!("{v:.1}"))
        .draw()
        .map_err(&e)?;
    cb.draw_series((0..100).map(|k| {
        let v = k as f64 / 100.0;
        Rectangle::new(
            [(0.0, v), (1.0, v + 0.01)],
            ViridisRGB::get_color(v).filled(),
        )
    }))
    .map_err(&e)?;
    root.present().map_err(&e)?;
    Ok(())
}

/// Fig. 4.18 style: power ratio against AE number for the steepest significant windows of
/// one experiment × channel, with their fitted lines. A series of more than
/// `MAX_PLOT_POINTS` hits draws every m-th point and says so in the caption.
pub fn trend_png(path: &Path, pic: &crate::analysis::trend::TrendPicture) -> Result<(), PlotError> {
    use crate::analysis::trend::window_name;
    ensure_font()?;
    let sel = pic.selection;
    let k = sel.hits_used;
    let e = err(path);
    let root = BitMapBackend::new(path, (1000, 620)).into_drawing_area();
    root.fill(&WHITE).map_err(&e)?;
    let ymax = pic.ymax.max(1e-6) * 1.05;
    let sampled = if pic.every > 1 {
        format!("; every {}th point drawn", pic.every)
    } else {
        String::new()
    };
    let mut c = ChartBuilder::on(&root)
        .caption(
            format!(
                "{} ch{}: power ratio vs AE number ({}{sampled})",
                sel.experiment, sel.channel, sel.cutoff
            ),
            ("sans-serif", 18),
        )
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..(k.max(2) as f64 + 1.0), 0.0..ymax)
        .map_err(&e)?;
    c.configure_mesh()
        .x_desc("AE number")
        .y_desc("power ratio")
        .draw()
        .map_err(&e)?;
    let palette = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(148, 103, 189),
        RGBColor(255, 127, 14),
        RGBColor(23, 190, 207),
    ];
    for (i, (r, pts)) in pic.lines.iter().enumerate() {
        let color = palette[i % palette.len()];
        c.draw_series(
            pts.iter()
                .map(|p| Circle::new(*p, 2, color.mix(0.5).filled())),
        )
        .map_err(&e)?;
        let f = r.fit.expect("significant");
        c.draw_series(LineSeries::new(
            [
                (1.0, f.slope + f.intercept),
                (k as f64, f.slope * k as f64 + f.intercept),
            ],
            color.stroke_width(3),
        ))
        .map_err(&e)?
        .label(format!(
            "{}: y = {:.2e}·x + {:.3}, r = {:.2}, p = {:.1e}",
            window_name(&r.column),
            f.slope,
            f.intercept,
            f.r,
            f.p
        ))
        .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], color.stroke_width(3)));
    }
    // (plotters' default position)
    draw_legend(&mut c, SeriesLabelPosition::MiddleRight, path)?;
    root.present().map_err(&e)?;
    Ok(())
}

/// Draw a map-sized grid of values as coloured cells with optional text per cell.
fn grid_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    rows: usize,
    cols: usize,
    values: &[f64],
    text: &dyn Fn(usize) -> String,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let e = |x: DrawingAreaErrorKind<DB::ErrorType>| x.to_string();
    let mut c = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 16))
        .margin(8)
        .x_label_area_size(20)
        .y_label_area_size(25)
        .build_cartesian_2d(0..cols, 0..rows)
        .map_err(e)?;
    c.configure_mesh()
        .disable_mesh()
        .x_labels(cols)
        .y_labels(rows)
        .label_style(("sans-serif", 11))
        .draw()
        .map_err(e)?;
    let (lo, hi) = values
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |m, &v| {
            (m.0.min(v), m.1.max(v))
        });
    let span = if hi > lo { hi - lo } else { 1.0 };
    for (j, &value) in values.iter().enumerate().take(rows * cols) {
        let (r, col) = (j / cols, j % cols);
        // Row 0 at the top, as maps are usually drawn.
        let y = rows - 1 - r;
        let color = ViridisRGB::get_color((value - lo) / span);
        c.draw_series(std::iter::once(Rectangle::new(
            [(col, y), (col + 1, y + 1)],
            color.filled(),
        )))
        .map_err(e)?;
        let t = text(j);
        if !t.is_empty() {
            let style = TextStyle::from(("sans-serif", 12).into_font()).color(&WHITE);
            c.draw_series(std::iter::once(Text::new(t, (col, y + 1), style)))
                .map_err(e)?;
        }
    }
    Ok(())
}

fn short_label(l: &str) -> String {
    match crate::model::Mechanism::parse(l) {
        Some(m) => m.short().into(),
        None => l.chars().take(3).collect(),
    }
}

/// U-matrix of a trained map with each node's label (B bond, F fibre, BF both, E erroneous).
pub fn u_matrix_png(path: &Path, som: &crate::som::Som) -> Result<(), PlotError> {
    ensure_font()?;
    let e = err(path);
    let root = BitMapBackend::new(path, (620, 620)).into_drawing_area();
    root.fill(&WHITE).map_err(&e)?;
    let u = som.u_matrix();
    grid_panel(
        &root,
        "U-matrix (mean distance to 4-neighbours; light = border) and node labels",
        som.rows,
        som.cols,
        u.as_slice().expect("a new array is contiguous"),
        &|j| {
            som.labels
                .get(j)
                .map(|l| short_label(l))
                .unwrap_or_default()
        },
    )
    .map_err(err(path))?;
    root.present().map_err(&e)?;
    Ok(())
}

/// One panel per reference class: how many of its hits land on each node.
pub fn hit_maps_png(
    path: &Path,
    som: &crate::som::Som,
    hits: &std::collections::BTreeMap<String, Vec<f64>>,
) -> Result<(), PlotError> {
    ensure_font()?;
    let e = err(path);
    let n = hits.len().max(1);
    let root = BitMapBackend::new(path, (380 * n as u32, 400)).into_drawing_area();
    root.fill(&WHITE).map_err(&e)?;
    let panels = root.split_evenly((1, n));
    for ((class, counts), area) in hits.iter().zip(panels.iter()) {
        let total: f64 = counts.iter().sum();
        grid_panel(
            area,
            &format!("{class} ({total} hits)"),
            som.rows,
            som.cols,
            counts,
            &|j| {
                if counts[j] > 0.0 {
                    format!("{}", counts[j])
                } else {
                    String::new()
                }
            },
        )
        .map_err(err(path))?;
    }
    root.present().map_err(&e)?;
    Ok(())
}

/// The damage profile of one experiment × channel (Fig. 6.1): the load over time above, and
/// below, for each class, the share of its hits so far (so that a class of 9 hits is as
/// visible as one of 500; the legend gives the totals), with the peak load marked.
///
/// `rows` are (position in the series, row): all of them, or every `every`-th and the last
/// for a long series (the caption says so).
pub fn damage_profile_png(
    path: &Path,
    rows: &[(usize, crate::som::profile::ProfileRow)],
    summary: &crate::som::profile::ProfileSummary,
    every: usize,
) -> Result<(), PlotError> {
    use crate::som::profile::{slot_names, SLOTS};
    ensure_font()?;
    let e = err(path);
    let x_of = |i: usize, r: &crate::som::profile::ProfileRow| r.time_s.unwrap_or(i as f64);
    let xlabel = if rows.iter().all(|(_, r)| r.time_s.is_some()) {
        "time (s)"
    } else {
        "hit (in order)"
    };
    let xmax = rows.iter().map(|(i, r)| x_of(*i, r)).fold(1e-9, f64::max);
    let sampled = if every > 1 {
        format!("; every {every}th hit drawn")
    } else {
        String::new()
    };
    let root = BitMapBackend::new(path, (1000, 640)).into_drawing_area();
    root.fill(&WHITE).map_err(&e)?;
    let (top, bottom) = root.split_vertically(240);
    let lmax = summary.peak_load_n.unwrap_or(1.0).max(1e-9) * 1.05;
    let mut c = ChartBuilder::on(&top)
        .caption(
            format!(
                "{} ch{}: damage profile (Fig. 6.1){sampled}",
                summary.experiment, summary.channel
            ),
            ("sans-serif", 18),
        )
        .margin(12)
        .x_label_area_size(30)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..xmax, 0.0..lmax)
        .map_err(&e)?;
    c.configure_mesh().y_desc("load (N)").draw().map_err(&e)?;
    c.draw_series(LineSeries::new(
        rows.iter()
            .filter_map(|(i, r)| r.load_n.map(|l| (x_of(*i, r), l))),
        BLACK.stroke_width(2),
    ))
    .map_err(&e)?;
    let mut c = ChartBuilder::on(&bottom)
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..xmax, 0.0..1.02)
        .map_err(&e)?;
    c.configure_mesh()
        .x_desc(xlabel)
        .y_desc("share of the class's hits so far")
        .draw()
        .map_err(&e)?;
    let last = rows.last().map(|(_, r)| r.counts).unwrap_or([0; SLOTS]);
    let names = slot_names();
    for k in 0..SLOTS {
        if last[k] == 0 {
            continue;
        }
        let colour = sources::class_colour(names[k]);
        c.draw_series(LineSeries::new(
            rows.iter()
                .map(|(i, r)| (x_of(*i, r), r.counts[k] as f64 / last[k] as f64)),
            colour.stroke_width(2),
        ))
        .map_err(&e)?
        .label(format!("{} ({} hits)", names[k], last[k]))
        .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], colour.stroke_width(2)));
    }
    if let Some(t) = summary.peak_time_s {
        c.draw_series(LineSeries::new(
            [(t, 0.0), (t, 1.02)],
            BLACK.mix(0.6).stroke_width(1),
        ))
        .map_err(&e)?
        .label("peak load")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 20, y)], BLACK.mix(0.6)));
    }
    draw_legend(&mut c, SeriesLabelPosition::UpperLeft, path)?;
    root.present().map_err(&e)?;
    Ok(())
}
