//! The explorable part of the report (issue 41): the run's points as data in the page and
//! a small canvas chart library of our own (no CDN, no request to the network), so the page
//! stays one file that opens offline.
//!
//! Charts: the test over time (the axis chosen), a feature scatter whose axes the reader
//! chooses (RA against AF to start), the event locations and the cumulative hits per class.
//! They zoom (drag; double-click resets), pan (drag with Alt, or the arrow keys), name the
//! point under the pointer (experiment, channel, hit, class), and are linked: a region
//! selected with Shift-drag in one is highlighted in all. Colour is by any class the run
//! has (ch. 4.7 label, SOM class, cluster, zone). A click on a point shows its identity and,
//! for a hit the page embeds (the gallery's), its waveform and CWT; for any other, the
//! `aepipe cwt` command that draws it.

use crate::store::read::HitKey;
use std::fmt::Write;

/// One plottable column of the points.
#[derive(Debug, Clone, Default)]
pub struct PlotColumn {
    pub name: String,
    pub label: String,
    pub values: Vec<Option<f64>>,
}

/// A way to colour the points: its name, the class names, each point's class index.
#[derive(Debug, Clone, Default)]
pub struct Coloring {
    pub name: String,
    pub classes: Vec<String>,
    pub of_point: Vec<Option<u32>>,
}

/// The explorer's data.
#[derive(Debug, Clone, Default)]
pub struct Explorer {
    /// Feature rows in the run, and every how many one is a point.
    pub total: usize,
    pub stride: usize,
    pub keys: Vec<HitKey>,
    pub columns: Vec<PlotColumn>,
    pub colorings: Vec<Coloring>,
    /// The source position (x, y, m) of each point's event.
    pub location: Option<[Vec<Option<f64>>; 2]>,
    /// Hits whose waveform and CWT the page opens (the gallery's pictures).
    pub embedded: Vec<HitKey>,
    /// The run's inputs, as `aepipe cwt` takes them (for the hits not embedded).
    pub inputs: String,
    /// Rows each point stands for, when points were thinned unevenly (the live page's, per
    /// class); else every point stands for `stride`.
    pub weights: Option<Vec<u64>>,
    /// The clustering's validity indices against k.
    pub validity: Option<ValidityCurves>,
}

/// Each validity index against k, and the k chosen.
#[derive(Debug, Clone, Default)]
pub struct ValidityCurves {
    pub k: Vec<f64>,
    /// (index name, its value at each k).
    pub indices: Vec<(String, Vec<Option<f64>>)>,
    pub chosen: usize,
}

impl Explorer {
    /// The explorer thinned evenly (every k-th point) so that its section takes at most
    /// `bytes` (none fit: no points, and the section is left out).
    pub fn within(&self, bytes: usize) -> Explorer {
        self.fitted(bytes).0.into_owned()
    }

    /// [`Explorer::within`] with the fitted explorer's JSON: serialised once when the whole
    /// explorer fits (the usual case), and borrowed rather than copied.
    pub fn fitted(&self, bytes: usize) -> (std::borrow::Cow<'_, Explorer>, String) {
        let json = self.json();
        let have = json.len() + 4096;
        if have <= bytes || self.keys.is_empty() {
            return (std::borrow::Cow::Borrowed(self), json);
        }
        let thin = self.thinned(have, bytes);
        let json = thin.json();
        (std::borrow::Cow::Owned(thin), json)
    }

    /// Every k-th point, so that `have` bytes of section become at most `bytes`.
    fn thinned(&self, have: usize, bytes: usize) -> Explorer {
        let keep = (self.keys.len() as f64 * bytes as f64 / have as f64 * 0.95) as usize;
        if keep == 0 {
            return Explorer::default();
        }
        let k = self.keys.len().div_ceil(keep);
        let pick = |n: usize| (0..n).step_by(k);
        let thin = |v: &Vec<Option<f64>>| pick(v.len()).map(|i| v[i]).collect::<Vec<_>>();
        Explorer {
            total: self.total,
            stride: self.stride * k,
            keys: pick(self.keys.len())
                .map(|i| self.keys[i].clone())
                .collect(),
            columns: self
                .columns
                .iter()
                .map(|c| PlotColumn {
                    values: thin(&c.values),
                    ..c.clone()
                })
                .collect(),
            colorings: self
                .colorings
                .iter()
                .map(|c| Coloring {
                    of_point: pick(c.of_point.len()).map(|i| c.of_point[i]).collect(),
                    ..c.clone()
                })
                .collect(),
            location: self.location.as_ref().map(|[x, y]| [thin(x), thin(y)]),
            weights: self
                .weights
                .as_ref()
                .map(|w| pick(w.len()).map(|i| w[i] * k as u64).collect()),
            ..self.clone()
        }
    }

