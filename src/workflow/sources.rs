//! After the classification: the damage evolution (`evolution.parquet` and a picture per
//! experiment) and where the classified events are (a location picture per experiment).
//! Both take what the damage profile emits, sorted on disk as it passes (bounded memory).

use super::*;
use crate::analysis::cycles::{Cycle, CycleFinder, CycleParams, Felicity};
use crate::analysis::evolution::{EvolutionParams, EvolutionRow, Series, Source, StrainEnergy};
use crate::analysis::trend::thin_every;
use crate::model::columns as cols;
use crate::plot::sources::LocatedSource;
use crate::som::layout::ClassifyDir;
use crate::som::profile::{ProfileRow, ProfileSummary};
use crate::store::spill::{Dec, Enc, Sorter, Spill};

/// A profile row as a source of its experiment's evolution, in the order the evolution
/// reads them: by time (null last), hit, then the profile's own order.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct EvoRec {
    pub experiment: String,
    pub time_s: Option<f64>,
    pub hit: i64,
    /// Position in the damage profile's output (ties keep the profile's order).
    pub row: u64,
    pub channel: i32,
    pub load_n: Option<f64>,
    pub extension_m: Option<f64>,
    pub amplitude_db: Option<f64>,
    pub energy_eu: Option<f64>,
    pub hits: u64,
    pub class: String,
}

impl Eq for EvoRec {}
impl PartialOrd for EvoRec {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for EvoRec {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        let t = |r: &EvoRec| r.time_s.unwrap_or(f64::NAN);
        self.experiment
            .cmp(&o.experiment)
            .then(t(self).total_cmp(&t(o)))
            .then(self.hit.cmp(&o.hit))
            .then(self.row.cmp(&o.row))
    }
}

impl Spill for EvoRec {
    fn encode(&self, out: &mut Vec<u8>) {
        Enc(out)
            .str(&self.experiment)
            .opt_f64(self.time_s)
            .i64(self.hit)
            .u64(self.row)
            .i32(self.channel)
            .opt_f64(self.load_n)
            .opt_f64(self.extension_m)
            .opt_f64(self.amplitude_db)
            .opt_f64(self.energy_eu)
            .u64(self.hits)
            .str(&self.class);
    }
    fn decode(b: &mut Dec<'_>) -> Option<Self> {
        Some(EvoRec {
            experiment: b.str()?,
            time_s: b.opt_f64()?,
            hit: b.i64()?,
            row: b.u64()?,
            channel: b.i32()?,
            load_n: b.opt_f64()?,
            extension_m: b.opt_f64()?,
            amplitude_db: b.opt_f64()?,
            energy_eu: b.opt_f64()?,
            hits: b.u64()?,
            class: b.str()?,
        })
    }
    fn mem_bytes(&self) -> usize {
        std::mem::size_of::<Self>() + self.experiment.len() + self.class.len()
    }
}

impl EvoRec {
    fn source(&self) -> Source {
        Source {
            key: (self.experiment.clone(), self.channel, self.hit),
            time_s: self.time_s,
            load_n: self.load_n,
            extension_m: self.extension_m,
            strain_energy_j: None,
            amplitude_db: self.amplitude_db,
            energy_eu: self.energy_eu,
            hits: self.hits,
            class: self.class.clone(),
        }
    }
}

/// The damage profile's rows, gathered for the evolution as the profile emits them.
pub(super) struct EvolutionInput {
    sorter: Sorter<EvoRec>,
    rows: u64,
}

impl EvolutionInput {
    pub fn new(spill_dir: &Path) -> EvolutionInput {
        EvolutionInput {
            sorter: Sorter::new(spill_dir),
            rows: 0,
        }
    }

    pub fn push(&mut self, r: &ProfileRow) -> Result<(), WorkflowError> {
        self.sorter.push(EvoRec {
            experiment: r.key.0.clone(),
            time_s: r.time_s,
            hit: r.key.2,
            row: self.rows,
            channel: r.key.1,
            load_n: r.load_n,
            extension_m: r.extension_m,
            amplitude_db: r.amplitude_db,
            energy_eu: r.energy_eu,
            hits: r.source_hits,
            class: r.class.clone(),
        })?;
        self.rows += 1;
        Ok(())
    }

