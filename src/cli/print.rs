//! What the commands print on the terminal.

use crate::bench::{CwtBench, SimScale};
use crate::model::Mechanism;
use crate::pipeline::RunReport;
use crate::som::tables::Model;
use std::path::Path;

/// At most this many of the experiments' own lines (a rate implied, hits without load).
const SAID_LINES: usize = 20;

/// The summary of a streaming run (`aepipe features`, `aepipe waveforms`).
pub fn stream_run(report: &RunReport, what: &str) {
    let s = &report.stats;
    println!(
        "{what}: {} rows, {} rejects, {} records read, {:.2} s ({:.0} hits/s)",
        s.rows,
        s.rejects,
        s.records_read,
        s.seconds,
        s.rows as f64 / s.seconds.max(1e-9)
    );
    for (exp, c) in &s.by_experiment {
        let extra = match (c.parametric, c.markers) {
            (0, 0) => String::new(),
            (p, m) => format!(" {p:>7} parametric {m:>5} markers"),
        };
        println!(
            "  {:<40} {:>7} rows {:>6} rejects{extra}",
            if exp.is_empty() {
                "(no experiment)"
            } else {
                exp
            },
            c.rows,
            c.rejects
        );
    }
    for (exp, t, c) in s.unbalanced() {
        eprintln!(
            "  not accounted for: {exp}: {} {t} record(s) read, {} rows + {} rejects",
            c.read.unwrap_or(0),
            c.rows,
            c.rejects
        );
    }
    // What a reader of an experiment's numbers must know, one line each.
    for l in s.said_lines(SAID_LINES) {
        println!("{l}");
    }
    if let Some(n) = s.notes.iter().find(|n| !n.said) {
        println!(
            "  {} note(s) on what readers had to assume or could not decode (in the manifest), e.g.: {}",
            s.notes.len(),
            n.message
        );
    }
    if !report.skipped.is_empty() {
        println!("  {} file(s) in the input folders are not recordings and were passed over (listed in the manifest)", report.skipped.len());
    }
    for r in &s.first_rejects {
        eprintln!("  reject: {r}");
    }
    if s.rejects as usize > s.first_rejects.len() {
        eprintln!(
            "  … {} more in {}",
            s.rejects as usize - s.first_rejects.len(),
            report.rejects_path.display()
        );
    }
    println!(
        "  wrote {}, {}, {}, {}, {}, {}",
        report.table_path.display(),
        report.hits_path.display(),
        report.rejects_path.display(),
        report.parametric_path.display(),
        report.markers_path.display(),
        report.manifest_path.display()
    );
}

/// A shard of `aepipe run --shard K/N`: its features, and what to do next.
pub fn shard_run(report: &RunReport) {
    stream_run(report, "features (this shard)");
    println!(
        "  when every shard is done: aepipe merge {}",
        report
            .manifest_path
            .parent()
            .and_then(Path::parent)
            .unwrap_or(Path::new("."))
            .display()
    );
}

pub fn demo(d: &crate::demo::DemoResult, out: &Path) {
    println!(
        "aepipe demo: synthetic notched-paper experiment built from simulated reference signals"
    );
    println!("{}\n", d.synth);
    for s in &d.inspect {
        println!("{s}");
    }
    stream_run(&d.run.features, "features");
    println!();
    for l in crate::workflow::headline(&d.run) {
        println!("{l}");
    }
    if d.run.config.report.enabled {
        println!("report: {}", out.join("run/report.html").display());
    }
    if let Some(c) = &d.cross {
        cross_model(c, &d.run, out);
    }
    println!("\ndemo finished in {:.1} s", d.seconds);
}

