//! The hybrid vibro-acoustic simulator of ch. 3–4: a mass/spring model of the fibres
//! ([`mech`]) coupled to a 2-D acoustic pressure FDTD ([`acoustic`]) through the volumetric
//! acceleration of the masses (Eq. 3.4.6), with bond and fibre failures while it runs.
//! Inputs: the thesis's sectioned file ([`input`]), TOML, or a built-in scenario
//! ([`scenario`]). Output: labelled rows of the canonical waveform table ([`output`]).

pub mod acoustic;
pub mod acoustic3d;
pub mod chain;
pub mod convergence;
pub mod decay;
pub mod geometry;
pub mod hybrid;
pub mod input;
pub mod material;
pub mod mech;
pub mod model;
pub mod network3d;
pub mod order;
pub mod output;
pub mod paper;
pub mod params;
pub mod parts;
pub mod reference;
pub mod scenario;
pub mod sources;
pub mod string;
pub mod sweep;
pub mod velocity;

pub use hybrid::simulate;
use mech::Relaxed;
use model::ModelFile;

#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error("model: {0}")]
    Model(String),
    #[error("{path}:{line}: {message}")]
    Parse {
        path: String,
        line: usize,
        message: String,
    },
    #[error("solver: {0}")]
    Solver(String),
    /// A model or library definition could not be read.
    #[error("{0}")]
    Read(String),
    /// An output could not be written.
    #[error("{0}")]
    Io(String),
    /// The shards of a library do not make one (missing, disagreeing, changed files).
    #[error(transparent)]
    Shards(#[from] crate::store::shard::ShardSetError),
    /// The caller asked the job to stop ([`crate::util::JobControl`]).
    #[error("interrupted")]
    Cancelled,
    /// A measurement chain could not be used (unknown, or not valid at the sample rate).
    #[error(transparent)]
    Chain(#[from] chain::ChainError),
}

impl crate::util::HasKind for SimError {
    fn kind(&self) -> crate::util::ErrorKind {
        match self {
            SimError::Model(_) | SimError::Parse { .. } | SimError::Read(_) => {
                crate::util::ErrorKind::Usage
            }
            SimError::Solver(_) | SimError::Io(_) | SimError::Cancelled => {
                crate::util::ErrorKind::Failed
            }
            SimError::Shards(e) => e.kind(),
            SimError::Chain(_) => crate::util::ErrorKind::Usage,
        }
    }
}

/// What to keep besides the sensor signals.
#[derive(Debug, Clone, Default)]
pub struct SimOptions {
    /// Node positions every this many mass/spring steps.
    pub trajectory_every: Option<usize>,
    /// Pressure field every this many acoustic steps.
    pub snapshot_every: Option<usize>,
}

/// Node positions at one time (z 0 in a plane model).
#[derive(Debug, Clone)]
pub struct Frame {
    pub t: f64,
    pub r: Vec<[f64; 3]>,
    pub u: Vec<[f64; 3]>,
    /// Each spring's tension, N (empty for a continuum model).
    pub tension: Vec<f64>,
    /// Kinetic and elastic energy, J (none for a continuum model).
    pub energy: Option<[f64; 2]>,
}

#[derive(Debug, Clone)]
pub struct SimOutput {
    /// Pressure at each sensor, one value per acoustic step, Pa.
    pub sensors: Vec<Vec<f64>>,
    /// 1 / grid.dt (0 without a grid).
    pub sample_rate_hz: f64,
    pub relaxed: Relaxed,
    pub trajectory: Vec<Frame>,
    pub snapshots: Vec<(f64, Vec<f64>)>,
    pub solver_iterations: usize,
    pub mass_steps: usize,
    /// 2 (the thesis's plane) or 3 (§6.2).
    pub dims: usize,
}

/// Dominant frequency of a signal: the largest bin of its zero-padded power spectrum
/// (at least 16 384 points), refined by a parabola through the three bins around it.
pub fn dominant_frequency(x: &[f64], fs: f64) -> f64 {
    if x.len() < 4 || fs <= 0.0 {
        return 0.0;
    }
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    let n = x.len().next_power_of_two().max(16_384);
    let centred: Vec<f64> = x.iter().map(|v| v - mean).collect();
    let buf = crate::dsp::filter::spectrum(&centred, n);
    let p: Vec<f64> = buf[..n / 2].iter().map(|c| c.norm_sqr()).collect();
    let k = (1..p.len())
        .max_by(|&a, &b| p[a].total_cmp(&p[b]))
        .unwrap_or(1);
    let delta = if k + 1 < p.len() {
        let (a, b, c) = (p[k - 1].sqrt(), p[k].sqrt(), p[k + 1].sqrt());
        let den = a - 2.0 * b + c;
        if den != 0.0 {
            0.5 * (a - c) / den
        } else {
            0.0
        }
    } else {
        0.0
    };
    (k as f64 + delta) * fs / n as f64
}

/// What `aepipe simulate` runs.
#[derive(Debug, Clone)]
pub struct SimJob {
    /// A model file, or a scenario name.
    pub model: Option<std::path::PathBuf>,
    pub scenario: Option<String>,
    pub params: scenario::Params,
    /// Run the scenario once per combination of the sweeps' values (none: once).
    pub sweep: Vec<scenario::Sweep>,
    pub solver: Option<model::Solver>,
    pub out: std::path::PathBuf,
    pub run: SimOptions,
    /// How the sensors record (sensitivity, threshold, noise, pretrigger).
    pub acquisition: output::Acquisition,
}

/// What a job wrote: the lines to print, and a sweep's table (drawn by the caller: the
/// simulator sits below the plots).
#[derive(Debug, Clone, Default)]
pub struct SimReport {
    pub lines: Vec<String>,
    pub sweep: Option<sweep::SweepTable>,
}

/// Run a job into `job.out`: `waveforms.parquet` (the sensors, when the model has a grid),
/// `trajectories.parquet` and `snapshots/*.png` when asked, `sweep.parquet` for a sweep.
pub fn run_job(job: &SimJob) -> Result<SimReport, SimError> {
    scenario::check_sweeps(&job.sweep)?;
    if job.scenario.as_deref() == Some(string::NAME) && job.model.is_none() {
        return string::run_job(job);
    }
    let io = |e: std::io::Error| SimError::Io(format!("{}: {e}", job.out.display()));
    std::fs::create_dir_all(&job.out).map_err(io)?;
    let models = job_models(job)?;
    let mut lines = Vec::new();
    let mut outs = Vec::new();
    let mut table = sweep::SweepTable::of(&job.sweep);
    let grid = scenario::sweep_grid(&job.sweep);
    for (hit, (m, _, json)) in models.iter().enumerate() {
        let t0 = std::time::Instant::now();
        let out = simulate(m, &job.run)?;
        let secs = t0.elapsed().as_secs_f64();
        lines.push(format!(
            "{} {json}: {} masses, {} springs, {} steps of {:e} s ({:?}) in {secs:.2} s; relaxation {} steps{}",
            m.name,
            m.nodes.len(),
            m.springs.len(),
            m.system.iterations,
            m.system.dt,
            m.system.solver,
            out.relaxed.steps,
            if out.relaxed.converged { String::new() } else { format!(" (NOT converged, residual {:.1e})", out.relaxed.residual) },
        ));
        let heard = heard(m, &out);
        sensor_lines(m, &heard, &mut lines);
        write_run_files(job, hit, models.len() > 1, m, &out, &mut lines)?;
        if !job.sweep.is_empty() {
            let values = grid[hit].iter().map(|(_, v)| *v).collect();
            table.push_run(
                hit as u64 + 1,
                values,
                json,
                &heard,
                (Some(m.system.damping), secs),
            );
        }
        outs.push(out);
    }
    let runs: Vec<output::Run> = models
        .iter()
        .zip(&outs)
        .enumerate()
        .map(|(k, ((m, source, json), out))| output::Run {
            model: m,
            out,
            source: source.clone(),
            params: json.clone(),
            hit: k as u64 + 1,
            acq: &job.acquisition,
            faults: Vec::new(),
        })
        .collect();
    write_sensor_signals(job, &runs, &mut lines)?;
    finish(job, table, lines)
}

/// The job's report: a sweep's table written (when there is a sweep) beside the lines.
fn finish(
    job: &SimJob,
    table: sweep::SweepTable,
    mut lines: Vec<String>,
) -> Result<SimReport, SimError> {
    let sweep = if job.sweep.is_empty() {
        None
    } else {
        table.write_into(&job.out, &mut lines)?;
        Some(table)
    };
    Ok(SimReport { lines, sweep })
}

/// The job's models, one per sweep value, with source and parameters: all built before a run.
fn job_models(job: &SimJob) -> Result<Vec<(ModelFile, String, String)>, SimError> {
    let runs = scenario::sweep_grid(&job.sweep);
    let mut models = Vec::new();
    for v in &runs {
        let mut params = job.params.clone();
        params.0.extend(v.iter().cloned());
        let (mut m, source) = match (&job.model, &job.scenario) {
            (Some(path), None) => (input::read_model(path)?, path.display().to_string()),
            (None, Some(name)) => (scenario::build(name, &params)?, format!("scenario:{name}")),
            _ => {
                return Err(SimError::Model(
                    "give a model file or --scenario NAME (not both)".into(),
                ))
            }
        };
        if let Some(s) = job.solver {
            m.system.solver = s;
        }
        models.push((m, source, params.to_json()));
    }
    Ok(models)
}

/// What a run shows at one place: a sensor's band-limited pressure, or (with no sensors)
/// the free node that moves most, measured once for the terminal and a sweep's table.
#[derive(Debug, Clone)]
pub struct Heard {
    /// Sensor number (1-based); 0: the node.
    pub sensor: u32,
    /// The node (`sensor` 0).
    pub node: usize,
    /// Largest |p| (Pa), or |y − mean| (m) of the node.
    pub peak: f64,
    pub dominant_hz: f64,
    pub decay: Option<decay::Decay>,
}

/// Each sensor's band-limited pressure measured (peak, dominant frequency, decay); with no
/// sensors, the node that moves most (needs trajectories).
pub fn heard(m: &ModelFile, out: &SimOutput) -> Vec<Heard> {
    let fs = out.sample_rate_hz;
    let mut v: Vec<Heard> = out
        .sensors
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let p = match &m.grid {
                Some(g) => output::band_limited(s, g),
                None => s.clone(),
            };
            let f = dominant_frequency(&p, fs);
            Heard {
                sensor: k as u32 + 1,
                node: 0,
                peak: p.iter().fold(0.0f64, |a, v| a.max(v.abs())),
                dominant_hz: f,
                decay: decay::fit(&p, 1.0 / fs, 1.0 / f),
            }
        })
        .collect();
    if v.is_empty() {
        if let Some((node, f, d)) = node_frequency(m, out) {
            let y: Vec<f64> = out.trajectory.iter().map(|fr| fr.r[node][1]).collect();
            let mean = y.iter().sum::<f64>() / y.len() as f64;
            v.push(Heard {
                sensor: 0,
                node,
                peak: y.iter().fold(0.0f64, |a, v| a.max((v - mean).abs())),
                dominant_hz: f,
                decay: d,
            });
        }
    }
    v
}

