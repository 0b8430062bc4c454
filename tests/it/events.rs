//! Sources, not hits: the event builder against vallenae 0.14's `EventBuilder` on real
//! Vallen files, the steel plate's event located with its `.vaex` setup, and the event
//! columns of the hit tables.

use crate::vendor::python;
use crate::TempDir;
use aepipe::config::PipelineConfig;
use aepipe::pipeline::{run, Manifest, StreamJob, StreamOptions};
use arrow::array::{Array, AsArray};
use arrow::datatypes::{Float64Type, Int32Type, Int64Type};
use std::path::{Path, PathBuf};

fn opts() -> StreamOptions {
    StreamOptions::with_threads(2)
}

/// One event as read back: time, channels, close reason, hit numbers, x, y, lucy, status.
#[derive(Debug, Clone)]
pub struct Ev {
    pub experiment: String,
    pub time_s: f64,
    pub channels: Vec<i32>,
    pub close: String,
    pub hits: Vec<i64>,
    pub dt: Vec<f64>,
    pub x: Option<f64>,
    pub y: Option<f64>,
    pub lucy: Option<f64>,
    pub status: Option<String>,
    pub zone: Option<String>,
}

pub fn read_events(path: &Path) -> Vec<Ev> {
    let (schema, _, batches) = aepipe::store::read_parquet(path).unwrap();
    let idx = |n: &str| schema.index_of(n).unwrap();
    let mut out = Vec::new();
    for b in batches {
        let s = |n: &str| b.column(idx(n)).as_string::<i32>().clone();
        let f = |n: &str| b.column(idx(n)).as_primitive::<Float64Type>().clone();
        let (exp, time, close) = (s("experiment"), f("time_s"), s("close_reason"));
        let (x, y, lucy) = (f("x_m"), f("y_m"), f("lucy_m"));
        let (status, zone) = (s("location_status"), s("zone"));
        let chans = b.column(idx("channels")).as_list::<i32>().clone();
        let hits = b.column(idx("hits")).as_list::<i32>().clone();
        let dts = b.column(idx("dt_to_first_s")).as_list::<i32>().clone();
        let opt = |a: &arrow::array::Float64Array, i: usize| (!a.is_null(i)).then(|| a.value(i));
        let opt_s = |a: &arrow::array::StringArray, i: usize| {
            (!a.is_null(i)).then(|| a.value(i).to_string())
        };
        for i in 0..b.num_rows() {
            out.push(Ev {
                experiment: exp.value(i).to_string(),
                time_s: time.value(i),
                channels: chans.value(i).as_primitive::<Int32Type>().values().to_vec(),
                close: close.value(i).to_string(),
                hits: hits.value(i).as_primitive::<Int64Type>().values().to_vec(),
                dt: dts.value(i).as_primitive::<Float64Type>().values().to_vec(),
                x: opt(&x, i),
                y: opt(&y, i),
                lucy: opt(&lucy, i),
                status: opt_s(&status, i),
                zone: opt_s(&zone, i),
            });
        }
    }
    out
}

