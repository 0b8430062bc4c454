//! `series.parquet`: a lab's tests side by side, one row per experiment — how many hits,
//! how many have load, the peak load, what the SOM's classes and the clusters say, and the
//! energy exponent. The rows are gathered from a run's tables by `workflow`; here are the
//! table, its row and the terminal's lines.

use crate::model::columns as cols;
use crate::store::{ColType, ColumnSpec, Table, Value};
use std::path::PathBuf;

/// One experiment of a run.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SeriesRow {
    pub experiment: String,
    pub hits: u64,
    pub rejects: u64,
    pub hits_with_load: u64,
    pub peak_load_n: Option<f64>,
    pub peak_load_s: Option<f64>,
    /// Hits the SOM classified, and the share of them unlike the map's references.
    pub classified: Option<u64>,
    pub unlike_references_share: Option<f64>,
    /// Hits per SOM class, in the order of [`Series::classes`].
    pub classes: Vec<Option<u64>>,
    /// Distinct clusters among the experiment's hits (`[cluster] enabled`).
    pub clusters: Option<u64>,
    /// Sources with a positive energy, and the energy exponent (null below the power law's
    /// minimum tail, `statistics.parquet`).
    pub energy_n: u64,
    pub alpha: Option<f64>,
    /// Significant trend rows (null: the trend stage did not run), and why a series of the
    /// experiment states none (`n = 3: too few hits for a trend`).
    pub significant_trends: Option<u64>,
    pub trend_note: Option<String>,
}

/// The series table of a run: its rows and the classes that have a column.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Series {
    pub classes: Vec<String>,
    pub clustering: bool,
    pub rows: Vec<SeriesRow>,
    pub path: PathBuf,
}

/// `series.parquet` with one `<class>_hits` column per class and `clusters` when clustering
/// ran.
pub fn series_table(classes: &[String], clustering: bool) -> Table<SeriesRow> {
    let f = |n: &str, u: &str, d: &str| ColumnSpec::new(n, ColType::Float64, u, d).nullable();
    let i = |n: &str, d: &str| ColumnSpec::new(n, ColType::Int64, "", d);
    let mut t = Table::new("series")
        .col(ColumnSpec::of(cols::EXPERIMENT, "", "experiment id"), |r: &SeriesRow| Value::Str(Some(r.experiment.clone())))
        .col(i("hits", "rows of hits.parquet"), |r| Value::I64(Some(r.hits as i64)))
        .col(i("rejects", "reject rows (any record type)"), |r| Value::I64(Some(r.rejects as i64)))
        .col(i("hits_with_load", "hits with a load_n (inside the machine log's or load file's span)"), |r| Value::I64(Some(r.hits_with_load as i64)))
        .col(f("peak_load_n", "N", "the largest load of parametric.parquet (else of the hits); null: no load"), |r| Value::F64(r.peak_load_n))
        .col(f("peak_load_s", "s", "when the peak load was reached, AE clock"), |r| Value::F64(r.peak_load_s))
        .col(i("classified", "hits the SOM classified; null: no SOM stage").nullable(), |r| Value::I64(r.classified.map(|v| v as i64)))
        .col(f("unlike_references_share", "1", "share of the classified hits whose som_label is unlike_references (like none of the map's references); above 0.5 the map's classes do not describe the test"), |r| Value::F64(r.unlike_references_share));
    for (k, c) in classes.iter().enumerate() {
        t = t.col(
            i(
                &format!("{c}_hits"),
                &format!("hits the SOM classified {c}"),
            )
            .nullable(),
            move |r: &SeriesRow| Value::I64(r.classes.get(k).copied().flatten().map(|v| v as i64)),
        );
    }
    if clustering {
        t = t.col(
            i("clusters", "distinct clusters among the experiment's hits").nullable(),
            |r| Value::I64(r.clusters.map(|v| v as i64)),
        );
    }
    t.col(i("energy_n", "sources with a positive energy_eu (statistics.parquet n_energy)"), |r| Value::I64(Some(r.energy_n as i64)))
        .col(f("alpha", "1", "energy exponent of p(E) ∝ E^−α (statistics.parquet energy_alpha); null with fewer than 50 energies, the power law's minimum tail"), |r| Value::F64(r.alpha))
        .col(i("significant_trends", "significant rows of trend.parquet; null: no trend stage").nullable(), |r| Value::I64(r.significant_trends.map(|v| v as i64)))
        .col(ColumnSpec::new("trend_note", ColType::Utf8, "", "why a series of the experiment states no trend (n below trend.min_hits)").nullable(), |r| Value::Str(r.trend_note.clone()))
}