/// The demo's classes on another model, beside the held-out figure of the same model.
fn cross_model(c: &crate::demo::CrossModel, run: &crate::workflow::RunSummary, out: &Path) {
    let balanced = |t: Option<&crate::report::TruthScore>| {
        t.and_then(|t| t.balanced_accuracy())
            .map_or("n/a (a mechanism is missing)".to_string(), |b| {
                format!("{:.1} %", 100.0 * b)
            })
    };
    let l = &c.library;
    println!(
        "\nanother model: a 3-D layered-network library ({} simulations, {} signals, \
         {:.1} s{}, one material draw; {})",
        l.runs,
        l.signals,
        l.seconds,
        if l.reused {
            " when simulated, reused from the cache"
        } else {
            ""
        },
        out.join("cross").display()
    );
    println!(
        "  held out, same model (plane map, plane test): balanced accuracy {}",
        balanced(run.truth.as_ref())
    );
    for (what, t) in [
        ("plane map on a 3-D test", &c.plane_map_on_3d),
        ("3-D map on the plane test", &c.map_3d_on_plane),
    ] {
        let (novel, all) = t.unlike(&[Mechanism::BondFailure, Mechanism::FibreFailure]);
        println!(
            "  {what}: balanced accuracy {}; recall {}; mechanisms unlike the references {novel}/{all}",
            balanced(Some(t)),
            t.recall_line()
        );
    }
    println!("  cross-model checks {:.1} s", c.seconds);
}

pub fn som_trained(m: &Model) {
    println!(
        "trained a {}×{} map on {}-D inputs",
        m.som.rows, m.som.cols, m.som.dim
    );
    println!(
        "training set ({} rows):",
        m.composition.values().map(|c| c.1).sum::<usize>()
    );
    for (c, (distinct, rows)) in &m.composition {
        println!(
            "  {c:<16} {distinct:>4} hits, {rows:>4} rows{}",
            if rows > distinct {
                format!(" (repeated ×{:.1})", *rows as f64 / *distinct as f64)
            } else {
                String::new()
            }
        );
    }
    if let Some(l) = &m.som.log {
        println!(
            "quantisation error: {}",
            l.qe.iter()
                .map(|q| format!("{q:.5}"))
                .collect::<Vec<_>>()
                .join(" → ")
        );
        println!("topographic error: {:.4}", l.topographic_error);
    }
}

/// The map's node labels, one grid row per line.
pub fn som_map(m: &Model) {
    println!(
        "{}×{} map, {}-D inputs ({}), labels from {}",
        m.som.rows,
        m.som.cols,
        m.som.dim,
        m.columns.join(", "),
        m.label_column
    );
    for r in 0..m.som.rows {
        let row: Vec<String> = (0..m.som.cols)
            .map(|c| {
                format!(
                    "{:>14}",
                    m.som
                        .labels
                        .get(r * m.som.cols + c)
                        .map(String::as_str)
                        .unwrap_or("-")
                )
            })
            .collect();
        println!("{}", row.join(""));
    }
}

pub fn sim_scale(rows: &[SimScale], steps: usize) {
    println!("implicit Euler on random fibre networks (Δt 10 ns, {steps} steps, 1 thread):");
    println!(
        "{:>8} {:>8} {:>10} {:>14} {:>13} {:>22}",
        "masses", "springs", "ms/step", "µs/step/1k sp", "BiCGSTAB it", "ns/spring/iteration"
    );
    for r in rows {
        println!(
            "{:>8} {:>8} {:>10.3} {:>14.2} {:>13.1} {:>22.2}",
            r.masses,
            r.springs,
            r.seconds_per_step * 1e3,
            r.seconds_per_step * 1e6 / (r.springs as f64 / 1e3),
            r.solver_iterations_per_step,
            r.seconds_per_step * 1e9 / (r.springs as f64 * r.solver_iterations_per_step.max(1.0))
        );
    }
}

pub fn cwt_bench(ours: &CwtBench) {
    println!(
        "{:<72} {:>7} {:>9} {:>15} {:>11}",
        "aepipe (651 signals × 4096 samples)", "threads", "median s", "min–max s", "ms/signal"
    );
    for r in &ours.rows {
        println!(
            "{:<72} {:>7} {:>9.3} {:>15} {:>11.3}",
            r.what,
            r.threads,
            r.seconds,
            format!("{:.3}–{:.3}", r.spread.0, r.spread.1),
            r.per_signal_ms
        );
    }
    if let Some(e) = ours.fast_error {
        println!(
            "fast W1 path against the exact one, first {} signals: largest |Δ|W|²| = {:.1e} of its row's peak, {:.1e} of the scalogram's",
            e.signals, e.of_row_peak, e.of_scalogram_peak
        );
    }
}

