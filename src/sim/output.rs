//! Simulator output: sensor signals as labelled rows of the canonical waveform table (plus
//! the simulation columns of `data-schema/sim_waveforms.md`), node trajectories, and pressure
//! field snapshots like Fig. 3.24c.

use super::model::ModelFile;
use super::{Frame, SimError, SimOutput};
use crate::model::columns as cols;
use crate::store::{self, ColType, ColumnSpec, Table, TableWriter, Value};
use sha2::Digest as _;
use std::path::Path;

/// One simulated signal: a row of the simulated waveform table.
pub struct SimSignal {
    pub wave: store::WaveformRow,
    pub sim_model: String,
    pub sim_params: String,
    pub sensor_x_m: f64,
    pub sensor_y_m: f64,
    /// The sensor's height in a 3-D model.
    pub sensor_z_m: Option<f64>,
    pub scale_v_per_pa: f64,
    pub dominant_frequency_hz: f64,
    /// Eq. 3.5.1's fit to the band-limited pressure's envelope ([`super::decay`]).
    pub decay: Option<super::decay::Decay>,
    /// The model's frictional damping b, kg/s (α = γ/b).
    pub damping_kg_s: f64,
}

/// `waveforms` columns, then the simulation's own.
pub fn sim_waveforms_table() -> Table<SimSignal> {
    let f = |name: &str, unit: &str, doc: &str| ColumnSpec::new(name, ColType::Float64, unit, doc);
    Table::new("sim_waveforms")
        .embed(store::waveforms_table(), |s: &mut SimSignal| &mut s.wave)
        .col(ColumnSpec::new("sim_model", ColType::Utf8, "", "scenario name or model file the signal was simulated from"), |s| Value::Str(Some(s.sim_model.clone())))
        .col(ColumnSpec::new("sim_params", ColType::Utf8, "", "scenario parameters as JSON (`{}` for a model file)"), |s| Value::Str(Some(s.sim_params.clone())))
        .col(f("sensor_x_m", "m", "x of the sensor cell's centre"), |s| Value::F64(Some(s.sensor_x_m)))
        .col(f("sensor_y_m", "m", "y of the sensor cell's centre"), |s| Value::F64(Some(s.sensor_y_m)))
        .col(f("sensor_z_m", "m", "z of the sensor cell's centre in a 3-D model (§6.2); null in the thesis's plane").nullable(), |s| Value::F64(s.sensor_z_m))
        .col(f("pressure_scale_v_per_pa", "V/Pa", "sensor sensitivity: samples_v = pressure × this"), |s| Value::F64(Some(s.scale_v_per_pa)))
        .col(f("dominant_frequency_hz", "Hz", "peak of the band-limited pressure's power spectrum (the whole simulated signal, before noise)"), |s| Value::F64(Some(s.dominant_frequency_hz)))
        .col(f("decay_gamma_hz", "1/s", "γ of Eq. 3.5.1: the band-limited pressure’s envelope (half its peak-to-peak swing in each dominant period, from the peak’s period until below 10⁻³ of the first) fitted by y0·exp(−γt); null when fewer than three periods stand above that").nullable(), |s| Value::F64(s.decay.as_ref().map(|d| d.gamma_hz)))
        .col(f("decay_alpha_per_kg", "1/kg", "α = γ/b of Eq. 3.5.2, b the model's frictional damping; null without damping or without γ").nullable(), |s| Value::F64(s.decay.as_ref().and_then(|d| d.alpha_per_kg(s.damping_kg_s))))
        .col(f("decay_fit_r2", "", "R² of the fit of ln(envelope) against time: 1 for a pure exponential decay, lower where modes beat").nullable(), |s| Value::F64(s.decay.as_ref().map(|d| d.r2)))
}

