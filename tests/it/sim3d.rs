//! The simulator in three dimensions (§6.2), against what must hold: the four solvers on a
//! spring along a skew axis at its analytic frequency, a plane model lifted into space
//! moving exactly as before (and, plucked through the sheet, as in the plane), the plucked
//! fibre heard in a 3-D field at the frequency it was heard at in the plane, the layered
//! network keeping the thesis's order of the two mechanisms, and Appendix-A files with a z
//! column. (The 3-D field alone — 1/r spreading and the speed of sound — is checked in
//! `sim_beyond`.)

use crate::sim::params;
use aepipe::sim::model::*;
use aepipe::sim::network3d;
use aepipe::sim::scenario;
use aepipe::sim::{dominant_frequency, simulate, zero_crossing_frequency, SimOptions};

fn frames(every: usize) -> SimOptions {
    SimOptions {
        trajectory_every: Some(every),
        snapshot_every: None,
    }
}

/// One mass on one spring from a fixed node, the spring along n̂ = (1, 2, 2)/3, pulled 1 %
/// along it and let go: it oscillates along n̂ at ω = √(k/m), k = E·t·w/L (Eq. 3.2.5),
/// whichever solver steps it, and never leaves the axis.
#[test]
fn the_four_solvers_ring_a_spring_along_a_skew_axis_at_its_analytic_frequency() {
    let n = [1.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0];
    let (e, t, w, l, m) = (2.0, 1.0, 1.0, 1.0, 0.5);
    let node = |p: [f64; 3], fixed: bool| NodeSpec {
        x: p[0],
        y: p[1],
        z: Some(p[2]),
        mass: m,
        fixed,
    };
    let pull = 0.01 * l;
    for solver in [
        Solver::ExplicitEuler,
        Solver::Rk4,
        Solver::Verlet,
        Solver::ImplicitEuler,
    ] {
        let model = ModelFile {
            name: "skew".into(),
            label: None,
            system: System {
                dt: 1e-3,
                damping: 0.0,
                iterations: 20_000,
                solver,
                relax: false,
            },
            nodes: vec![node([0.0; 3], true), node(n.map(|c| c * l), false)],
            springs: vec![SpringSpec {
                a: 0,
                b: 1,
                e,
                length: Some(l),
                t,
                w,
                poisson: 0.0,
                fibre: 0,
            }],
            initial: vec![InitialSpec {
                node: 1,
                dx: pull * n[0],
                dy: pull * n[1],
                dz: pull * n[2],
                du: 0.0,
                dv: 0.0,
                dw: 0.0,
                kind: IcKind::Eq,
            }],
            forces: vec![],
            damage: vec![],
            grid: None,
            sensors: vec![],
        };
        assert_eq!(model.dims(), 3);
        let out = simulate(&model, &frames(1)).unwrap();
        assert_eq!(out.dims, 3);
        let times: Vec<f64> = out.trajectory.iter().map(|f| f.t).collect();
        let along: Vec<f64> = out
            .trajectory
            .iter()
            .map(|f| (0..3).map(|c| f.r[1][c] * n[c]).sum())
            .collect();
        let off: f64 = out
            .trajectory
            .iter()
            .zip(&along)
            .map(|(f, a)| {
                (0..3)
                    .map(|c| (f.r[1][c] - a * n[c]).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .fold(0.0, f64::max);
        let f = zero_crossing_frequency(&times, &along).unwrap();
        let want = (e * t * w / l / m).sqrt() / (2.0 * std::f64::consts::PI);
        assert!(
            (f / want - 1.0).abs() < 5e-3,
            "{solver:?}: {f} Hz against {want} Hz"
        );
        assert!(off < 1e-9 * l, "{solver:?} left the axis by {off} m");
    }
}

/// The plane model is the 3-D one with z = 0: the paper fibre lifted into space (every node
/// at z = 0) follows the plane fibre's trajectory to round-off, and plucked through the sheet
/// (its dy given as dz) it rings at the same frequency — §6.2's check that the third
/// dimension leaves the plucked fibre as it was.
#[test]
fn a_plane_model_lifted_into_space_moves_as_before() {
    let plane = scenario::build("paper-fibre", &params(&[("grid", 0.0)])).unwrap();
    let centre = 14;
    let run = |m: &ModelFile, axis: usize| {
        let out = simulate(m, &frames(1)).unwrap();
        let t: Vec<f64> = out.trajectory.iter().map(|f| f.t).collect();
        let x: Vec<f64> = out.trajectory.iter().map(|f| f.r[centre][axis]).collect();
        (t, x)
    };
    let (t, y2) = run(&plane, 1);
    let mut lifted = plane.clone();
    network3d::lift(&mut lifted, &vec![0.0; plane.nodes.len()], None);
    assert_eq!(lifted.dims(), 3);
    let (_, y3) = run(&lifted, 1);
    let mut through = lifted.clone();
    for ic in &mut through.initial {
        (ic.dz, ic.dy) = (ic.dy, 0.0);
    }
    let (_, z3) = run(&through, 2);
    let amp = y2.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    for (name, other) in [("lifted", &y3), ("plucked through the sheet", &z3)] {
        let worst = y2
            .iter()
            .zip(other)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(
            worst < 1e-9 * amp,
            "{name}: differs from the plane by {worst:e} m of {amp:e}"
        );
    }
    let f2 = zero_crossing_frequency(&t, &y2).unwrap();
    let f3 = zero_crossing_frequency(&t, &z3).unwrap();
    assert!((f3 / f2 - 1.0).abs() < 1e-9, "{f2} against {f3}");
}

/// The plucked paper fibre heard by a sensor 1.8 mm above it in a 3-D field, and by the
/// plane model's sensor in 2-D: the same tone (a field changes how loud the fibre is and how
/// it falls with distance, not the frequency it rings at).
#[test]
fn the_plucked_fibre_heard_in_space_rings_as_in_the_plane() {
    let plane = scenario::build("paper-fibre", &params(&[])).unwrap();
    let out2 = simulate(&plane, &SimOptions::default()).unwrap();
    let g2 = plane.grid.as_ref().unwrap();
    let p2 = aepipe::sim::output::band_limited(&out2.sensors[0], g2);
    let f2 = dominant_frequency(&p2, out2.sample_rate_hz);
    // A 3-D box around the fibre: ±2.5 mm × ±2.5 mm × ±2.16 mm at the plane grid's cell.
    let h = g2.dx();
    let g3 = GridSpec {
        x1: -35.0 * h,
        x2: 35.0 * h,
        y1: -35.0 * h,
        y2: 35.0 * h,
        nx: 70,
        ny: 70,
        z: Some(ZAxis {
            z1: -30.0 * h,
            z2: 30.0 * h,
            nz: 60,
        }),
        ..g2.clone()
    };
    let mut space = plane.clone();
    // Plucked through the sheet, heard from above.
    for ic in &mut space.initial {
        (ic.dz, ic.dy) = (ic.dy, 0.0);
    }
    network3d::lift(&mut space, &vec![0.0; plane.nodes.len()], Some(g3.clone()));
    let above = g3.cell(0.0, 0.0).unwrap();
    space.sensors = vec![SensorSpec {
        i: above.0,
        j: above.1,
        k: Some(30 + 25),
    }];
    let out3 = simulate(&space, &SimOptions::default()).unwrap();
    let p3 = aepipe::sim::output::band_limited(&out3.sensors[0], &g3);
    let f3 = dominant_frequency(&p3, out3.sample_rate_hz);
    assert!(p3.iter().any(|v| v.abs() > 0.0));
    assert!((f3 / f2 - 1.0).abs() < 0.01, "plane {f2} Hz, space {f3} Hz");
}

/// The layered network keeps the thesis's order of the mechanisms: at both sensors (on the
/// sheet's surface, and above it) a fibre failure's dominant frequency lies above a bond
/// failure's. And its frequencies are its fibres' own, not only in the right order. The
/// freed 1 mm span of the 3-D bond failure is the plane mesh's (the same fibre, 14 springs of
/// the same stiffness and mass, the same stretch), so at each 3-D sensor its dominant
/// frequency is one of the span's modes: the plane mesh's fundamental (heard at the plane's
/// sensor 1) times 1, or times sin(3π/28)/sin(π/28) = 2.950, the lumped string's third mode
/// in closed form (the even modes do not move the span's centre, where the bond failed).
/// The bound is half the record's 1/T (the resolution of a record of that length) on the
/// fundamental, times the mode number's ratio (measured: 696.6 and 701.5 kHz, the third mode
/// of the plane's 237.9 kHz). The plane structure's fibre failure rings in the thesis's
/// fibre-failure range, above 800 kHz, at both sensors; the layered one does not (below).
///
/// Plants: a 3-D bond failure heard at the plane fundamental × 2 (an even mode), or at
/// one record bin beyond 2.950 × f₁'s bound, fails the mode check (run by [`mode_of`] below).
#[test]
fn in_the_layered_network_each_mechanism_rings_at_its_fibres_modes() {
    let (plane, plane_t) = heard("mesh3x3-bond-failure", &[("t2", -1.0)], 2);
    let f1 = plane[0];
    let (bond, t3) = heard("network3d-bond-failure", &[], 3);
    let (fibre, _) = heard("network3d-fibre-failure", &[], 3);
    let (plane_fibre, _) = heard("structure2x1-fibre-failure", &[], 2);
    assert_eq!(bond.len(), 2);
    for (b, f) in bond.iter().zip(&fibre) {
        assert!(f > b, "bond {bond:?} Hz, fibre {fibre:?} Hz");
    }
    let ratio3 = (3.0 * std::f64::consts::PI / 28.0).sin() / (std::f64::consts::PI / 28.0).sin();
    let half_bin = 0.5 / plane_t.min(t3);
    eprintln!(
        "plane f1 {:.1} kHz (record {:.1} us); 3-D bond {:?} kHz (record {:.1} us); 3-D fibre {:?} kHz; plane fibre {:?} kHz; half bin {:.1} kHz",
        f1 / 1e3,
        plane_t * 1e6,
        khz(&bond),
        t3 * 1e6,
        khz(&fibre),
        khz(&plane_fibre),
        half_bin / 1e3
    );
    assert!((2.94..2.96).contains(&ratio3), "{ratio3}");
    for &b in &bond {
        assert!(
            mode_of(b, f1, ratio3, half_bin).is_some(),
            "3-D bond failure at {b} Hz: neither f1 = {f1} Hz nor {ratio3:.3} f1 (± {half_bin} Hz × the mode's ratio)"
        );
    }
    // Plants: an even mode, and one record bin beyond the third mode's bound.
    assert_eq!(mode_of(2.0 * f1, f1, ratio3, half_bin), None);
    assert_eq!(
        mode_of(
            ratio3 * f1 + (ratio3 + 2.0) * half_bin,
            f1,
            ratio3,
            half_bin
        ),
        None
    );
    assert_eq!(mode_of(ratio3 * f1, f1, ratio3, half_bin), Some(3));
    // The thesis's fibre-failure range starts at 800 kHz, and the plane structure's fibre
    // failure is inside it; the layered one is not. Written as a bound before its first run
    // (> 800 kHz), it failed: 765.7 and 797.2 kHz at sensors 1 and 2, 17 % and 12 % under the
    // plane structure's 925.6 and 909.3 kHz. That is recorded (docs/fidelity.md, "The third
    // dimension") and pinned here as a regression guard at the measured values, ± half a
    // bin: a pin, not a verdict.
    for &f in &plane_fibre {
        assert!(
            f > 800e3,
            "plane fibre failure at {f} Hz: under the thesis's 800 kHz"
        );
    }
    for (&f, pinned) in fibre.iter().zip([765.7e3, 797.2e3]) {
        assert!(
            (f - pinned).abs() <= half_bin,
            "3-D fibre failure at {f} Hz: the pin is {pinned} Hz ± {half_bin} Hz"
        );
        assert!(
            f < 800e3,
            "3-D fibre failure at {f} Hz: now inside the thesis's range; update the record"
        );
    }
}

/// Scenario `name` (its defaults, `p` set), a model of `dims` dimensions, simulated: each
/// sensor's band-limited dominant frequency, and the record's length (s).
fn heard(name: &str, p: &[(&str, f64)], dims: usize) -> (Vec<f64>, f64) {
    let m = scenario::build(name, &params(p)).unwrap();
    assert_eq!(m.dims(), dims, "{name}");
    let out = simulate(&m, &SimOptions::default()).unwrap();
    let g = m.grid.as_ref().unwrap();
    let f = out
        .sensors
        .iter()
        .map(|s| {
            let p = aepipe::sim::output::band_limited(s, g);
            dominant_frequency(&p, out.sample_rate_hz)
        })
        .collect();
    (f, out.sensors[0].len() as f64 / out.sample_rate_hz)
}

fn khz(f: &[f64]) -> Vec<f64> {
    f.iter().map(|x| (x / 1e2).round() / 10.0).collect()
}

/// Which of the freed span's two odd modes `f` is (1 or 3), within `half_bin` × the mode's
/// ratio of f₁ (the fundamental's uncertainty carries into its multiple).
fn mode_of(f: f64, f1: f64, ratio3: f64, half_bin: f64) -> Option<u32> {
    if (f - f1).abs() <= half_bin {
        Some(1)
    } else if (f - ratio3 * f1).abs() <= ratio3 * half_bin {
        Some(3)
    } else {
        None
    }
}

/// An Appendix-A file with z columns (nodes, initial conditions, forces, the grid's z axis,
/// a sensor's layer) reads as a 3-D model; what a third axis cannot mean is refused by name.
#[test]
fn a_model_file_with_z_columns_is_three_dimensional_and_checked() {
    let text = "Section System
x1 x2 y1 y2 dt damping gravity iters solver runwave stretch
-1e-3 1e-3 -1e-3 1e-3 1.0e-08 0.0 0.0 200 IEuler true true
End System
Section Nodes
Node x y z type m
0 -5.0E-04 0.0 0.0 1 5.1E-12
1 0.0 0.0 1.0E-06 0 5.1E-12
2 5.0E-04 0.0 0.0 1 5.1E-12
End Nodes
Section Springs
Spring N1 N2 E L t w P.Ratio Fibre Type
0 0 1 3.5E10 5.0E-04 2.8E-06 3.5E-05 0.28 0 0
1 1 2 3.5E10 5.0E-04 2.8E-06 3.5E-05 0.28 0 0
End Springs
Section Initial
Node dx dy dz du dv dw type
1 0.0 0.0 1.0e-06 0.0 0.0 0.0 0
End Initial
Section Grid
x1 x2 y1 y2 z1 z2 Nx Ny Nz dt rho c Method
-1.44e-3 1.44e-3 -1.44e-3 1.44e-3 -7.2e-4 7.2e-4 40 40 20 1e-7 1.25 350 acoustic04
End Grid
Section Sensor
X Y Z
20 20 15
20 10 -
End Sensor
";
    let d = crate::TempDir::new("sim3d-input");
    let p = d.path().join("m.txt");
    // The second sensor's "-" is not a layer: refused, naming the line.
    std::fs::write(&p, text).unwrap();
    let e = aepipe::sim::input::read_model(&p).unwrap_err().to_string();
    assert!(e.contains(":27:") && e.contains("Z"), "{e}");
    std::fs::write(&p, text.replace("20 10 -\n", "")).unwrap();
    let m = aepipe::sim::input::read_model(&p).unwrap();
    assert_eq!(m.dims(), 3);
    assert_eq!(m.nodes[1].z, Some(1e-6));
    assert_eq!(m.initial[0].dz, 1e-6);
    assert_eq!(m.grid.as_ref().unwrap().z.unwrap().nz, 20);
    assert_eq!(m.sensor_cell3(&m.sensors[0]), (20, 20, 15));
    let out = simulate(&m, &SimOptions::default()).unwrap();
    assert_eq!(out.sensors[0].len(), 20);
    // A sensor without a layer stands on the sheet's surface: the layer above the highest
    // mass (z = 1 µm lies in layer 10 of −0.72…0.72 mm in 72 µm cells).
    let mut surface = m.clone();
    surface.sensors[0].k = None;
    assert_eq!(surface.sensor_cell3(&surface.sensors[0]), (20, 20, 11));

    let refused = |m: &ModelFile, words: &str| {
        let e = m.check().unwrap_err().to_string();
        assert!(e.contains(words), "{e}");
    };
    // A plane model with a z displacement.
    let mut plane = scenario::build("paper-fibre", &params(&[])).unwrap();
    plane.initial[2].dz = 1e-6;
    refused(&plane, "need a 3-D model");
    // Heights without a z axis on the grid.
    let mut flat = m.clone();
    flat.grid.as_mut().unwrap().z = None;
    refused(&flat, "need a grid with a z axis");
    // Cells that are not cubes; a layer outside; a field over the cell cap (checked before
    // anything is allocated: 4 000³ cells would be 2 TB).
    let mut tall = m.clone();
    tall.grid.as_mut().unwrap().z.as_mut().unwrap().z2 = 1e-3;
    refused(&tall, "cubes");
    let mut high = m.clone();
    high.sensors[0].k = Some(20);
    refused(&high, "outside the grid's 20 layers");
    let mut huge = m.clone();
    {
        let g = huge.grid.as_mut().unwrap();
        let h = g.dx();
        (g.nx, g.ny) = (4000, 4000);
        (g.x2, g.y2) = (g.x1 + 4000.0 * h, g.y1 + 4000.0 * h);
        let z = g.z.as_mut().unwrap();
        z.nz = 4000;
        z.z2 = z.z1 + 4000.0 * h;
    }
    refused(&huge, "exceed the limit");
}

/// A reference library can hold the 3-D scenarios (issue 51: references from another model):
/// a definition naming `network3d-bond-failure` builds, its signals labelled with the
/// mechanism and heard at the given cell on the sheet's surface (the 3-D grid's own cells:
/// (62, 37) is 1.8 mm from the zone's centre, as the plane library's first sensor); an
/// unknown name is refused listing the plane and the 3-D scenarios.
#[test]
fn a_reference_library_holds_the_3d_scenarios() {
    use aepipe::sim::reference::{build_library, ReferenceFile};
    let d = crate::TempDir::new("sim3d-ref");
    let cfg = d.path().join("lib3d.toml");
    std::fs::write(
        &cfg,
        "[reference]\nsensors = [[62, 37]]\nscale_v_per_pa = 3e-3\n\
         [[reference.scenario]]\nname = \"network3d-bond-failure\"\nparams = { iterations = [3000] }\n",
    )
    .unwrap();
    let f = ReferenceFile::read(&cfg).unwrap();
    let (runs, signals, _) = build_library(&f.reference, &d.path().join("lib"), false).unwrap();
    assert_eq!((runs, signals), (1, 1));
    let wf = d.path().join("lib/waveforms.parquet");
    let (names, rows) = crate::table_rows(&wf);
    let col = |n: &str| names.iter().position(|x| x == n).unwrap();
    assert_eq!(rows[0][col("label")], "bond_failure");
    // On the sheet's surface (the first cell layer above it; the six layers of fibre are
    // 17 µm thick), 1.8 mm (25 cells of 72 µm) from the centre along −y.
    let y: f64 = rows[0][col("sensor_y_m")].parse().unwrap();
    let z: f64 = rows[0][col("sensor_z_m")].parse().unwrap();
    assert!((y + 1.8e-3).abs() < 0.5 * 72e-6, "y {y}");
    assert!(z > 17e-6 && z < 2.0 * 72e-6, "z {z}");
    std::fs::write(
        &cfg,
        "[reference]\n[[reference.scenario]]\nname = \"network3d-mesh\"\n",
    )
    .unwrap();
    let e = ReferenceFile::read(&cfg).unwrap_err().to_string();
    assert!(
        e.contains("unknown scenario") && e.contains("network3d-fibre-failure"),
        "{e}"
    );
}

/// Issue 51 item 5: `pipelines/reference-library-3d.toml` hears its 3-D signals where the
/// plane library hears its own — the same distances and directions from the damage zone, to
/// within a cell — or the cross-model table compares models *and* sensor places. Its grid
/// (`cells`) must hold every sensor, and `cells` outside 60–401 is refused by name.
#[test]
fn the_3d_library_hears_where_the_plane_library_does() {
    use aepipe::sim::network3d::grid3_across;
    use aepipe::sim::reference::{library_sensors, ReferenceFile};
    use aepipe::sim::scenario::paper_grid;
    let plane = ReferenceFile::default_library().reference;
    let lib3 = ReferenceFile::library_3d().reference;
    let cells: Vec<f64> = lib3
        .scenario
        .iter()
        .map(|s| {
            let v = s.params.get("cells");
            let v = v.unwrap_or_else(|| panic!("{} names no cells", s.name));
            assert_eq!(v.len(), 1, "{}", s.name);
            v[0]
        })
        .collect();
    assert!(cells.iter().all(|&c| c == cells[0]), "{cells:?}");
    let (g2, g3) = (paper_grid(), grid3_across(cells[0] as usize));
    assert_eq!(plane.sensors.len(), lib3.sensors.len());
    let s2 = library_sensors(&plane.sensors, &g2);
    let s3 = library_sensors(&lib3.sensors, &g3);
    for (a, b) in s2.iter().zip(&s3) {
        assert!(
            b.i < g3.nx && b.j < g3.ny,
            "sensor ({}, {}) outside",
            b.i,
            b.j
        );
        let (pa, pb) = (g2.centre(a.i, a.j), g3.centre(b.i, b.j));
        let d = ((pa.0 - pb.0).powi(2) + (pa.1 - pb.1).powi(2)).sqrt();
        assert!(d <= 72e-6, "plane {pa:?} vs 3-D {pb:?}: {d} m apart");
    }
    for bad in ["59", "125.5", "402"] {
        let p = aepipe::sim::scenario::Params(vec![("cells".into(), bad.parse().unwrap())]);
        let e = aepipe::sim::scenario::build("network3d-fibre-failure", &p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("cells"), "{bad}: {e}");
    }
}
