//! The report's source sections: the events each experiment's hits made, the grip and
//! machine noise the zone and the guard sensors kept out, where the events are, and the
//! damage evolution.

use super::{esc, figures, RunSummary};
use std::fmt::Write as _;

/// Events, location, zone and guard sensors per experiment; the location pictures.
pub(super) fn sources_section(h: &mut String, s: &RunSummary) {
    let built: Vec<&crate::events::EventsSummary> = s
        .features
        .stats
        .events
        .iter()
        .filter(|e| e.enabled)
        .collect();
    if built.is_empty() {
        return;
    }
    let exclude = s.config.location.exclude_outside;
    let _ = write!(
        h,
        "<h2>Sources: events and location</h2><p>The hits of one source at several sensors \
         form an event (Vallen's event builder); the trend, the map and the class counts take \
         one row per event{}.</p>\
         <table><tr><th class=l>experiment</th><th>hits</th><th>events</th><th>single-hit</th>\
         <th>hits in events</th><th>located</th><th>inside</th><th>outside</th>\
         <th>guard-suppressed</th><th>not started (FHCDT)</th><th class=l>setup</th></tr>",
        if exclude {
            ", and only the events inside the zone"
        } else {
            ""
        }
    );
    for e in &built {
        let _ = write!(
            h,
            "<tr><td class=l>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>\
             <td>{}</td><td>{}</td><td>{}</td><td>{}</td><td class=l>{}</td></tr>",
            esc(&e.experiment),
            e.hits,
            e.events,
            e.single_hit_events,
            e.hits_in_events,
            e.located,
            e.inside,
            e.outside,
            e.guard_suppressed,
            e.not_started,
            esc(&format!(
                "FHCDT {:.1} µs, DT1X {:.1} µs, DTNX {:.1} µs; {}; arrival {}",
                e.fhcdt_s * 1e6,
                e.dt1x_max_s * 1e6,
                e.dtnx_max_s * 1e6,
                e.location.as_deref().unwrap_or("no location"),
                e.arrival
            ))
        );
    }
    h.push_str("</table>");
    let (outside, guard): (u64, u64) = built
        .iter()
        .fold((0, 0), |(o, g), e| (o + e.outside, g + e.guard_suppressed));
    let _ = write!(
        h,
        "<h3>Grip and machine noise</h3><p>{outside} event(s) located outside the zone and \
         {guard} hit(s) a guard sensor kept from opening an event. {}</p>",
        if exclude {
            "They are left out of the trend, the SOM's training and the class counts, and stay \
             in every table (<code>zone</code> = <code>outside</code> / <code>guard</code>)."
        } else {
            "<code>[location] exclude_outside</code> is off: the events outside the zone still \
             count (guard-suppressed hits never open an event, so they never do)."
        }
    );
    if let Some(sc) = &s.sources {
        let _ = write!(h, "<p>Against the synthetic test's truth:</p><ul>");
        for l in sc.lines() {
            let _ = write!(h, "<li>{}</li>", esc(&l));
        }
        h.push_str("</ul>");
    }
    if let Some(m) = &s.som {
        figures(
            h,
            &m.location_plots,
            "location",
            ": events by the SOM's class of their first hit",
        );
    }
}

/// The damage evolution pictures (`evolution.parquet`).
pub(super) fn evolution_section(h: &mut String, s: &RunSummary) {
    let Some(m) = &s.som else {
        reloads_table(h, s);
        return;
    };
    if m.evolution_plots.is_empty() {
        reloads_table(h, s);
        return;
    }
    let e = &s.config.evolution;
    let _ = write!(
        h,
        "<h2>Damage evolution</h2><p>Cumulative sources of each class against time and load, \
         and the b-value (Aki's maximum likelihood, M = A<sub>dB</sub>/20, M ≥ {:.1}) and \
         Ib-value (Shiotani, α₁ = {}, α₂ = {}) over windows of the last {} sources: a falling \
         value means large events gaining on small ones. Table: <code>{}</code>.</p>",
        e.completeness_db / 20.0,
        e.ib_alpha1,
        e.ib_alpha2,
        e.window,
        esc(&m.evolution_table.display().to_string())
    );
    figures(h, &m.evolution_plots, "damage evolution", "");
    reloads_table(h, s);
}

/// The Felicity ratio and Kaiser effect of each reload (load–unload–reload tests only).
fn reloads_table(h: &mut String, s: &RunSummary) {
    let reloads = match (&s.som, &s.cluster) {
        (Some(m), _) => &m.reloads,
        (None, Some(c)) => &c.reloads,
        _ => return,
    };
    if reloads.is_empty() {
        return;
    }
    let e = &s.config.evolution;
    let _ = write!(
        h,
        "<h3>Load cycles: Felicity ratio and Kaiser effect</h3><p>A reload's AE onset is its \
         source number {} (counting those at or above {} dB) while it loads; its Felicity \
         ratio is the load there over the highest load before the reload, and the Kaiser \
         effect holds at a ratio ≥ {}. All sources of the test (<code>cycles.parquet</code> \
         has each class).</p><table><tr><th>experiment</th><th>cycle</th><th>peak load, N</th>\
         <th>previous maximum, N</th><th>onset load, N</th><th>Felicity ratio</th>\
         <th>Kaiser effect</th></tr>",
        e.felicity_onset_sources, e.felicity_onset_db, e.kaiser_min_ratio
    );
    let num = |v: Option<f64>, d: usize| v.map_or("–".to_string(), |x| format!("{x:.d$}"));
    for r in reloads {
        let kaiser = match r.kaiser {
            None => "–",
            Some(true) => "yes",
            Some(false) => "no",
        };
        let _ = write!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{:.2}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(&r.experiment),
            r.cycle.index,
            r.cycle.peak_load_n,
            num(r.cycle.previous_max_n, 2),
            num(r.onset_load_n, 2),
            num(r.felicity_ratio, 3),
            kaiser
        );
    }
    h.push_str("</table>");
}
