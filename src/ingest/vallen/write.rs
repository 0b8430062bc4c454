//! A Vallen `.pridb`/`.tradb` writer for fixtures, the demo and the synthetic experiment.

use rusqlite::Connection;
use std::path::{Path, PathBuf};

/// One hit to write into a Vallen pair (see [`write_pair`]).
pub struct HitToWrite<'a> {
    pub channel: u32,
    pub trai: u64,
    pub time_s: f64,
    pub sample_rate_hz: f64,
    pub pretrigger: u32,
    /// Volts; quantised to int16 with the pair's `TR_mV`.
    pub samples_v: &'a [f32],
    /// Recording was restarted into the database before this hit: a section-start marker
    /// (`SetType` 6) precedes it, and the caller restarts `trai` and `time_s`.
    pub restart: bool,
    /// Write the transient (`tr_data` row); `false` leaves the hit without one.
    pub transient: bool,
}

/// How the writer's databases keep their journal: `Off` for a file written at once,
/// `Delete` (the rollback journal, as the AMSY-6 software writes) or `Wal` for one that a
/// reader follows while it grows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Journal {
    Off,
    Delete,
    Wal,
}

/// A Vallen pair written set by set, as an acquisition writes it: each call is its own
/// transaction (unless inside [`PairWriter::batch`]), so a reader sees the pair grow.
pub struct PairWriter {
    pri: Connection,
    tra: Connection,
    pri_path: PathBuf,
    tra_path: PathBuf,
    tr_mv: f64,
    adc_uv: f64,
    thr_adc: i64,
    blob: std::cell::RefCell<Vec<u8>>,
}

impl PairWriter {
    /// Create `base.pridb` and `base.tradb` (replacing them) with the tables and views of the
    /// real AMSY-6 files; waveforms quantised with `tr_mv`, hits' threshold `threshold_v`.
    pub fn create(
        base: &Path,
        tr_mv: f64,
        threshold_v: f64,
        journal: Journal,
    ) -> rusqlite::Result<PairWriter> {
        let pri_path = base.with_extension("pridb");
        let tra_path = base.with_extension("tradb");
        for p in [&pri_path, &tra_path] {
            for suffix in ["", "-journal", "-wal", "-shm"] {
                let mut name = p.as_os_str().to_owned();
                name.push(suffix);
                let _ = std::fs::remove_file(PathBuf::from(name));
            }
        }
        let pri = Connection::open(&pri_path)?;
        let tra = Connection::open(&tra_path)?;
        let mode = match journal {
            Journal::Off => "OFF",
            Journal::Delete => "DELETE",
            Journal::Wal => "WAL",
        };
        for c in [&pri, &tra] {
            // A reader holding a shared lock for a moment makes a commit wait, not fail.
            c.busy_timeout(std::time::Duration::from_secs(10))?;
            c.query_row(&format!("PRAGMA journal_mode={mode}"), [], |_| Ok(()))?;
            c.execute_batch("PRAGMA synchronous=OFF;")?;
        }
        let adc_uv = tr_mv * 1e3 / 2.0f64.powi(11); // arbitrary but consistent hit-feature ADC step
        pri.execute_batch(&format!(
        "{AE_SCHEMA}
        INSERT INTO ae_globalinfo VALUES ('Version', 1), ('FileStatus', 0), ('TimeBase', 10000000), ('WriterName', 'aepipe');
        INSERT INTO ae_fieldinfo VALUES ('Time','[s]',NULL,NULL,1e-07),('Thr','[µV]',12,'ADC_µV',NULL),('Amp','[µV]',4,'ADC_µV',NULL),('RiseT','[µs]',4,NULL,0.1),('Dur','[µs]',4,NULL,0.1),('Eny','[eu]',12,'ADC_TE',NULL),('SS','[nVs]',12,'ADC_SS',NULL),('RMS','[µV]',12,'ADC_µV',0.0065536),('PA0','[mV]',2,'PA0_mV',NULL),('PA1','[mV]',2,'PA1_mV',NULL);
        INSERT INTO ae_params VALUES (1, 1, 0, 0.0, 0.0, 0.0, 0.001, 0.001), (2, 1, 1, {adc_uv}, 1.0, 1.0, 0.0, 0.0);"
    ))?;
        tra.execute_batch(&format!(
        "{TR_TABLES}
        CREATE INDEX idx_TRAI on tr_data (TRAI);
        CREATE VIEW view_tr_data as select (d.SetID) as SetID,(d.Time*1E-7) as Time,(d.TRAI) as TRAI,(d.Status) as Status,(d.Chan) as Chan,(d.Pretrigger) as Pretrigger,(d.Thr*p.ADC_µV) as Thr,(d.SampleRate) as SampleRate,(d.Samples) as Samples,(d.DataFormat) as DataFormat,p.TR_mV as TR_mV,(d.Data) as Data from tr_data d  left join tr_params p on p.ID=d.ParamID;
        INSERT INTO tr_globalinfo VALUES ('Version', 1), ('FileStatus', 0), ('TimeBase', 10000000), ('WriterName', 'aepipe');
        INSERT INTO tr_fieldinfo VALUES ('Time','[s]',NULL),('Thr','[µV]','ADC_µV'),('SampleRate','[Hz]',NULL);
        INSERT INTO tr_params VALUES (1, 1, 0, 0.0, 0.0), (2, 1, 1, {adc_uv}, {tr_mv});"
    ))?;
        Ok(PairWriter {
            pri,
            tra,
            pri_path,
            tra_path,
            tr_mv,
            adc_uv,
            thr_adc: (threshold_v * 1e6 / adc_uv).round() as i64,
            blob: std::cell::RefCell::new(Vec::new()),
        })
    }