/// Run the CWT peers in the same run and print their times against ours.
pub fn cwt_peers(ours: &CwtBench, python: &Path, peers: &Path) {
    let find = |prefix: &str, t: usize| {
        ours.rows
            .iter()
            .find(|r| r.what.starts_with(prefix) && r.threads == t)
            .map(|r| r.seconds)
    };
    println!(
        "\n{:<40} {:>9} {:>15} {:>30} {:>12}",
        "peer (same inputs, same run)",
        "median s",
        "min–max s",
        "peer / aepipe (same threads)",
        "vs exact"
    );
    let ratio = |secs: f64, ours: Option<f64>| {
        ours.map(|o| format!("{:.2}x", secs / o))
            .unwrap_or_else(|| "–".into())
    };
    for p in crate::bench::CWT_PEERS {
        match crate::bench::run_peer(python, peers, p.script, p.args) {
            Ok(r) => {
                let secs = r.median;
                let exact =
                    (p.workload == "W1").then(|| find(crate::bench::W1_EXACT_ROW, p.threads));
                println!(
                    "{:<40} {secs:>9.3} {:>15} {:>30} {:>12}",
                    p.name,
                    format!("{:.3}–{:.3}", r.min, r.max),
                    ratio(secs, find(p.workload, p.threads)),
                    exact.map_or("–".into(), |e| ratio(secs, e)),
                );
            }
            Err(e) => println!("{:<40} failed: {e}", p.name),
        }
    }
}

/// `aepipe bench analysis`: a row per stage.
pub fn analysis_bench(b: &crate::bench::analysis::AnalysisBench) {
    println!(
        "{} feature rows in {} experiments ({})",
        b.rows,
        b.experiments,
        b.out.display()
    );
    println!("{:<18} {:>10} {:>14}", "stage", "seconds", "peak RSS MB");
    for (name, s, rss) in &b.stages {
        let rss = rss.map_or("–".to_string(), |r| format!("{:.0}", r as f64 / 1e6));
        println!("{name:<18} {s:>10.2} {rss:>14}");
    }
    let total: f64 = b.stages.iter().map(|s| s.1).sum();
    println!(
        "total {total:.1} s; disk {:.2} GB (features.parquet {:.2} GB)",
        b.disk_bytes as f64 / 1e9,
        b.features_bytes as f64 / 1e9
    );
    if let Some(peak) = b.stages.iter().filter_map(|s| s.2).max() {
        println!("peak RSS of the stages: {:.0} MB", peak as f64 / 1e6);
    }
}

/// `aepipe bench watch`.
pub fn watch_bench(r: &crate::live::bench::WatchBenchResult) {
    println!(
        "steady phase: {} hits written at {:.0} hits/s; lag file written → row committed: \
         median {:.2} s, p99 {:.2} s, max {:.2} s",
        r.steady.hits, r.steady_rate, r.steady.median_s, r.steady.p99_s, r.steady.max_s
    );
    println!(
        "burst: {} hits arrived in {:.2} s; lag median {:.2} s, p99 {:.2} s, max {:.2} s; \
         last row committed {:.2} s after the last write",
        r.burst.hits,
        r.burst_write_s,
        r.burst.median_s,
        r.burst.p99_s,
        r.burst.max_s,
        r.burst_drain_s
    );
    println!("{} hits committed in {} flushes", r.committed, r.flushes);
}