    /// A column's values by name.
    pub fn column(&self, name: &str) -> Option<&[Option<f64>]> {
        self.columns
            .iter()
            .find(|c| c.name == name)
            .map(|c| c.values.as_slice())
    }

    /// Colour by `name`: each point's class (in point order).
    pub fn add_coloring(&mut self, name: &str, of_point: Vec<Option<String>>) {
        let mut classes: Vec<String> = of_point.iter().flatten().cloned().collect();
        classes.sort();
        classes.dedup();
        let of_point = of_point
            .iter()
            .map(|c| {
                c.as_ref()
                    .and_then(|c| classes.binary_search(c).ok())
                    .map(|i| i as u32)
            })
            .collect();
        self.colorings.push(Coloring {
            name: name.to_string(),
            classes,
            of_point,
        });
    }

    /// The data as JSON (numbers in their shortest round-trip form of f32: the page plots
    /// them, it does not compute with them).
    pub fn json(&self) -> String {
        let mut j = String::with_capacity(self.keys.len() * 120);
        let mut exps: Vec<&str> = self.keys.iter().map(|k| k.0.as_str()).collect();
        exps.sort();
        exps.dedup();
        let _ = write!(
            j,
            "{{\"total\":{},\"stride\":{},\"experiments\":{},",
            self.total,
            self.stride,
            strings(exps.iter().copied())
        );
        let ex: Vec<String> = self
            .keys
            .iter()
            .map(|k| exps.binary_search(&k.0.as_str()).unwrap_or(0).to_string())
            .collect();
        let _ = write!(j, "\"exp\":[{}],", ex.join(","));
        let ch: Vec<String> = self.keys.iter().map(|k| k.1.to_string()).collect();
        let _ = write!(j, "\"ch\":[{}],", ch.join(","));
        let hit: Vec<String> = self.keys.iter().map(|k| k.2.to_string()).collect();
        let _ = write!(j, "\"hit\":[{}],\"columns\":[", hit.join(","));
        for (i, c) in self.columns.iter().enumerate() {
            let _ = write!(
                j,
                "{}{{\"name\":{},\"label\":{},\"v\":{}}}",
                if i > 0 { "," } else { "" },
                string(&c.name),
                string(&c.label),
                numbers(&c.values)
            );
        }
        j.push_str("],\"colorings\":[");
        for (i, c) in self.colorings.iter().enumerate() {
            let of: Vec<String> = c
                .of_point
                .iter()
                .map(|v| v.map_or("null".into(), |v| v.to_string()))
                .collect();
            let _ = write!(
                j,
                "{}{{\"name\":{},\"classes\":{},\"of\":[{}]}}",
                if i > 0 { "," } else { "" },
                string(&c.name),
                strings(c.classes.iter().map(String::as_str)),
                of.join(",")
            );
        }
        j.push(']');
        if let Some([x, y]) = &self.location {
            let _ = write!(j, ",\"loc_x\":{},\"loc_y\":{}", numbers(x), numbers(y));
        }
        if let Some(v) = &self.validity {
            let idx: Vec<String> = v
                .indices
                .iter()
                .map(|(n, vals)| format!("{}:{}", string(n), numbers(vals)))
                .collect();
            let ks: Vec<Option<f64>> = v.k.iter().map(|k| Some(*k)).collect();
            let _ = write!(
                j,
                ",\"validity\":{{\"k\":{},\"chosen\":{},\"indices\":{{{}}}}}",
                numbers(&ks),
                v.chosen,
                idx.join(",")
            );
        }
        if let Some(w) = &self.weights {
            let w: Vec<String> = w.iter().map(u64::to_string).collect();
            let _ = write!(j, ",\"w\":[{}]", w.join(","));
        }
        let emb: Vec<String> = self.embedded.iter().map(|k| string(&key_text(k))).collect();
        let _ = write!(
            j,
            ",\"embedded\":[{}],\"inputs\":{}}}",
            emb.join(","),
            string(&self.inputs)
        );
        j
    }
}

