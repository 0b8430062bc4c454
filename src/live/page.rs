//! `DIR/live.html`: the operator's page, rewritten atomically at each flush and reloading
//! itself every few seconds. Self-contained (inline SVG, no script), so any browser shows
//! it from the disk.

use super::{Flush, State, WatchDir, WatchError};
use crate::config::ValidConfig;
use crate::report::esc;
use crate::report::explore::Explorer;
use crate::store::HitKey;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::time::Instant;

/// How many flush lines the page lists.
const LINES: usize = 20;

/// The page's history: cumulative rows per class at each flush.
pub struct Page {
    start: Instant,
    /// (seconds since the watch started, hits in all, class → rows in all).
    points: Vec<(f64, u64, BTreeMap<String, u64>)>,
    lines: Vec<String>,
    /// The latest hits' CWT pictures (relative to DIR), newest first.
    cwts: Vec<(String, String)>,
    /// Class → the classified rows' (time, load) since this watcher started, thinned.
    by_class: BTreeMap<String, Thinned>,
    /// The watched inputs, as `aepipe cwt` takes them (the explorer's command for a hit).
    pub inputs: String,
}

/// Points kept for a picture: every `stride`-th one, the stride doubled whenever more than
/// [`KEEP`] are kept (bounded memory over a test of any length).
#[derive(Default)]
struct Thinned {
    stride: u64,
    seen: u64,
    /// (time, load, the row's key and amplitude).
    pts: Vec<(f64, Option<f64>, HitKey, Option<f64>)>,
}

/// Points kept per class at most.
const KEEP: usize = 4000;

impl Thinned {
    fn push(&mut self, p: (f64, Option<f64>, HitKey, Option<f64>)) {
        self.stride = self.stride.max(1);
        if self.seen.is_multiple_of(self.stride) {
            self.pts.push(p);
            if self.pts.len() > KEEP {
                let mut k = 0;
                self.pts.retain(|_| {
                    k += 1;
                    k % 2 == 1
                });
                self.stride *= 2;
            }
        }
        self.seen += 1;
    }
}

/// CWT pictures the page shows (the latest hits'), and the files they rotate through.
const CWTS: usize = 3;

/// The last record of a pending source: its last file read again (one hit per file), a
/// growing pair's latest transient read alone, or a chain's or a stream's last one taken from
/// its items.
pub fn latest_record(
    p: &super::pending::Pending,
    cfg: &ValidConfig,
) -> Option<crate::model::AeRecord> {
    use super::pending::Part;
    use crate::model::Item;
    match &p.part {
        Some(Part::Vallen(w)) => crate::ingest::vallen::tail::last_record(w, &cfg.ingest),
        Some(Part::Dta { items, .. } | Part::Stream { items, .. }) => {
            items.lock().ok()?.iter().rev().find_map(|i| match i {
                Item::Record(r) => Some(r.clone()),
                _ => None,
            })
        }
        None if p.per_hit() => {
            let last = p.source.files.last()?.clone();
            let src = crate::ingest::Source {
                first_hit: p.source.first_hit + p.source.files.len() as u64 - 1,
                files: vec![last],
                ..p.source.clone()
            };
            crate::ingest::open(&src, cfg.read_settings(), &cfg.load).find_map(|it| match it {
                Item::Record(r) => Some(r),
                _ => None,
            })
        }
        None => None,
    }
}

/// The CWT picture of a record, windowed on its burst as the report's gallery is:
/// (picture, caption), or `None` when it cannot be drawn (the page then keeps the earlier
/// ones).
pub fn draw_latest(
    dir: &WatchDir,
    cfg: &ValidConfig,
    r: &crate::model::AeRecord,
    slot: u32,
) -> Option<(String, String)> {
    crate::features::validate(r, &cfg.validate).ok()?;
    let rel = format!("watch/live/latest-{}.png", slot as usize % CWTS);
    let png = dir.path().join(&rel);
    std::fs::create_dir_all(png.parent()?).ok()?;
    let mut ex = crate::features::FeatureExtractor::new(cfg);
    let title = crate::workflow::burst_picture(&mut ex, r, &png, None).ok()?;
    Some((rel, title))
}

impl Page {
    pub fn new(state: &State) -> Page {
        Page {
            start: Instant::now(),
            points: vec![(0.0, state.hits, state.classes.clone())],
            lines: Vec::new(),
            cwts: Vec::new(),
            by_class: BTreeMap::new(),
            inputs: String::new(),
        }
    }

