//! Leaf utilities every room may use and that use no room: atomic writes, time stamps,
//! hashing, base64, the seeded RNG, file-name-safe ids. Nothing here knows about AE.

use sha2::{Digest, Sha256};
use std::f64::consts::PI;
use std::io::Read;
use std::path::{Path, PathBuf};

/// What kind of failure an error is, decided by the room that raises it (each room's error
/// enum implements [`HasKind`], variant by variant, with no catch-all arm): the CLI's exit
/// code and, for another front door, the exception class follow from it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorKind {
    /// The input is at fault: a flag, a configuration, model or library file, a table or
    /// folder that is not what the command needs (exit code 1).
    Usage,
    /// The run failed: an output could not be written, a stage failed (exit code 3).
    Failed,
}

/// An error that knows its [`ErrorKind`].
pub trait HasKind {
    fn kind(&self) -> ErrorKind;
}

impl HasKind for IoAt {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Failed
    }
}

/// Settings that passed their room's checks (linfa's validated hyper-parameters): only the
/// room's `check` makes one (the constructor is crate-private), and it reads as the settings
/// (`Deref`). A function that needs checked settings takes a `&Checked<…>`.
#[derive(Debug, Clone, PartialEq)]
pub struct Checked<T>(T);

impl<T> Checked<T> {
    pub(crate) fn new(t: T) -> Checked<T> {
        Checked(t)
    }

    /// The settings, to change and check again.
    pub fn into_inner(self) -> T {
        self.0
    }
}

impl<T> std::ops::Deref for Checked<T> {
    type Target = T;
    fn deref(&self) -> &T {
        &self.0
    }
}

/// `Option<PathBuf>` as TOML writes it: a path, or `""` for none (the file format before
/// the type existed, kept so the canonical TOML and its hash do not change).
pub mod empty_is_none {
    use serde::{Deserialize, Deserializer, Serializer};
    use std::path::PathBuf;

    pub fn serialize<S: Serializer>(p: &Option<PathBuf>, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&p.as_ref().map(|p| p.to_string_lossy()).unwrap_or_default())
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<PathBuf>, D::Error> {
        let s = String::deserialize(d)?;
        Ok((!s.is_empty()).then(|| PathBuf::from(s)))
    }
}

/// An I/O failure at a path: the one error this module returns.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {source}")]
pub struct IoAt {
    pub path: String,
    #[source]
    pub source: std::io::Error,
}

impl IoAt {
    pub fn new(path: &Path, source: std::io::Error) -> IoAt {
        IoAt {
            path: path.display().to_string(),
            source,
        }
    }
}

/// The temporary name a file is written under before it is renamed into place.
pub fn tmp_path_for(final_path: &Path) -> PathBuf {
    let name = final_path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    final_path.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

/// Write a file atomically (temporary name, then rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), IoAt> {
    let tmp = tmp_path_for(path);
    std::fs::write(&tmp, bytes).map_err(|e| IoAt::new(path, e))?;
    std::fs::rename(&tmp, path).map_err(|e| IoAt::new(path, e))
}

/// Peak resident set size of this process so far (VmHWM), bytes; `None` off Linux.
pub fn peak_rss_bytes() -> Option<u64> {
    proc_status_kib("VmHWM:").map(|k| k * 1024)
}

/// Current resident set size (VmRSS), bytes; `None` off Linux.
pub fn rss_bytes() -> Option<u64> {
    proc_status_kib("VmRSS:").map(|k| k * 1024)
}

fn proc_status_kib(field: &str) -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with(field))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// Give the memory freed since the last call back to the operating system (glibc keeps
/// freed heap for reuse): between whole-batch stages, so that one stage's sort buffers do
/// not stay resident through the next, and each stage's peak reads as its own.
pub fn release_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free heap pages to the kernel; it touches no live
    // allocation.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Start a new peak-RSS reading: the kernel's mark (VmHWM) drops to the current RSS, so the
/// next [`peak_rss_bytes`] is the peak since now (Linux ≥ 4.0: `/proc/self/clear_refs` 5;
/// elsewhere, or where that is refused, the mark keeps the process's peak so far).
pub fn reset_peak_rss() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// Logical cores (1 when unknown).
pub fn num_cpus() -> usize {
    std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
}

