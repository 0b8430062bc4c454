//! The report's opening: the tests side by side (`series.parquet`) as a table a reader sorts
//! by clicking a column, each number drawn as a bar against its column's largest, and
//! what each test's numbers rest on (a rate implied, hits outside the machine log).

use super::{esc, RunSummary};
use std::fmt::Write;

/// Sorts a `table.sortable` by the clicked column: by number where both cells hold one
/// (`data-v`), else by text; a second click reverses.
const SORT_JS: &str = "<script>document.querySelectorAll('table.sortable th').forEach((th,i)=>{th.style.cursor='pointer';th.title='sort';th.onclick=()=>{const b=th.closest('table').tBodies[0];const d=th.dataset.d=th.dataset.d==='1'?'-1':'1';const v=c=>c.dataset.v!==undefined?parseFloat(c.dataset.v):NaN;[...b.rows].sort((x,y)=>{const a=v(x.cells[i]),c=v(y.cells[i]);const r=isNaN(a)||isNaN(c)?x.cells[i].textContent.localeCompare(y.cells[i].textContent):a-c;return d*r}).forEach(r=>b.appendChild(r))}})</script>";

/// The experiments' own lines (the terminal says them too).
pub(super) fn said(s: &RunSummary) -> Vec<&str> {
    s.features.stats.said()
}

/// The lines about hits a load series does not cover (beside the load's pictures).
pub(super) fn load_coverage(s: &RunSummary) -> Vec<&str> {
    said(s)
        .into_iter()
        .filter(|m| m.ends_with(": no load"))
        .collect()
}

pub(super) fn series_section(h: &mut String, s: &RunSummary) {
    let Some(se) = &s.series else { return };
    let _ = write!(
        h,
        "<h2>Tests side by side</h2><p>One row per experiment (<code>{}</code>); click a \
         column to sort.</p><table class=sortable><thead><tr><th class=l>experiment</th>",
        esc(&se.path.display().to_string())
    );
    let mut heads: Vec<String> = [
        "hits",
        "rejects",
        "hits with load",
        "peak load (N)",
        "at (s)",
        "unlike the references",
    ]
    .iter()
    .map(|x| x.to_string())
    .collect();
    heads.extend(se.classes.iter().map(|c| format!("{c} hits")));
    if se.clustering {
        heads.push("clusters".into());
    }
    heads.push("energy exponent α".into());
    heads.push("significant trends".into());
    for x in &heads {
        let _ = write!(h, "<th>{}</th>", esc(x));
    }
    h.push_str("<th class=l>note</th></tr></thead><tbody>");
    let rows: Vec<Vec<Option<f64>>> = se
        .rows
        .iter()
        .map(|r| {
            let mut v = vec![
                Some(r.hits as f64),
                Some(r.rejects as f64),
                Some(r.hits_with_load as f64),
                r.peak_load_n,
                r.peak_load_s,
                r.unlike_references_share.map(|x| 100.0 * x),
            ];
            v.extend(r.classes.iter().map(|c| c.map(|c| c as f64)));
            if se.clustering {
                v.push(r.clusters.map(|c| c as f64));
            }
            v.push(r.alpha);
            v.push(r.significant_trends.map(|c| c as f64));
            v
        })
        .collect();
    let top: Vec<f64> = (0..heads.len())
        .map(|k| {
            rows.iter()
                .filter_map(|r| r[k])
                .fold(0f64, |a, b| a.max(b.abs()))
        })
        .collect();
    for (r, vals) in se.rows.iter().zip(&rows) {
        let _ = write!(h, "<tr><td class=l>{}</td>", esc(&r.experiment));
        for (k, v) in vals.iter().enumerate() {
            match v {
                Some(v) => {
                    let share = if top[k] > 0.0 {
                        100.0 * v.abs() / top[k]
                    } else {
                        0.0
                    };
                    let text = match k {
                        3 | 4 => format!("{v:.1}"),
                        5 => format!("{v:.0} %"),
                        _ if v.fract() == 0.0 => format!("{v:.0}"),
                        _ => format!("{v:.2}"),
                    };
                    let _ = write!(
                        h,
                        "<td data-v=\"{v}\" style=\"background:linear-gradient(90deg,#cde 0,#cde {share:.0}%,transparent {share:.0}%)\">{text}</td>"
                    );
                }
                None => h.push_str("<td data-v=\"-1e300\">–</td>"),
            }
        }
        let _ = write!(
            h,
            "<td class=l>{}</td></tr>",
            esc(r.trend_note.as_deref().unwrap_or(""))
        );
    }
    h.push_str("</tbody></table>");
    h.push_str(SORT_JS);
    let lines = said(s);
    if !lines.is_empty() {
        h.push_str("<p>What the tests' numbers rest on:</p><ul>");
        for l in lines {
            let _ = write!(h, "<li>{}</li>", esc(l));
        }
        h.push_str("</ul>");
    }
}