    pub fn add(&mut self, f: &Flush, state: &State, cwt: Option<(String, String)>) {
        if let Some(c) = cwt {
            self.cwts.retain(|(p, _)| *p != c.0);
            self.cwts.insert(0, c);
            self.cwts.truncate(CWTS);
        }
        self.points.push((
            self.start.elapsed().as_secs_f64(),
            state.hits,
            state.classes.clone(),
        ));
        for p in &f.points {
            let th = self.by_class.entry(p.class.clone()).or_default();
            th.push((p.time_s, p.load_n, p.key.clone(), p.amplitude_db));
        }
        self.lines.push(f.line());
        if self.lines.len() > LINES {
            self.lines.remove(0);
        }
    }

    pub fn write(
        &self,
        dir: &WatchDir,
        state: &State,
        last: Option<&Flush>,
        cfg: &ValidConfig,
    ) -> Result<(), WatchError> {
        let refresh = (cfg.live.flush_s.ceil() as u64).max(1);
        let mut h = String::new();
        let _ = write!(
            h,
            "<!doctype html><html><head><meta charset=\"utf-8\">\
             <noscript><meta http-equiv=\"refresh\" content=\"{refresh}\"></noscript>\
             <title>aepipe watch</title><style>\
             body{{font-family:sans-serif;margin:1.5em;color:#222}}\
             td,th{{padding:2px 10px;text-align:right}}th{{text-align:left}}\
             .line{{font-family:monospace;font-size:90%}}</style></head><body>\
             <h1>aepipe watch</h1><p>{} hits, {} feature rows, {} rejects in {} flushes \
             (this page reloads every {refresh} s; <label><input type=checkbox id=hold> hold \
             this view</label>).</p><script>setTimeout(function again() {{\
             if (document.getElementById('hold').checked) return setTimeout(again, 1000);\
             location.reload(); }}, {refresh}000);</script>",
            state.hits, state.rows, state.rejects, state.flushes
        );
        if let Some(f) = last {
            let _ = write!(
                h,
                "<p>Last flush: <b>+{}</b> hits, {:.0} hits/s, lag {:.1} s from the newest \
                 file's last write.</p>",
                f.hits, f.hits_per_s, f.lag_s
            );
        }
        if !state.classes.is_empty() {
            h.push_str("<table><tr><th>SOM class</th><th>rows</th><th>share</th></tr>");
            let total: u64 = state.classes.values().sum();
            for (c, n) in &state.classes {
                let _ = write!(
                    h,
                    "<tr><th>{}</th><td>{n}</td><td>{:.1} %</td></tr>",
                    esc(c),
                    100.0 * *n as f64 / total.max(1) as f64
                );
            }
            h.push_str("</table>");
        }
        crate::report::explore::section(&mut h, &self.explorer());
        if self.by_class.is_empty() {
            h.push_str(&self.svg(state));
        } else {
            h.push_str(&self.by_time());
            h.push_str(&self.profile());
        }
        if !self.cwts.is_empty() {
            h.push_str("<h2>The latest hits</h2>");
            for (png, caption) in &self.cwts {
                // The flush number in the query: a browser does not show a cached picture
                // of the same name.
                let _ = write!(
                    h,
                    "<figure><img src=\"{}?{}\" width=\"550\" alt=\"{}\">\
                     <figcaption>{}</figcaption></figure>",
                    esc(png),
                    state.flushes,
                    esc(caption),
                    esc(caption)
                );
            }
        }
        h.push_str("<h2>Flushes</h2>");
        for l in self.lines.iter().rev() {
            let _ = write!(h, "<div class=\"line\">{}</div>", esc(l));
        }
        let _ = write!(
            h,
            "<p>Tables: the Hive datasets <code>features/</code>, <code>hits/</code>, \
             <code>rejects/</code>, <code>classification/</code> in {} \
             (e.g. <code>pl.scan_parquet(\"{}/features/**/*.parquet\")</code>).</p>\
             </body></html>",
            esc(&dir.path().display().to_string()),
            esc(&dir.path().display().to_string())
        );
        crate::util::write_atomic(&dir.live_html(), h.as_bytes())?;
        Ok(())
    }

    /// The classified rows kept, for the explorable charts (each point weighs the rows it
    /// stands for).
    fn explorer(&self) -> Explorer {
        let mut e = Explorer {
            stride: 1,
            inputs: self.inputs.clone(),
            ..Default::default()
        };
        let (mut time, mut load, mut amp) = (Vec::new(), Vec::new(), Vec::new());
        let (mut classes, mut weights) = (Vec::new(), Vec::new());
        for (c, th) in &self.by_class {
            for p in &th.pts {
                e.keys.push(p.2.clone());
                time.push(Some(p.0));
                load.push(p.1);
                amp.push(p.3);
                classes.push(Some(c.clone()));
                weights.push(th.stride);
            }
            e.total += th.seen as usize;
        }
        let col = |name: &str, label: &str, values| crate::report::explore::PlotColumn {
            name: name.into(),
            label: label.into(),
            values,
        };
        e.columns = vec![
            col("time_s", "time (s)", time),
            col("load_n", "load (N)", load),
            col("peak_amplitude_db", "amplitude (dB_AE)", amp),
        ];
        e.add_coloring("SOM class", classes);
        e.weights = Some(weights);
        e
    }