/// What a front door other than the terminal (the Python package, a watcher) shares with a
/// long job while it runs: a stop request the job honours at its next record or stage, and
/// the number of records done so far, which the caller can show as progress. The job only
/// reads the flag and adds to the count; the caller owns both.
#[derive(Debug, Default)]
pub struct JobControl {
    cancelled: std::sync::atomic::AtomicBool,
    done: std::sync::atomic::AtomicU64,
}

impl JobControl {
    /// Ask the job to stop; it returns a `Cancelled` error at its next check.
    pub fn cancel(&self) {
        self.cancelled
            .store(true, std::sync::atomic::Ordering::Relaxed)
    }
    pub fn is_cancelled(&self) -> bool {
        self.cancelled.load(std::sync::atomic::Ordering::Relaxed)
    }
    /// Count `n` more records done.
    pub fn add(&self, n: u64) {
        self.done.fetch_add(n, std::sync::atomic::Ordering::Relaxed);
    }
    pub fn done(&self) -> u64 {
        self.done.load(std::sync::atomic::Ordering::Relaxed)
    }
}

/// Whether an optional control asks to stop.
pub fn cancelled(c: &Option<std::sync::Arc<JobControl>>) -> bool {
    c.as_ref().is_some_and(|c| c.is_cancelled())
}

/// Run `f` on a rayon pool of `threads` workers (0 = all cores); on the global pool if a
/// pool cannot be made.
pub fn with_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    match rayon::ThreadPoolBuilder::new().num_threads(threads).build() {
        Ok(p) => p.install(f),
        Err(_) => f(),
    }
}

/// A string made safe as one file-name component: characters other than letters, digits,
/// `-`, `_` and `.` become `_`, and leading dots go (no `..`, no path separators, no hidden
/// files). The tables keep the original id; only names on disk use this.
pub fn file_safe(id: &str) -> String {
    let s: String = id
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect();
    let s = s.trim_start_matches('.');
    if s.is_empty() {
        "_".into()
    } else {
        s.into()
    }
}

/// A tally as the terminal writes it: `name count, name count, …`.
pub fn tally<K: std::fmt::Display, V: std::fmt::Display>(
    counts: impl IntoIterator<Item = (K, V)>,
) -> String {
    counts
        .into_iter()
        .map(|(k, v)| format!("{k} {v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Lower-case hex of bytes.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// SHA-256 of bytes, as hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

/// SHA-256 and size of a file, streamed.
pub fn file_digest(path: &Path) -> std::io::Result<(u64, String)> {
    let mut f = std::fs::File::open(path)?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut size = 0u64;
    loop {
        let n = f.read(&mut buf)?;
        if n == 0 {
            break;
        }
        size += n as u64;
        h.update(&buf[..n]);
    }
    Ok((size, hex(&h.finalize())))
}

/// RFC 3339 UTC timestamp of now (no time-zone database needed).
pub fn utc_now() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs() as i64)
        .unwrap_or(0);
    let (days, rem) = (secs.div_euclid(86400), secs.rem_euclid(86400));
    // Civil date from days since 1970-01-01 (Howard Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

/// Standard base64 (RFC 4648) of `data`.
pub fn base64(data: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(data.len().div_ceil(3) * 4);
    for c in data.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// SplitMix64: small, fast, seedable; the one RNG of the simulator, the synthetic data and
/// the SOM, so a seed means the same stream everywhere (no dependency).
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed ^ 0x9E37_79B9_7F4A_7C15)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }
    /// Shuffle `v` in place (Fisher–Yates from the back: each slot i takes a draw from
    /// 0..=i).
    pub fn shuffle<T>(&mut self, v: &mut [T]) {
        for i in (1..v.len()).rev() {
            let j = (self.next_u64() % (i as u64 + 1)) as usize;
            v.swap(i, j);
        }
    }

    /// `k` of the indices 0..n drawn without replacement (a partial Fisher–Yates from the
    /// front), ascending; all of them when n ≤ k.
    pub fn sample_sorted(&mut self, n: usize, k: usize) -> Vec<usize> {
        let mut idx: Vec<usize> = (0..n).collect();
        if n > k {
            for i in 0..k {
                let j = i + (self.next_u64() % (n - i) as u64) as usize;
                idx.swap(i, j);
            }
            idx.truncate(k);
            idx.sort_unstable();
        }
        idx
    }

    /// Standard normal (Box–Muller).
    pub fn normal(&mut self) -> f64 {
        let u1 = self.uniform().max(1e-300);
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
    }
}

