//! Pictures: what the report shows besides the summary (the CWT gallery), and `aepipe cwt`.

use super::*;
use crate::model::columns as cols;

/// Read what the report shows besides the summary (the hits per class and experiment, the
/// gallery's choice, the manifest) and draw the CWT gallery (one pass over the inputs). The
/// label columns are read a batch at a time: nothing per hit is kept.
pub(super) fn gather(s: &RunSummary) -> Result<Gathered, WorkflowError> {
    let per = s.config.report.gallery_per_class;
    let (criteria, by_criteria) =
        count_labels(&s.features.table_path, cols::CRITERIA_LABEL.name, per)?;
    let (som, by_som) = match &s.som {
        Some(m) => count_labels(&m.classification, cols::SOM_LABEL.name, per)?,
        None => (BTreeMap::new(), crate::report::GalleryChoice::new(per)),
    };
    let (by, chosen) = if som.is_empty() {
        ("criteria", by_criteria.chosen())
    } else {
        ("SOM", by_som.chosen())
    };
    let by_cluster = match &s.cluster {
        Some(c) => cluster_choice(&c.report.clusters, per)?.chosen(),
        None => BTreeMap::new(),
    };
    // Appendix B: the first `appendix_b_hits` hits of the run in key order, whatever class.
    let appendix: Vec<HitKey> = match s.config.report.appendix_b_hits {
        0 => Vec::new(),
        n => first_hits(&s.features.table_path, n)?,
    };
    let mut disagree = match &s.som {
        Some(m) => disagreements(&m.classification, per)?,
        None => crate::report::Disagreements::new(0),
    };
    // One pass over the inputs draws the galleries' hits and the disagreeing ones.
    let mut wanted = chosen.clone();
    wanted.extend(by_cluster.iter().map(|(c, k)| (c.clone(), k.clone())));
    wanted.insert("disagree".into(), disagree.first.keys().cloned().collect());
    let thumbs_only: std::collections::BTreeSet<HitKey> = appendix
        .iter()
        .filter(|k| !wanted.values().flatten().any(|w| w == *k))
        .cloned()
        .collect();
    wanted.insert("appendix B".into(), appendix.clone());
    let run = RunDir::new(&s.out);
    let pics = draw_gallery(&s.inputs, &s.config, &wanted, &thumbs_only, &run);
    let total: usize = criteria.values().sum();
    let appendix_b = match appendix.is_empty() {
        true => None,
        false => {
            let drawn: Vec<(HitKey, Option<PathBuf>)> = appendix
                .iter()
                .map(|k| (k.clone(), pics.get(k).map(|p| p.0.clone())))
                .collect();
            let dir = run.appendix_b();
            Some(
                crate::report::write_appendix_b(&dir, &drawn, total)
                    .map_err(|e| input_err(&dir, e))?,
            )
        }
    };
    disagree.pictures = disagree
        .first
        .keys()
        .filter_map(|k| pics.get(k).map(|p| (k.clone(), p.clone())))
        .collect();
    // The explorer opens the gallery's hits that were drawn.
    let drawn: BTreeMap<String, Vec<HitKey>> = chosen
        .iter()
        .map(|(c, keys)| {
            let k = keys.iter().filter(|k| pics.contains_key(*k)).cloned();
            (c.clone(), k.collect())
        })
        .collect();
    let mut explorer = super::explore::explorer(s, &drawn)?;
    explorer.inputs = s
        .inputs
        .iter()
        .map(|p| format!("'{}'", p.display()))
        .collect::<Vec<_>>()
        .join(" ");
    let pictures = |chosen: BTreeMap<String, Vec<HitKey>>| {
        chosen
            .into_iter()
            .map(|(c, keys)| {
                let v = keys
                    .into_iter()
                    .map(|k| {
                        let p = pics.get(&k).cloned();
                        (k, p)
                    })
                    .collect();
                (c, v)
            })
            .collect()
    };
    let gallery = Gallery {
        by,
        classes: pictures(chosen),
    };
    let cluster_gallery = Gallery {
        by: "cluster",
        classes: pictures(by_cluster),
    };
    let manifest = std::fs::read_to_string(&s.features.manifest_path)
        .map_err(|e| input_err(&s.features.manifest_path, e))?;
    Ok(Gathered {
        criteria,
        som,
        gallery,
        cluster_gallery,
        manifest,
        explorer,
        disagree,
        appendix_b,
    })
}