/// A run's lines on what it showed: each sensor's frequency, peak and decay, or a node's.
fn sensor_lines(m: &ModelFile, heard: &[Heard], lines: &mut Vec<String>) {
    for h in heard {
        let words = decay_words(h.decay.as_ref(), m.system.damping);
        lines.push(match h.sensor {
            0 => format!(
                "  no sensors; node {} oscillates at {:.4} Hz (zero crossings of y){words}",
                h.node, h.dominant_hz
            ),
            k => {
                let s = &m.sensors[k as usize - 1];
                let cell = match m.dims() {
                    3 => {
                        let (i, j, l) = m.sensor_cell3(s);
                        format!("({i}, {j}, {l})")
                    }
                    _ => format!("({}, {})", s.i, s.j),
                };
                format!(
                    "  sensor {k} at cell {cell}: dominant {:.1} kHz, peak {:.3e} Pa (band-limited to the grid){words}",
                    h.dominant_hz / 1e3,
                    h.peak
                )
            }
        });
    }
}

/// ", decay γ … (α = γ/b …)" for a terminal line; what is missing, said.
fn decay_words(d: Option<&decay::Decay>, b: f64) -> String {
    match d {
        None => ", decay: fewer than three periods above 10⁻³ of the peak (no fit)".into(),
        Some(d) => format!(
            ", decay γ {:.4e} 1/s (R² {:.3}){}",
            d.gamma_hz,
            d.r2,
            d.alpha_per_kg(b)
                .map_or(", no damping b (no α)".into(), |a| format!(
                    ", α = γ/b {a:.4e} 1/kg"
                ))
        ),
    }
}