/// The trajectory table of a 3-D model: the plane one's columns, then z and its velocity.
pub fn trajectory_table_3d() -> Table<TrajectoryPoint> {
    let f = |name: &str, unit: &str, doc: &str| ColumnSpec::new(name, ColType::Float64, unit, doc);
    trajectory_table()
        .renamed("sim_trajectories_3d")
        .col(f("z_m", "m", "position, height"), |p: &TrajectoryPoint| {
            Value::F64(Some(p.r[2]))
        })
        .col(f("w_m_s", "m/s", "velocity, z"), |p| {
            Value::F64(Some(p.u[2]))
        })
}

/// One node at one time: a row of the trajectory table.
pub struct TrajectoryPoint {
    pub t_s: f64,
    pub node: usize,
    pub r: [f64; 3],
    pub u: [f64; 3],
}

/// Node trajectory table.
pub fn trajectory_table() -> Table<TrajectoryPoint> {
    let f = |name: &str, unit: &str, doc: &str| ColumnSpec::new(name, ColType::Float64, unit, doc);
    Table::new("sim_trajectories")
        .col(f("t_s", "s", "simulation time"), |p: &TrajectoryPoint| {
            Value::F64(Some(p.t_s))
        })
        .col(
            ColumnSpec::new(
                "node",
                ColType::Int32,
                "",
                "node index (nodes made by bond failures are numbered after the given ones)",
            ),
            |p| Value::I32(Some(p.node as i32)),
        )
        .col(f(cols::X_M.name, "m", "position"), |p| {
            Value::F64(Some(p.r[0]))
        })
        .col(f(cols::Y_M.name, "m", "position"), |p| {
            Value::F64(Some(p.r[1]))
        })
        .col(f("u_m_s", "m/s", "velocity, x"), |p| {
            Value::F64(Some(p.u[0]))
        })
        .col(f("v_m_s", "m/s", "velocity, y"), |p| {
            Value::F64(Some(p.u[1]))
        })
}

/// One simulated run to be written.
pub struct Run<'a> {
    pub model: &'a ModelFile,
    pub out: &'a SimOutput,
    /// Scenario name or model path.
    pub source: String,
    /// Scenario parameters as JSON.
    pub params: String,
    /// Hit number of this run in the experiment.
    pub hit: u64,
    pub acq: &'a Acquisition,
    /// Erroneous records to make from this run's signals besides its own.
    pub faults: Vec<Fault>,
}

/// How the simulated sensor records a hit, the way an AE system does: the pressure,
/// band-limited to what the grid carries ([`super::acoustic::band_limit`]), times the
/// sensitivity, plus the electronics' white noise; the record starts `pretrigger` samples
/// before the first sample whose magnitude reaches the threshold, and runs to the end of the
/// simulation. Before the simulation starts (t < 0) the field is silent, so a pretrigger
/// longer than the signal's delay is noise alone, exactly.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Acquisition {
    /// Volts per pascal. The 2-D model's pressure is per unit depth, so its level is not a
    /// physical one: the default puts the reference library's hits at 70–100 dB_AE.
    pub scale_v_per_pa: f64,
    /// Detection threshold, dB_AE (1 µV = 0 dB); recorded in `threshold_v`.
    pub threshold_db: f64,
    /// RMS of the white noise added to every sample, dB_AE (none below −100).
    pub noise_db: f64,
    /// Samples recorded before the trigger (the thesis's records: 500 at 10 MHz).
    pub pretrigger: usize,
    /// Seed of the noise (each signal's noise also depends on its hit and channel).
    pub seed: u64,
}

impl Default for Acquisition {
    fn default() -> Self {
        Acquisition {
            scale_v_per_pa: 3e-5,
            threshold_db: 40.0,
            noise_db: 26.0,
            pretrigger: 500,
            seed: 2008,
        }
    }
}

/// A recorded hit: samples (V), the trigger's index and the threshold.
#[derive(Debug, Clone, PartialEq)]
pub struct Recorded {
    pub samples: Vec<f32>,
    pub pretrigger: usize,
    pub threshold_v: f64,
}

impl Acquisition {
    pub fn threshold_v(&self) -> f64 {
        crate::model::db_to_v(self.threshold_db)
    }

