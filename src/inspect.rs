//! `aepipe inspect`: a human summary per experiment — format, channels, hits, sample rates,
//! record lengths, time span, load/extension channels found, rejects.

use crate::config::ValidConfig;
use crate::ingest::{self, Source};
use crate::model::Item;
use std::collections::BTreeSet;
use std::fmt;

/// What one source holds.
#[derive(Debug, Clone, Default)]
pub struct Summary {
    pub id: String,
    pub format: String,
    pub files: usize,
    pub companions: Vec<String>,
    pub channels: BTreeSet<u32>,
    /// Hit rows (the acquisition system's hits).
    pub hits: u64,
    /// Transient records (waveforms) read, and how many no hit points to.
    pub transients: u64,
    pub standalone: u64,
    /// Parametric rows (the recording's own and a `[load]` file's) and marker/status rows.
    pub parametric: u64,
    pub markers: u64,
    pub notes: Vec<String>,
    pub rejects: u64,
    pub first_reject: Option<String>,
    pub sample_rates_hz: BTreeSet<u64>,
    pub min_len: usize,
    pub max_len: usize,
    pub time_span_s: Option<(f64, f64)>,
    pub load_n: Option<(f64, f64)>,
    pub hits_with_load: u64,
    pub extension_m: Option<(f64, f64)>,
    pub labels: BTreeSet<String>,
    /// Experiments inside (a Parquet table may hold several).
    pub experiments: BTreeSet<String>,
}

fn widen(r: &mut Option<(f64, f64)>, v: f64) {
    *r = Some(match *r {
        None => (v, v),
        Some((a, b)) => (a.min(v), b.max(v)),
    });
}

/// Read a source fully (one record at a time) and summarise it.
pub fn summarise(src: &Source, cfg: &ValidConfig) -> Summary {
    let mut s = Summary {
        id: src.id.clone(),
        format: src.format.as_str().into(),
        files: src.files.len(),
        companions: src.companion_names(),
        min_len: usize::MAX,
        ..Default::default()
    };
    // Vallen: the transients are summarised from the .tradb's integer columns and only the
    // hit rows are read, so inspecting a large database decodes no waveform.
    let vallen_stats = match (src.format, src.files.first()) {
        (ingest::Format::Vallen, Some(tradb)) if src.has_hit_list() => {
            ingest::vallen::transient_stats(tradb).ok()
        }
        _ => None,
    };
    let items = match &vallen_stats {
        Some(t) => {
            s.transients = t.transients;
            s.min_len = t.shortest;
            s.max_len = t.longest;
            s.sample_rates_hz.extend(t.sample_rates_hz.iter().copied());
            s.channels.extend(t.channels.iter().copied());
            ingest::loadfile::attach(
                ingest::vallen::open_hits(src, cfg.read_settings()),
                src,
                &cfg.load,
            )
        }
        None => ingest::open(src, cfg.read_settings(), &cfg.load),
    };
    for item in items {
        match item {
            Item::Hit(h) => {
                s.hits += 1;
                s.channels.insert(h.channel);
                s.experiments.insert(h.experiment.clone());
                if let Some(t) = h.time_s {
                    widen(&mut s.time_span_s, t);
                }
                if let Some(l) = h.load_n {
                    widen(&mut s.load_n, l);
                    s.hits_with_load += 1;
                }
                if let Some(e) = h.extension_m {
                    widen(&mut s.extension_m, e);
                }
            }
            Item::Note(n) => s.notes.push(n.message),
            Item::Parametric(_) => s.parametric += 1,
            Item::Marker(_) => s.markers += 1,
            Item::Setup(_) | Item::Tally(_) => {}
            Item::Record(r) => {
                s.transients += 1;
                if r.kind == crate::model::RecordKind::Standalone {
                    s.standalone += 1;
                }
                s.channels.insert(r.channel);
                s.experiments.insert(r.experiment.clone());
                s.sample_rates_hz.insert(r.sample_rate_hz.round() as u64);
                s.min_len = s.min_len.min(r.samples.len());
                s.max_len = s.max_len.max(r.samples.len());
                if let Some(l) = r.label {
                    s.labels.insert(l);
                }
            }
            Item::Reject(r) => {
                s.rejects += 1;
                if s.first_reject.is_none() {
                    let id = if r.record_id.is_empty() {
                        String::new()
                    } else {
                        format!(" [{}]", r.record_id)
                    };
                    s.first_reject = Some(format!("{}{id}: {}", r.source_file, r.reason));
                }
            }
        }
    }
    if s.transients == 0 {
        s.min_len = 0;
    }
    s
}

fn khz_list(rates: &BTreeSet<u64>) -> String {
    rates
        .iter()
        .map(|r| format!("{} kHz", *r as f64 / 1e3))
        .collect::<Vec<_>>()
        .join(", ")
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "{}  [{}]", self.id, self.format)?;
        writeln!(
            f,
            "  files          {} waveform file(s){}",
            self.files,
            if self.companions.is_empty() {
                String::new()
            } else {
                format!(" + {}", self.companions.join(", "))
            }
        )?;
        if self.experiments.len() > 1 || self.experiments.iter().any(|e| e != &self.id) {
            writeln!(
                f,
                "  experiments    {}",
                self.experiments
                    .iter()
                    .cloned()
                    .collect::<Vec<_>>()
                    .join(", ")
            )?;
        }
        writeln!(f, "  hits           {}", self.hits)?;
        if self.standalone > 0 {
            writeln!(
                f,
                "  transients     {} ({} without a hit)",
                self.transients, self.standalone
            )?;
        } else {
            writeln!(f, "  transients     {}", self.transients)?;
        }
        if self.parametric + self.markers > 0 {
            writeln!(
                f,
                "  parametric     {} row(s); markers/status {}",
                self.parametric, self.markers
            )?;
        }
        writeln!(
            f,
            "  channels       {}",
            self.channels
                .iter()
                .map(|c| c.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )?;
        writeln!(f, "  sample rate    {}", khz_list(&self.sample_rates_hz))?;
        writeln!(
            f,
            "  record length  {}",
            if self.min_len == self.max_len {
                format!("{} samples", self.min_len)
            } else {
                format!("{}–{} samples", self.min_len, self.max_len)
            }
        )?;
        match self.time_span_s {
            Some((a, b)) => writeln!(f, "  time span      {a:.6} – {b:.6} s ({:.3} s)", b - a)?,
            None => writeln!(f, "  time span      not recorded by this format")?,
        }
        match self.load_n {
            Some((a, b)) => writeln!(
                f,
                "  load           {a:.3} – {b:.3} N ({} of {} hits)",
                self.hits_with_load, self.hits
            )?,
            None => writeln!(f, "  load           no load channel")?,
        }
        match self.extension_m {
            Some((a, b)) => writeln!(f, "  extension      {:.4} – {:.4} mm", a * 1e3, b * 1e3)?,
            None => writeln!(f, "  extension      no extension channel")?,
        }
        if !self.labels.is_empty() {
            writeln!(
                f,
                "  labels         {}",
                self.labels.iter().cloned().collect::<Vec<_>>().join(", ")
            )?;
        }
        for n in &self.notes {
            writeln!(f, "  note           {n}")?;
        }
        if self.rejects > 0 {
            writeln!(
                f,
                "  rejects        {} (first: {})",
                self.rejects,
                self.first_reject.as_deref().unwrap_or("")
            )?;
        }
        Ok(())
    }
}