    /// A source from another stage (the clusters'); its place in the input is set here.
    pub fn push_rec(&mut self, mut r: EvoRec) -> Result<(), WorkflowError> {
        r.row = self.rows;
        self.sorter.push(r)?;
        self.rows += 1;
        Ok(())
    }
}

/// An experiment's load cycles from its sources' own loads (two passes over its sorted
/// rows), for a test whose parametric series gives no load: cycles with AE on the
/// unloadings show; a reload whose unloading was silent does not.
fn cycles_of_sources(
    sorted: &crate::store::spill::Sorted<EvoRec>,
    span: crate::store::spill::Span,
    min_span_n: f64,
    cp: &CycleParams,
) -> Result<Vec<Cycle>, WorkflowError> {
    let mut check = crate::analysis::load::LoadCheck::new();
    for r in sorted.span_iter(span) {
        if let Some(l) = r?.load_n {
            check.push(l);
        }
    }
    let Some(mut finder) = CycleFinder::new(&check, min_span_n, cp) else {
        return Ok(vec![]);
    };
    for r in sorted.span_iter(span) {
        let r = r?;
        if let (Some(t), Some(l)) = (r.time_s, r.load_n) {
            finder.push(t, l);
        }
    }
    Ok(finder.cycles())
}

/// What the evolution stage wrote: the table, its pictures, and the `all` series' cycles of
/// each load–unload–reload test.
pub(super) struct Evolution {
    pub table: PathBuf,
    pub plots: Vec<(String, PathBuf)>,
    pub reloads: Vec<crate::analysis::cycles::CycleRow>,
}

/// `evolution.parquet` and `cycles.parquet` from the damage profile's rows (the classified
/// sources; an experiment's channels' series merge into one by time) and one picture per
/// experiment (the first `[report] series_figures`). Each experiment is read 1 + C times
/// from the sorted rows: `all` (which also finds its classes), then each of its C classes
/// in name order. The load cycles come from the test's load series in `parametric`
/// (else from the sources' own loads).
pub(super) fn evolution_stage(
    cfg: &ValidConfig,
    input: EvolutionInput,
    summaries: &[ProfileSummary],
    parametric: &Path,
    som_dir: &ClassifyDir,
) -> Result<Evolution, WorkflowError> {
    let p = EvolutionParams::of(&cfg.evolution);
    let cp = CycleParams::of(&cfg.evolution);
    let min_span = cfg.trend.min_load_span_n;
    let mut test_cycles = match parametric.is_file() {
        true => crate::analysis::cycles::cycles_of_table(parametric, min_span, &cp)?,
        false => Default::default(),
    };
    let sorted = input.sorter.finish()?;
    let table_path = som_dir.evolution();
    let table = crate::analysis::evolution::evolution_table();
    let meta = [("aepipe.config_sha256".to_string(), cfg.hash())];
    let mut w = crate::store::TableWriter::create(&table_path, table.schema(), &meta, 65_536)?;
    let ctable = crate::analysis::cycles::cycles_table();
    let mut cw =
        crate::store::TableWriter::create(&som_dir.cycles(), ctable.schema(), &meta, 4096)?;
    let mut plots = Vec::new();
    let mut reloads = Vec::new();
    for (k, (exp, span)) in sorted
        .groups(|r| r.experiment.clone())?
        .into_iter()
        .enumerate()
    {
        let cycles = match test_cycles.remove(&exp) {
            Some(c) => c,
            None => cycles_of_sources(&sorted, span, min_span, &cp)?,
        };
        let draw = k < cfg.report.series_figures;
        let every = thin_every(span.len as usize);
        let mut drawn: Vec<EvolutionRow> = Vec::new();
        // `all` first; its pass also finds the classes, each then read in name order.
        let mut todo: Vec<String> = vec!["all".into()];
        let mut classes: Vec<String> = Vec::new();
        let mut next = 0;
        while next < todo.len() {
            let class = todo[next].as_str();
            let all = next == 0;
            next += 1;
            let mut series = Series::new(&exp, class, &p);
            let mut felicity = Felicity::new(&exp, class, &cycles, &cp);
            // The strain energy integrates every source's (extension, load), whatever its
            // class.
            let mut strain = StrainEnergy::default();
            let mut i = 0usize;
            let mut last = None;
            for r in sorted.span_iter(span) {
                let r = r?;
                let es = strain.add(r.extension_m, r.load_n);
                if all {
                    if let Err(at) = classes.binary_search(&r.class) {
                        classes.insert(at, r.class.clone());
                    }
                } else if r.class != class {
                    continue;
                }
                let mut src = r.source();
                src.strain_energy_j = es;
                let mut row = series.step(&src);
                row.at_cycle = felicity.step(r.time_s, r.load_n, r.amplitude_db);
                w.push(table.row(row.clone()))?;
                if draw {
                    if i.is_multiple_of(every) {
                        drawn.push(row);
                        last = None;
                    } else {
                        last = Some(row);
                    }
                }
                i += 1;
            }
            let rows = felicity.finish();
            if all && rows.len() >= 2 {
                reloads.extend(rows.iter().cloned());
            }
            for c in rows {
                cw.push(ctable.row(c))?;
            }
            // Each drawn series ends at its last row (its totals are in the legend).
            drawn.extend(last);
            if all {
                todo.append(&mut classes);
            }
        }
        if draw {
            let peak = summaries
                .iter()
                .filter(|s| s.experiment == exp)
                .find_map(|s| s.peak_time_s);
            let png = som_dir.evolution_png(&exp);
            let rows: Vec<&EvolutionRow> = drawn.iter().collect();
            crate::plot::sources::evolution_png(&png, &exp, &rows, p.window, peak, every)?;
            plots.push((exp, png));
        }
    }
    w.finish()?;
    cw.finish()?;
    Ok(Evolution {
        table: table_path,
        plots,
        reloads,
    })
}