/// "experiment|channel|hit": how the page names a hit (and the gallery's pictures).
pub fn key_text(k: &HitKey) -> String {
    format!("{}|{}|{}", k.0, k.1, k.2)
}

fn string(s: &str) -> String {
    // JSON, and safe inside a <script> element (no "</").
    serde_json::to_string(s)
        .expect("a string serialises")
        .replace("</", "<\\/")
}

fn strings<'a>(v: impl Iterator<Item = &'a str>) -> String {
    format!("[{}]", v.map(string).collect::<Vec<_>>().join(","))
}

fn numbers(v: &[Option<f64>]) -> String {
    let s: Vec<String> = v
        .iter()
        .map(|x| match x {
            Some(x) if x.is_finite() => format!("{}", *x as f32),
            _ => "null".into(),
        })
        .collect();
    format!("[{}]", s.join(","))
}

/// The section: its controls, the charts, the detail panel, the data and the code.
pub fn section(h: &mut String, e: &Explorer) {
    section_with(h, e, &e.json());
}

/// [`section`] with the explorer's JSON already made ([`Explorer::fitted`]).
pub fn section_with(h: &mut String, e: &Explorer, json: &str) {
    if e.keys.is_empty() {
        return;
    }
    let thinned = if e.keys.len() < e.total {
        format!(
            " {} of the {} rows are points, taken evenly{}: the page stays small; the tables \
             hold every row.",
            e.keys.len(),
            e.total,
            match e.stride > 1 {
                true => format!(" (every {}th)", e.stride),
                false => String::new(),
            }
        )
    } else {
        format!(" All {} rows are points.", e.total)
    };
    let _ = write!(
        h,
        "<h2 id=explore>Explore</h2><p>Drag to zoom, double-click to reset, Alt-drag or arrow \
         keys to pan; Shift-drag selects a region, highlighted in every chart; a click on a \
         point opens it.{}</p>\
         <p>Colour by <select id=ex-color></select> · scatter <select id=ex-x></select> against \
         <select id=ex-y></select> · over the test <select id=ex-t></select> \
         <button id=ex-clear>clear selection</button> <span id=ex-sel></span></p>\
         <style>#ex-tip{{position:absolute;display:none;background:#ffe;border:1px solid #aa8;\
         padding:2px 6px;font-size:12px;pointer-events:none}}#ex-charts canvas{{border:1px solid #ccc}}\
         #ex-charts figure{{margin:0 0 8px 0}}</style>\
         <div id=ex-legend></div><div id=ex-charts></div><div id=ex-tip></div>\
         <div id=ex-detail><p>Click a point.</p></div>\
         <script id=explore-data type=application/json>{}</script><script>{}</script>",
        super::esc(&thinned),
        json,
        SCRIPT
    );
}

/// The charts' code (canvas, no library).
const SCRIPT: &str = include_str!("explore.js");

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    pub(in crate::report) fn explorer(n: usize) -> Explorer {
        let mut e = Explorer {
            total: n,
            stride: 1,
            keys: (0..n).map(|i| ("e".to_string(), 1, i as i64 + 1)).collect(),
            columns: vec![PlotColumn {
                name: "time_s".into(),
                label: "time (s)".into(),
                values: (0..n).map(|i| Some(i as f64 * 0.123_456)).collect(),
            }],
            ..Default::default()
        };
        e.add_coloring(
            "class",
            (0..n).map(|i| Some(format!("c{}", i % 3))).collect(),
        );
        e
    }

    /// Thinned to a byte budget: its JSON fits, every k-th point is kept with its own
    /// values and class, and the stride says how many rows a point stands for.
    #[test]
    fn an_explorer_thins_evenly_to_fit_its_budget() {
        let e = explorer(10_000);
        let full = e.json().len();
        assert_eq!(e.within(full + 10_000).keys.len(), 10_000);
        let t = e.within(full / 3);
        assert!(
            t.json().len() <= full / 3,
            "{} > {}",
            t.json().len(),
            full / 3
        );
        let k = t.stride;
        assert!((3..=5).contains(&k), "stride {k}");
        assert_eq!(t.keys.len(), 10_000usize.div_ceil(k));
        for (j, key) in t.keys.iter().enumerate() {
            assert_eq!(key.2 as usize, j * k + 1);
            assert_eq!(t.columns[0].values[j], e.columns[0].values[j * k]);
            assert_eq!(t.colorings[0].of_point[j], e.colorings[0].of_point[j * k]);
        }
        assert!(e.within(10).keys.is_empty());
    }
}
