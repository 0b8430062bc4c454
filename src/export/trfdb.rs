//! `aepipe export trfdb`: a VisualAE transient-feature database per Vallen experiment, a
//! CSV per experiment of the other systems.
//!
//! The `.trfdb` is laid out as vallenae 0.14's `TrfDatabase.create` lays one out (its
//! `trfdb.sql`: `trf_data` with `TRAI INT UNIQUE` and REAL feature columns,
//! `trf_fieldinfo` with field, SetTypes, Unit, LongName, Description, ShortName,
//! FormatStr, and `trf_globalinfo` with Version 1, FileStatus 0, WriterID, ValidSets), with
//! `ReferenceID` set to the `.pridb`'s `FileID` as VisualAE's own `.trfdb` has it. The name
//! `<experiment>.aepipe.trfdb` never collides with the lab's `<experiment>.trfdb`, and an
//! existing file of that name is replaced only when asked.

use super::table::{power_ratio_names, FeatureRow, Results};
use super::ExportError;
use crate::model::columns as cols;
use crate::store::read::{HitKey, TableScan};
use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};

/// The tables an export reads: a run's features, and the results that exist.
#[derive(Debug, Clone)]
pub struct RunTables {
    pub features: PathBuf,
    /// hits.parquet: the vendor's hit numbers and the acquisitions.
    pub hits: Option<PathBuf>,
    pub classification: Option<PathBuf>,
    pub clusters: Option<PathBuf>,
    pub events: Option<PathBuf>,
}

/// One file written.
#[derive(Debug, Clone, PartialEq)]
pub struct Exported {
    pub experiment: String,
    pub path: PathBuf,
    pub rows: u64,
}

/// What an export wrote, and what it left out and why.
#[derive(Debug, Clone, Default)]
pub struct ExportSummary {
    pub files: Vec<Exported>,
    pub notes: Vec<String>,
}

/// Where a row goes.
enum Sink {
    Trfdb {
        conn: rusqlite::Connection,
        tmp: PathBuf,
        path: PathBuf,
        /// The row insert, written once for the export's columns.
        insert: String,
        rows: u64,
        /// Rows of a later acquisition (their TRAI repeats the first's): left out.
        later: u64,
    },
    Csv {
        w: Box<csv::Writer<std::fs::File>>,
        tmp: PathBuf,
        path: PathBuf,
        rows: u64,
    },
}

/// Export every experiment of `t` into `out`: `<experiment>.aepipe.trfdb` for a Vallen
/// pair (keyed by TRAI), `<experiment>.aepipe.csv` for the others (keyed by aepipe's hit,
/// with the vendor's hit number and file). An existing output is an error unless `force`.
pub fn export(t: &RunTables, out: &Path, force: bool) -> Result<ExportSummary, ExportError> {
    let scan = TableScan::open(&t.features)?;
    let ratios = power_ratio_names(&scan.column_names());
    let mut names: Vec<&str> = vec![
        cols::EXPERIMENT.name,
        cols::CHANNEL.name,
        cols::HIT.name,
        "source_file",
        cols::CRITERIA_LABEL.name,
        "crack_mode",
        "ra_ms_per_v",
        "af_khz",
        cols::EVENT.name,
        cols::ZONE.name,
    ];
    names.extend(ratios.iter().map(String::as_str));
    scan.require(&names, "an export")?;
    let res = Results::read(
        t.classification.as_deref(),
        t.clusters.as_deref(),
        t.events.as_deref(),
        &ratios,
    )?;
    let hits = t
        .hits
        .as_deref()
        .map(read_hits)
        .transpose()?
        .unwrap_or_default();
    std::fs::create_dir_all(out).map_err(|e| crate::util::IoAt::new(out, e))?;
    let mut sinks: BTreeMap<String, Sink> = BTreeMap::new();
    for batch in scan.batches(&names) {
        let (_, df) = batch?;
        let keys = scan.hit_keys(&df)?;
        let text = |n: &str| scan.strings(&df, n);
        let (src, crit, crack, zone) = (
            text("source_file")?,
            text(cols::CRITERIA_LABEL.name)?,
            text("crack_mode")?,
            text(cols::ZONE.name)?,
        );
        let (ra, af) = (scan.f64s(&df, "ra_ms_per_v")?, scan.f64s(&df, "af_khz")?);
        let event = scan.i64s(&df, cols::EVENT)?;
        let pr: Vec<Vec<Option<f64>>> = ratios
            .iter()
            .map(|n| scan.f64s(&df, n))
            .collect::<Result<_, _>>()?;
        for (i, key) in keys.iter().enumerate() {
            let f = FeatureRow {
                source_file: src[i].clone().unwrap_or_default(),
                criteria: crit[i].clone(),
                crack: crack[i].clone(),
                ra: ra[i],
                af: af[i],
                event: event[i],
                zone: zone[i].clone(),
                ratios: pr.iter().map(|c| c[i]).collect(),
            };
            let sink = match sinks.get_mut(&key.0) {
                Some(s) => s,
                None => {
                    let s = open_sink(&key.0, &f.source_file, out, force, &res)?;
                    sinks.entry(key.0.clone()).or_insert(s)
                }
            };
            write_row(sink, key, &f, &res, &hits)?;
        }
    }
    let mut summary = ExportSummary::default();
    for (experiment, sink) in sinks {
        finish(experiment, sink, &mut summary)?;
    }
    Ok(summary)
}