/// The first `n` hits of the features table in key order (a bounded choice, a batch at a
/// time).
fn first_hits(features: &Path, n: usize) -> Result<Vec<HitKey>, WorkflowError> {
    let mut choice = crate::report::GalleryChoice::new(n);
    let t = TableScan::open(features)?;
    let sel = [cols::EXPERIMENT.name, cols::CHANNEL.name, cols::HIT.name];
    for b in t.batches(&sel) {
        let (_, df) = b?;
        for k in t.hit_keys(&df)? {
            choice.offer(&k, "all");
        }
    }
    Ok(choice.chosen().remove("all").unwrap_or_default())
}

/// Table 5.3's hits: those whose SOM class differs from their reference label, counted, the
/// first `keep` kept with their node (a batch at a time).
fn disagreements(
    classification: &Path,
    keep: usize,
) -> Result<crate::report::Disagreements, WorkflowError> {
    let mut d = crate::report::Disagreements::new(keep);
    let t = TableScan::open(classification)?;
    let sel = [
        cols::EXPERIMENT.name,
        cols::CHANNEL.name,
        cols::HIT.name,
        cols::SOM_LABEL.name,
        cols::REFERENCE_LABEL.name,
        cols::BMU_ROW.name,
        cols::BMU_COL.name,
    ];
    for b in t.batches(&sel) {
        let (_, df) = b?;
        let keys = t.hit_keys(&df)?;
        let som = t.texts(&df, cols::SOM_LABEL)?;
        let reference = t.texts(&df, cols::REFERENCE_LABEL)?;
        let (rows, cols_) = (t.i32s(&df, cols::BMU_ROW)?, t.i32s(&df, cols::BMU_COL)?);
        for i in 0..keys.len() {
            if let Some(s) = &som[i] {
                let node = (rows[i].unwrap_or(-1), cols_[i].unwrap_or(-1));
                d.offer(&keys[i], s, reference[i].as_deref(), node);
            }
        }
    }
    Ok(d)
}

/// The cluster gallery's choice: the first `per` hits of each cluster in key order.
fn cluster_choice(
    clusters: &Path,
    per: usize,
) -> Result<crate::report::GalleryChoice, WorkflowError> {
    let mut choice = crate::report::GalleryChoice::new(per);
    let t = TableScan::open(clusters)?;
    let sel = [
        cols::EXPERIMENT.name,
        cols::CHANNEL.name,
        cols::HIT.name,
        "cluster",
    ];
    for b in t.batches(&sel) {
        let (_, df) = b?;
        let keys = t.hit_keys(&df)?;
        for (k, c) in keys.iter().zip(t.as_strings(&df, "cluster")?) {
            if let Some(c) = c {
                choice.offer(k, &format!("cluster {c}"));
            }
        }
    }
    Ok(choice)
}

/// Hits per (experiment, label), and the gallery's choice.
type LabelCounts = (
    BTreeMap<(String, String), usize>,
    crate::report::GalleryChoice,
);

/// Hits per (experiment, label) of a table's label column (null as ""), and the gallery's
/// choice among them, a batch at a time.
fn count_labels(path: &Path, column: &str, per: usize) -> Result<LabelCounts, WorkflowError> {
    let mut counts: BTreeMap<(String, String), usize> = BTreeMap::new();
    let mut choice = crate::report::GalleryChoice::new(per);
    TableScan::open(path)?.for_each_keyed_string(column, |k, l| {
        choice.offer(&k, &l);
        *counts.entry((k.0, l)).or_insert(0) += 1;
        Ok::<(), WorkflowError>(())
    })?;
    Ok((counts, choice))
}

/// The gallery thumbnails' window about the first threshold crossing, s.
const GALLERY_BEFORE_S: f64 = 10e-6;
const GALLERY_AFTER_S: f64 = 90e-6;