/// Write run `hit`'s kept node frames, if any, to `trajectories.parquet` (numbered
/// `trajectories_N.parquet` when the job has `several` runs), with a line.
fn write_trajectories(
    job: &SimJob,
    hit: usize,
    several: bool,
    frames: &[Frame],
    dims: usize,
    lines: &mut Vec<String>,
) -> Result<(), SimError> {
    if frames.is_empty() {
        return Ok(());
    }
    let p = job.out.join(if several {
        format!("trajectories_{}.parquet", hit + 1)
    } else {
        "trajectories.parquet".into()
    });
    let n = output::write_trajectories(&p, frames, dims)?;
    lines.push(format!("  {n} trajectory rows → {}", p.display()));
    // Beside them, the springs' tension and the energies of the same frames (Appendix A's
    // Storage `Tension` and `Energy`; Fig. 3.4c).
    let numbered = |stem: &str| {
        job.out.join(if several {
            format!("{stem}_{}.parquet", hit + 1)
        } else {
            format!("{stem}.parquet")
        })
    };
    if frames.iter().any(|f| !f.tension.is_empty()) {
        let p = numbered("tension");
        let n = output::write_tension(&p, frames)?;
        lines.push(format!("  {n} spring tension rows → {}", p.display()));
    }
    if frames.iter().any(|f| f.energy.is_some()) {
        let p = numbered("energy");
        let n = output::write_energy(&p, frames)?;
        lines.push(format!("  {n} energy rows → {}", p.display()));
    }
    Ok(())
}