    /// Record a pressure signal (Pa, already band-limited): `None` when it never reaches the
    /// threshold (an AE system records nothing). `key` makes each signal's noise its own.
    pub fn record(&self, pressure: &[f64], key: u64) -> Option<Recorded> {
        self.record_with_lead(pressure, key, 0)
    }

    /// [`Acquisition::record`] with the trigger `lead` samples before the signal's first
    /// crossing (`lead` > 0: the system was triggered by something else before the front
    /// arrived, Fig. 5.8c).
    pub fn record_with_lead(&self, pressure: &[f64], key: u64, lead: usize) -> Option<Recorded> {
        let thr = self.threshold_v();
        let sigma = if self.noise_db > -100.0 {
            crate::model::db_to_v(self.noise_db)
        } else {
            0.0
        };
        let mut rng = crate::util::Rng::new(
            self.seed
                .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                .wrapping_add(key),
        );
        let pre = self.pretrigger + lead;
        // Noise alone before t = 0, then signal plus noise.
        let stream: Vec<f64> = (0..pre)
            .map(|_| 0.0)
            .chain(pressure.iter().map(|p| p * self.scale_v_per_pa))
            .map(|v| v + sigma * rng.normal())
            .collect();
        let first = stream.iter().position(|v| v.abs() >= thr)?;
        let start = first.saturating_sub(pre);
        Some(Recorded {
            samples: stream[start..].iter().map(|&v| v as f32).collect(),
            pretrigger: (first - start).saturating_sub(lead),
            threshold_v: thr,
        })
    }
}

/// The acquisition faults of ch. 5.4 (Table 5.1's "erroneous data"), made from simulated
/// signals for the reference library's `erroneous` class.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// Triggered 10–30 µs before the front arrived (Fig. 5.8c).
    BeforeFront,
    /// A second signal (another sensor of the run, 0.7–1× the first's peak) arriving
    /// 20–35 µs after the first, when the first has rung down: two distinct signals in one
    /// record, both inside the bins' 40 µs.
    TwoSignals,
    /// Clipped at 5–20 % of the peak (a hit 14–26 dB over the ADC's range): hard enough
    /// that the CWT's shape is wrong, which is what makes a record "erroneous" in ch. 5.4
    /// (a record clipped near its peak keeps its shape and its mechanism).
    Clipped,
}

impl Fault {
    pub const ALL: [Fault; 3] = [Fault::BeforeFront, Fault::TwoSignals, Fault::Clipped];

    pub fn as_str(self) -> &'static str {
        match self {
            Fault::BeforeFront => "before_front",
            Fault::TwoSignals => "two_signals",
            Fault::Clipped => "clipped",
        }
    }
}

