//! What a run prints on the terminal.

use super::*;

/// Terminal lines: the headline numbers.
pub fn headline(s: &RunSummary) -> Vec<String> {
    let mut l = Vec::new();
    let st = &s.features.stats;
    l.push(format!(
        "hits: {} read, {} feature rows, {} rejects",
        st.records_read, st.rows, st.rejects
    ));
    if let Some(t) = &s.trend {
        for sel in &t.selections {
            l.push(format!(
                "trend {} ch{}: {} of {} hits used ({})",
                sel.experiment, sel.channel, sel.hits_used, sel.hits_total, sel.cutoff
            ));
        }
        for r in t.rows.iter().filter(|r| r.significant) {
            if let Some(f) = &r.fit {
                l.push(format!(
                    "  {:<16} r = {:+.2}  p = {:.1e}  slope {:+.2e}",
                    crate::analysis::trend::window_name(&r.column),
                    f.r,
                    f.p,
                    f.slope
                ));
            }
        }
    }
    if let Some(m) = &s.som {
        l.push(format!(
            "SOM trained on {} ({} training rows)",
            m.trained_on, m.training_rows
        ));
        l.push(format!(
            "SOM classes: {}",
            m.classes
                .iter()
                .map(|(k, v)| format!("{k} {v}"))
                .collect::<Vec<_>>()
                .join(", ")
        ));
        l.extend(m.profile.iter().map(|p| p.line()));
        if let Some(a) = m.confusion.accuracy() {
            l.push(format!(
                "agreement with the ch. 4.7 criteria labels: {}/{} = {:.1} %",
                m.confusion.correct,
                m.confusion.total,
                100.0 * a
            ));
        }
    }
    if let Some(sc) = &s.sources {
        l.extend(sc.lines());
    }
    if let Some(t) = &s.truth {
        if let Some(a) = t.accuracy() {
            l.push(format!(
                "accuracy against the ground truth, bond vs fibre failures: {}/{} = {:.1} %",
                t.bond_fibre_correct,
                t.bond_fibre_total,
                100.0 * a
            ));
        }
        let (ek, en) = t.erroneous_recall();
        let (ok, all) = t.thesis_overall();
        l.push(format!(
            "erroneous records recognised: {ek}/{en}; overall the thesis's way (mechanism or erroneous, over all hits): {ok}/{all} = {:.1} %",
            100.0 * ok as f64 / all.max(1) as f64
        ));
        l.push("Table 5.4 (share of each SOM class's hits):".into());
        l.extend(t.format_table_5_4().lines().map(|x| format!("  {x}")));
    }
    l.push(format!(
        "stages: {}",
        s.seconds
            .iter()
            .map(|(k, v)| format!("{k} {v:.1} s"))
            .collect::<Vec<_>>()
            .join(", ")
    ));
    l
}
