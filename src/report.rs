//! The HTML report of a run: one self-contained file (pictures embedded as data URIs) with
//! the inputs and rejects, per-experiment class counts, the trend table and plot (Table 4.3,
//! Fig. 4.18), a CWT gallery by class (Appendix B), the U-matrix and hit maps, the confusion
//! (Table 5.4 orientation), the accuracy against ground truth, and the manifest.

use crate::workflow::RunSummary;
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::Path;

/// Standard base64 (RFC 4648) of `data`.
pub fn base64(data: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(data.len().div_ceil(3) * 4);
    for c in data.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn img(path: &Path, alt: &str, width: Option<u32>) -> String {
    match std::fs::read(path) {
        Ok(bytes) => format!(
            "<img alt=\"{}\" src=\"data:image/png;base64,{}\"{}>",
            esc(alt),
            base64(&bytes),
            width.map(|w| format!(" width=\"{w}\"")).unwrap_or_default()
        ),
        Err(e) => format!(
            "<p class=\"missing\">{}: {}</p>",
            esc(&path.display().to_string()),
            esc(&e.to_string())
        ),
    }
}

/// Write the report of `s` to `path`.
pub fn write(s: &RunSummary, path: &Path) -> Result<(), String> {
    let html = render(s)?;
    crate::pipeline::write_atomic(path, html.as_bytes())
        .map_err(|e| format!("{}: {e}", path.display()))
}

/// Read a string column of a table, keyed by (experiment, channel, hit).
fn column(path: &Path, name: &str) -> BTreeMap<(String, i32, i64), String> {
    crate::workflow::keyed_column(path, name)
        .unwrap_or_default()
        .into_iter()
        .collect()
}

pub fn render(s: &RunSummary) -> Result<String, String> {
    let mut h = String::new();
    let title = format!("aepipe run — {}", s.out.display());
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title><style>\
body{{font-family:sans-serif;margin:2em;max-width:1200px}}table{{border-collapse:collapse;margin:1em 0}}\
td,th{{border:1px solid #bbb;padding:3px 8px;text-align:right}}th{{background:#eee}}td.l,th.l{{text-align:left}}\
.gallery{{display:flex;flex-wrap:wrap;gap:6px}}.gallery figure{{margin:0;width:270px}}figcaption{{font-size:11px}}\
pre{{background:#f6f6f6;padding:8px;overflow-x:auto}}.missing{{color:#b00}}</style></head><body>\n<h1>{}</h1>\n",
        esc(&title),
        esc(&title)
    );
    // Inputs and rejects.
    let st = &s.features.stats;
    let _ = write!(
        h,
        "<h2>Inputs</h2><p>{} input path(s): {}</p><table><tr><th class=l>experiment</th><th>feature rows</th><th>rejects</th></tr>",
        s.inputs.len(),
        esc(&s.inputs.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", "))
    );
    for (e, c) in &st.by_experiment {
        let _ = write!(
            h,
            "<tr><td class=l>{}</td><td>{}</td><td>{}</td></tr>",
            esc(e),
            c.rows,
            c.rejects
        );
    }
    let _ = write!(
        h,
        "</table><p>{} records read, {} rows, {} rejects.</p>",
        st.records_read, st.rows, st.rejects
    );
    if !st.first_rejects.is_empty() {
        let _ = write!(
            h,
            "<h3>Rejects</h3><pre>{}</pre>",
            esc(&st.first_rejects.join("\n"))
        );
    }
    // Class counts per experiment.
    let crit = column(&s.features.table_path, "criteria_label");
    let som = s
        .som
        .as_ref()
        .map(|m| column(&m.classification, "som_label"))
        .unwrap_or_default();
    let mut classes: BTreeSet<String> = crit.values().cloned().collect();
    classes.extend(som.values().cloned());
    let experiments: BTreeSet<String> = crit.keys().map(|k| k.0.clone()).collect();
    let _ = write!(
        h,
        "<h2>Hits by class</h2><table><tr><th class=l>experiment</th><th class=l>labels</th>"
    );
    for c in &classes {
        let _ = write!(h, "<th>{}</th>", esc(c));
    }
    h.push_str("</tr>");
    for e in &experiments {
        for (name, map) in [("ch. 4.7 criteria", &crit), ("SOM", &som)] {
            if map.is_empty() {
                continue;
            }
            let _ = write!(h, "<tr><td class=l>{}</td><td class=l>{name}</td>", esc(e));
            for c in &classes {
                let n = map.iter().filter(|(k, v)| &k.0 == e && *v == c).count();
                let _ = write!(h, "<td>{n}</td>");
            }
            h.push_str("</tr>");
        }
    }
    h.push_str("</table>");
    // Trend.
    if let Some(t) = &s.trend {
        let _ = write!(h, "<h2>Trend of the power ratios (ch. 4.5.5)</h2>");
        for sel in &t.selections {
            let _ = write!(
                h,
                "<p>{} ch{}: {} of {} hits used ({}{}).</p>",
                esc(&sel.experiment),
                sel.channel,
                sel.hits_used,
                sel.hits_total,
                esc(&sel.cutoff),
                sel.peak_load_n
                    .map(|l| format!(", peak load {l:.1} N"))
                    .unwrap_or_default()
            );
        }
        h.push_str("<table><tr><th class=l>experiment</th><th class=l>frequency window</th><th>m</th><th>c</th><th>r</th><th>p</th><th>n</th></tr>");
        for r in t.rows.iter().filter(|r| r.significant) {
            if let Some(f) = &r.fit {
                let _ = write!(
                    h,
                    "<tr><td class=l>{} ch{}</td><td class=l>{}</td><td>{:.2e}</td><td>{:.3}</td><td>{:+.2}</td><td>{:.2e}</td><td>{}</td></tr>",
                    esc(&r.experiment),
                    r.channel,
                    esc(&crate::analysis::trend::window_name(&r.column)),
                    f.slope,
                    f.intercept,
                    f.r,
                    f.p,
                    f.n
                );
            }
        }
        h.push_str("</table>");
        for (name, p) in &s.trend_plots {
            let _ = write!(
                h,
                "<figure>{}<figcaption>{}</figcaption></figure>",
                img(p, &format!("trend {name}"), Some(900)),
                esc(name)
            );
        }
    }
    // SOM.
    if let Some(m) = &s.som {
        let _ = write!(
            h,
            "<h2>Self-organising map (ch. 5)</h2><p>Trained on {} ({} training rows).</p>",
            esc(&m.trained_on),
            m.training_rows
        );
        if let Some(p) = &m.u_matrix {
            h.push_str(&img(p, "U-matrix", Some(450)));
        }
        if let Some(p) = &m.hit_maps {
            h.push_str(&img(p, "hit maps by class", Some(700)));
        }
        let _ = write!(
            h,
            "<h3>Confusion against the ch. 4.7 criteria labels (Table 5.4 orientation)</h3><pre>{}</pre>",
            esc(&m.confusion.format())
        );
    }
    if let Some(t) = &s.truth {
        let truths: BTreeSet<&String> = t.counts.keys().map(|k| &k.1).collect();
        let soms: BTreeSet<&String> = t.counts.keys().map(|k| &k.0).collect();
        let _ = write!(
            h,
            "<h3>Against the ground truth ({})</h3><table><tr><th class=l>SOM class \\ truth</th>",
            esc(&t.path.display().to_string())
        );
        for c in &truths {
            let _ = write!(h, "<th>{}</th>", esc(c));
        }
        h.push_str("</tr>");
        for sc in &soms {
            let _ = write!(h, "<tr><td class=l>{}</td>", esc(sc));
            for c in &truths {
                let _ = write!(
                    h,
                    "<td>{}</td>",
                    t.counts
                        .get(&((*sc).clone(), (*c).clone()))
                        .copied()
                        .unwrap_or(0)
                );
            }
            h.push_str("</tr>");
        }
        h.push_str("</table>");
        if let Some(a) = t.accuracy() {
            let _ = write!(
                h,
                "<p><b>Bond vs fibre failures: {}/{} = {:.1} % correct.</b></p>",
                t.bond_fibre_correct,
                t.bond_fibre_total,
                100.0 * a
            );
        }
    }
    // CWT gallery by class.
    let per = s.config.report.gallery_per_class;
    if per > 0 {
        let by = if som.is_empty() { &crit } else { &som };
        let mut chosen: BTreeMap<String, Vec<(String, i32, i64)>> = BTreeMap::new();
        for (k, c) in by {
            let v = chosen.entry(c.clone()).or_default();
            if v.len() < per {
                v.push(k.clone());
            }
        }
        let dir = s.out.join("gallery");
        let pics = crate::workflow::draw_gallery(&s.inputs, &s.config, &chosen, &dir);
        let _ = write!(
            h,
            "<h2>CWT gallery by {} class (Appendix B)</h2>",
            if som.is_empty() { "criteria" } else { "SOM" }
        );
        for (class, keys) in &chosen {
            let _ = write!(h, "<h3>{}</h3><div class=gallery>", esc(class));
            for k in keys {
                let cap = format!("{} ch{} hit {}", k.0, k.1, k.2);
                match pics.get(k) {
                    Some(p) => {
                        let _ = write!(
                            h,
                            "<figure>{}<figcaption>{}</figcaption></figure>",
                            img(p, &cap, Some(270)),
                            esc(&cap)
                        );
                    }
                    None => {
                        let _ = write!(h, "<p class=missing>{}: not drawn</p>", esc(&cap));
                    }
                }
            }
            h.push_str("</div>");
        }
    }
    // Manifest and timings.
    let manifest = std::fs::read_to_string(&s.features.manifest_path).unwrap_or_default();
    let _ = write!(
        h,
        "<h2>Run</h2><p>Stages: {}.</p><details><summary>manifest.json</summary><pre>{}</pre></details>\n\
<script>/* self-check: how many pictures decoded (read by the headless-browser test) */\
window.addEventListener('load',function(){{var i=Array.prototype.slice.call(document.images);\
document.body.setAttribute('data-images-loaded',i.filter(function(x){{return x.complete&&x.naturalWidth>0}}).length+'/'+i.length);}});</script>\
</body></html>\n",
        esc(&s.seconds.iter().map(|(k, v)| format!("{k} {v:.1} s")).collect::<Vec<_>>().join(", ")),
        esc(&manifest)
    );
    Ok(h)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc4648_vectors() {
        for (i, o) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(i.as_bytes()), o);
        }
    }
}
