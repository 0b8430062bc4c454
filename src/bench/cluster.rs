//! `aepipe bench cluster`: `aepipe cluster` against scikit-learn's `KMeans` and
//! `GaussianMixture` on the same matrix, each a whole process (read, fit, write), timed
//! and its peak RSS read from `wait4`, in the same run.

use super::BenchError;
use crate::model::columns as cols;
use crate::store::{ColType, ColumnSpec, Table, TableWriter, Value};
use std::path::{Path, PathBuf};

/// Columns of the bench matrix.
pub const DIM: usize = 20;

/// One bench row: the matrix written as a features-like table.
struct Row {
    hit: i64,
    x: [f64; DIM],
}

/// Write `n` rows of a mixture of `k` overlapping Gaussian blobs in `DIM` columns
/// (`f0`…), keyed like hits.
pub fn write_matrix(path: &Path, n: usize, k: usize, seed: u64) -> Result<(), BenchError> {
    let mut t = Table::new("bench_matrix")
        .col(ColumnSpec::of(cols::EXPERIMENT, "", ""), |_: &Row| {
            Value::Str(Some("bench".into()))
        })
        .col(ColumnSpec::of(cols::CHANNEL, "", ""), |_| {
            Value::I32(Some(1))
        })
        .col(ColumnSpec::of(cols::HIT, "", ""), |r| {
            Value::I64(Some(r.hit))
        });
    for j in 0..DIM {
        t = t.col(
            ColumnSpec::new(format!("f{j}"), ColType::Float64, "", ""),
            move |r: &Row| Value::F64(Some(r.x[j])),
        );
    }
    let mut rng = crate::util::Rng::new(seed);
    let centres: Vec<[f64; DIM]> = (0..k)
        .map(|_| std::array::from_fn(|_| 3.0 * rng.normal()))
        .collect();
    let mut w = TableWriter::create(path, t.schema(), &[], 65_536).map_err(BenchError::run)?;
    for i in 0..n {
        let c = &centres[i % k];
        let x = std::array::from_fn(|j| c[j] + rng.normal());
        w.push(t.row(Row {
            hit: i as i64 + 1,
            x,
        }))
        .map_err(BenchError::run)?;
    }
    w.finish().map_err(BenchError::run)?;
    Ok(())
}

/// Wall seconds and peak RSS (bytes) of a child process run to its end.
pub fn run_measured(cmd: &mut std::process::Command) -> Result<(f64, u64), BenchError> {
    let t0 = std::time::Instant::now();
    let child = cmd
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .map_err(|e| BenchError::Run(format!("{cmd:?}: {e}")))?;
    let pid = child.id() as libc::pid_t;
    let mut status = 0;
    // SAFETY: an all-zero rusage is a valid value for wait4 to fill.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: pid is our child, not yet waited for; status and usage are valid pointers.
    let r = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    let secs = t0.elapsed().as_secs_f64();
    if r != pid || !libc::WIFEXITED(status) || libc::WEXITSTATUS(status) != 0 {
        let mut err = String::new();
        if let Some(mut e) = child.stderr {
            use std::io::Read;
            let _ = e.read_to_string(&mut err);
        }
        return Err(BenchError::Run(format!("{cmd:?} failed: {}", err.trim())));
    }
    Ok((secs, usage.ru_maxrss as u64 * 1024))
}

/// One line of the bench: a tool's method at N rows.
#[derive(Debug, Clone)]
pub struct ClusterBenchRow {
    pub rows: usize,
    pub method: &'static str,
    pub aepipe: (f64, u64),
    pub peer: Option<Result<(f64, u64), String>>,
}

/// For each N: the matrix, then `aepipe cluster` (k-means and mixture, fit on all rows,
/// one k) and, with a Python, the scikit-learn script on the same file.
pub fn bench_cluster(
    rows: &[usize],
    k: usize,
    python: Option<&Path>,
    script: &Path,
    dir: &Path,
) -> Result<Vec<ClusterBenchRow>, BenchError> {
    std::fs::create_dir_all(dir).map_err(BenchError::run)?;
    let exe = std::env::current_exe().map_err(BenchError::run)?;
    let columns: Vec<String> = (0..DIM).map(|j| format!("f{j}")).collect();
    let mut out = Vec::new();
    for &n in rows {
        let m = dir.join(format!("matrix-{n}.parquet"));
        write_matrix(&m, n, k, 7)?;
        for method in ["kmeans", "gmm"] {
            let o: PathBuf = dir.join(format!("out-{method}-{n}"));
            let mine = run_measured(
                std::process::Command::new(&exe)
                    .arg("cluster")
                    .arg(&m)
                    .arg("--out")
                    .arg(&o)
                    .args(["--method", method, "--k", &k.to_string()])
                    .args(["--columns", &columns.join(",")])
                    .args(["--max-fit-rows", &n.max(10).to_string()]),
            )?;
            let peer = python.map(|py| {
                run_measured(
                    std::process::Command::new(py)
                        .arg(script)
                        .arg(&m)
                        .args([method, &k.to_string()]),
                )
                .map_err(|e| e.to_string())
            });
            out.push(ClusterBenchRow {
                rows: n,
                method,
                aepipe: mine,
                peer,
            });
        }
    }
    Ok(out)
}
