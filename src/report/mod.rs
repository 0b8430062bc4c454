//! The HTML report of a run: one self-contained file (pictures embedded as data URIs) with
//! the inputs and rejects, per-experiment class counts, the trend table and plot (Table 4.3,
//! Fig. 4.18), a CWT gallery by class (Appendix B), the U-matrix and hit maps, the confusion
//! (Table 5.4 orientation), the accuracy against ground truth, and the manifest.
//!
//! The report renders from what it is handed: the run's [`RunSummary`] and the [`Gathered`]
//! columns and gallery pictures the workflow read and drew. It reads no input recording and
//! no table; it only embeds the PNG files it is pointed at.

pub mod explore;
mod gallery;
mod page;
mod series;
mod sources;

use gallery::{appendix_b_section, disagree_section, gallery_section};
pub use gallery::{
    write_appendix_b, AppendixB, Disagreements, Gallery, GalleryChoice, GalleryPicture,
};

use crate::analysis::trend::TrendReport;
use crate::model::Mechanism;
use crate::pipeline::RunReport;
use crate::som::classify::Confusion;
use crate::util::{write_atomic, IoAt};
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Why the report was not written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error(transparent)]
    Write(#[from] IoAt),
}

impl crate::util::HasKind for ReportError {
    fn kind(&self) -> crate::util::ErrorKind {
        match self {
            ReportError::Write(_) => crate::util::ErrorKind::Failed,
        }
    }
}

/// What a run produced, for the terminal and the report.
pub struct RunSummary {
    pub out: PathBuf,
    pub inputs: Vec<PathBuf>,
    pub features: RunReport,
    pub trend: Option<TrendReport>,
    pub trend_plots: Vec<(String, PathBuf)>,
    pub som: Option<SomStage>,
    /// The clustering stage (`[cluster] enabled`).
    pub cluster: Option<ClusterStage>,
    /// The files `[export] trfdb` wrote back for the lab's tools.
    pub export: Option<crate::export::ExportSummary>,
    /// The energy power law per experiment (`statistics.parquet`).
    pub statistics: Vec<crate::analysis::powerlaw::StatRow>,
    pub truth: Option<TruthScore>,
    /// Events and location against the truth's sources (a synthetic test with sensors).
    pub sources: Option<SourceScore>,
    pub config: crate::config::ValidConfig,
    pub seconds: Vec<(String, f64)>,
    /// Each stage's peak resident memory, bytes (see `workflow::StageLog`).
    pub peak_rss: Vec<(String, u64)>,
    /// The tests side by side (`series.parquet`).
    pub series: Option<crate::analysis::series::Series>,
    /// What the report's page bound left out (once the report is written).
    pub page: Option<PageFit>,
}

impl RunSummary {
    /// Each stage in order: its name, seconds and peak RSS (bytes, if measured).
    pub fn stages(&self) -> Vec<(&str, f64, Option<u64>)> {
        self.seconds
            .iter()
            .map(|(k, v)| {
                let rss = self.peak_rss.iter().find(|(n, _)| n == k).map(|(_, b)| *b);
                (k.as_str(), *v, rss)
            })
            .collect()
    }
}

/// The clustering stage of a run.
pub struct ClusterStage {
    pub report: crate::cluster::ClusterReport,
    pub validity_png: PathBuf,
    /// RA against AF coloured by cluster, and by SOM class when the SOM ran.
    pub ra_af_pngs: Vec<(String, PathBuf)>,
    /// Cumulative hits per cluster against time and load, per experiment.
    pub cumulative_pngs: Vec<(String, PathBuf)>,
    /// The feature distributions per cluster.
    pub distributions_png: Option<PathBuf>,
    /// Where the events are, coloured by their first hit's cluster, per experiment.
    pub location_pngs: Vec<(String, PathBuf)>,
    /// Hits per cluster the pictures found in the feature tables (equal to the report's
    /// sizes when they show every clustered hit).
    pub pictured: Vec<usize>,
    /// The damage evolution by cluster, per experiment (`cluster/evolution.parquet`).
    pub evolution_pngs: Vec<(String, PathBuf)>,
    /// The `all` series' load cycles of each load–unload–reload test (as the SOM's).
    pub reloads: Vec<crate::analysis::cycles::CycleRow>,
}

