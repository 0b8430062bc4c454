//! Long calls: the work runs on a worker thread without the interpreter, and the calling
//! thread wakes every 100 ms to look for Ctrl-C and to draw the progress line. Ctrl-C asks
//! the job to stop (`JobControl::cancel`: the core checks it per record, simulation run or
//! stage), waits at most 0.8 s for it to let go of its files (so the call returns within
//! 0.9 s of the signal whatever the job is doing), and raises
//! `KeyboardInterrupt`. Any exception that ends the wait — a Ctrl-C the interpreter raises
//! inside the progress line's `sys.stderr.write` (Python code, as in a notebook), or a
//! stream that cannot be written — stops the job the same way: a call never returns while
//! its job runs on unasked. A job's temporary folder belongs to the job ([`run_in`]), so it
//! goes when the job has stopped writing into it, not when the call returns.

use crate::errors;
use aepipe::util::JobControl;
use pyo3::prelude::*;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// How often the caller looks for Ctrl-C and redraws the progress line.
const TICK: Duration = Duration::from_millis(100);
/// How long a cancelled job may take to stop before the call returns anyway.
const GRACE: Duration = Duration::from_millis(800);

/// A progress line on Python's `sys.stderr` (so that it shows in a notebook too):
/// "N unit, R/s, T s", redrawn in place.
pub struct ProgressLine {
    unit: &'static str,
    t0: Instant,
    drawn: bool,
}

impl ProgressLine {
    pub fn new(unit: &'static str) -> ProgressLine {
        ProgressLine {
            unit,
            t0: Instant::now(),
            drawn: false,
        }
    }

    pub fn draw(&mut self, py: Python<'_>, done: u64) -> PyResult<()> {
        let secs = self.t0.elapsed().as_secs_f64();
        let rate = if secs > 0.0 { done as f64 / secs } else { 0.0 };
        let line = format!(
            "\raepipe: {done} {}  {rate:.0}/s  {secs:.1} s   ",
            self.unit
        );
        let err = py.import("sys")?.getattr("stderr")?;
        err.call_method1("write", (line,))?;
        err.call_method0("flush")?;
        self.drawn = true;
        Ok(())
    }

    pub fn end(&mut self, py: Python<'_>, done: u64) -> PyResult<()> {
        if self.drawn {
            self.draw(py, done)?;
            let err = py.import("sys")?.getattr("stderr")?;
            err.call_method1("write", ("\n",))?;
        }
        Ok(())
    }
}

/// Run `job` on a worker thread with the interpreter released; see the module doc.
/// `progress` names the unit the job counts (records, simulation runs) to draw a line.
pub fn run<T: Send + 'static>(
    py: Python<'_>,
    progress: Option<&'static str>,
    job: impl FnOnce(Arc<JobControl>) -> T + Send + 'static,
) -> PyResult<T> {
    let control = Arc::new(JobControl::default());
    let (tx, rx) = crossbeam_channel::bounded(1);
    let c = control.clone();
    std::thread::Builder::new()
        .name("aepipe-py-job".into())
        .spawn(move || {
            let _ = tx.send(job(c));
        })
        .map_err(|e| errors::AepipeError::new_err(format!("cannot start a thread: {e}")))?;
    let mut line = progress.map(ProgressLine::new);
    loop {
        match py.detach(|| rx.recv_timeout(TICK)) {
            Ok(v) => {
                if let Some(l) = &mut line {
                    l.end(py, control.done())?;
                }
                return Ok(v);
            }
            Err(crossbeam_channel::RecvTimeoutError::Timeout) => {
                let looked = py.check_signals().and_then(|()| match &mut line {
                    Some(l) => l.draw(py, control.done()),
                    None => Ok(()),
                });
                if let Err(e) = looked {
                    control.cancel();
                    let _ = py.detach(|| rx.recv_timeout(GRACE));
                    return Err(e);
                }
            }
            Err(crossbeam_channel::RecvTimeoutError::Disconnected) => {
                return Err(errors::AepipeError::new_err(
                    "aepipe: the worker thread panicked (please report)",
                ))
            }
        }
    }
}

/// [`run`] with a temporary folder that the job owns: `job` gets its path, and the folder is
/// removed on the worker thread once the job has returned (whether or not the call is still
/// waiting for it), never while the job may still write into it.
pub fn run_in<T: Send + 'static>(
    py: Python<'_>,
    progress: Option<&'static str>,
    job: impl FnOnce(Arc<JobControl>, &std::path::Path) -> T + Send + 'static,
) -> PyResult<T> {
    let dir = TempDir::new()?;
    run(py, progress, move |c| {
        let out = job(c, dir.path());
        drop(dir);
        out
    })
}

/// A fresh, empty temporary folder, removed when dropped.
pub struct TempDir(pub std::path::PathBuf);

impl TempDir {
    pub fn new() -> PyResult<TempDir> {
        static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let p = std::env::temp_dir().join(format!("aepipe-py-{}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p)
            .map_err(|e| errors::AepipeError::new_err(format!("{}: {e}", p.display())))?;
        Ok(TempDir(p))
    }

    pub fn path(&self) -> &std::path::Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