    /// Cumulative classified rows per class against the hits' own time (since this
    /// watcher started).
    fn by_time(&self) -> String {
        let all = self
            .by_class
            .values()
            .flat_map(|c| c.pts.iter().map(|p| p.0));
        let (t0, t1) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), t| {
            (a.min(t), b.max(t))
        });
        let series: Vec<(String, Vec<(f64, f64)>)> = self
            .by_class
            .iter()
            .map(|(c, th)| {
                let mut ts: Vec<f64> = th.pts.iter().map(|p| p.0).collect();
                ts.sort_by(f64::total_cmp);
                let pts = ts
                    .iter()
                    .enumerate()
                    .map(|(i, t)| (*t, ((i as u64 + 1) * th.stride) as f64))
                    .collect();
                (c.clone(), pts)
            })
            .collect();
        let y_max = series
            .iter()
            .filter_map(|s| s.1.last().map(|p| p.1))
            .fold(1.0, f64::max);
        let mut s = String::from("<h2>Classified rows per class against the hits' time</h2>");
        s.push_str(&frame(t0, t1, 0.0, y_max, "s (acquisition clock)", "rows"));
        let (x, y) = scales(t0, t1, 0.0, y_max);
        for (i, (name, pts)) in series.iter().enumerate() {
            let at = pts.iter().map(|(t, v)| (x(*t), y(*v)));
            line(&mut s, at, COLOURS[i % COLOURS.len()], name, i);
        }
        s.push_str("</svg>");
        s
    }

    /// The damage profile so far (Fig. 6.1): each classified row at its time and load, the
    /// peak load so far, and the rows per class before and after it.
    fn profile(&self) -> String {
        let pts: Vec<(usize, f64, f64)> = self
            .by_class
            .values()
            .enumerate()
            .flat_map(|(i, c)| c.pts.iter().filter_map(move |p| Some((i, p.0, p.1?))))
            .filter(|p| p.2.is_finite())
            .collect();
        if pts.is_empty() {
            return "<p>No load with the hits (no load channel or load file): no damage \
                    profile.</p>"
                .into();
        }
        let (t0, t1) = pts
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                (a.min(p.1), b.max(p.1))
            });
        let peak = pts.iter().fold((f64::NAN, f64::NEG_INFINITY), |m, p| {
            if p.2 > m.1 {
                (p.1, p.2)
            } else {
                m
            }
        });
        let l_min = pts
            .iter()
            .map(|p| p.2)
            .fold(f64::INFINITY, f64::min)
            .min(0.0);
        let mut s = String::from("<h2>Damage profile so far</h2>");
        s.push_str(&frame(t0, t1, l_min, peak.1, "s (acquisition clock)", "N"));
        let (x, y) = scales(t0, t1, l_min, peak.1);
        for &(i, t, l) in &pts {
            let _ = write!(
                s,
                "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"2\" fill=\"{}\" fill-opacity=\"0.6\"/>",
                x(t),
                y(l),
                COLOURS[i % COLOURS.len()]
            );
        }
        // The label on the side of the line with room for it.
        let (lx, anchor) = if x(peak.0) > W / 2.0 {
            (x(peak.0) - 4.0, "end")
        } else {
            (x(peak.0) + 4.0, "start")
        };
        let _ = write!(
            s,
            "<line x1=\"{0:.1}\" x2=\"{0:.1}\" y1=\"{PAD}\" y2=\"{1}\" stroke=\"#000\" \
             stroke-dasharray=\"4 3\"/><text x=\"{lx:.1}\" y=\"{2}\" font-size=\"12\" \
             text-anchor=\"{anchor}\">peak load {3:.1} N at {4:.2} s</text>",
            x(peak.0),
            H - PAD,
            H - PAD - 6.0,
            peak.1,
            peak.0
        );
        for (i, c) in self.by_class.keys().enumerate() {
            let colour = COLOURS[i % COLOURS.len()];
            let _ = write!(
                s,
                "<text x=\"{}\" y=\"{}\" font-size=\"12\" fill=\"{colour}\">{}</text>",
                PAD + 6.0,
                PAD + 14.0 * (i as f64 + 1.0),
                esc(c)
            );
        }
        s.push_str(
            "</svg><table><tr><th>SOM class</th><th>before the peak load</th><th>after</th></tr>",
        );
        for (c, th) in &self.by_class {
            let before = th.pts.iter().filter(|p| p.0 <= peak.0).count() as u64 * th.stride;
            let after = th.pts.len() as u64 * th.stride - before;
            let approx = if th.stride > 1 { "≈ " } else { "" };
            let _ = write!(
                s,
                "<tr><th>{}</th><td>{approx}{before}</td><td>{approx}{after}</td></tr>",
                esc(c)
            );
        }
        s.push_str("</table>");
        s
    }

    /// Cumulative rows per class (and hits in all) against the watch's time.
    fn svg(&self, state: &State) -> String {
        let t_max = self.points.last().map_or(1.0, |p| p.0).max(1.0);
        let y_max = self.points.iter().map(|p| p.1).max().unwrap_or(0).max(1) as f64;
        let mut s = String::from("<h2>Hits against time</h2>");
        s.push_str(&frame(0.0, t_max, 0.0, y_max, "s (watch)", "hits"));
        let (x, y) = scales(0.0, t_max, 0.0, y_max);
        let all = self.points.iter().map(|p| (x(p.0), y(p.1 as f64)));
        line(&mut s, all, "#000", "all hits", 0);
        for (i, c) in state.classes.keys().enumerate() {
            let pts = self
                .points
                .iter()
                .map(|p| (x(p.0), y(p.2.get(c).copied().unwrap_or(0) as f64)));
            line(&mut s, pts, COLOURS[i % COLOURS.len()], c, i + 1);
        }
        s.push_str("</svg>");
        s
    }
}