/// One erroneous record made from a run's band-limited sensor pressures, drawing from the
/// sensors in `heard` (those that triggered; `None` when there is none), with what was done,
/// for `sim_params`.
pub fn fault_record(
    acq: &Acquisition,
    pressures: &[Vec<f64>],
    heard: &[usize],
    fault: Fault,
    fs: f64,
    key: u64,
) -> Option<(Recorded, serde_json::Map<String, serde_json::Value>)> {
    let mut rng = crate::util::Rng::new(key ^ 0x00E7_7A0E_0000_0000 ^ acq.seed);
    if heard.is_empty() {
        return None;
    }
    let pick = |rng: &mut crate::util::Rng| heard[(rng.next_u64() % heard.len() as u64) as usize];
    let a = pick(&mut rng);
    let mut info = serde_json::Map::new();
    info.insert("fault".into(), fault.as_str().into());
    info.insert("fault_sensor".into(), (a + 1).into());
    let rec = match fault {
        Fault::BeforeFront => {
            let lead = (rng.range(10e-6, 30e-6) * fs).round() as usize;
            info.insert("fault_lead_us".into(), (lead as f64 / fs * 1e6).into());
            acq.record_with_lead(&pressures[a], key, lead)?
        }
        Fault::TwoSignals => {
            let b = pick(&mut rng);
            let delay = (rng.range(20e-6, 35e-6) * fs).round() as usize;
            let gain = rng.range(0.7, 1.0);
            let peak = |x: &[f64]| x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let g = gain * peak(&pressures[a]) / peak(&pressures[b]).max(f64::MIN_POSITIVE);
            let mut sum = pressures[a].clone();
            for (i, v) in pressures[b].iter().enumerate() {
                if let Some(o) = sum.get_mut(i + delay) {
                    *o += g * v;
                }
            }
            info.insert("fault_second_sensor".into(), (b + 1).into());
            info.insert("fault_delay_us".into(), (delay as f64 / fs * 1e6).into());
            info.insert("fault_gain".into(), gain.into());
            acq.record(&sum, key)?
        }
        Fault::Clipped => {
            let level = rng.range(0.05, 0.2);
            let mut r = acq.record(&pressures[a], key)?;
            let peak = r.samples.iter().fold(0.0f32, |m, v| m.max(v.abs()));
            let clip = (level as f32) * peak;
            for v in &mut r.samples {
                *v = v.clamp(-clip, clip);
            }
            info.insert("fault_clip_share".into(), level.into());
            r
        }
    };
    Some((rec, info))
}

/// The pressure a sensor passes on: the simulated signal band-limited to what the grid
/// carries (nothing above the grid's `stop_hz` is a sound wave of the model).
pub fn band_limited(sig: &[f64], g: &super::model::GridSpec) -> Vec<f64> {
    let b = super::acoustic::band_limit(g);
    super::acoustic::low_pass(sig, 1.0 / g.dt, b.pass_hz, b.stop_hz)
}

/// Eq. 4.5.4's bands as the thesis's tables (4.2–4.3) take them: 25 of 100 kHz.
pub const POWER_BANDS: usize = 25;
pub const POWER_BAND_HZ: f64 = 100e3;

/// Eq. 4.5.4's power ratios of a whole simulated signal (band-limited to its grid, at `fs`):
/// the share of its power below 2.5 MHz in each 100 kHz band. None: a silent signal.
pub fn power_ratios(x: &[f64], fs: f64) -> Option<[f64; POWER_BANDS]> {
    let spec: Vec<rustfft::num_complex::Complex32> = crate::dsp::filter::spectrum(x, x.len())
        .into_iter()
        .map(|c| rustfft::num_complex::Complex32::new(c.re as f32, c.im as f32))
        .collect();
    let mut ratios = [0.0; POWER_BANDS];
    crate::dsp::spectrum::power_ratios(&spec, x.len(), fs, POWER_BAND_HZ, &mut ratios)?;
    Some(ratios)
}