/// The SOM stage of a run.
pub struct SomStage {
    pub model_dir: PathBuf,
    pub trained_on: String,
    /// The map's cache entry (issue 52): its key and whether this run reused it.
    pub map_cache: Option<crate::som::layout::MapCache>,
    pub training_rows: usize,
    /// Against the criteria labels of the run's hits (Table 5.4 orientation).
    pub confusion: Confusion,
    pub classification: PathBuf,
    pub u_matrix: Option<PathBuf>,
    pub hit_maps: Option<PathBuf>,
    /// RA against AF by SOM class, with the crack-mode line (none without RA and AF).
    pub ra_af_plot: Option<PathBuf>,
    /// SOM class → number of hits.
    pub classes: BTreeMap<String, usize>,
    /// The damage profile (Fig. 6.1): `damage_profile.parquet`, a summary and a picture
    /// per experiment × channel.
    pub profile_table: PathBuf,
    pub profile: Vec<crate::som::profile::ProfileSummary>,
    pub profile_plots: Vec<(String, PathBuf)>,
    /// The damage evolution (`evolution.parquet`) and its picture per experiment.
    pub evolution_table: PathBuf,
    pub evolution_plots: Vec<(String, PathBuf)>,
    /// The `all` series' cycles of each load–unload–reload test (≥ 2 cycles; the rows of
    /// `cycles.parquet`).
    pub reloads: Vec<crate::analysis::cycles::CycleRow>,
    /// Where the classified events are, per experiment with located events.
    pub location_plots: Vec<(String, PathBuf)>,
}

/// Events and location against the ground truth's sources (`truth.parquet` `event`,
/// `source_x_m`, `source_kind`).
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
pub struct SourceScore {
    /// Sources in the truth, and how many are specimen / grip.
    pub sources: usize,
    pub specimen: usize,
    pub grip: usize,
    /// Events aepipe built.
    pub events: usize,
    /// Sources whose hits form exactly one event holding nothing else.
    pub found: usize,
    /// Found specimen sources with a location, and the median and 90th-percentile
    /// |x − source_x|, m.
    pub located: usize,
    pub median_error_m: Option<f64>,
    pub p90_error_m: Option<f64>,
    /// Grip sources none of whose hits counts (outside the zone, or guard-suppressed).
    pub grip_removed: usize,
    /// Specimen sources none of whose hits counts.
    pub specimen_lost: usize,
}

impl SourceScore {
    pub fn lines(&self) -> Vec<String> {
        let pct = |a: usize, b: usize| 100.0 * a as f64 / b.max(1) as f64;
        let mut l = vec![format!(
            "events: {} built for {} sources ({} specimen, {} grip); {} sources are exactly one event",
            self.events, self.sources, self.specimen, self.grip, self.found
        )];
        if let (Some(m), Some(p)) = (self.median_error_m, self.p90_error_m) {
            l.push(format!(
                "location: {} specimen events, error median {:.2} mm, 90 % within {:.2} mm",
                self.located,
                m * 1e3,
                p * 1e3
            ));
        }
        l.push(format!(
            "zone: {}/{} grip sources removed ({:.1} %), {}/{} specimen sources lost ({:.1} %)",
            self.grip_removed,
            self.grip,
            pct(self.grip_removed, self.grip),
            self.specimen_lost,
            self.specimen,
            pct(self.specimen_lost, self.specimen)
        ));
        l
    }
}

