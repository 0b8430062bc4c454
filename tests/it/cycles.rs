//! Load–unload–reload: a synthetic test of four cycles whose truth states where AE resumes
//! on each reload (Felicity ratios 1.0, 0.9, 0.8 by design), and whose energies follow a
//! stated power law; the run recovers both from the recordings alone.

use crate::TempDir;

/// A column of a table as floats (nulls as NaN), by name.
fn floats(path: &std::path::Path, col: &str) -> Vec<f64> {
    let (names, rows) = crate::table_rows(path);
    let i = names
        .iter()
        .position(|n| n == col)
        .unwrap_or_else(|| panic!("{col}"));
    rows.iter()
        .map(|r| r[i].parse().unwrap_or(f64::NAN))
        .collect()
}

#[test]
fn felicity_ratios_and_the_energy_exponent_of_a_synthetic_cyclic_test() {
    let d = TempDir::new("cycles");
    // Held out: the map's library and the test's are built with different seeds.
    let train = crate::e2e::small_library_seeded(d.path(), "train-lib", 21, 2);
    let lib = crate::e2e::small_library_seeded(d.path(), "exp-lib", 22, 2);
    let shape = aepipe::synth::Shape {
        cycles: 4,
        energy_exponent: Some(1.6),
        ..Default::default()
    };
    aepipe::synth::synth_test(d.path(), "cyc", 700, 31, shape, Some(&lib), false).unwrap();
    let mut cfg = aepipe::demo::demo_config().into_inner();
    cfg.som.reference_library = Some(train);
    cfg.report.enabled = false;
    cfg.cluster.enabled = false;
    let cfg = cfg.check().unwrap();
    let out = d.path().join("run");
    aepipe::workflow::run(&aepipe::workflow::RunJob::new(
        &cfg,
        &[d.path().join("data")],
        &out,
        2,
    ))
    .unwrap();

    // The truth: four cycles; the first hit of a specimen source in each and its load.
    let truth = d.path().join("truth_cycles.parquet");
    crate::pipeline::check_against_schema_file(&truth, "truth_cycles.md");
    let t_prev = floats(&truth, "previous_max_n");
    let t_first = floats(&truth, "first_hit_load_n");
    let t_design = floats(&truth, "felicity_ratio");
    let t_peak = floats(&truth, "peak_load_n");
    let t_start = floats(&truth, "start_s");
    assert_eq!(t_design.len(), 4);
    assert!(t_design[0].is_nan());
    for (k, want) in [(1, 1.0), (2, 0.9), (3, 0.8)] {
        assert!((t_design[k] - want).abs() < 1e-12, "{t_design:?}");
    }

    // The run's cycles, found in the test machine's series: the same corners.
    let cycles = out.join("som").join("cycles.parquet");
    crate::pipeline::check_against_schema_file(&cycles, "cycles.md");
    let (names, rows) = crate::table_rows(&cycles);
    let class = names.iter().position(|n| n == "class").unwrap();
    let all: Vec<usize> = (0..rows.len())
        .filter(|&i| rows[i][class] == "all")
        .collect();
    assert_eq!(all.len(), 4, "{rows:?}");
    let got = |col: &str| -> Vec<f64> {
        let v = floats(&cycles, col);
        all.iter().map(|&i| v[i]).collect()
    };
    let (start, peak, ratio) = (got("start_s"), got("peak_load_n"), got("felicity_ratio"));
    let kaiser_col = names.iter().position(|n| n == "kaiser").unwrap();
    for k in 0..4 {
        assert!(
            (start[k] - t_start[k]).abs() <= 0.1 + 1e-9,
            "cycle {k}: {start:?}"
        );
        assert!((peak[k] - t_peak[k]).abs() < 0.01, "cycle {k}: {peak:?}");
    }
    assert!(ratio[0].is_nan(), "a first loading has no Felicity ratio");
    // Each reload's ratio: the load at the first specimen hit over the previous maximum
    // (the load interpolated at the hit from the 10 Hz series, quantised to 1 mN), never
    // below the designed ratio; the Kaiser effect exactly where it reaches 1.
    for k in 1..4 {
        let want = t_first[k] / t_prev[k];
        assert!(
            (ratio[k] - want).abs() < 1e-4,
            "cycle {k}: {ratio:?} vs {want}"
        );
        assert!(ratio[k] >= t_design[k] - 1e-4, "cycle {k}: {ratio:?}");
        let kaiser = &rows[all[k]][kaiser_col];
        assert_eq!(kaiser == "true", ratio[k] >= 1.0, "cycle {k}: {kaiser}");
    }
    assert_eq!(
        rows[all[1]][kaiser_col], "true",
        "the first reload resumes at its maximum"
    );
    assert_eq!(rows[all[3]][kaiser_col], "false");

    // evolution.parquet carries the same ratios on the onset rows of the `all` series.
    let evo = out.join("som").join("evolution.parquet");
    crate::pipeline::check_against_schema_file(&evo, "evolution.md");
    let (en, er) = crate::table_rows(&evo);
    let ec = en.iter().position(|n| n == "class").unwrap();
    let fr = floats(&evo, "felicity_ratio");
    let onsets: Vec<f64> = (0..er.len())
        .filter(|&i| er[i][ec] == "all" && !fr[i].is_nan())
        .map(|i| fr[i])
        .collect();
    assert_eq!(onsets, ratio[1..].to_vec());

    // The energies' exponent, within three of its standard errors.
    let stats = out.join("statistics.parquet");
    let alpha = floats(&stats, "energy_alpha")[0];
    let se = floats(&stats, "energy_alpha_se")[0];
    assert!(se > 0.0 && se < 0.05, "{se}");
    assert!((alpha - 1.6).abs() <= 3.0 * se, "α = {alpha} ± {se}");
}