    /// The `.pridb` and `.tradb` paths.
    pub fn paths(&self) -> (PathBuf, PathBuf) {
        (self.pri_path.clone(), self.tra_path.clone())
    }

    /// Run `f` as one transaction in each database.
    pub fn batch<R>(&self, f: impl FnOnce(&Self) -> rusqlite::Result<R>) -> rusqlite::Result<R> {
        self.pri.execute_batch("BEGIN")?;
        self.tra.execute_batch("BEGIN")?;
        let r = f(self)?;
        self.pri.execute_batch("COMMIT")?;
        self.tra.execute_batch("COMMIT")?;
        Ok(r)
    }

    /// A parametric row (`SetType` 1): PA0 and PA1 in millivolts.
    pub fn parametric(&self, time_s: f64, pa0_mv: f64, pa1_mv: f64) -> rusqlite::Result<()> {
        self.pri
            .prepare_cached(INSERT_SET)?
            .execute(rusqlite::params![
                1,
                to_ticks(time_s),
                Option::<i64>::None,
                1,
                Option::<i64>::None,
                Option::<i64>::None,
                Option::<i64>::None,
                (pa0_mv * 1e3).round() as i64,
                (pa1_mv * 1e3).round() as i64
            ])?;
        Ok(())
    }

    /// A status row (`SetType` 3) of a channel: its threshold and an RMS of `rms_v`.
    pub fn status(&self, time_s: f64, channel: u32, rms_v: f64) -> rusqlite::Result<()> {
        self.pri.execute(
            "INSERT INTO ae_data (SetType, Time, Chan, Status, ParamID, Thr, RMS) \
             VALUES (3, ?1, ?2, 0, 2, ?3, ?4)",
            rusqlite::params![
                to_ticks(time_s),
                channel,
                self.thr_adc,
                (rms_v * 1e6 / (0.0065536 * self.adc_uv)).round() as i64
            ],
        )?;
        Ok(())
    }

    /// A section-start marker (`SetType` 6): the recording restarts (acquisition `number`).
    pub fn section(&self, number: i64) -> rusqlite::Result<()> {
        self.pri
            .prepare_cached("INSERT INTO ae_data (SetType, Time) VALUES (6, 0)")?
            .execute([])?;
        self.pri.execute(
            "INSERT INTO ae_markers (SetID, Number, Data) VALUES (last_insert_rowid(), ?1, '')",
            [number],
        )?;
        Ok(())
    }