/// `aepipe cluster`'s table: each k's indices, the chosen one starred, then the clusters.
/// `aepipe bench report`'s table.
pub fn report_bench(rows: &[crate::bench::report::ReportRow], whole: bool) -> String {
    let mut s = String::from(if whole {
        "whole report (`aepipe report` on a synthetic run of that many feature rows; build s = the whole process)\n"
    } else {
        "explorable charts alone (the rest of a report is bounded by classes, not rows)\n"
    });
    s += "     rows   points   page MB  build s  first paint ms  load s  errors\n";
    let opt = |v: Option<f64>, p: usize| v.map_or("–".to_string(), |v| format!("{v:.p$}"));
    for r in rows {
        s += &format!(
            "{:>9} {:>8} {:>9.2} {:>8.2} {:>15} {:>7} {:>7}\n",
            r.rows,
            r.points,
            r.bytes as f64 / 1e6,
            r.build_s,
            opt(r.first_paint_ms, 0),
            opt(r.load_s, 2),
            r.errors.map_or("–".to_string(), |e| e.to_string())
        );
    }
    s
}

/// The head of `aepipe thesis`'s table.
pub fn thesis_header() -> String {
    format!(
        "{:<10} {:<28} {:>12} {:>12} {:>9} {:>6}  {:<7} compared",
        "entry", "thesis", "thesis val", "aepipe", "dev", "tol", "verdict"
    )
}

/// One entry's line.
pub fn thesis_line(o: &crate::thesis::Outcome) -> String {
    let e = &o.entry;
    format!(
        "{:<10} {:<28} {:>12.5} {:>12.5} {:>+8.1}% {:>5.1}%  {:<7} {}",
        e.id,
        e.section,
        e.thesis,
        o.aepipe,
        o.deviation * 100.0,
        e.tolerance.rel * 100.0,
        o.verdict.as_str(),
        e.compared
    ) + &format!("\n{:<10} tolerance: {}", "", e.tolerance.source)
        + &e.departs
            .map(|d| {
                format!(
                    "\n{:<10} departure expected at {:.5} ± {:.1} %: {}; tolerance: {}",
                    "",
                    d.expected,
                    d.tolerance.rel * 100.0,
                    d.evidence,
                    d.tolerance.source
                )
            })
            .unwrap_or_default()
        + &e.caveat
            .map(|c| format!("\n{:<10} but: {c}", ""))
            .unwrap_or_default()
}

/// Tables 3.2/3.4 as measured.
pub fn solver_table(rows: &[crate::bench::SolverRow]) {
    println!("Tables 3.2/3.4 (no acoustics; median wall time of the whole run):");
    println!(
        "{:<16} {:<14} {:>7} {:>10} {:>10} {:>16}",
        "scenario", "solver", "Δt s", "steps", "time ms", "µs per step"
    );
    for r in rows {
        println!(
            "{:<16} {:<14} {:>7} {:>10} {:>10.3} {:>16.3}",
            r.scenario,
            format!("{:?}", r.solver),
            r.dt,
            r.iterations,
            r.seconds * 1e3,
            r.seconds * 1e6 / r.iterations as f64
        );
    }
}

/// The 3-D field bench's table.
pub fn field3d(rows: &[crate::bench::Field3dRow]) {
    println!(
        "3-D acoustic field, 4th order, {} thread(s):\n   cells     steps   seconds  Mcell-steps/s  fields MB       RSS MB",
        rayon::current_num_threads()
    );
    for r in rows {
        let cells = (r.n * r.n * r.n) as f64;
        println!(
            "{:>5}³ {:>9} {:>9.2} {:>14.1} {:>10.0} {:>12.0}",
            r.n,
            r.steps,
            r.seconds,
            cells * r.steps as f64 / r.seconds / 1e6,
            r.field_bytes as f64 / 1048576.0,
            r.rss as f64 / 1048576.0
        );
    }
}

/// The 3-D scenarios' bench table.
pub fn network3d(rows: &[crate::bench::Network3dRow]) {
    println!(
        "scenarios end to end (relaxation, 4 000 implicit steps, the field's steps), {} thread(s):\n{:<28} {:>8} {:>11} {:>7} {:>9} {:>12}",
        rayon::current_num_threads(),
        "scenario", "grid µm", "cells", "steps", "seconds", "peak RSS MB"
    );
    for r in rows {
        println!(
            "{:<28} {:>8} {:>11} {:>7} {:>9.2} {:>12.0}",
            r.scenario,
            r.grid_um,
            r.cells,
            r.acoustic_steps,
            r.seconds,
            r.peak_rss as f64 / 1048576.0
        );
    }
}