/// The classes the default reference map labels (the schema page's example columns).
pub fn default_classes() -> Vec<String> {
    crate::model::Mechanism::ALL
        .iter()
        .filter(|m| **m != crate::model::Mechanism::Unclassified)
        .map(|m| m.as_str().to_string())
        .collect()
}

/// The terminal's table of the series, for up to `max` tests.
pub fn series_lines(s: &Series, max: usize) -> Vec<String> {
    if s.rows.len() > max {
        return vec![format!(
            "series: {} tests, side by side in {}",
            s.rows.len(),
            s.path.display()
        )];
    }
    let opt = |v: Option<f64>, d: usize| v.map_or("–".to_string(), |v| format!("{v:.d$}"));
    let mut head = format!(
        "{:<16} {:>6} {:>6} {:>10} {:>8} {:>7}",
        "series", "hits", "load", "peak N", "at s", "unlike"
    );
    for c in &s.classes {
        head += &format!(" {:>9}", short(c));
    }
    if s.clustering {
        head += &format!(" {:>8}", "clusters");
    }
    head += &format!(" {:>6}", "alpha");
    let mut l = vec![head];
    for r in &s.rows {
        let mut line = format!(
            "{:<16} {:>6} {:>6} {:>10} {:>8} {:>7}",
            r.experiment,
            r.hits,
            r.hits_with_load,
            opt(r.peak_load_n, 1),
            opt(r.peak_load_s, 1),
            r.unlike_references_share
                .map_or("–".to_string(), |v| format!("{:.0} %", 100.0 * v))
        );
        for v in &r.classes {
            line += &format!(" {:>9}", v.map_or("–".to_string(), |v| v.to_string()));
        }
        if s.clustering {
            line += &format!(
                " {:>8}",
                r.clusters.map_or("–".to_string(), |v| v.to_string())
            );
        }
        line += &format!(" {:>6}", opt(r.alpha, 2));
        l.push(line);
    }
    l
}