    /// The hit row (`SetType` 2) of `h`; its transient is [`PairWriter::transient`].
    pub fn hit(&self, h: &HitToWrite) -> rusqlite::Result<()> {
        let scale = 1e3 / self.tr_mv; // volts -> ADC counts
        let mut peak = 0i64;
        for &v in h.samples_v {
            let q = (v as f64 * scale).round().clamp(-32768.0, 32767.0) as i16;
            peak = peak.max((q as i64).abs());
        }
        let amp = (peak as f64 * self.tr_mv * 1e3 / self.adc_uv).round() as i64;
        self.pri
            .prepare_cached(INSERT_SET)?
            .execute(rusqlite::params![
                2,
                to_ticks(h.time_s),
                h.channel,
                2,
                self.thr_adc,
                amp,
                h.trai as i64,
                Option::<i64>::None,
                Option::<i64>::None
            ])?;
        Ok(())
    }

    /// The transient (`tr_data` row, raw int16) of `h`.
    pub fn transient(&self, h: &HitToWrite) -> rusqlite::Result<()> {
        let scale = 1e3 / self.tr_mv;
        let mut blob = self.blob.borrow_mut();
        blob.clear();
        for &v in h.samples_v {
            let q = (v as f64 * scale).round().clamp(-32768.0, 32767.0) as i16;
            blob.extend_from_slice(&q.to_le_bytes());
        }
        self.tra
            .prepare_cached(
                "INSERT INTO tr_data (Time, TRAI, Status, ParamID, Chan, Pretrigger, Thr, SampleRate, Samples, DataFormat, Data) \
                 VALUES (?1, ?2, 0, 2, ?3, ?4, ?5, ?6, ?7, 0, ?8)",
            )?
            .execute(rusqlite::params![
                to_ticks(h.time_s),
                h.trai as i64,
                h.channel,
                h.pretrigger,
                self.thr_adc,
                h.sample_rate_hz.round() as i64,
                h.samples_v.len() as i64,
                &*blob
            ])?;
        Ok(())
    }
}

const INSERT_SET: &str = "INSERT INTO ae_data (SetType, Time, Chan, Status, ParamID, Thr, Amp, RiseT, Dur, Eny, SS, RMS, Counts, TRAI, PA0, PA1) \
     VALUES (?1, ?2, ?3, 0, ?4, ?5, ?6, 0, 0, 0, 0, 0, 0, ?7, ?8, ?9)";

fn to_ticks(t: f64) -> i64 {
    (t * 1e7).round() as i64
}

