//! What the report shows of the clusters besides their validity and RA–AF: the cumulative
//! hits per cluster against time and load, the feature distributions per cluster, and where
//! the events are coloured by cluster. One pass over the feature tables walks
//! `clusters.parquet` beside them: the clustering assigned the source rows in the tables'
//! order, leaving out rows with a null feature, so its rows are a subsequence of theirs and
//! a merge by key joins the two in bounded memory.

use super::*;
use crate::model::columns as cols;
use crate::plot::{CumulativePoint, Distribution};
use crate::store::spill::{Dec, Enc, Sorter, Spill};

/// The features whose distributions are drawn, in panel order (the evolution reads the
/// amplitude, 0, and the energy, 4, from them).
const DISTRIBUTIONS: [Distribution; 6] = [
    Distribution {
        column: "peak_amplitude_db",
        label: "peak amplitude (dB_AE)",
        scale: 1.0,
        log10: false,
    },
    Distribution {
        column: "peak_freq_hz",
        label: "peak frequency (kHz)",
        scale: 1e-3,
        log10: false,
    },
    Distribution {
        column: "centroid_freq_hz",
        label: "centroid frequency (kHz)",
        scale: 1e-3,
        log10: false,
    },
    Distribution {
        column: "duration_s",
        label: "duration (µs)",
        scale: 1e6,
        log10: true,
    },
    Distribution {
        column: "energy_eu",
        label: "energy (eu)",
        scale: 1.0,
        log10: true,
    },
    Distribution {
        column: "counts",
        label: "counts",
        scale: 1.0,
        log10: true,
    },
];

/// Hits sampled per cluster for the distributions (a seeded reservoir).
pub const SAMPLE_PER_CLUSTER: usize = 4000;

/// The pictures.
#[derive(Debug, Clone, Default)]
pub struct ClusterViews {
    pub cumulative: Vec<(String, PathBuf)>,
    pub distributions: Option<PathBuf>,
    pub locations: Vec<(String, PathBuf)>,
    /// The damage evolution by cluster (`cluster/evolution.parquet`, `cycles.parquet`).
    pub evolution_plots: Vec<(String, PathBuf)>,
    pub reloads: Vec<crate::analysis::cycles::CycleRow>,
    /// Hits per cluster the walk joined to their feature rows: `clusters.parquet`'s sizes
    /// when every row was found.
    pub joined: Vec<usize>,
}

/// A clustered hit of a drawn experiment, sorted by (experiment, time, position).
#[derive(Debug, Clone, PartialEq)]
struct CumRec {
    experiment: String,
    time_s: f64,
    seq: u64,
    load_n: Option<f64>,
    cluster: u32,
}

impl Eq for CumRec {}
impl PartialOrd for CumRec {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for CumRec {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        self.experiment
            .cmp(&o.experiment)
            .then(self.time_s.total_cmp(&o.time_s))
            .then(self.seq.cmp(&o.seq))
    }
}

impl Spill for CumRec {
    fn encode(&self, out: &mut Vec<u8>) {
        Enc(out)
            .str(&self.experiment)
            .f64(self.time_s)
            .u64(self.seq)
            .opt_f64(self.load_n)
            .u32(self.cluster);
    }
    fn decode(b: &mut Dec<'_>) -> Option<Self> {
        Some(CumRec {
            experiment: b.str()?,
            time_s: b.f64()?,
            seq: b.u64()?,
            load_n: b.opt_f64()?,
            cluster: b.u32()?,
        })
    }
    fn mem_bytes(&self) -> usize {
        std::mem::size_of::<Self>() + self.experiment.len()
    }
}

/// `clusters.parquet` row by row: (key, cluster).
struct ClusterCursor<'a> {
    batches: Box<dyn Iterator<Item = Result<(usize, polars::prelude::DataFrame), StoreError>> + 'a>,
    scan: &'a TableScan,
    buf: std::collections::VecDeque<(HitKey, u32)>,
}