/// What hits.parquet says of each transient: its acquisition and the vendor's hit number.
#[derive(Debug, Default)]
struct HitInfo {
    /// (experiment, transient) of a later acquisition.
    later: HashSet<(String, i64)>,
    /// (experiment, channel, transient) → the system's hit number.
    vendor_hit: std::collections::HashMap<HitKey, i64>,
}

fn read_hits(path: &Path) -> Result<HitInfo, crate::store::StoreError> {
    let t = TableScan::open(path)?;
    let df = t.columns(&[
        cols::EXPERIMENT.name,
        cols::CHANNEL.name,
        cols::HIT.name,
        "acquisition",
        cols::TRANSIENT.name,
    ])?;
    let keys = t.hit_keys(&df)?;
    let acq = t.f64s(&df, "acquisition")?;
    let tr = t.i64s(&df, cols::TRANSIENT)?;
    let mut info = HitInfo::default();
    for (i, (e, ch, hit)) in keys.into_iter().enumerate() {
        let Some(tr) = tr[i] else { continue };
        if acq[i].is_some_and(|a| a > 1.0) {
            info.later.insert((e.clone(), tr));
        }
        info.vendor_hit.insert((e, ch, tr), hit);
    }
    Ok(info)
}

/// An experiment id as a file name (characters other than letters, digits, `-`, `_` and
/// `.` become `_`).
fn file_safe(experiment: &str) -> String {
    experiment
        .chars()
        .map(|c| match c.is_ascii_alphanumeric() || "-_.".contains(c) {
            true => c,
            false => '_',
        })
        .collect()
}

fn is_vallen(source_file: &str) -> bool {
    Path::new(source_file)
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("tradb"))
}