/// (experiment, event) → the SOM's class of its first hit, sorted by the event.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
struct EventClass {
    experiment: String,
    event: i64,
    class: String,
}

impl Spill for EventClass {
    fn encode(&self, out: &mut Vec<u8>) {
        Enc(out)
            .str(&self.experiment)
            .i64(self.event)
            .str(&self.class);
    }
    fn decode(b: &mut Dec<'_>) -> Option<Self> {
        Some(EventClass {
            experiment: b.str()?,
            event: b.i64()?,
            class: b.str()?,
        })
    }
    fn mem_bytes(&self) -> usize {
        std::mem::size_of::<Self>() + self.experiment.len() + self.class.len()
    }
}

/// The classes of the events the damage profile's rows opened, gathered as it emits them.
pub(super) struct EventClasses(Sorter<EventClass>);

impl EventClasses {
    pub fn new(spill_dir: &Path) -> EventClasses {
        EventClasses(Sorter::new(spill_dir))
    }

    pub fn push(&mut self, r: &ProfileRow) -> Result<(), WorkflowError> {
        if let Some(event) = r.event {
            self.push_class(&r.key.0, event, &r.class)?;
        }
        Ok(())
    }

    /// An event's class (its first hit's), from any stage.
    pub fn push_class(
        &mut self,
        experiment: &str,
        event: i64,
        class: &str,
    ) -> Result<(), WorkflowError> {
        self.0.push(EventClass {
            experiment: experiment.to_string(),
            event,
            class: class.to_string(),
        })?;
        Ok(())
    }
}

/// A located event of `events.parquet`, sorted by (experiment, event).
#[derive(Debug, Clone, PartialEq)]
struct Located {
    experiment: String,
    event: i64,
    seq: u64,
    x_m: f64,
    y_m: Option<f64>,
    outside: bool,
}

impl Eq for Located {}
impl PartialOrd for Located {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Located {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        (self.experiment.as_str(), self.event, self.seq).cmp(&(
            o.experiment.as_str(),
            o.event,
            o.seq,
        ))
    }
}

impl Spill for Located {
    fn encode(&self, out: &mut Vec<u8>) {
        Enc(out)
            .str(&self.experiment)
            .i64(self.event)
            .u64(self.seq)
            .f64(self.x_m)
            .opt_f64(self.y_m)
            .u8(self.outside as u8);
    }
    fn decode(b: &mut Dec<'_>) -> Option<Self> {
        Some(Located {
            experiment: b.str()?,
            event: b.i64()?,
            seq: b.u64()?,
            x_m: b.f64()?,
            y_m: b.opt_f64()?,
            outside: b.u8()? != 0,
        })
    }
    fn mem_bytes(&self) -> usize {
        std::mem::size_of::<Self>() + self.experiment.len()
    }
}

