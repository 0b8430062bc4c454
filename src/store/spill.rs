//! External sorting for the whole-batch stages: records pushed in any order come back in
//! their order, and memory stays within a budget whatever their number. Records beyond the
//! budget are sorted in runs and spilled to temporary files, then merged (k-way) into one
//! sorted file, which can be read again, whole or by group, as often as a stage needs
//! (the trend's three passes, the damage profile's two).
//!
//! Sorting is stable in effect: every record type carries its position in the input as
//! the last part of its order (the stages' in-memory `sort_by` kept equal keys in input
//! order), so the merged order is one total order, the same however the runs fell.

use super::StoreError;
use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// Bytes of records a sorter keeps in memory before it spills a run.
pub const SORT_BUDGET_BYTES: usize = 32 << 20;

/// A record that can be spilled: a compact binary form, and its size in memory.
pub trait Spill: Sized + Ord {
    fn encode(&self, out: &mut Vec<u8>);
    fn decode(b: &mut Dec<'_>) -> Option<Self>;
    /// Bytes the record holds in memory (its struct and what it owns).
    fn mem_bytes(&self) -> usize {
        std::mem::size_of::<Self>()
    }
}

/// Reads the fields of one encoded record, in the order they were written.
pub struct Dec<'a>(&'a [u8]);

impl Dec<'_> {
    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let (h, t) = self.0.split_at_checked(N)?;
        self.0 = t;
        h.try_into().ok()
    }
    pub fn u8(&mut self) -> Option<u8> {
        self.take::<1>().map(|b| b[0])
    }
    pub fn u32(&mut self) -> Option<u32> {
        self.take().map(u32::from_le_bytes)
    }
    pub fn u64(&mut self) -> Option<u64> {
        self.take().map(u64::from_le_bytes)
    }
    pub fn i32(&mut self) -> Option<i32> {
        self.take().map(i32::from_le_bytes)
    }
    pub fn i64(&mut self) -> Option<i64> {
        self.take().map(i64::from_le_bytes)
    }
    pub fn f64(&mut self) -> Option<f64> {
        self.take().map(f64::from_le_bytes)
    }
    pub fn opt_f64(&mut self) -> Option<Option<f64>> {
        Some(match self.u8()? {
            0 => None,
            _ => Some(self.f64()?),
        })
    }
    pub fn opt_i64(&mut self) -> Option<Option<i64>> {
        Some(match self.u8()? {
            0 => None,
            _ => Some(self.i64()?),
        })
    }
    pub fn opt_bool(&mut self) -> Option<Option<bool>> {
        Some(match self.u8()? {
            0 => None,
            1 => Some(false),
            _ => Some(true),
        })
    }
    pub fn str(&mut self) -> Option<String> {
        let n = self.u32()? as usize;
        let (h, t) = self.0.split_at_checked(n)?;
        self.0 = t;
        String::from_utf8(h.to_vec()).ok()
    }
}

/// Writes the fields of one record (the counterpart of [`Dec`]).
pub struct Enc<'a>(pub &'a mut Vec<u8>);

impl Enc<'_> {
    pub fn u8(&mut self, v: u8) -> &mut Self {
        self.0.push(v);
        self
    }
    pub fn u32(&mut self, v: u32) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    pub fn u64(&mut self, v: u64) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    pub fn i32(&mut self, v: i32) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    pub fn i64(&mut self, v: i64) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    pub fn f64(&mut self, v: f64) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    pub fn opt_f64(&mut self, v: Option<f64>) -> &mut Self {
        match v {
            None => self.u8(0),
            Some(x) => self.u8(1).f64(x),
        }
    }
    pub fn opt_i64(&mut self, v: Option<i64>) -> &mut Self {
        match v {
            None => self.u8(0),
            Some(x) => self.u8(1).i64(x),
        }
    }
    pub fn opt_bool(&mut self, v: Option<bool>) -> &mut Self {
        self.u8(match v {
            None => 0,
            Some(false) => 1,
            Some(true) => 2,
        })
    }
    pub fn str(&mut self, v: &str) -> &mut Self {
        self.u32(v.len() as u32);
        self.0.extend_from_slice(v.as_bytes());
        self
    }
}

fn io_err(p: &Path, source: std::io::Error) -> StoreError {
    StoreError::Io {
        path: p.display().to_string(),
        source,
    }
}

fn corrupt(p: &Path) -> StoreError {
    StoreError::Read {
        path: p.display().to_string(),
        message: "a spilled record does not decode (the temporary file was changed)".into(),
    }
}