/// A class name cut to a column's width.
fn short(c: &str) -> String {
    c.chars().take(9).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default map's classes are the `<class>_hits` columns the committed schema page
    /// (data-schema/series.md) documents, in the mechanisms' order. Plants (cargo mutants):
    /// an empty list, an empty or a made-up name, and the filter inverted each fail it.
    #[test]
    fn the_default_classes_are_the_schema_pages_columns() {
        let page = include_str!("../../data-schema/series.md");
        let documented: Vec<&str> = page
            .lines()
            .filter_map(|l| {
                l.strip_prefix("| `")?
                    .split_once("_hits` |")
                    .map(|(c, _)| c)
            })
            .collect();
        assert_eq!(documented.len(), 4, "{documented:?}");
        assert_eq!(default_classes(), documented);
    }

    fn row() -> SeriesRow {
        SeriesRow {
            experiment: "EXP1".into(),
            hits: 12,
            rejects: 2,
            hits_with_load: 3,
            peak_load_n: Some(1950.0),
            peak_load_s: Some(19.5),
            classified: Some(10),
            unlike_references_share: Some(0.3),
            classes: vec![Some(4), None],
            clusters: Some(3),
            energy_n: 11,
            alpha: Some(1.654),
            significant_trends: Some(2),
            trend_note: Some("ch1: n = 3".into()),
        }
    }

    fn classes() -> Vec<String> {
        vec!["bond_failure".into(), "both".into()]
    }

    /// The columns of a table, each with the cell a row gives it.
    fn cells(t: &Table<SeriesRow>, r: SeriesRow) -> Vec<(String, Value)> {
        let names = t.schema().columns.into_iter().map(|c| c.name);
        names.zip(t.row(r).cells().to_vec()).collect()
    }

    /// What [`row`] must give, column by column (worked out from its fields by hand).
    fn expected(clustering: bool) -> Vec<(String, Value)> {
        let s = |v: &str| Value::Str(Some(v.into()));
        let mut want = vec![
            ("experiment", s("EXP1")),
            ("hits", Value::I64(Some(12))),
            ("rejects", Value::I64(Some(2))),
            ("hits_with_load", Value::I64(Some(3))),
            ("peak_load_n", Value::F64(Some(1950.0))),
            ("peak_load_s", Value::F64(Some(19.5))),
            ("classified", Value::I64(Some(10))),
            ("unlike_references_share", Value::F64(Some(0.3))),
            ("bond_failure_hits", Value::I64(Some(4))),
            ("both_hits", Value::I64(None)),
            ("clusters", Value::I64(Some(3))),
            ("energy_n", Value::I64(Some(11))),
            ("alpha", Value::F64(Some(1.654))),
            ("significant_trends", Value::I64(Some(2))),
            ("trend_note", s("ch1: n = 3")),
        ];
        if !clustering {
            want.retain(|(n, _)| *n != "clusters");
        }
        want.into_iter().map(|(n, v)| (n.to_string(), v)).collect()
    }

    /// Each column holds its own field, one `<class>_hits` per class in order (null past the
    /// row's counts), `clusters` only with clustering. Plant: a row whose `rejects` and
    /// `energy_n` are swapped fails the same comparison.
    #[test]
    fn each_column_holds_its_field() {
        for clustering in [true, false] {
            let t = series_table(&classes(), clustering);
            assert_eq!(cells(&t, row()), expected(clustering));
        }
        let t = series_table(&classes(), true);
        let mut r = row();
        r.classes.clear();
        let got = cells(&t, r);
        assert_eq!(got[8], ("bond_failure_hits".into(), Value::I64(None)));
        let planted = SeriesRow {
            rejects: 11,
            energy_n: 2,
            ..row()
        };
        assert_ne!(cells(&t, planted), expected(true));
    }

    /// The terminal's table of two tests, one of them all nulls, as it must read; more tests
    /// than `max` name the file instead.
    #[test]
    fn the_terminal_table_reads_as_worked_out() {
        let empty = SeriesRow {
            experiment: "EXP2".into(),
            hits: 5,
            classes: vec![None, None],
            ..Default::default()
        };
        let s = Series {
            classes: classes(),
            clustering: true,
            rows: vec![row(), empty],
            path: PathBuf::from("/run/series.parquet"),
        };
        assert_eq!(
            series_lines(&s, 20),
            [
                "series             hits   load     peak N     at s  unlike bond_fail      both clusters  alpha",
                "EXP1                 12      3     1950.0     19.5    30 %         4         –        3   1.65",
                "EXP2                  5      0          –        –       –         –         –        –      –",
            ]
        );
        assert_eq!(
            series_lines(&s, 1),
            ["series: 2 tests, side by side in /run/series.parquet"]
        );
        // Up to `max` tests is a table: exactly two at max 2 (plant: `>=` gives the summary).
        assert_eq!(series_lines(&s, 2), series_lines(&s, 20));
        let s = Series {
            clustering: false,
            ..s
        };
        assert!(!series_lines(&s, 20)[0].contains("clusters"));
    }
}