/// Classification against the ground truth (`truth.parquet`).
#[derive(Debug, Clone)]
pub struct TruthScore {
    pub path: PathBuf,
    /// (SOM class, true mechanism) → hits.
    pub counts: BTreeMap<(String, String), usize>,
    /// Bond vs fibre failures: hits whose truth is one of the two, and how many the SOM got.
    pub bond_fibre_total: usize,
    pub bond_fibre_correct: usize,
}

impl TruthScore {
    pub fn accuracy(&self) -> Option<f64> {
        (self.bond_fibre_total > 0)
            .then(|| self.bond_fibre_correct as f64 / self.bond_fibre_total as f64)
    }

    /// Hits of a true class the SOM gave a class.
    fn count(&self, som: &str, truth: &str) -> usize {
        self.counts
            .get(&(som.to_string(), truth.to_string()))
            .copied()
            .unwrap_or(0)
    }

    /// Hits of a true mechanism the SOM gave that mechanism.
    fn right(&self, m: Mechanism) -> usize {
        self.count(m.as_str(), m.as_str())
    }

    /// Hits of a true mechanism (by name) the SOM found unlike its references, and all
    /// hits of that mechanism.
    pub fn unlike(&self, truth: &[Mechanism]) -> (usize, usize) {
        let of = |t: &str| Mechanism::parse(t).is_some_and(|m| truth.contains(&m));
        let all = self
            .counts
            .iter()
            .filter(|((_, t), _)| of(t))
            .map(|(_, n)| n)
            .sum();
        let novel = self
            .counts
            .iter()
            .filter(|((c, t), _)| c == crate::model::UNLIKE_REFERENCES && of(t))
            .map(|(_, n)| n)
            .sum();
        (novel, all)
    }

    /// True erroneous hits kept from the mechanisms, of all true erroneous hits: called
    /// erroneous, or unlike the references (novelty comes first, so a faulty record the
    /// map's library never held is the latter; the thesis had no such class).
    pub fn erroneous_recall(&self) -> (usize, usize) {
        let (u, total) = self.unlike(&[Mechanism::Erroneous]);
        (self.erroneous_called() + u, total)
    }

    /// True erroneous hits the SOM calls erroneous.
    pub fn erroneous_called(&self) -> usize {
        self.right(Mechanism::Erroneous)
    }

    /// A true class's recall: its hits the SOM gave that class, and all its hits.
    pub fn recall(&self, m: Mechanism) -> (usize, usize) {
        let total = self
            .counts
            .iter()
            .filter(|((_, t), _)| t == m.as_str())
            .map(|(_, n)| n)
            .sum();
        (self.right(m), total)
    }

    /// The balanced accuracy of the two mechanisms: the mean of bond and fibre failures'
    /// recalls (None unless both occur). Unlike the pooled bond-vs-fibre figure it does not
    /// hide the rare class: calling every hit a bond failure scores 50 %, not 97 %.
    pub fn balanced_accuracy(&self) -> Option<f64> {
        let r = |m| {
            let (k, n) = self.recall(m);
            (n > 0).then(|| k as f64 / n as f64)
        };
        Some(0.5 * (r(Mechanism::BondFailure)? + r(Mechanism::FibreFailure)?))
    }