/// A value named by the word its serde form uses (a unit variant's `rename_all` name: the
/// pipeline file's word), so a flag, a Python argument and the TOML key accept the same
/// words and a new variant needs no second parser.
pub fn from_serde_name<T: serde::de::DeserializeOwned>(
    word: &str,
) -> Result<T, serde::de::value::Error> {
    use serde::de::IntoDeserializer;
    T::deserialize(word.into_deserializer())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utc_now_is_well_formed() {
        let s = utc_now();
        assert_eq!(s.len(), 20, "{s}");
        assert!(s.starts_with("20") && s.ends_with('Z'));
    }

    #[test]
    fn base64_matches_rfc4648_vectors() {
        for (i, o) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(i.as_bytes()), o);
        }
    }

    #[test]
    fn ids_become_safe_file_names() {
        assert_eq!(file_safe("../../etc/passwd"), "_.._etc_passwd");
        assert_eq!(file_safe("exp 1/ch2"), "exp_1_ch2");
        assert_eq!(file_safe(".."), "_");
        assert_eq!(file_safe("PLBS4_CP090.x-1"), "PLBS4_CP090.x-1");
        for id in ["../a", "/abs", "a/../../b", "..", "."] {
            let f = file_safe(id);
            assert!(
                !f.contains('/') && !f.starts_with('.') && !f.is_empty(),
                "{id} -> {f}"
            );
        }
    }

    #[test]
    fn sha256_of_abc_is_the_fips_vector() {
        assert_eq!(
            sha256_hex(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }
}

/// One of `n` shards of a batch (`--shard K/N`). An experiment belongs to the shard its
/// id's SHA-256 names: stable across file order, thread count, machine and run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub k: u32,
    pub n: u32,
}

impl Shard {
    /// The shard of `key` among `n`.
    pub fn of(key: &str, n: u32) -> u32 {
        let h = Sha256::digest(key.as_bytes());
        let v = u64::from_be_bytes([h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7]]);
        (v % n.max(1) as u64) as u32
    }
    pub fn owns(&self, key: &str) -> bool {
        Shard::of(key, self.n) == self.k
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.k, self.n)
    }
}

/// Why a `--shard` value was refused.
#[derive(Debug, thiserror::Error)]
#[error("--shard {0:?}: expected K/N with 0 ≤ K < N ≤ 100000 (a Slurm array's $SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT)")]
pub struct ShardError(String);

impl std::str::FromStr for Shard {
    type Err = ShardError;
    fn from_str(s: &str) -> Result<Shard, ShardError> {
        let bad = || ShardError(s.to_string());
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let (k, n): (u32, u32) = (
            k.trim().parse().map_err(|_| bad())?,
            n.trim().parse().map_err(|_| bad())?,
        );
        if n == 0 || k >= n || n > 100_000 {
            return Err(bad());
        }
        Ok(Shard { k, n })
    }
}

/// A value as a Hive partition path segment (`experiment=<this>`): bytes outside
/// `A–Z a–z 0–9 - _` (and a `.` anywhere but first, which would hide the folder) are
/// percent-encoded, which pyarrow, Polars and DuckDB decode.
pub fn hive_value(v: &str) -> String {
    let mut s = String::new();
    for (i, b) in v.bytes().enumerate() {
        if b.is_ascii_alphanumeric() || matches!(b, b'-' | b'_') || (b == b'.' && i > 0) {
            s.push(b as char);
        } else {
            s.push_str(&format!("%{b:02X}"));
        }
    }
    s
}