impl<'a> ClusterCursor<'a> {
    fn new(scan: &'a TableScan, sel: &'a [&'a str]) -> ClusterCursor<'a> {
        ClusterCursor {
            batches: Box::new(scan.batches(sel)),
            scan,
            buf: Default::default(),
        }
    }

    fn next(&mut self) -> Result<Option<(HitKey, u32)>, StoreError> {
        while self.buf.is_empty() {
            let Some(b) = self.batches.next() else {
                return Ok(None);
            };
            let (_, df) = b?;
            let keys = self.scan.hit_keys(&df)?;
            let c = self.scan.f64s(&df, "cluster")?;
            self.buf.extend(
                keys.into_iter()
                    .zip(c)
                    .filter_map(|(k, c)| Some((k, c? as u32))),
            );
        }
        Ok(self.buf.pop_front())
    }
}

/// What the walk gathers.
struct Gathered {
    cum: Sorter<CumRec>,
    loads: BTreeMap<String, crate::analysis::load::LoadCheck>,
    samples: BTreeMap<usize, Vec<Vec<f64>>>,
    seen: BTreeMap<usize, usize>,
    events: super::sources::EventClasses,
    evolution: super::sources::EvolutionInput,
}

impl Gathered {
    /// Offer a cluster's row to its seeded reservoir of at most [`SAMPLE_PER_CLUSTER`].
    fn sample(&mut self, c: usize, row: Vec<f64>, rng: &mut crate::util::Rng) {
        let n = self.seen.entry(c).or_insert(0);
        let s = self.samples.entry(c).or_default();
        if s.len() < SAMPLE_PER_CLUSTER {
            s.push(row);
        } else {
            let j = (rng.next_u64() % (*n as u64 + 1)) as usize;
            if j < SAMPLE_PER_CLUSTER {
                s[j] = row;
            }
        }
        *n += 1;
    }
}

/// Walk the feature tables and `clusters` together (see the module's doc) and draw into
/// `dir`.
pub(super) fn cluster_views(
    cfg: &ValidConfig,
    feats: &[PathBuf],
    clusters: &Path,
    written: &crate::pipeline::RunReport,
    dir: &Path,
) -> Result<ClusterViews, WorkflowError> {
    let mut g = Gathered {
        cum: Sorter::new(dir),
        loads: BTreeMap::new(),
        samples: BTreeMap::new(),
        seen: BTreeMap::new(),
        events: super::sources::EventClasses::new(dir),
        evolution: super::sources::EvolutionInput::new(dir),
    };
    let drawn_max = cfg.report.series_figures;
    let mut drawn: Vec<String> = Vec::new();
    let mut rng = crate::util::Rng::new(cfg.cluster.seed ^ 0xd157);
    let ct = TableScan::open(clusters)?;
    let csel = [
        cols::EXPERIMENT.name,
        cols::CHANNEL.name,
        cols::HIT.name,
        "cluster",
    ];
    let mut cursor = ClusterCursor::new(&ct, &csel);
    let mut head = cursor.next()?;
    let mut seq = 0u64;
    for p in feats {
        let t = TableScan::open(p)?.sources(cfg.source_rows());
        let names = t.column_names();
        let has = |c: &str| names.iter().any(|n| n == c);
        let mut sel: Vec<&str> = vec![cols::EXPERIMENT.name, cols::CHANNEL.name, cols::HIT.name];
        let optional = [
            cols::TIME_S.name,
            cols::LOAD_N.name,
            cols::EXTENSION_M.name,
            cols::EVENT.name,
            cols::EVENT_FIRST.name,
        ];
        sel.extend(optional.iter().filter(|c| has(c)));
        let dist: Vec<&str> = DISTRIBUTIONS
            .iter()
            .map(|d| d.column)
            .filter(|c| has(c))
            .collect();
        sel.extend(&dist);
        for b in t.batches(&sel) {
            let (_, df) = b?;
            let keys = t.hit_keys(&df)?;
            let f = |c: &str| -> Result<Vec<Option<f64>>, StoreError> {
                match has(c) {
                    true => t.f64s(&df, c),
                    false => Ok(vec![None; df.height()]),
                }
            };
            let (time, load, event) = (
                f(cols::TIME_S.name)?,
                f(cols::LOAD_N.name)?,
                f(cols::EVENT.name)?,
            );
            let extension = f(cols::EXTENSION_M.name)?;
            let first = t.event_first(&df)?;
            let values: Vec<Vec<Option<f64>>> = DISTRIBUTIONS
                .iter()
                .map(|d| f(d.column))
                .collect::<Result<_, _>>()?;
            for (i, key) in keys.into_iter().enumerate() {
                let Some((_, c)) = head.as_ref().filter(|(k, _)| *k == key) else {
                    continue;
                };
                let c = *c;
                head = cursor.next()?;
                let exp = &key.0;
                if !drawn.contains(exp) && drawn.len() < drawn_max {
                    drawn.push(exp.clone());
                }
                if let (true, Some(ts)) = (drawn.contains(exp), time[i]) {
                    if let Some(l) = load[i] {
                        g.loads.entry(exp.clone()).or_default().push(l);
                    }
                    g.cum.push(CumRec {
                        experiment: exp.clone(),
                        time_s: ts,
                        seq,
                        load_n: load[i],
                        cluster: c,
                    })?;
                }
                seq += 1;
                // As the damage profile gives the SOM's evolution its sources: an event's
                // first hit, or a hit outside events (`hits` counts the source once: the
                // other sensors' rows are not clustered).
                g.evolution.push_rec(super::sources::EvoRec {
                    experiment: exp.clone(),
                    time_s: time[i],
                    hit: key.2,
                    row: 0,
                    channel: crate::store::group_channel(key.1, first[i]),
                    load_n: load[i],
                    extension_m: extension[i],
                    amplitude_db: values[0][i],
                    energy_eu: values[4][i],
                    hits: 1,
                    class: format!("cluster {c}"),
                })?;
                if let (Some(true), Some(e)) = (first[i], event[i]) {
                    g.events
                        .push_class(exp, e as i64, &format!("cluster {c}"))?;
                }
                let row: Vec<f64> = values.iter().map(|v| v[i].unwrap_or(f64::NAN)).collect();
                g.sample(c as usize, row, &mut rng);
            }
        }
    }
    draw(cfg, g, written, dir)
}

fn draw(
    cfg: &ValidConfig,
    g: Gathered,
    written: &crate::pipeline::RunReport,
    dir: &Path,
) -> Result<ClusterViews, WorkflowError> {
    let k = g.seen.keys().next_back().map_or(0, |c| c + 1);
    let mut out = ClusterViews {
        joined: (0..k)
            .map(|c| g.seen.get(&c).copied().unwrap_or(0))
            .collect(),
        ..Default::default()
    };
    let sorted = g.cum.finish()?;
    for (exp, span) in sorted.groups(|r| r.experiment.clone())? {
        let every = crate::analysis::trend::thin_every(span.len as usize);
        let mut series: BTreeMap<usize, Vec<CumulativePoint>> = BTreeMap::new();
        let mut count: BTreeMap<usize, u64> = BTreeMap::new();
        let mut last: BTreeMap<usize, CumulativePoint> = BTreeMap::new();
        for (i, r) in sorted.span_iter(span).enumerate() {
            let r = r?;
            let c = r.cluster as usize;
            let n = count.entry(c).or_insert(0);
            *n += 1;
            let p = (r.time_s, r.load_n, *n);
            if i.is_multiple_of(every) {
                series.entry(c).or_default().push(p);
                last.remove(&c);
            } else {
                last.insert(c, p);
            }
        }
        // Each curve ends at its cluster's total.
        for (c, p) in last {
            series.entry(c).or_default().push(p);
        }
        let verdict = g
            .loads
            .get(&exp)
            .map(|l| l.verdict(cfg.trend.min_load_span_n))
            .unwrap_or(crate::analysis::load::LoadVerdict::Absent);
        let no_load = match &verdict {
            crate::analysis::load::LoadVerdict::Load => None,
            crate::analysis::load::LoadVerdict::Absent => Some("no load channel".to_string()),
            crate::analysis::load::LoadVerdict::Noise(why) => Some(why.clone()),
        };
        let mut title = format!("{exp}: cumulative hits per cluster ({} hits", span.len);
        if every > 1 {
            title += &format!("; every {every}th drawn");
        }
        title += ")";
        if let Some(why) = &no_load {
            title += &format!("; not against load: {why}");
        }
        let png = dir.join(format!("cumulative_{}.png", crate::util::file_safe(&exp)));
        crate::plot::cumulative_png(&png, &title, &series, no_load.as_deref())?;
        out.cumulative.push((exp, png));
    }
    if !g.samples.is_empty() {
        let png = dir.join("distributions.png");
        let total: usize = g.seen.values().sum();
        let sampled: usize = g.samples.values().map(Vec::len).sum();
        let title = format!(
            "Feature distributions per cluster ({sampled} of {total} hits: up to {SAMPLE_PER_CLUSTER} a cluster, a seeded sample)"
        );
        crate::plot::distributions_png(&png, &title, &DISTRIBUTIONS, &g.samples)?;
        out.distributions = Some(png);
    }
    let to = super::sources::LocationPictures {
        dir,
        png: &|e: &str| dir.join(format!("location_{}.png", crate::util::file_safe(e))),
        by: "cluster",
    };
    out.locations = super::sources::location_stage(cfg, g.events, &written.events_path, &to)?;
    let evolution = super::sources::evolution_stage(
        cfg,
        g.evolution,
        &[],
        &written.parametric_path,
        &crate::som::layout::ClassifyDir::new(dir.to_path_buf()),
    )?;
    out.evolution_plots = evolution.plots;
    out.reloads = evolution.reloads;
    Ok(out)
}