/// The simulated signals of a run, one per sensor that triggered, then the run's erroneous
/// records (`run.faults`, channels 101, 102, …).
pub fn rows(run: &Run) -> Vec<SimSignal> {
    let g = match &run.model.grid {
        Some(g) => g,
        None => return vec![],
    };
    let fs = run.out.sample_rate_hz;
    let band = super::acoustic::band_limit(g);
    let pressures: Vec<Vec<f64>> = run
        .out
        .sensors
        .iter()
        .map(|s| super::acoustic::low_pass(s, fs, band.pass_hz, band.stop_hz))
        .collect();
    let row = |channel: i32,
               rec: Recorded,
               label: Option<String>,
               params: String,
               (x, y, z): (f64, f64, Option<f64>),
               p: &[f64]| {
        let dominant = super::dominant_frequency(p, fs);
        SimSignal {
            wave: store::WaveformRow::from(crate::model::AeRecord {
                experiment: run.model.name.clone(),
                channel: channel as u32,
                hit: run.hit,
                time_s: Some(0.0),
                sample_rate_hz: fs,
                pretrigger: rec.pretrigger as u32,
                samples: rec.samples,
                load_n: None,
                extension_m: None,
                label,
                threshold_v: Some(rec.threshold_v),
                source_file: run.source.clone(),
                kind: crate::model::RecordKind::Hit,
            }),
            sim_model: run.source.clone(),
            sim_params: params,
            sensor_x_m: x,
            sensor_y_m: y,
            sensor_z_m: z,
            scale_v_per_pa: run.acq.scale_v_per_pa,
            dominant_frequency_hz: dominant,
            decay: super::decay::fit(p, 1.0 / fs, 1.0 / dominant),
            damping_kg_s: run.model.system.damping,
        }
    };
    let mut out = Vec::new();
    let mut heard = Vec::new();
    for (k, (p, spec)) in pressures.iter().zip(&run.model.sensors).enumerate() {
        if let Some(rec) = run.acq.record(p, (run.hit << 16) | k as u64) {
            heard.push(k);
            out.push(row(
                k as i32 + 1,
                rec,
                run.model.label.clone(),
                run.params.clone(),
                sensor_position(run.model, spec),
                p,
            ));
        }
    }
    for (j, &fault) in run.faults.iter().enumerate() {
        let key = (run.hit << 16) | (0x100 + j as u64);
        let Some((rec, info)) = fault_record(run.acq, &pressures, &heard, fault, fs, key) else {
            continue;
        };
        let mut params: serde_json::Map<String, serde_json::Value> =
            serde_json::from_str(&run.params).unwrap_or_default();
        params.extend(info.clone());
        let a = info["fault_sensor"].as_u64().unwrap_or(1) as usize - 1;
        out.push(row(
            101 + j as i32,
            rec,
            Some(crate::model::Mechanism::Erroneous.as_str().to_string()),
            serde_json::Value::Object(params).to_string(),
            sensor_position(run.model, &run.model.sensors[a]),
            &pressures[a],
        ));
    }
    out
}

/// The centre of a sensor's cell: (x, y) and, in a 3-D model, z.
fn sensor_position(m: &ModelFile, spec: &super::model::SensorSpec) -> (f64, f64, Option<f64>) {
    let Some(g) = &m.grid else {
        return (0.0, 0.0, None);
    };
    let (x, y) = g.centre(spec.i, spec.j);
    let z = g.z.map(|z| {
        let (_, _, k) = m.sensor_cell3(spec);
        z.z1 + (k as f64 + 0.5) * g.dx()
    });
    (x, y, z)
}

/// Write the simulated waveform table (atomic, like every table).
pub fn write_waveforms(path: &Path, runs: &[Run]) -> Result<u64, SimError> {
    let io = |e: store::StoreError| SimError::Io(e.to_string());
    // The models' digest plays the role of the pipeline configuration's.
    let mut h = sha2::Sha256::new();
    for run in runs {
        sha2::Digest::update(&mut h, serde_json::to_vec(run.model).unwrap_or_default());
        sha2::Digest::update(&mut h, run.params.as_bytes());
    }
    let digest: String = sha2::Digest::finalize(h)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    let meta = [("aepipe.config_sha256".to_string(), digest)];
    let table = sim_waveforms_table();
    let mut w = TableWriter::create(path, table.schema(), &meta, 256).map_err(io)?;
    for run in runs {
        for sig in rows(run) {
            w.push(table.row(sig)).map_err(io)?;
        }
    }
    w.finish().map_err(io)
}

/// Write node frames: the plane table, or with `dims` 3 the one with z (`sim_trajectories_3d`).
pub fn write_trajectories(path: &Path, frames: &[Frame], dims: usize) -> Result<u64, SimError> {
    let table = if dims == 3 {
        trajectory_table_3d()
    } else {
        trajectory_table()
    };
    let rows = frames.iter().flat_map(|f| {
        f.r.iter()
            .zip(&f.u)
            .enumerate()
            .map(|(node, (r, u))| TrajectoryPoint {
                t_s: f.t,
                node,
                r: *r,
                u: *u,
            })
    });
    table
        .write_all(path, &[], 65_536, rows)
        .map_err(|e| SimError::Io(e.to_string()))
}