    /// "bond_failure 460/467 = 98.5 %, fibre_failure 11/12 = 91.7 %, …": each true class's
    /// recall (true class → the same SOM class), the classes the truth holds.
    pub fn recall_line(&self) -> String {
        Mechanism::ALL
            .iter()
            .filter_map(|&m| {
                let (k, n) = self.recall(m);
                (n > 0).then(|| {
                    format!(
                        "{} {k}/{n} = {:.1} %",
                        m.as_str(),
                        100.0 * k as f64 / n as f64
                    )
                })
            })
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The thesis's overall figure (ch. 5.4: (537 + 8 + 26) / 651 = 87.71 %): hits given
    /// their true mechanism or erroneous records kept from the mechanisms
    /// ([`Self::erroneous_recall`]), over all hits ("both" hits count as wrong whatever the
    /// SOM says, as in the thesis).
    pub fn thesis_overall(&self) -> (usize, usize) {
        let correct = self.right(Mechanism::BondFailure)
            + self.right(Mechanism::FibreFailure)
            + self.erroneous_recall().0;
        (correct, self.counts.values().sum())
    }

    /// Table 5.4 as the thesis prints it: a column per SOM class, a row per true class,
    /// each cell the share of the SOM class's hits (and the ratio).
    pub fn format_table_5_4(&self) -> String {
        // Table 5.4's order (not the enum's): bond, fibre, erroneous, both, then the rest.
        let order = [
            Mechanism::BondFailure,
            Mechanism::FibreFailure,
            Mechanism::Erroneous,
            Mechanism::Both,
        ];
        let rank = |c: &str| {
            Mechanism::parse(c)
                .and_then(|m| order.iter().position(|o| *o == m))
                .unwrap_or(order.len())
        };
        let mut soms: Vec<&String> = self.counts.keys().map(|k| &k.0).collect();
        let mut truths: Vec<&String> = self.counts.keys().map(|k| &k.1).collect();
        for v in [&mut soms, &mut truths] {
            v.sort_by(|a, b| rank(a).cmp(&rank(b)).then(a.cmp(b)));
            v.dedup();
        }
        let mut out = format!("{:<16}", "truth \\ SOM");
        for c in &soms {
            out.push_str(&format!(" | {:>22}", c));
        }
        out.push('\n');
        for t in &truths {
            out.push_str(&format!("{:<16}", t));
            for c in &soms {
                let n: usize = truths.iter().map(|tt| self.count(c, tt)).sum();
                let k = self.count(c, t);
                let cell = format!("{:.2} % ({k}/{n})", 100.0 * k as f64 / n.max(1) as f64);
                out.push_str(&format!(" | {cell:>22}"));
            }
            out.push('\n');
        }
        out
    }
}

/// What the report shows besides the summary, gathered by the workflow from the run folder.
#[derive(Default)]
pub struct Gathered {
    /// Hits per (experiment, ch. 4.7 label).
    pub criteria: BTreeMap<(String, String), usize>,
    /// Hits per (experiment, SOM class) (empty without a SOM stage).
    pub som: BTreeMap<(String, String), usize>,
    pub gallery: Gallery,
    /// The same by cluster (`[cluster] enabled`).
    pub cluster_gallery: Gallery,
    /// The features stage's `manifest.json`, as text.
    pub manifest: String,
    /// The points and hits the explorable charts show.
    pub explorer: explore::Explorer,
    /// The hits the SOM reads otherwise than their reference label (Table 5.3).
    pub disagree: Disagreements,
    /// Appendix B's pages, when asked for (`[report] appendix_b_hits`).
    pub appendix_b: Option<AppendixB>,
}

/// Text made safe inside HTML (element content and quoted attributes).
pub fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A picture, embedded when the page is fitted within its bound (else linked as its file).
fn img(path: &Path, alt: &str, width: Option<u32>) -> String {
    page::Pic::new(path, alt, width).marker()
}

/// One 900-px figure per (name, picture): alt text "`what` name", caption "name`note`".
fn figures(h: &mut String, plots: &[(String, PathBuf)], what: &str, note: &str) {
    for (name, p) in plots {
        let _ = write!(
            h,
            "<figure>{}<figcaption>{}{}</figcaption></figure>",
            img(p, &format!("{what} {name}"), Some(900)),
            esc(name),
            esc(note)
        );
    }
}

/// A thumbnail that a click swaps for the whole picture (and back): the full PNG rides in a
/// data attribute, so the report stays one file and no data: URL is navigated to (browsers
/// refuse that). Where the page's bound leaves no room for it, the thumbnail names its file.
fn img_swap(thumb: &Path, full: &Path, alt: &str, width: u32) -> String {
    page::Pic::new(thumb, alt, Some(width)).swap(full).marker()
}

/// Write the report to `path` (atomically): what the page's bound left out.
pub fn write(s: &RunSummary, g: &Gathered, path: &Path) -> Result<PageFit, ReportError> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let (page, fit) = render_in(s, g, dir);
    write_atomic(path, page.as_bytes())?;
    Ok(fit)
}