const COLOURS: [&str; 6] = [
    "#d62728", "#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b",
];
/// A named series (picture coordinates) as a line, its name in the legend's row `row` at
/// the top right.
fn line(
    s: &mut String,
    pts: impl Iterator<Item = (f64, f64)>,
    colour: &str,
    name: &str,
    row: usize,
) {
    let path: Vec<String> = pts.map(|(x, y)| format!("{x:.1},{y:.1}")).collect();
    let _ = write!(
        s,
        "<polyline fill=\"none\" stroke=\"{colour}\" stroke-width=\"2\" points=\"{}\"/>\
         <text x=\"{}\" y=\"{}\" font-size=\"12\" fill=\"{colour}\">{}</text>",
        path.join(" "),
        W - PAD - 116.0,
        PAD + 14.0 * (row as f64 + 1.0),
        esc(name)
    );
}

/// A picture's width, height and margin (px).
const W: f64 = 640.0;
const H: f64 = 300.0;
const PAD: f64 = 40.0;

/// Data to picture coordinates: x over `[x0, x1]`, y over `[y0, y1]`.
fn scales(x0: f64, x1: f64, y0: f64, y1: f64) -> (impl Fn(f64) -> f64, impl Fn(f64) -> f64) {
    let (dx, dy) = ((x1 - x0).max(1e-9), (y1 - y0).max(1e-9));
    (
        move |x: f64| PAD + (W - 2.0 * PAD) * (x - x0) / dx,
        move |y: f64| H - PAD - (H - 2.0 * PAD) * (y - y0) / dy,
    )
}

/// An SVG's opening: its frame and the axes' ends with their units.
fn frame(x0: f64, x1: f64, y0: f64, y1: f64, x_unit: &str, y_unit: &str) -> String {
    format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{W}\" height=\"{H}\">\
         <rect x=\"{PAD}\" y=\"{PAD}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"#999\"/>\
         <text x=\"{PAD}\" y=\"{}\" font-size=\"12\">{}</text>\
         <text x=\"{}\" y=\"{}\" font-size=\"12\" text-anchor=\"end\">{} {}</text>\
         <text x=\"4\" y=\"{}\" font-size=\"12\">{} {}</text>\
         <text x=\"4\" y=\"{}\" font-size=\"12\">{}</text>",
        W - 2.0 * PAD,
        H - 2.0 * PAD,
        H - PAD + 16.0,
        num(x0),
        W - PAD,
        H - PAD + 16.0,
        num(x1),
        esc(x_unit),
        PAD - 6.0,
        num(y1),
        esc(y_unit),
        H - PAD,
        num(y0),
    )
}

/// A number for an axis end: a few significant digits.
fn num(v: f64) -> String {
    if v.abs() >= 100.0 || v == 0.0 {
        format!("{v:.0}")
    } else {
        format!("{v:.3}")
    }
}