/// The springs' tension in each kept frame (`sim_tension`).
pub fn tension_table() -> Table<(f64, usize, f64)> {
    Table::new("sim_tension")
        .col(
            ColumnSpec::new("t_s", ColType::Float64, "s", "simulation time"),
            |r: &(f64, usize, f64)| Value::F64(Some(r.0)),
        )
        .col(
            ColumnSpec::new(
                "spring",
                ColType::Int32,
                "",
                "spring index, as in the model",
            ),
            |r| Value::I32(Some(r.1 as i32)),
        )
        .col(
            ColumnSpec::new(
                "tension_n",
                ColType::Float64,
                "N",
                "k·(l − L), k = E·A/L with A at the load (Eq. 3.2.9); 0 once broken",
            ),
            |r| Value::F64(Some(r.2)),
        )
}

/// The energies in each kept frame (`sim_energy`).
pub fn energy_table() -> Table<(f64, [f64; 2])> {
    let f = |name: &str, doc: &str| ColumnSpec::new(name, ColType::Float64, "J", doc);
    Table::new("sim_energy")
        .col(
            ColumnSpec::new("t_s", ColType::Float64, "s", "simulation time"),
            |r: &(f64, [f64; 2])| Value::F64(Some(r.0)),
        )
        .col(f("kinetic_j", "Σ ½·m·|u|² of the free masses"), |r| {
            Value::F64(Some(r.1[0]))
        })
        .col(
            f("potential_j", "Σ ½·k·(l − L)² of the intact springs"),
            |r| Value::F64(Some(r.1[1])),
        )
        .col(
            f(
                "total_j",
                "kinetic + potential: constant without damping, for an exact solver",
            ),
            |r| Value::F64(Some(r.1[0] + r.1[1])),
        )
}

/// Write each frame's spring tensions (long format).
pub fn write_tension(path: &Path, frames: &[Frame]) -> Result<u64, SimError> {
    let rows = frames
        .iter()
        .flat_map(|f| f.tension.iter().enumerate().map(|(k, t)| (f.t, k, *t)));
    tension_table()
        .write_all(path, &[], 65_536, rows)
        .map_err(|e| SimError::Io(e.to_string()))
}

/// Write each frame's energies.
pub fn write_energy(path: &Path, frames: &[Frame]) -> Result<u64, SimError> {
    let rows = frames.iter().filter_map(|f| f.energy.map(|e| (f.t, e)));
    energy_table()
        .write_all(path, &[], 65_536, rows)
        .map_err(|e| SimError::Io(e.to_string()))
}

