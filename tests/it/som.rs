//! The SOM workflow on feature tables (ch. 5.4): balanced training set, classification,
//! confusion report, model files.

use crate::{table_rows, TempDir};
use aepipe::som::classify::classify_tables as classify;
use aepipe::som::tables::{load_model, train, TrainOptions};
use aepipe::som::Som;

#[test]
fn som_trained_on_criteria_labels_classifies_the_experiment() {
    let t = TempDir::new("som");
    let features = crate::synthetic_features(
        t.path(),
        "notched",
        400,
        31,
        &aepipe::config::ValidConfig::default(),
        2,
    );
    let model_dir = t.path().join("model");
    let m = train(
        std::slice::from_ref(&features),
        &model_dir,
        &TrainOptions::default(),
    )
    .unwrap();
    // Balanced: every trained class has the same number of rows; ~10 % of 400 hits.
    let rows: Vec<usize> = m.composition.values().map(|c| c.1).collect();
    assert!(rows.windows(2).all(|w| w[0] == w[1]), "{:?}", m.composition);
    assert!(
        (36..=44).contains(&rows.iter().sum::<usize>()),
        "{:?}",
        m.composition
    );
    assert!(!m.composition.contains_key("erroneous"));
    for f in ["model.json", "model.cod", "train.dat"] {
        assert!(model_dir.join(f).exists(), "{f}");
    }
    // Classify every hit against the criteria labels.
    let back = load_model(&model_dir).unwrap();
    assert!(back == m, "model.json does not round-trip exactly");
    let out = t.path().join("c");
    let conf = classify(
        &back,
        std::slice::from_ref(&features),
        Some("criteria_label"),
        &out,
        Default::default(),
        aepipe::som::classify::ClassifyRules {
            read: aepipe::config::ReadErroneous::Map,
            ..Default::default()
        },
    )
    .unwrap();
    let acc = conf.accuracy().unwrap();
    assert!(acc > 0.85, "accuracy {acc}\n{}", conf.format());
    // Of the mechanisms it was trained on, bond vs fibre failures are told apart.
    let get = |a: &str, b: &str| {
        conf.counts
            .get(&(a.to_string(), b.to_string()))
            .copied()
            .unwrap_or(0)
    };
    assert_eq!(
        get("bond_failure", "fibre_failure") + get("fibre_failure", "bond_failure"),
        0,
        "{}",
        conf.format()
    );
    // The table matches its schema file and holds every hit.
    let (names, rows) = table_rows(&out.join("classification.parquet"));
    let doc = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/data-schema/classification.md"
    ))
    .unwrap();
    let cols: Vec<String> = aepipe::store::parse_schema_markdown(&doc)
        .into_iter()
        .map(|c| c.0)
        .collect();
    assert_eq!(names, cols);
    assert_eq!(rows.len(), 400);
    // The SOM_PAK codebook gives the same classification as the JSON model.
    let cod =
        Som::from_cod(&std::fs::read_to_string(model_dir.join("model.cod")).unwrap()).unwrap();
    assert_eq!(cod.labels, m.som.labels);
    let w: Vec<f64> = cod
        .weights
        .iter()
        .zip(&m.som.weights)
        .map(|(a, b)| (a - b).abs())
        .collect();
    assert!(w.iter().all(|d| *d < 1e-12), "cod weights differ");
}

/// A SOM_PAK codebook is read: the `.cod` aepipe wrote classifies exactly as `model.json`
/// does (weights are written as `{:e}`, the shortest form that reads back equal), and a
/// codebook relabelled outside aepipe changes the classes.
#[test]
fn som_pak_codebook_classifies_like_the_model_and_carries_its_labels() {
    let t = TempDir::new("som-cod");
    let features = crate::synthetic_features(
        t.path(),
        "cod",
        200,
        8,
        &aepipe::config::ValidConfig::default(),
        2,
    );
    let dir = t.path().join("model");
    let m = train(
        std::slice::from_ref(&features),
        &dir,
        &TrainOptions::default(),
    )
    .unwrap();
    let from_cod = load_model(&dir.join("model.cod")).unwrap();
    assert_eq!(from_cod.som.weights, m.som.weights);
    assert_eq!(from_cod.som.labels, m.som.labels);
    // (som_label, novel) per row.
    let read = |model: &aepipe::som::tables::Model, out: &str| -> Vec<(String, String)> {
        let o = t.path().join(out);
        classify(
            model,
            std::slice::from_ref(&features),
            None,
            &o,
            Default::default(),
            Default::default(),
        )
        .unwrap();
        let (names, rows) = table_rows(&o.join("classification.parquet"));
        let k = |c: &str| names.iter().position(|n| n == c).unwrap();
        rows.into_iter()
            .map(|r| (r[k("som_label")].clone(), r[k("novel")].clone()))
            .collect()
    };
    let classes = |model: &aepipe::som::tables::Model, out: &str| -> Vec<String> {
        read(model, out).into_iter().map(|r| r.0).collect()
    };
    // The trained map carries its novelty calibration; a codebook does not, so its rows'
    // `novel` is null and a hit the trained map calls unlike the references keeps its
    // node's class. Every other hit is classed alike.
    assert!(m.novelty.is_some() && from_cod.novelty.is_none());
    let a_rows = read(&m, "a");
    let b_rows = read(&from_cod, "b");
    assert!(a_rows.iter().all(|r| r.1 == "true" || r.1 == "false"));
    assert!(b_rows.iter().all(|r| r.1.is_empty()), "{:?}", &b_rows[..3]);
    assert_eq!(a_rows.len(), b_rows.len());
    for (x, y) in a_rows.iter().zip(&b_rows) {
        if x.1 == "true" {
            assert_eq!(x.0, "unlike_references");
        } else {
            assert_eq!(x.0, y.0);
        }
    }
    let a = classes(&from_cod, "b2");
    // Every node relabelled "x" in the text, as a SOM_PAK user would edit it.
    let text = std::fs::read_to_string(dir.join("model.cod")).unwrap();
    let relabelled: String = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i == 0 {
                format!("{l}\n")
            } else {
                let mut w: Vec<&str> = l.split_whitespace().collect();
                w.pop();
                format!("{} x\n", w.join(" "))
            }
        })
        .collect();
    std::fs::write(dir.join("edited.cod"), relabelled).unwrap();
    let edited = load_model(&dir.join("edited.cod")).unwrap();
    let c = classes(&edited, "c");
    assert_eq!(c.len(), a.len());
    assert!(c.iter().all(|x| x == "x"), "{:?}", &c[..3]);
}