/// What an export wrote (one line a file) and what it left out.
pub fn export_summary(s: &crate::export::ExportSummary) -> String {
    let mut out = String::new();
    for f in &s.files {
        out += &format!(
            "export {}: {} rows → {}\n",
            f.experiment,
            f.rows,
            f.path.display()
        );
    }
    for n in &s.notes {
        out += &format!("export note: {n}\n");
    }
    out
}

pub fn cluster_report(r: &crate::cluster::ClusterReport) -> String {
    let opt = |v: Option<f64>| v.map_or("–".to_string(), |v| format!("{v:.4}"));
    let mut s = format!(
        "{} rows clustered on {} columns ({} left out: a null or non-finite feature); fit on {} rows\n",
        r.rows,
        r.columns.len(),
        r.skipped,
        r.fit_rows
    );
    s += &format!(
        "{:<11} {:>3} {:>14} {:>11} {:>18} {:>14} {:>14}\n",
        "method", "k", "Davies-Bouldin", "silhouette", "Calinski-Harabasz", "BIC", "inertia"
    );
    for v in &r.validity {
        s += &format!(
            "{:<11} {:>3} {:>14} {:>11} {:>18} {:>14} {:>14.4}{}\n",
            v.method.as_str(),
            v.k,
            opt(v.davies_bouldin),
            opt(v.silhouette),
            opt(v.calinski_harabasz),
            v.bic.map_or("–".into(), |b| format!("{b:.1}")),
            v.inertia,
            if v.chosen { "  *" } else { "" }
        );
    }
    let sizes: Vec<String> = r
        .sizes
        .iter()
        .enumerate()
        .map(|(c, n)| format!("{c}: {n}"))
        .collect();
    s += &format!("k = {}: hits per cluster {}\n", r.k, sizes.join(", "));
    s
}

/// `aepipe bench detect`: the stage alone.
pub fn detect_stage(r: &crate::bench::detect::StageResult, seconds: f64) {
    let ms = r.ms_per_core();
    println!(
        "detect int16: {ms:.0} MS/s per core, {:.0}× real time at 10 MHz ({} thread(s), one 10 MHz channel of {seconds} s each in memory, {} hits cut)",
        ms / (crate::bench::detect::RATE_HZ / 1e6),
        r.threads,
        r.hits
    );
}

/// `aepipe bench detect --python`: NumPy's cut of the same stream beside aepipe's.
pub fn detect_peer(
    one: &crate::bench::detect::StageResult,
    peer: Result<(f64, usize), crate::bench::BenchError>,
) {
    match peer {
        Ok((s, hits)) => {
            let peer = one.samples as f64 / s / 1e6;
            println!(
                "numpy (crossings vectorised, the rules per crossing), the same stream: {peer:.0} MS/s, {hits} hits; aepipe one thread {:.0} MS/s, {} hits: {:.1}×",
                one.ms_per_core(),
                one.hits,
                one.ms_per_core() / peer
            );
        }
        Err(e) => println!("numpy peer: not run ({e})"),
    }
}

/// `aepipe bench detect`: the whole runs on stream files.
pub fn detect_runs(runs: &[crate::bench::detect::RunResult], threads: usize) {
    println!(
        "aepipe features on a detected stream (one channel, WAV int16 at 10 MHz, {threads} thread(s), a whole process each):"
    );
    println!(
        "{:>9} {:>8} {:>7} {:>9} {:>14} {:>12}",
        "stream s", "wall s", "hits", "hits/s", "× real time", "peak RSS MB"
    );
    for x in runs {
        println!(
            "{:>9} {:>8.2} {:>7} {:>9.0} {:>14.1} {:>12.0}",
            x.stream_s,
            x.wall_s,
            x.hits,
            x.hits as f64 / x.wall_s,
            x.stream_s / x.wall_s,
            x.peak_rss as f64 / 1048576.0
        );
    }
}