/// A pressure snapshot as a PNG, one pixel block per cell, red positive, blue negative,
/// white zero, symmetric scale ±`max` (north up).
pub fn snapshot_png(
    path: &Path,
    p: &[f64],
    nx: usize,
    ny: usize,
    max: f64,
) -> Result<(), SimError> {
    use plotters::prelude::*;
    let px = (600 / nx.max(1)).max(1) as u32;
    let (w, h) = (nx as u32 * px, ny as u32 * px);
    let e = |x: String| SimError::Io(format!("{}: {x}", path.display()));
    {
        let root = BitMapBackend::new(path, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|x| e(x.to_string()))?;
        let scale = if max > 0.0 { max } else { 1.0 };
        for j in 0..ny {
            for i in 0..nx {
                let v = (p[j * nx + i] / scale).clamp(-1.0, 1.0);
                let c = if v >= 0.0 {
                    let k = (255.0 * (1.0 - v)) as u8;
                    RGBColor(255, k, k)
                } else {
                    let k = (255.0 * (1.0 + v)) as u8;
                    RGBColor(k, k, 255)
                };
                let (x0, y0) = ((i as u32 * px) as i32, ((ny - 1 - j) as u32 * px) as i32);
                root.draw(&Rectangle::new(
                    [(x0, y0), (x0 + px as i32, y0 + px as i32)],
                    c.filled(),
                ))
                .map_err(|x| e(x.to_string()))?;
            }
        }
        root.present().map_err(|x| e(x.to_string()))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 250 kHz ring decaying over ~20 µs that starts at sample 100 of 600, in pascals.
    fn ring(start: usize) -> Vec<f64> {
        (0..600)
            .map(|i| {
                if i < start {
                    return 0.0;
                }
                let t = (i - start) as f64 * 1e-7;
                300.0 * (-t / 20e-6).exp() * (2.0 * std::f64::consts::PI * 250e3 * t).sin()
            })
            .collect()
    }

    #[test]
    fn a_record_starts_pretrigger_samples_before_the_first_crossing() {
        let acq = Acquisition::default();
        let r = acq.record(&ring(100), 7).unwrap();
        let thr = acq.threshold_v();
        assert_eq!(r.pretrigger, 500);
        assert!(r.samples[..500].iter().all(|v| (*v as f64).abs() < thr));
        assert!((r.samples[500] as f64).abs() >= thr);
        // The noise floor before the signal is the configured 26 dB_AE (20 µV rms).
        let rms = (r.samples[..400]
            .iter()
            .map(|v| (*v as f64).powi(2))
            .sum::<f64>()
            / 400.0)
            .sqrt();
        assert!((rms / 20e-6 - 1.0).abs() < 0.15, "{rms}");
        // Nothing reaches the threshold: no record; the same key gives the same noise.
        assert!(acq.record(&vec![0.0; 600], 7).is_none());
        assert_eq!(acq.record(&ring(100), 7), Some(r));
    }

    #[test]
    fn faults_are_what_ch_5_4_calls_erroneous() {
        let acq = Acquisition::default();
        let thr = acq.threshold_v() as f32;
        let p = vec![ring(100), ring(150)];
        // Triggered before the front: the threshold is first reached 10–30 µs after the
        // trigger.
        let (r, info) = fault_record(&acq, &p, &[0, 1], Fault::BeforeFront, 1e7, 1).unwrap();
        let first = r.samples.iter().position(|v| v.abs() >= thr).unwrap();
        let lead = first - r.pretrigger;
        assert!((100..=300).contains(&lead), "{lead}");
        assert!((info["fault_lead_us"].as_f64().unwrap() - lead as f64 / 10.0).abs() < 1e-9);
        // Clipped: a run of samples at the extreme, at 5–20 % of the unclipped peak.
        let (r, _) = fault_record(&acq, &p, &[0, 1], Fault::Clipped, 1e7, 2).unwrap();
        let top = r.samples.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        assert!(r.samples.iter().filter(|v| v.abs() == top).count() >= 10);
        let unclipped = 300.0 * acq.scale_v_per_pa;
        assert!((0.04..0.21).contains(&(top as f64 / unclipped)), "{top}");
        // Two signals: sensor b's signal added 20–35 µs later, scaled to 0.7–1 of sensor
        // a's peak; the record is exactly that sum recorded.
        let (r, info) = fault_record(&acq, &p, &[0, 1], Fault::TwoSignals, 1e7, 3).unwrap();
        let delay = (info["fault_delay_us"].as_f64().unwrap() * 10.0).round() as usize;
        let gain = info["fault_gain"].as_f64().unwrap();
        assert!(
            (200..=350).contains(&delay) && (0.7..1.0).contains(&gain),
            "{info:?}"
        );
        let a = info["fault_sensor"].as_u64().unwrap() as usize - 1;
        let b = info["fault_second_sensor"].as_u64().unwrap() as usize - 1;
        let mut sum = p[a].clone();
        for i in delay..sum.len() {
            sum[i] += gain * p[b][i - delay]; // both rings peak at 300 Pa
        }
        let again = acq.record(&sum, 3).unwrap();
        assert_eq!(again.pretrigger, r.pretrigger);
        let diff = again
            .samples
            .iter()
            .zip(&r.samples)
            .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()));
        assert!(diff < 1e-6, "{diff}");
    }
}