/// The whole page, its pictures' links relative to the run folder.
pub fn render(s: &RunSummary, g: &Gathered) -> String {
    render_in(s, g, &s.out).0
}

/// The whole page for a report written in `dir`: every section, then the page fitted within
/// [`PAGE_BYTES`] (the explorer's points before the pictures; see `page`).
fn render_in(s: &RunSummary, g: &Gathered, dir: &Path) -> (String, PageFit) {
    let mut h = String::new();
    let title = format!("aepipe run — {}", s.out.display());
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title><style>\
body{{font-family:sans-serif;margin:2em;max-width:1200px}}table{{border-collapse:collapse;margin:1em 0}}\
td,th{{border:1px solid #bbb;padding:3px 8px;text-align:right}}th{{background:#eee}}td.l,th.l{{text-align:left}}\
.gallery{{display:flex;flex-wrap:wrap;gap:6px}}.gallery figure{{margin:0;width:270px}}\
.gallery figure.big{{width:100%}}.gallery figure.big img{{width:100%}}img.swap{{cursor:zoom-in}}figcaption{{font-size:11px}}\
pre{{background:#f6f6f6;padding:8px;overflow-x:auto}}.missing{{color:#b00}}</style></head><body>\n<h1>{}</h1>\n",
        esc(&title),
        esc(&title)
    );
    first_lines(&mut h, s);
    h.push_str(page::FIT_NOTE_HERE);
    series::series_section(&mut h, s);
    inputs_section(&mut h, s);
    classes_section(&mut h, g);
    // The explorer goes here once the rest is written: its points fit what is left of the
    // page's bound.
    h.push_str(EXPLORE_HERE);
    trend_section(&mut h, s);
    som_section(&mut h, s);
    disagree_section(
        &mut h,
        &g.disagree,
        "the reference label (`reference_label`: the ch. 4.7 criteria by default)",
    );
    cluster_section(&mut h, s);
    statistics_section(&mut h, s);
    profile_section(&mut h, s);
    sources::sources_section(&mut h, s);
    sources::evolution_section(&mut h, s);
    truth_section(&mut h, s);
    gallery_section(&mut h, &g.gallery);
    appendix_b_section(&mut h, g.appendix_b.as_ref());
    gallery_section(&mut h, &g.cluster_gallery);
    footer(&mut h, s, g);
    page::fit(&h, &g.explorer, dir)
}

use page::EXPLORE_HERE;
pub use page::{PageFit, PAGE_BYTES};

/// What a reader must know before any number below: how much of each test the map's
/// references describe (issue 39), and which tests have no usable load.
fn first_lines(h: &mut String, s: &RunSummary) {
    let Some(m) = &s.som else { return };
    let nov = &m.confusion.novelty;
    let undescribed = nov.undescribed();
    let style = if undescribed.is_empty() {
        ""
    } else {
        " class=missing"
    };
    let _ = write!(h, "<p{style}><b>{}.</b></p>", esc(&nov.describe()));
    if nov.threshold.is_some() && nov.per_experiment.len() > 12 {
        let _ = write!(
            h,
            "<p>{} of {} tests are mostly (&gt; half) unlike the references{}.</p>",
            undescribed.len(),
            nov.per_experiment.len(),
            if undescribed.is_empty() {
                String::new()
            } else {
                format!(
                    ": {}",
                    esc(&undescribed
                        .iter()
                        .take(20)
                        .copied()
                        .collect::<Vec<_>>()
                        .join(", "))
                )
            }
        );
    }
}

fn inputs_section(h: &mut String, s: &RunSummary) {
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
}

fn classes_section(h: &mut String, g: &Gathered) {
    let mut classes: BTreeSet<String> = g.criteria.keys().map(|k| k.1.clone()).collect();
    classes.extend(g.som.keys().map(|k| k.1.clone()));
    let experiments: BTreeSet<String> = g.criteria.keys().map(|k| k.0.clone()).collect();
    let _ = write!(
        h,
        "<h2>Hits by class</h2><table><tr><th class=l>experiment</th><th class=l>labels</th>"
    );
    for c in &classes {
        let _ = write!(h, "<th>{}</th>", esc(c));
    }
    h.push_str("</tr>");
    for e in &experiments {
        for (name, map) in [("ch. 4.7 criteria", &g.criteria), ("SOM", &g.som)] {
            if map.is_empty() {
                continue;
            }
            let _ = write!(h, "<tr><td class=l>{}</td><td class=l>{name}</td>", esc(e));
            for c in &classes {
                let n = map.get(&(e.clone(), c.clone())).copied().unwrap_or(0);
                let _ = write!(h, "<td>{n}</td>");
            }
            h.push_str("</tr>");
        }
    }
    h.push_str("</table>");
}

fn trend_section(h: &mut String, s: &RunSummary) {
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
            if let Some(few) = t.too_few(sel) {
                let _ = write!(h, "<p>No trend stated for it: {}.</p>", esc(&few));
            }
        }
        h.push_str("<table><tr><th class=l>experiment</th><th class=l>frequency window</th><th>m</th><th>c</th><th>r</th><th>p</th><th>n</th></tr>");
        for r in &t.significant {
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
        figures(h, &s.trend_plots, "trend", "");
    }
}

fn som_section(h: &mut String, s: &RunSummary) {
    // SOM.
    if let Some(m) = &s.som {
        let _ = write!(
            h,
            "<h2>Self-organising map (ch. 5)</h2><p>Trained on {} ({} training rows). {}.</p>",
            esc(&m.trained_on),
            m.training_rows,
            esc(&m.confusion.reading.describe())
        );
        if let Some(p) = &m.u_matrix {
            h.push_str(&img(p, "U-matrix", Some(450)));
        }
        if let Some(p) = &m.hit_maps {
            h.push_str(&img(p, "hit maps by class", Some(700)));
        }
        // Beside the clusters' section when it runs; here otherwise.
        if let (Some(p), None) = (&m.ra_af_plot, &s.cluster) {
            h.push_str(&img(
                p,
                "RA against AF by SOM class (crack mode)",
                Some(820),
            ));
        }
        let _ = write!(
            h,
            "<h3>Confusion against the ch. 4.7 criteria labels (Table 5.4 orientation)</h3><pre>{}</pre>",
            esc(&m.confusion.format())
        );
    }
}

fn cluster_section(h: &mut String, s: &RunSummary) {
    let Some(c) = &s.cluster else { return };
    let r = &c.report;
    let chosen = r.validity.iter().find(|v| v.chosen);
    let _ = write!(
        h,
        "<h2>Clusters of the hits' own features</h2><p>{} rows on {} z-scored columns ({} left out for a null feature; fitted on {}). Method {}, k = {} chosen by the {} index from {}..{}. Hits per cluster (numbered by rising mean peak frequency): {}.</p>",
        r.rows,
        r.columns.len(),
        r.skipped,
        r.fit_rows,
        chosen.map_or("", |v| v.method.as_str()),
        r.k,
        esc(s.config.cluster.choose.as_str()),
        s.config.cluster.k_min,
        s.config.cluster.k_max,
        r.sizes.iter().enumerate().map(|(c, n)| format!("{c}: {n}")).collect::<Vec<_>>().join(", ")
    );
    h.push_str(&img(
        &c.validity_png,
        "validity indices against k",
        Some(1100),
    ));
    h.push_str("<table><tr><th>k</th><th>Davies–Bouldin</th><th>silhouette</th><th>Calinski–Harabasz</th><th>BIC</th><th>inertia</th></tr>");
    let o = |v: Option<f64>| v.map_or("–".to_string(), |v| format!("{v:.4}"));
    for v in &r.validity {
        let _ = write!(
            h,
            "<tr><td>{}{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.2}</td></tr>",
            v.k,
            if v.chosen { " *" } else { "" },
            o(v.davies_bouldin),
            o(v.silhouette),
            o(v.calinski_harabasz),
            v.bic.map_or("–".to_string(), |b| format!("{b:.1}")),
            v.inertia
        );
    }
    h.push_str("</table>");
    figures(h, &c.ra_af_pngs, "RA against AF", "");
    figures(
        h,
        &c.cumulative_pngs,
        "cumulative hits per cluster",
        ": cumulative hits per cluster against time and load",
    );
    if let Some(p) = &c.distributions_png {
        h.push_str(&img(p, "feature distributions per cluster", Some(1100)));
    }
    figures(
        h,
        &c.evolution_pngs,
        "damage evolution by cluster",
        ": cumulative sources, hits and energy per cluster (cluster/evolution.parquet)",
    );
    figures(
        h,
        &c.location_pngs,
        "location by cluster",
        ": where the events are, by their first hit's cluster",
    );
}

fn statistics_section(h: &mut String, s: &RunSummary) {
    if s.statistics.is_empty() {
        return;
    }
    h.push_str("<h2>Energy distribution (Fig. 2.1)</h2><p>The sources' AE energy above x_min follows p(E) ∝ E^−α; α by maximum likelihood, x_min by the least Kolmogorov–Smirnov distance (Clauset, Shalizi &amp; Newman 2009). With fewer than 50 energies no fit is stated.</p><table><tr><th class=l>experiment</th><th>energies</th><th>x_min (eu)</th><th>tail</th><th>α</th><th>cumulative exponent α − 1</th><th>KS distance</th></tr>");
    for r in s.statistics.iter().take(200) {
        match &r.fit {
            Some(f) => {
                let _ = write!(
                    h,
                    "<tr><td class=l>{}</td><td>{}</td><td>{:.4e}</td><td>{}</td><td>{:.3} ± {:.3}</td><td>{:.3}</td><td>{:.3}</td></tr>",
                    esc(&r.experiment), r.n, f.x_min, f.n_tail, f.alpha, f.alpha_se, f.alpha - 1.0, f.ks_distance
                );
            }
            None => {
                let _ = write!(
                    h,
                    "<tr><td class=l>{}</td><td>{}</td><td colspan=5 class=l>too few energies for a power-law fit</td></tr>",
                    esc(&r.experiment), r.n
                );
            }
        }
    }
    h.push_str("</table>");
}

fn profile_section(h: &mut String, s: &RunSummary) {
    let Some(m) = &s.som else { return };
    if m.profile.is_empty() {
        return;
    }
    let _ = write!(
        h,
        "<h2>Damage profile (Fig. 6.1)</h2><p>The SOM's classes in time order against the \
         load; the table is <code>{}</code>.</p><table><tr><th class=l>experiment</th>\
         <th>peak load (N)</th><th>at (s)</th><th class=l>class</th><th>hits</th>\
         <th>before the peak load</th><th>last fibre failure (s)</th><th>last hit (s)</th></tr>",
        esc(&m.profile_table.display().to_string())
    );
    let opt = |v: Option<f64>, d: usize| v.map(|x| format!("{x:.d$}")).unwrap_or("–".into());
    for p in &m.profile {
        for (k, (c, (n, before))) in p.classes.iter().enumerate() {
            let _ = write!(
                h,
                "<tr><td class=l>{}</td><td>{}</td><td>{}</td><td class=l>{}</td><td>{n}</td><td>{before}</td><td>{}</td><td>{}</td></tr>",
                if k == 0 { esc(&format!("{} ch{}", p.experiment, p.channel)) } else { String::new() },
                if k == 0 { opt(p.peak_load_n, 1) } else { String::new() },
                if k == 0 { opt(p.peak_time_s, 2) } else { String::new() },
                esc(c),
                if k == 0 { opt(p.last_fibre_s, 2) } else { String::new() },
                if k == 0 { opt(p.last_hit_s, 2) } else { String::new() },
            );
        }
    }
    h.push_str("</table>");
    // A series whose load channel is no load has no profile against load: say why.
    let no_load: Vec<String> = m
        .profile
        .iter()
        .filter_map(|p| {
            let why = p.load_note.as_ref()?;
            Some(format!("{} ch{}: {why}", p.experiment, p.channel))
        })
        .collect();
    if !no_load.is_empty() {
        let _ = write!(
            h,
            "<p>No load, so no peak and no profile against load, for {} series: {}.</p>",
            no_load.len(),
            esc(&no_load.join("; "))
        );
    }
    for l in series::load_coverage(s) {
        let _ = write!(h, "<p>{}.</p>", esc(l));
    }
    figures(h, &m.profile_plots, "damage profile", "");
}

fn truth_section(h: &mut String, s: &RunSummary) {
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
        let _ = write!(
            h,
            "<p>Recall by true class (true class → the same SOM class): {}.",
            esc(&t.recall_line())
        );
        if let Some(b) = t.balanced_accuracy() {
            let _ = write!(
                h,
                " Balanced accuracy (the mean of bond and fibre failures' recalls): {:.1} %.",
                100.0 * b
            );
        }
        h.push_str("</p>");
        let (ek, en) = t.erroneous_recall();
        let (ok, all) = t.thesis_overall();
        let called = t.erroneous_called();
        let _ = write!(
            h,
            "<p>Erroneous records kept from the mechanisms: {ek}/{en} ({called} called erroneous, \
             {} unlike the references). Overall, the thesis's way (true mechanism or an erroneous \
             record kept from the mechanisms, over all hits): {ok}/{all} = {:.1} %.</p>\
             <p>Table 5.4 layout (share of each SOM class's hits):</p><pre>{}</pre>",
            ek - called,
            100.0 * ok as f64 / all.max(1) as f64,
            esc(&t.format_table_5_4())
        );
    }
}

/// "features 0.4 s (75 MB), trend 0.1 s (40 MB), …": each stage's time and peak memory.
pub fn stage_line(s: &RunSummary) -> String {
    s.stages()
        .into_iter()
        .map(|(k, v, rss)| {
            let cached = match (k, s.som.as_ref().and_then(|m| m.map_cache.as_ref())) {
                ("som training", Some(c)) => format!(", {c}"),
                _ => String::new(),
            };
            match rss {
                Some(b) => format!("{k} {v:.1} s ({:.0} MB){cached}", b as f64 / 1e6),
                None => format!("{k} {v:.1} s{cached}"),
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

fn footer(h: &mut String, s: &RunSummary, g: &Gathered) {
    // Manifest and timings.
    let manifest = &g.manifest;
    let _ = write!(
        h,
        "<h2>Run</h2><p>Stages: {}.</p><details><summary>manifest.json</summary><pre>{}</pre></details>\n\
<script>/* self-check: how many pictures decoded (read by the headless-browser test) */\
window.addEventListener('load',function(){{var i=Array.prototype.slice.call(document.images);\
document.body.setAttribute('data-images-loaded',i.filter(function(x){{return x.complete&&x.naturalWidth>0}}).length+'/'+i.length);}});</script>\
</body></html>\n",
        esc(&stage_line(s)),
        esc(manifest)
    );
}