/// One parameter set compared: (FHCDT, DT1X, DTNX, duplicates allowed, roles).
type Case = (f64, f64, f64, bool, Vec<(u32, &'static str)>);
/// One event as vallenae gives it: time, channels, close reason, hit times.
type TheirEvent = (f64, Vec<i32>, String, Vec<f64>);

fn cases() -> Vec<Case> {
    vec![
        (2e-3, 2e-3, 2e-3, false, vec![]),
        (1e-4, 1e-4, 1e-4, false, vec![]),
        (5e-5, 2e-4, 5e-5, true, vec![]),
        (1e-5, 4e-5, 2e-5, false, vec![]),
        (
            1e-3,
            5e-4,
            1e-4,
            false,
            vec![(1, "guard"), (2, "unused"), (3, "combined")],
        ),
    ]
}

#[test]
fn the_event_builder_equals_vallenaes_on_real_files() {
    let name = "the_event_builder_equals_vallenaes_on_real_files";
    let Some(real) = crate::real_data(name) else {
        return;
    };
    let files: Vec<PathBuf> = [
        "vallen/steel_plate/sample",
        "vallen/bearing/bearing",
        "plb_cfrp_vallen/PLBS4_CP090_PCLO1",
        "plb_cfrp_vallen/PLBS8_QI090_T1",
        "plb_cfrp_vallen/PLBS8_QI090_ST1",
    ]
    .iter()
    .map(|p| real.join(p))
    .collect();
    let t = TempDir::new("events-vallenae");
    // Every (file, case) for vallenae in one call.
    let mut spec = Vec::new();
    for f in &files {
        for (fh, d1, dn, dup, roles) in cases() {
            spec.push(serde_json::json!({
                "pridb": f.with_extension("pridb"), "fhcdt": fh, "dt1x": d1, "dtnx": dn,
                "allow_duplicates": dup,
                "roles": roles.iter().map(|(c, r)| (c.to_string(), serde_json::Value::from(*r))).collect::<serde_json::Map<_, _>>(),
            }));
        }
    }
    let spec_path = t.path().join("cases.json");
    std::fs::write(&spec_path, serde_json::to_string(&spec).unwrap()).unwrap();
    let Some(js) = python(name, "vallenae_events.py", &[&spec_path]) else {
        return;
    };
    let theirs: Vec<Vec<TheirEvent>> = serde_json::from_str(js.trim()).unwrap();
    let (mut n_events, mut n_multi, mut k) = (0, 0, 0);
    for f in &files {
        for (ci, (fh, d1, dn, dup, roles)) in cases().into_iter().enumerate() {
            let role_list = |r: &str| {
                roles
                    .iter()
                    .filter(|(_, x)| *x == r)
                    .map(|(c, _)| c.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            };
            let toml = format!(
                "[events]\nenabled = true\nfhcdt_s = {fh:e}\ndt1x_max_s = {d1:e}\ndtnx_max_s = {dn:e}\nallow_duplicates = {dup}\nguard_channels = [{}]\nunused_channels = [{}]\ncombined_channels = [{}]\n",
                role_list("guard"),
                role_list("unused"),
                role_list("combined")
            );
            let cfg = PipelineConfig::from_toml(&toml).unwrap();
            let out = t.path().join(format!("{k}"));
            // The events step needs only the hits: the waveforms job is the cheaper carrier.
            let r = run(
                StreamJob::Waveforms,
                &[f.with_extension("pridb"), f.with_extension("tradb")],
                &out,
                &cfg,
                &opts(),
            )
            .unwrap();
            let mine = read_events(&r.events_path);
            let want = &theirs[k];
            k += 1;
            let what = format!("{} case {ci}", f.display());
            assert_eq!(mine.len(), want.len(), "{what}: number of events");
            for (m, w) in mine.iter().zip(want) {
                assert_eq!(
                    m.channels, w.1,
                    "{what}: channel sequence of the event at {}",
                    w.0
                );
                assert!(
                    (m.time_s - w.0).abs() < 1e-9,
                    "{what}: {} vs {}",
                    m.time_s,
                    w.0
                );
                assert_eq!(m.close, w.2, "{what}: close reason at {}", w.0);
                let dts: Vec<f64> = w.3[1..].iter().map(|t| t - w.3[0]).collect();
                assert_eq!(m.dt.len(), dts.len());
                for (a, b) in m.dt.iter().zip(&dts) {
                    assert!((a - b).abs() < 1e-9, "{what}: dt {a} vs {b}");
                }
            }
            n_events += mine.len();
            n_multi += mine.iter().filter(|e| e.channels.len() > 1).count();
            // Every hit is in one event or none, never two.
            let mut seen = std::collections::BTreeSet::new();
            for e in &mine {
                for h in &e.hits {
                    assert!(
                        seen.insert((e.experiment.clone(), *h)),
                        "{what}: hit {h} twice"
                    );
                }
            }
        }
    }
    eprintln!("{n_events} events ({n_multi} with several hits) equal to vallenae's in {k} runs");
    assert!(
        n_multi > 100,
        "the comparison must include multi-hit events"
    );
}

#[test]
fn the_steel_plate_event_is_located_with_its_vaex_setup() {
    let name = "the_steel_plate_event_is_located_with_its_vaex_setup";
    let Some(real) = crate::real_data(name) else {
        return;
    };
    let t = TempDir::new("events-plate");
    let r = run(
        StreamJob::Features,
        &[real.join("vallen/steel_plate")],
        t.path(),
        &aepipe::config::ValidConfig::default(),
        &opts(),
    )
    .unwrap();
    let ev: Vec<Ev> = read_events(&r.events_path)
        .into_iter()
        .filter(|e| e.experiment == "sample")
        .collect();
    assert_eq!(ev.len(), 1);
    let e = &ev[0];
    assert_eq!(e.channels, vec![3, 2, 4, 1]);
    // vallenae's ex5_location.py, minimising LUCY at 5 km/s: (0.221653, 0.365659) m, LUCY
    // 1.1159e-3 m.
    let (x, y) = (e.x.unwrap(), e.y.unwrap());
    let err = (x - 0.221653).hypot(y - 0.365659);
    eprintln!(
        "steel plate: ({x:.6}, {y:.6}) m, {:.3} mm from vallenae's point, LUCY {:.4e} m",
        err * 1e3,
        e.lucy.unwrap()
    );
    assert!(err < 2e-3, "({x}, {y}) is {err} m away");
    assert!((e.lucy.unwrap() - 1.1159e-3).abs() < 2e-6);
    assert_eq!(e.status.as_deref(), Some("located"));
    // The setup came from the .vaex: 2 ms windows, 5 km/s, four sensors.
    let m = Manifest::read(&r.manifest_path).unwrap();
    let s = m.events.iter().find(|s| s.experiment == "sample").unwrap();
    assert_eq!((s.fhcdt_s, s.dt1x_max_s, s.dtnx_max_s), (2e-3, 2e-3, 2e-3));
    assert!(
        s.sources["dt1x_max_s"].starts_with("vaex"),
        "{:?}",
        s.sources
    );
    assert!(s.sources["location"].starts_with("vaex"), "{:?}", s.sources);
    assert_eq!(s.location.as_deref(), Some("planar, 5000 m/s, 4 sensors"));
}

/// `pipelines/demo.toml` locates with the geometry the demo's strip is made with: the same
/// sensors at the same positions and the same velocity (else the demo's location error
/// would measure a typo).
#[test]
fn the_demo_pipeline_states_the_synthetic_strips_geometry() {
    let cfg = aepipe::demo::demo_config();
    let strip = aepipe::synth::Strip::demo();
    let loc = &cfg.location;
    assert_eq!(loc.velocity_m_s, Some(strip.velocity_m_s));
    let stated: Vec<(u32, Vec<f64>)> = loc
        .sensors
        .iter()
        .map(|(k, v)| (k.parse().unwrap(), v.clone()))
        .collect();
    let made: Vec<(u32, Vec<f64>)> = strip.sensors.iter().map(|&(c, x)| (c, vec![x])).collect();
    assert_eq!(stated, made);
    // The zone lies between the sensors and holds the notch's damage (±notch_limit_m).
    let Some(aepipe::config::ZoneSpec::Interval([lo, hi])) = loc.zone else {
        panic!("{:?}", loc.zone)
    };
    assert!(
        lo <= -strip.notch_limit_m && hi >= strip.notch_limit_m,
        "{lo} {hi}"
    );
    assert!(loc.exclude_outside);
}

/// Guard sensors, as VisualAE uses them: two more sensors between the strip's sensors and
/// the grips. Grip noise reaches a guard first; its hit opens no event and keeps the later
/// hits of the same source at the two location sensors from opening one, so they are
/// counted as guard-suppressed and never reach the trend. Damage at the notch reaches the
/// location sensors first; the guard hits join its event but stay out of location.
#[test]
fn guard_sensors_suppress_grip_noise_and_leave_the_notchs_damage() {
    let t = TempDir::new("events-guard");
    let mut strip = aepipe::synth::Strip::demo();
    strip.sensors.extend([(3, -0.026), (4, 0.026)]);
    strip.grip_share = 0.3;
    let mut e = aepipe::synth::Experiment::new("guarded", 200, 77);
    e.strip = Some(strip.clone());
    let truth = t.path().join("truth.parquet");
    let n_hits = e.write_with_truth(&t.path().join("data"), &truth).unwrap();
    let cfg = PipelineConfig::from_toml(
        "[events]\nguard_channels = [3, 4]\n\
         [location]\nkind = \"linear\"\nvelocity_m_s = 2700\nsensors = { 1 = [-0.020], 2 = [0.020] }\n\
         zone = [-0.015, 0.015]\nexclude_outside = true\n",
    )
    .unwrap();
    let r = run(
        StreamJob::Features,
        &[t.path().join("data")],
        &t.path().join("o"),
        &cfg,
        &opts(),
    )
    .unwrap();
    let (tn, trows) = crate::table_rows(&truth);
    assert_eq!(trows.len(), n_hits);
    let tc = |n: &str| tn.iter().position(|x| x == n).unwrap();
    // (channel, hit) → (source, kind)
    let truth_of: std::collections::BTreeMap<(String, String), (String, String)> = trows
        .iter()
        .map(|r| {
            (
                (r[tc("channel")].clone(), r[tc("hit")].clone()),
                (r[tc("event")].clone(), r[tc("source_kind")].clone()),
            )
        })
        .collect();
    let (hn, hrows) = crate::table_rows(&r.hits_path);
    assert_eq!(hrows.len(), n_hits);
    let hc = |n: &str| hn.iter().position(|x| x == n).unwrap();
    let mut grip_events = std::collections::BTreeSet::new();
    let mut specimen_events = std::collections::BTreeMap::<String, String>::new();
    let mut suppressed = 0u64;
    let mut grip_sources = std::collections::BTreeSet::new();
    let mut specimen_sources = std::collections::BTreeSet::new();
    for h in &hrows {
        let (src, kind) = &truth_of[&(h[hc("channel")].clone(), h[hc("hit")].clone())];
        let (ev, zone) = (&h[hc("event")], &h[hc("zone")]);
        if zone == "guard" {
            suppressed += 1;
        }
        match kind.as_str() {
            "grip" => {
                grip_sources.insert(src.clone());
                if !ev.is_empty() {
                    grip_events.insert(ev.clone());
                }
            }
            _ => {
                specimen_sources.insert(src.clone());
                if !ev.is_empty() {
                    // All hits of one source in one event.
                    let prev = specimen_events.insert(src.clone(), ev.clone());
                    assert!(prev.is_none() || prev.as_ref() == Some(ev), "source {src}");
                }
            }
        }
    }
    assert!(
        grip_sources.len() > 30,
        "{} grip sources",
        grip_sources.len()
    );
    // No grip source opens an event: every one of its hits is guard-suppressed.
    assert!(grip_events.is_empty(), "grip events {grip_events:?}");
    // Every specimen source is an event.
    assert_eq!(specimen_events.len(), specimen_sources.len());
    let m = Manifest::read(&r.manifest_path).unwrap();
    let s = m.events.iter().find(|s| s.experiment == "guarded").unwrap();
    assert_eq!(s.guard_suppressed, suppressed);
    assert_eq!(s.events as usize, specimen_sources.len());
    // The events are inside the zone, and the trend's series counts them, not the hits.
    let ev = read_events(&r.events_path);
    assert!(
        ev.iter().all(|e| e.zone.as_deref() == Some("inside")),
        "{ev:?}"
    );
    let (_, series) = aepipe::analysis::trend::read_series(
        std::slice::from_ref(&r.table_path),
        &[],
        cfg.source_rows(),
    )
    .unwrap();
    assert_eq!(series.len(), 1);
    assert_eq!(series[0].hit.len(), specimen_sources.len());
}