/// Where a location picture goes, and what colours its events.
pub(super) struct LocationPictures<'a> {
    /// Spill files go here.
    pub dir: &'a Path,
    pub png: &'a dyn Fn(&str) -> PathBuf,
    /// "SOM class", "cluster".
    pub by: &'a str,
}

/// A location picture per experiment with located events (the first `[report]
/// series_figures`): each event coloured by its first hit's class (the SOM's, from the
/// damage profile's rows, or its cluster), "outside the zone" for those the zone leaves out
/// (which are not classified with `exclude_outside`). Events and classes are joined in
/// event order.
pub(super) fn location_stage(
    cfg: &ValidConfig,
    classes: EventClasses,
    events: &Path,
    to: &LocationPictures,
) -> Result<Vec<(String, PathBuf)>, WorkflowError> {
    if !events.is_file() {
        return Ok(Vec::new());
    }
    let ev = TableScan::open(events)?;
    let sel = [
        cols::EXPERIMENT.name,
        cols::EVENT.name,
        cols::X_M.name,
        cols::Y_M.name,
        cols::ZONE.name,
    ];
    let mut located: Sorter<Located> = Sorter::new(to.dir);
    let mut seq = 0u64;
    for batch in ev.batches(&sel) {
        let (_, df) = batch?;
        let exps = ev.texts(&df, cols::EXPERIMENT)?;
        let numbers = ev.i64s(&df, cols::EVENT)?;
        let (xs, ys) = (ev.floats(&df, cols::X_M)?, ev.floats(&df, cols::Y_M)?);
        let zones = ev.texts(&df, cols::ZONE)?;
        for i in 0..df.height() {
            if let (Some(exp), Some(n), Some(x)) = (&exps[i], numbers[i], xs[i]) {
                located.push(Located {
                    experiment: exp.clone(),
                    event: n,
                    seq,
                    x_m: x,
                    y_m: ys[i],
                    outside: zones[i].as_deref() == Some("outside"),
                })?;
            }
            seq += 1;
        }
    }
    let located = located.finish()?;
    if located.is_empty() {
        return Ok(Vec::new());
    }
    let classes = classes.0.finish()?;
    let mut class_iter = classes.iter();
    let mut head: Option<EventClass> = class_iter.next().transpose()?;
    let mut plots = Vec::new();
    for (k, (exp, span)) in located
        .groups(|r| r.experiment.clone())?
        .into_iter()
        .enumerate()
    {
        let draw = k < cfg.report.series_figures;
        let every = thin_every(span.len as usize);
        let mut drawn: Vec<LocatedSource> = Vec::new();
        for (i, r) in located.span_iter(span).enumerate() {
            let r = r?;
            // Advance the classes to this event (both are in (experiment, event) order).
            let mut class = None;
            while let Some(c) = &head {
                match (c.experiment.as_str(), c.event).cmp(&(r.experiment.as_str(), r.event)) {
                    std::cmp::Ordering::Less => head = class_iter.next().transpose()?,
                    std::cmp::Ordering::Equal => {
                        class = Some(c.class.clone());
                        break;
                    }
                    std::cmp::Ordering::Greater => break,
                }
            }
            if draw && (i.is_multiple_of(every) || i as u64 + 1 == span.len) {
                drawn.push(LocatedSource {
                    x_m: r.x_m,
                    y_m: r.y_m,
                    class: if r.outside {
                        "outside the zone".to_string()
                    } else {
                        class.unwrap_or_else(|| "unclassified".to_string())
                    },
                });
            }
        }
        if draw {
            let png = (to.png)(&exp);
            let mut title = format!(
                "{exp}: where the events are by {} ({} located)",
                to.by, span.len
            );
            if every > 1 {
                title += &format!("; every {every}th drawn");
            }
            crate::plot::sources::location_png(
                &png,
                &title,
                &drawn,
                cfg.location.zone.as_ref(),
                &cfg.location.sensors,
            )?;
            plots.push((exp, png));
        }
    }
    Ok(plots)
}