/// Write a run's trajectories and snapshots if kept (numbered when `several`), with lines.
fn write_run_files(
    job: &SimJob,
    hit: usize,
    several: bool,
    m: &ModelFile,
    out: &SimOutput,
    lines: &mut Vec<String>,
) -> Result<(), SimError> {
    let io = |e: std::io::Error| SimError::Io(format!("{}: {e}", job.out.display()));
    write_trajectories(job, hit, several, &out.trajectory, out.dims, lines)?;
    if !out.snapshots.is_empty() {
        let dir = job.out.join("snapshots");
        std::fs::create_dir_all(&dir).map_err(io)?;
        let g = m.grid.as_ref().expect("snapshots need a grid");
        let max = out
            .snapshots
            .iter()
            .flat_map(|(_, p)| p.iter())
            .fold(0.0f64, |a, v| a.max(v.abs()));
        for (t, p) in &out.snapshots {
            let f = dir.join(format!("p_{}_{:08.3}us.png", hit + 1, t * 1e6));
            output::snapshot_png(&f, p, g.nx, g.ny, max)?;
        }
        lines.push(format!(
            "  {} field snapshots (±{max:.2e} Pa) → {}",
            out.snapshots.len(),
            dir.display()
        ));
    }
    Ok(())
}

/// Write the sensors' signals to `waveforms.parquet` when any run has some, with a line.
fn write_sensor_signals(
    job: &SimJob,
    runs: &[output::Run],
    lines: &mut Vec<String>,
) -> Result<(), SimError> {
    if runs.iter().any(|r| !r.out.sensors.is_empty()) {
        let p = job.out.join("waveforms.parquet");
        let n = output::write_waveforms(&p, runs)?;
        let sensors: usize = runs.iter().map(|r| r.out.sensors.len()).sum();
        let silent = sensors as u64 - n;
        lines.push(format!(
            "{n} sensor signals → {}{}",
            p.display(),
            if silent > 0 {
                format!(
                    " ({silent} sensor(s) never reached the {:.0} dB_AE threshold: no record)",
                    job.acquisition.threshold_db
                )
            } else {
                String::new()
            }
        ));
    }
    Ok(())
}

/// Frequency of the free node that moves most in y, from the zero crossings of its
/// displacement about its mean, and the decay of that displacement (needs trajectories;
/// used for models without a grid).
fn node_frequency(m: &ModelFile, out: &SimOutput) -> Option<(usize, f64, Option<decay::Decay>)> {
    if out.trajectory.len() < 4 {
        return None;
    }
    let n = m.nodes.len();
    let node = (0..n).max_by(|&a, &b| {
        let span = |i: usize| {
            let (lo, hi) = out
                .trajectory
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), f| {
                    (l.min(f.r[i][1]), h.max(f.r[i][1]))
                });
            hi - lo
        };
        span(a).total_cmp(&span(b))
    })?;
    let t: Vec<f64> = out.trajectory.iter().map(|f| f.t).collect();
    let y: Vec<f64> = out.trajectory.iter().map(|f| f.r[node][1]).collect();
    let f = zero_crossing_frequency(&t, &y)?;
    let d = decay::fit(&y, t[1] - t[0], 1.0 / f);
    Some((node, f, d))
}

/// Frequency from the upward zero crossings of x − mean(x), linearly interpolated in time:
/// (crossings − 1) / (last − first). `None` with fewer than two crossings.
pub fn zero_crossing_frequency(t: &[f64], x: &[f64]) -> Option<f64> {
    let mean = x.iter().sum::<f64>() / x.len().max(1) as f64;
    let mut times = Vec::new();
    for k in 1..x.len() {
        let (a, b) = (x[k - 1] - mean, x[k] - mean);
        if a < 0.0 && b >= 0.0 {
            times.push(t[k - 1] + (t[k] - t[k - 1]) * (-a) / (b - a));
        }
    }
    (times.len() >= 2).then(|| (times.len() - 1) as f64 / (times[times.len() - 1] - times[0]))
}