/// The tables and views of a `.pridb`, as the AMSY-6 files declare them: what the writer
/// creates, and what a damaged file's salvaged rows are rebuilt into when its own schema page
/// is lost.
pub(super) const AE_SCHEMA: &str = "CREATE TABLE ae_data (\"SetID\" INTEGER PRIMARY KEY,\"SetType\" INT,\"Time\" INT,\"Chan\" INT,\"Status\" INT,\"ParamID\" INT,\"Thr\" INT,\"Amp\" INT,\"RiseT\" INT,\"Dur\" INT,\"Eny\" INT,\"SS\" INT,\"RMS\" INT,\"Counts\" INT,\"TRAI\" INT,\"PCTD\" INT,\"PCTA\" INT,\"PA0\" INT,\"PA1\" INT);
CREATE TABLE acq_setup(ID INTEGER PRIMARY KEY, Data TEXT);
CREATE TABLE ae_markers (\"SetID\" INT UNIQUE,\"Number\" INT,\"Data\" TEXT);
CREATE TABLE ae_globalinfo(Key UNIQUE, Value);
CREATE TABLE ae_fieldinfo (field,Unit,SetTypes,Parameter,Factor);
CREATE TABLE ae_params (\"ID\" INTEGER PRIMARY KEY,\"SetupID\" INT,\"Chan\" INT,\"ADC_µV\" REAL,\"ADC_TE\" REAL,\"ADC_SS\" REAL,\"PA0_mV\" REAL,\"PA1_mV\" REAL);
CREATE TABLE data_integrity(TableName TEXT PRIMARY KEY UNIQUE, HashV1 INT, LastRow INT);
CREATE VIEW view_ae_data as select (d.SetID) as SetID,(d.SetType) as SetType,(d.Time*1E-7) as Time,(d.Chan) as Chan,(d.Status) as Status,(d.Thr*p.ADC_µV) as Thr,(d.Amp*p.ADC_µV) as Amp,(d.RiseT*0.1) as RiseT,(d.Dur*0.1) as Dur,(d.Eny*p.ADC_TE) as Eny,(d.SS*p.ADC_SS) as SS,(d.RMS*0.0065536*p.ADC_µV) as RMS,(d.Counts) as Counts,(d.TRAI) as TRAI,(d.PCTD) as PCTD,(d.PCTA) as PCTA,(d.PA0*p.PA0_mV) as PA0,(d.PA1*p.PA1_mV) as PA1 from ae_data d  left join ae_params p on p.ID=d.ParamID;
CREATE VIEW view_ae_markers as select m.*, l.SetType, l.Time*1E-7 as Time from ae_markers m cross join ae_data l on l.SetID = m.SetID;";

/// The tables of a `.tradb`, as VisualAE's files declare them (the real sets' schema): what
/// the writer creates, and the shapes salvage tells a damaged file's pages by.
pub(super) const TR_TABLES: &str = "CREATE TABLE tr_data (\"SetID\" INTEGER PRIMARY KEY,\"Time\" INT,\"TRAI\" INT,\"Status\" INT,\"ParamID\" INT,\"Chan\" INT,\"Pretrigger\" INT,\"Thr\" INT,\"SampleRate\" INT,\"Samples\" INT,\"DataFormat\" INT,\"Data\" BLOB);
CREATE TABLE tr_globalinfo(Key UNIQUE, Value);
CREATE TABLE tr_fieldinfo (field,Unit,Parameter);
CREATE TABLE tr_params (\"ID\" INTEGER PRIMARY KEY,\"SetupID\" INT,\"Chan\" INT,\"ADC_µV\" REAL,\"TR_mV\" REAL);";

/// Write a Vallen `.pridb`/`.tradb` pair (raw int16 waveforms, `DataFormat` 0) with the
/// tables and views of the real AMSY-6 files, so that aepipe's own reader and vallenae read
/// it. `parametric` rows are `(time_s, pa0_mv, pa1_mv)`. Used for fixtures, the demo and the
/// synthetic experiment. Returns the two paths.
pub fn write_pair<'a>(
    base: &Path,
    hits: impl IntoIterator<Item = HitToWrite<'a>>,
    parametric: &[(f64, f64, f64)],
    tr_mv: f64,
    threshold_v: f64,
) -> rusqlite::Result<(PathBuf, PathBuf)> {
    let w = PairWriter::create(base, tr_mv, threshold_v, Journal::Off)?;
    // Merge hits and parametric rows in time order, as the acquisition would have.
    enum Row<'a> {
        Par(f64, f64, f64),
        Hit(HitToWrite<'a>),
    }
    // Each acquisition in time order; the parametric rows belong to the first.
    let mut acquisitions: Vec<Vec<Row>> = vec![parametric
        .iter()
        .map(|&(t, a, b)| Row::Par(t, a, b))
        .collect()];
    for h in hits {
        if h.restart {
            acquisitions.push(Vec::new());
        }
        acquisitions.last_mut().expect("one").push(Row::Hit(h));
    }
    let t_of = |r: &Row| match r {
        Row::Par(t, ..) => *t,
        Row::Hit(h) => h.time_s,
    };
    for a in &mut acquisitions {
        a.sort_by(|a, b| t_of(a).total_cmp(&t_of(b)));
    }
    w.batch(|w| {
        for (k, rows) in acquisitions.into_iter().enumerate() {
            if k > 0 {
                w.section(k as i64 + 1)?;
            }
            for r in rows {
                match r {
                    Row::Par(t, a, b) => w.parametric(t, a, b)?,
                    Row::Hit(h) => {
                        w.hit(&h)?;
                        if h.transient {
                            w.transient(&h)?;
                        }
                    }
                }
            }
        }
        Ok(())
    })?;
    Ok(w.paths())
}