fn sqlite_err(path: &Path) -> impl Fn(rusqlite::Error) -> ExportError + '_ {
    move |e| ExportError::Sqlite {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

fn open_sink(
    experiment: &str,
    source_file: &str,
    out: &Path,
    force: bool,
    res: &Results,
) -> Result<Sink, ExportError> {
    let vallen = is_vallen(source_file);
    let name = format!(
        "{}.aepipe.{}",
        file_safe(experiment),
        if vallen { "trfdb" } else { "csv" }
    );
    let path = out.join(name);
    if path.exists() && !force {
        return Err(ExportError::Exists {
            path: path.display().to_string(),
        });
    }
    let tmp = path.with_extension("tmp");
    let _ = std::fs::remove_file(&tmp);
    if !vallen {
        let mut w = csv::Writer::from_path(&tmp).map_err(|e| ExportError::Csv {
            path: tmp.display().to_string(),
            message: e.to_string(),
        })?;
        let mut header = vec!["hit".to_string(), "vendor_hit".into(), "source_file".into()];
        header.extend(res.columns().map(|c| c.field.clone()));
        w.write_record(&header).map_err(|e| ExportError::Csv {
            path: tmp.display().to_string(),
            message: e.to_string(),
        })?;
        return Ok(Sink::Csv {
            w: Box::new(w),
            tmp,
            path,
            rows: 0,
        });
    }
    let conn = rusqlite::Connection::open(&tmp).map_err(sqlite_err(&tmp))?;
    create_schema(&conn, res, source_file).map_err(sqlite_err(&tmp))?;
    conn.execute_batch("BEGIN").map_err(sqlite_err(&tmp))?;
    let names: Vec<String> = res.columns().map(|c| format!("\"{}\"", c.field)).collect();
    let marks = vec!["?"; names.len() + 1].join(", ");
    let insert = format!(
        "INSERT INTO trf_data (\"TRAI\", {}) VALUES ({marks})",
        names.join(", ")
    );
    Ok(Sink::Trfdb {
        conn,
        tmp,
        path,
        insert,
        rows: 0,
        later: 0,
    })
}

/// The tables of vallenae's `trfdb.sql`, the export's columns (REAL, as vallenae adds
/// them) and their field info.
fn create_schema(
    c: &rusqlite::Connection,
    res: &Results,
    source_file: &str,
) -> rusqlite::Result<()> {
    let columns: Vec<String> = res
        .columns()
        .map(|k| format!(", \"{}\" REAL", k.field))
        .collect();
    c.execute_batch(&format!(
        "CREATE TABLE trf_data (\"TRAI\" INT UNIQUE{});
         CREATE TABLE trf_globalinfo (\"Key\" UNIQUE, \"Value\");
         CREATE TABLE trf_fieldinfo (\"field\", \"SetTypes\", \"Unit\", \"LongName\", \"Description\", \"ShortName\", \"FormatStr\");",
        columns.concat()
    ))?;
    let writer = format!("aepipe {}", env!("CARGO_PKG_VERSION"));
    let mut info = vec![
        ("Version", "1".to_string()),
        ("FileStatus", "0".to_string()),
        ("WriterID", writer),
        ("ValidSets", "0".to_string()),
    ];
    let pridb = Path::new(source_file).with_extension("pridb");
    if let Some(id) = file_id(&pridb) {
        info.push(("ReferenceID", id));
    }
    for (k, v) in info {
        c.execute(
            "INSERT INTO trf_globalinfo (Key, Value) VALUES (?1, ?2)",
            (k, v),
        )?;
    }
    for k in res.columns() {
        // SetTypes 2: a transient's features, as VisualAE marks its spectral features.
        c.execute(
            "INSERT INTO trf_fieldinfo (field, SetTypes, Unit, LongName, Description, ShortName, FormatStr) VALUES (?1, 2, ?2, ?3, ?4, NULL, ?5)",
            (
                &k.field,
                (!k.unit.is_empty()).then_some(&k.unit),
                &k.long_name,
                &k.description,
                k.integer.then_some("#"),
            ),
        )?;
    }
    Ok(())
}

/// The `FileID` of a Vallen `.pridb` (what a `.trfdb` names as its `ReferenceID`).
fn file_id(pridb: &Path) -> Option<String> {
    let c =
        rusqlite::Connection::open_with_flags(pridb, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
            .ok()?;
    c.query_row(
        "SELECT Value FROM ae_globalinfo WHERE Key = 'FileID'",
        [],
        |r| r.get::<_, String>(0),
    )
    .ok()
}

fn write_row(
    sink: &mut Sink,
    key: &HitKey,
    f: &FeatureRow,
    res: &Results,
    hits: &HitInfo,
) -> Result<(), ExportError> {
    let values = res.values(key, f);
    match sink {
        Sink::Trfdb {
            conn,
            tmp,
            insert,
            rows,
            later,
            ..
        } => {
            if hits.later.contains(&(key.0.clone(), key.2)) {
                *later += 1;
                return Ok(());
            }
            let mut st = conn.prepare_cached(insert).map_err(sqlite_err(tmp))?;
            let params: Vec<rusqlite::types::Value> =
                std::iter::once(rusqlite::types::Value::Integer(key.2))
                    .chain(values.iter().map(|v| match v {
                        Some(x) if x.is_finite() => rusqlite::types::Value::Real(*x),
                        _ => rusqlite::types::Value::Null,
                    }))
                    .collect();
            st.execute(rusqlite::params_from_iter(params))
                .map_err(sqlite_err(tmp))?;
            *rows += 1;
        }
        Sink::Csv { w, tmp, rows, .. } => {
            let vendor = hits.vendor_hit.get(key).map(|h| h.to_string());
            let mut rec = vec![
                key.2.to_string(),
                vendor.unwrap_or_default(),
                f.source_file.clone(),
            ];
            rec.extend(
                values
                    .iter()
                    .map(|v| v.map(|x| x.to_string()).unwrap_or_default()),
            );
            w.write_record(&rec).map_err(|e| ExportError::Csv {
                path: tmp.display().to_string(),
                message: e.to_string(),
            })?;
            *rows += 1;
        }
    }
    Ok(())
}

/// Commit a file and move it into place.
fn finish(experiment: String, sink: Sink, summary: &mut ExportSummary) -> Result<(), ExportError> {
    let (tmp, path, rows) = match sink {
        Sink::Trfdb {
            conn,
            tmp,
            path,
            rows,
            later,
            ..
        } => {
            conn.execute_batch(
                "UPDATE trf_globalinfo SET Value = (SELECT COUNT(*) FROM trf_data) WHERE Key = 'ValidSets'; COMMIT",
            )
            .map_err(sqlite_err(&tmp))?;
            drop(conn);
            if later > 0 {
                summary.notes.push(format!(
                    "{experiment}: {later} transients of acquisitions after a restart are not in the .trfdb (their TRAI repeats the first acquisition's; features.parquet keeps them)"
                ));
            }
            (tmp, path, rows)
        }
        Sink::Csv {
            mut w,
            tmp,
            path,
            rows,
        } => {
            w.flush().map_err(|e| crate::util::IoAt::new(&tmp, e))?;
            (tmp, path, rows)
        }
    };
    std::fs::rename(&tmp, &path).map_err(|e| crate::util::IoAt::new(&path, e))?;
    summary.files.push(Exported {
        experiment,
        path,
        rows,
    });
    Ok(())
}