/// A folder of temporary files, removed with everything in it when dropped.
#[derive(Debug)]
pub struct SpillDir(PathBuf);

impl SpillDir {
    /// A new folder `.spill-<pid>-<n>` in `parent` (beside the outputs: the same disk). The
    /// folders a killed earlier process left there (its pid no longer running) go first:
    /// only a clean exit drops them.
    pub fn new(parent: &Path) -> Result<SpillDir, StoreError> {
        static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        remove_stale(parent);
        let p = parent.join(format!(".spill-{}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).map_err(|e| io_err(&p, e))?;
        Ok(SpillDir(p))
    }
    fn file(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for SpillDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Remove `.spill-<pid>-*` folders in `parent` whose process is gone (Linux: no
/// `/proc/<pid>`; elsewhere nothing is removed).
fn remove_stale(parent: &Path) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(rd) = std::fs::read_dir(parent) else {
        return;
    };
    for e in rd.flatten() {
        let name = e.file_name().to_string_lossy().to_string();
        let Some(pid) = name
            .strip_prefix(".spill-")
            .and_then(|r| r.split('-').next())
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        if pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists() {
            let _ = std::fs::remove_dir_all(e.path());
        }
    }
}

/// Runs merged at once, at most: more are merged in levels (a run open costs a file handle
/// and a read buffer).
const MAX_FAN_IN: usize = 64;

/// Writes length-prefixed records.
struct RunWriter {
    w: BufWriter<File>,
    path: PathBuf,
    buf: Vec<u8>,
}

impl RunWriter {
    fn create(path: PathBuf) -> Result<RunWriter, StoreError> {
        let f = File::create(&path).map_err(|e| io_err(&path, e))?;
        Ok(RunWriter {
            w: BufWriter::with_capacity(1 << 20, f),
            path,
            buf: Vec::new(),
        })
    }
    /// Writes a record; returns its bytes in the file.
    fn put<T: Spill>(&mut self, t: &T) -> Result<u64, StoreError> {
        self.buf.clear();
        t.encode(&mut self.buf);
        let n = self.buf.len() as u32;
        self.w
            .write_all(&n.to_le_bytes())
            .and_then(|_| self.w.write_all(&self.buf))
            .map_err(|e| io_err(&self.path, e))?;
        Ok(4 + n as u64)
    }
    fn finish(mut self) -> Result<PathBuf, StoreError> {
        self.w.flush().map_err(|e| io_err(&self.path, e))?;
        Ok(self.path)
    }
}

/// Reads length-prefixed records back.
struct RunReader {
    r: BufReader<File>,
    path: PathBuf,
    buf: Vec<u8>,
    left: u64,
    /// Byte offset of the next record.
    pos: u64,
}

impl RunReader {
    fn open(path: &Path, offset: u64, count: u64) -> Result<RunReader, StoreError> {
        let mut f = File::open(path).map_err(|e| io_err(path, e))?;
        f.seek(SeekFrom::Start(offset))
            .map_err(|e| io_err(path, e))?;
        Ok(RunReader {
            r: BufReader::with_capacity(256 << 10, f),
            path: path.to_path_buf(),
            buf: Vec::new(),
            left: count,
            pos: offset,
        })
    }
    fn next<T: Spill>(&mut self) -> Option<Result<T, StoreError>> {
        if self.left == 0 {
            return None;
        }
        self.left -= 1;
        let mut n = [0u8; 4];
        if let Err(e) = self.r.read_exact(&mut n) {
            return Some(Err(io_err(&self.path, e)));
        }
        self.buf.resize(u32::from_le_bytes(n) as usize, 0);
        if let Err(e) = self.r.read_exact(&mut self.buf) {
            return Some(Err(io_err(&self.path, e)));
        }
        self.pos += 4 + self.buf.len() as u64;
        Some(T::decode(&mut Dec(&self.buf)).ok_or_else(|| corrupt(&self.path)))
    }
}

/// Collects records and sorts them within a memory budget.
pub struct Sorter<T: Spill> {
    dir: Option<SpillDir>,
    parent: PathBuf,
    buf: Vec<T>,
    bytes: usize,
    budget: usize,
    runs: Vec<(PathBuf, u64)>,
}

impl<T: Spill> Sorter<T> {
    /// A sorter that spills into a temporary folder in `parent` when its records exceed
    /// [`SORT_BUDGET_BYTES`].
    pub fn new(parent: &Path) -> Sorter<T> {
        Sorter::with_budget(parent, SORT_BUDGET_BYTES)
    }

    pub fn with_budget(parent: &Path, budget: usize) -> Sorter<T> {
        Sorter {
            dir: None,
            parent: parent.to_path_buf(),
            buf: Vec::new(),
            bytes: 0,
            budget: budget.max(1),
            runs: Vec::new(),
        }
    }

    pub fn push(&mut self, t: T) -> Result<(), StoreError> {
        // What the records own beyond their slots, and the slots the buffer has reserved.
        self.bytes += t.mem_bytes().saturating_sub(std::mem::size_of::<T>());
        self.buf.push(t);
        if self.bytes + self.buf.capacity() * std::mem::size_of::<T>() >= self.budget {
            self.spill()?;
        }
        Ok(())
    }

    fn spill(&mut self) -> Result<(), StoreError> {
        if self.dir.is_none() {
            self.dir = Some(SpillDir::new(&self.parent)?);
        }
        let dir = self.dir.as_ref().expect("made above");
        self.buf.sort_unstable();
        let path = dir.file(&format!("run-{}", self.runs.len()));
        let mut w = RunWriter::create(path)?;
        for t in &self.buf {
            w.put(t)?;
        }
        let n = self.buf.len() as u64;
        self.runs.push((w.finish()?, n));
        self.buf = Vec::new();
        self.bytes = 0;
        Ok(())
    }

    /// Every record pushed, in order: in memory if they fit the budget, else merged from
    /// the spilled runs into one sorted file.
    pub fn finish(mut self) -> Result<Sorted<T>, StoreError> {
        if self.runs.is_empty() {
            self.buf.sort_unstable();
            return Ok(Sorted::Memory(self.buf));
        }
        if !self.buf.is_empty() {
            self.spill()?;
        }
        let dir = self.dir.take().expect("runs were spilled");
        let mut runs = std::mem::take(&mut self.runs);
        let mut level = 0;
        while runs.len() > MAX_FAN_IN {
            let mut next = Vec::new();
            for (k, group) in runs.chunks(MAX_FAN_IN).enumerate() {
                next.push(merge_runs::<T>(
                    group,
                    dir.file(&format!("merge-{level}-{k}")),
                )?);
            }
            runs = next;
            level += 1;
        }
        let (path, len) = merge_runs::<T>(&runs, dir.file("sorted"))?;
        Ok(Sorted::File {
            path,
            len,
            _dir: dir,
        })
    }
}

/// Merge sorted runs into one at `out` (k-way, by a heap), removing the runs.
fn merge_runs<T: Spill>(
    runs: &[(PathBuf, u64)],
    out: PathBuf,
) -> Result<(PathBuf, u64), StoreError> {
    let mut readers: Vec<RunReader> = runs
        .iter()
        .map(|(p, n)| RunReader::open(p, 0, *n))
        .collect::<Result<_, _>>()?;
    let mut heap = BinaryHeap::new();
    for (k, r) in readers.iter_mut().enumerate() {
        if let Some(t) = r.next::<T>() {
            heap.push(Reverse((t?, k)));
        }
    }
    let mut w = RunWriter::create(out)?;
    let mut len = 0u64;
    while let Some(Reverse((t, k))) = heap.pop() {
        w.put(&t)?;
        len += 1;
        if let Some(next) = readers[k].next::<T>() {
            heap.push(Reverse((next?, k)));
        }
    }
    let path = w.finish()?;
    drop(readers);
    for (p, _) in runs {
        let _ = std::fs::remove_file(p);
    }
    Ok((path, len))
}

/// Sorted records, readable as often as needed.
pub enum Sorted<T> {
    Memory(Vec<T>),
    File {
        path: PathBuf,
        len: u64,
        _dir: SpillDir,
    },
}

/// Where a stretch of sorted records starts, and how many it holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Span {
    /// Index (in memory) or byte offset (in the file) of its first record.
    start: u64,
    pub len: u64,
}

impl<T: Spill + Clone> Sorted<T> {
    pub fn len(&self) -> u64 {
        match self {
            Sorted::Memory(v) => v.len() as u64,
            Sorted::File { len, .. } => *len,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether the records went to disk (they exceeded the budget).
    pub fn spilled(&self) -> bool {
        matches!(self, Sorted::File { .. })
    }

    /// Every record, in order.
    pub fn iter(&self) -> Box<dyn Iterator<Item = Result<T, StoreError>> + '_> {
        self.span_iter(Span {
            start: 0,
            len: self.len(),
        })
    }

    /// The records of one span, in order.
    pub fn span_iter(&self, s: Span) -> Box<dyn Iterator<Item = Result<T, StoreError>> + '_> {
        match self {
            Sorted::Memory(v) => Box::new(
                v[s.start as usize..(s.start + s.len) as usize]
                    .iter()
                    .cloned()
                    .map(Ok),
            ),
            Sorted::File { path, .. } => match RunReader::open(path, s.start, s.len) {
                Ok(mut r) => Box::new(std::iter::from_fn(move || r.next::<T>())),
                Err(e) => Box::new(std::iter::once(Err(e))),
            },
        }
    }

    /// The runs of records with equal `key`, each with its key and span: one pass that
    /// reads the records once and keeps nothing of them.
    pub fn groups<K: PartialEq>(
        &self,
        key: impl Fn(&T) -> K,
    ) -> Result<Vec<(K, Span)>, StoreError> {
        let mut out: Vec<(K, Span)> = Vec::new();
        let mut add = |k: K, pos: u64| match out.last_mut() {
            Some((last, span)) if *last == k => span.len += 1,
            _ => out.push((k, Span { start: pos, len: 1 })),
        };
        match self {
            Sorted::Memory(v) => {
                for (i, t) in v.iter().enumerate() {
                    add(key(t), i as u64);
                }
            }
            Sorted::File { path, len, .. } => {
                let mut r = RunReader::open(path, 0, *len)?;
                loop {
                    let pos = r.pos;
                    match r.next::<T>() {
                        None => break,
                        Some(t) => add(key(&t?), pos),
                    }
                }
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
    struct Rec {
        group: String,
        key: i64,
        seq: u64,
    }

    impl Spill for Rec {
        fn encode(&self, out: &mut Vec<u8>) {
            Enc(out).str(&self.group).i64(self.key).u64(self.seq);
        }
        fn decode(b: &mut Dec<'_>) -> Option<Self> {
            Some(Rec {
                group: b.str()?,
                key: b.i64()?,
                seq: b.u64()?,
            })
        }
        fn mem_bytes(&self) -> usize {
            std::mem::size_of::<Self>() + self.group.len()
        }
    }

    fn records(n: u64) -> Vec<Rec> {
        let mut r = crate::util::Rng::new(5);
        (0..n)
            .map(|seq| Rec {
                group: format!("exp{}", r.next_u64() % 7),
                key: (r.next_u64() % 50) as i64 - 25,
                seq,
            })
            .collect()
    }

    #[test]
    fn spilled_and_in_memory_sorts_give_the_same_order_and_groups() {
        let dir = std::env::temp_dir().join(format!("aepipe-spill-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let input = records(20_000);
        let mut want = input.clone();
        want.sort();
        // The last budget makes more than MAX_FAN_IN runs: a merge in levels.
        for budget in [usize::MAX, 100_000, 5_000, 500] {
            let mut s = Sorter::with_budget(&dir, budget);
            for r in input.iter().cloned() {
                s.push(r).unwrap();
            }
            let sorted = s.finish().unwrap();
            assert_eq!(sorted.spilled(), budget != usize::MAX);
            let got: Vec<Rec> = sorted.iter().map(Result::unwrap).collect();
            assert_eq!(got, want, "budget {budget}");
            // Groups: each span reads back exactly its records, twice over.
            let groups = sorted.groups(|r| r.group.clone()).unwrap();
            assert_eq!(groups.len(), 7);
            let mut again = Vec::new();
            for (g, span) in &groups {
                for _ in 0..2 {
                    let part: Vec<Rec> = sorted.span_iter(*span).map(Result::unwrap).collect();
                    assert!(part.iter().all(|r| &r.group == g));
                    assert_eq!(part.len() as u64, span.len);
                }
                again.extend(sorted.span_iter(*span).map(Result::unwrap));
            }
            assert_eq!(again, want);
        }
        // The spill folders are gone with their sorters.
        let left: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
        assert!(left.is_empty(), "{left:?}");
        // A folder a killed process left (its pid not running) goes with the next sorter's;
        // one of a live process (ours) stays.
        let stale = dir.join(".spill-4194305-0");
        let live = dir.join(format!(".spill-{}-999", std::process::id()));
        std::fs::create_dir_all(&stale).unwrap();
        std::fs::create_dir_all(&live).unwrap();
        let d = SpillDir::new(&dir).unwrap();
        assert!(!stale.exists() && live.exists());
        drop(d);
        std::fs::remove_dir_all(&live).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
