//! `DIR/live.html`: the operator's page, rewritten atomically at each flush and reloading
//! itself every few seconds. Self-contained (inline SVG, no script), so any browser shows
//! it from the disk.

use super::{Flush, State, WatchDir, WatchError};
use crate::config::ValidConfig;
use crate::report::esc;
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
}

/// CWT pictures the page shows (the latest hits'), and the files they rotate through.
const CWTS: usize = 3;

/// The CWT picture of the last hit of a one-hit-per-file source, windowed on its burst as
/// the report's gallery is: (picture, caption), or `None` when it cannot be read or drawn
/// (the page then keeps the earlier ones).
pub fn draw_latest(
    dir: &WatchDir,
    cfg: &ValidConfig,
    p: &super::follow::Pending,
    slot: u32,
) -> Option<(String, String)> {
    let last = p.source.files.last()?.clone();
    let src = crate::ingest::Source {
        first_hit: p.source.first_hit + p.source.files.len() as u64 - 1,
        files: vec![last],
        ..p.source.clone()
    };
    let r = crate::ingest::open(&src, cfg).find_map(|it| match it {
        crate::model::Item::Record(r) => Some(r),
        _ => None,
    })?;
    crate::features::validate(&r, cfg).ok()?;
    let rel = format!("watch/live/latest-{}.png", slot as usize % CWTS);
    let png = dir.path().join(&rel);
    std::fs::create_dir_all(png.parent()?).ok()?;
    let mut ex = crate::features::FeatureExtractor::new(cfg);
    let title = crate::workflow::burst_picture(&mut ex, &r, &png, None).ok()?;
    Some((rel, title))
}

impl Page {
    pub fn new(state: &State) -> Page {
        Page {
            start: Instant::now(),
            points: vec![(0.0, state.hits, state.classes.clone())],
            lines: Vec::new(),
            cwts: Vec::new(),
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
             <meta http-equiv=\"refresh\" content=\"{refresh}\">\
             <title>aepipe watch</title><style>\
             body{{font-family:sans-serif;margin:1.5em;color:#222}}\
             td,th{{padding:2px 10px;text-align:right}}th{{text-align:left}}\
             .line{{font-family:monospace;font-size:90%}}</style></head><body>\
             <h1>aepipe watch</h1><p>{} hits, {} feature rows, {} rejects in {} flushes \
             (this page reloads every {refresh} s).</p>",
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
        h.push_str(&self.svg(state));
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

    /// Cumulative rows per class (and hits in all) against the watch's time.
    fn svg(&self, state: &State) -> String {
        let (w, ht, pad) = (640.0, 300.0, 40.0);
        let t_max = self.points.last().map_or(1.0, |p| p.0).max(1.0);
        let y_max = self.points.iter().map(|p| p.1).max().unwrap_or(0).max(1) as f64;
        let x = |t: f64| pad + (w - 2.0 * pad) * t / t_max;
        let y = |v: f64| ht - pad - (ht - 2.0 * pad) * v / y_max;
        let mut s = format!(
            "<h2>Hits against time</h2><svg xmlns=\"http://www.w3.org/2000/svg\" \
             width=\"{w}\" height=\"{ht}\"><rect x=\"{pad}\" y=\"{pad}\" width=\"{}\" \
             height=\"{}\" fill=\"none\" stroke=\"#999\"/>\
             <text x=\"{pad}\" y=\"{}\" font-size=\"12\">0</text>\
             <text x=\"{}\" y=\"{}\" font-size=\"12\" text-anchor=\"end\">{t_max:.0} s</text>\
             <text x=\"4\" y=\"{}\" font-size=\"12\">{y_max:.0}</text>",
            w - 2.0 * pad,
            ht - 2.0 * pad,
            ht - pad + 16.0,
            w - pad,
            ht - pad + 16.0,
            pad + 4.0
        );
        const COLOURS: [&str; 6] = [
            "#d62728", "#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b",
        ];
        let mut series: Vec<(String, Vec<(f64, f64)>)> = vec![(
            "all hits".into(),
            self.points.iter().map(|p| (p.0, p.1 as f64)).collect(),
        )];
        for c in state.classes.keys() {
            series.push((
                c.clone(),
                self.points
                    .iter()
                    .map(|p| (p.0, p.2.get(c).copied().unwrap_or(0) as f64))
                    .collect(),
            ));
        }
        for (i, (name, pts)) in series.iter().enumerate() {
            let colour = if i == 0 {
                "#000"
            } else {
                COLOURS[(i - 1) % COLOURS.len()]
            };
            let path: Vec<String> = pts
                .iter()
                .map(|(t, v)| format!("{:.1},{:.1}", x(*t), y(*v)))
                .collect();
            let _ = write!(
                s,
                "<polyline fill=\"none\" stroke=\"{colour}\" stroke-width=\"2\" points=\"{}\"/>\
                 <text x=\"{}\" y=\"{}\" font-size=\"12\" fill=\"{colour}\">{}</text>",
                path.join(" "),
                w - pad + 4.0 - 120.0,
                pad + 14.0 * (i as f64 + 1.0),
                esc(name)
            );
        }
        s.push_str("</svg>");
        s
    }
}