/// Draw the CWT of the chosen hits (one pass over the inputs) into `dir`; returns the PNG
/// of each hit drawn (a hit that cannot be read or drawn is left out, and the report says
/// "not drawn").
fn draw_gallery(
    inputs: &[PathBuf],
    cfg: &ValidConfig,
    chosen: &BTreeMap<String, Vec<HitKey>>,
    thumbs_only: &std::collections::BTreeSet<HitKey>,
    run: &RunDir,
) -> BTreeMap<HitKey, (PathBuf, PathBuf)> {
    let dir = run.gallery();
    let want: std::collections::BTreeSet<&HitKey> = chosen.values().flatten().collect();
    let mut out = BTreeMap::new();
    if want.is_empty() || std::fs::create_dir_all(&dir).is_err() {
        return out;
    }
    let mut ex = crate::features::FeatureExtractor::new(cfg);
    let d = crate::ingest::discover(inputs, &cfg.ingest);
    for src in &d.sources {
        for it in crate::ingest::open(src, cfg.read_settings(), &cfg.load) {
            let crate::model::Item::Record(r) = it else {
                continue;
            };
            let key = (r.experiment.clone(), r.channel as i32, r.hit as i64);
            if !want.contains(&key) || crate::features::validate(&r, &cfg.validate).is_err() {
                continue;
            }
            let png = run.gallery_png(&key);
            let full = run.gallery_full_png(&key);
            // Appendix B's pages show thumbnails only: no whole-record picture for them.
            let whole = (!thumbs_only.contains(&key)).then_some(full.as_path());
            if burst_picture(&mut ex, &r, &png, whole).is_ok() {
                out.insert(key, (png, full));
            }
        }
    }
    out
}

/// Analyse a (valid) record and draw its CWT into `png` as the gallery's thumbnail shows a
/// burst, as the thesis's Appendix B figures do: from 10 µs before the first threshold
/// crossing (the trigger without one) to 90 µs after it; and the whole record into `full`
/// if given. Returns the picture's title (the hit and its ch. 4.7 criteria label).
pub fn burst_picture(
    ex: &mut crate::features::FeatureExtractor,
    r: &crate::model::AeRecord,
    png: &std::path::Path,
    full: Option<&std::path::Path>,
) -> Result<String, crate::plot::PlotError> {
    let a = ex.analyse(r);
    let (freqs, power) = ex.full_cwt(r);
    let title = format!("{} — {}", r.id(), a.label);
    let fs = r.sample_rate_hz;
    let at = a.hit.first_crossing.unwrap_or(r.pretrigger as usize);
    let from = at.saturating_sub((GALLERY_BEFORE_S * fs).round() as usize);
    let to = at + (GALLERY_AFTER_S * fs).round() as usize;
    crate::plot::cwt_window_png(png, r, &freqs, power.view(), &title, from..to)?;
    if let Some(full) = full {
        crate::plot::cwt_png(full, r, &freqs, power.view(), &title)?;
    }
    Ok(title)
}

/// Find a hit in the inputs, analyse it and draw it: the `aepipe cwt` command. Returns a
/// one-line summary (label, dominant frequency).
pub fn cwt_of_hit(
    inputs: &[std::path::PathBuf],
    cfg: &ValidConfig,
    experiment: Option<&str>,
    channel: Option<u32>,
    hit: u64,
    png: &Path,
) -> Result<String, WorkflowError> {
    let d = crate::ingest::discover(inputs, &cfg.ingest);
    let found = d
        .sources
        .iter()
        .filter(|s| {
            experiment.is_none_or(|e| s.id == e || s.format == crate::ingest::Format::Parquet)
        })
        .flat_map(|s| crate::ingest::open(s, cfg.read_settings(), &cfg.load))
        .find_map(|it| match it {
            crate::model::Item::Record(r)
                if r.hit == hit
                    && channel.is_none_or(|c| r.channel == c)
                    && experiment.is_none_or(|e| r.experiment == e) =>
            {
                Some(r)
            }
            _ => None,
        });
    let Some(rec) = found else {
        return Err(WorkflowError::NoHit(format!(
            "no hit {hit}{}{} in {}",
            channel
                .map(|c| format!(" on channel {c}"))
                .unwrap_or_default(),
            experiment.map(|e| format!(" of {e}")).unwrap_or_default(),
            inputs
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )));
    };
    crate::features::validate(&rec, &cfg.validate)
        .map_err(|e| WorkflowError::NoHit(format!("{}: {e}", rec.id())))?;
    let mut ex = crate::features::FeatureExtractor::new(cfg);
    let a = ex.analyse(&rec);
    let (freqs, power) = ex.full_cwt(&rec);
    let summary = format!(
        "{}: {} ({}), dominant {} kHz, peak {:.1} dB_AE",
        rec.id(),
        a.label,
        a.reason,
        a.components
            .dominant
            .map(|d| format!("{:.0}", d.freq_hz / 1e3))
            .unwrap_or_else(|| "–".into()),
        a.hit.amplitude_db
    );
    crate::plot::cwt_png(
        png,
        &rec,
        &freqs,
        power.view(),
        &format!("{} — {}", rec.id(), a.label),
    )?;
    Ok(summary)
}
