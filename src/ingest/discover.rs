//! Discovery: find the experiments in files and folders. Walking, telling each file's kind,
//! grouping files into sources, and naming the sources uniquely are one function each.

use super::sniff::{self, Kind as TextKind};
use super::{aewin, dta, vallen, whole_file_reject, Format, Source};
use crate::ingest::settings::FormatChoice;
use crate::ingest::settings::IngestConfig;
use crate::model::{Reject, Stage};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// What [`discover`] found.
#[derive(Debug, Default)]
pub struct Discovery {
    /// Sources sorted by (id, first file).
    pub sources: Vec<Source>,
    /// Inputs that cannot be read at all (explicitly named unknown files, missing paths).
    pub rejects: Vec<Reject>,
    /// Files inside input folders that are not recordings (READMEs, setups, pick lists…),
    /// with the reason they were passed over.
    pub skipped: Vec<(PathBuf, String)>,
}

/// What one file looks like: binary formats by extension (and magic bytes), text by what
/// it holds ([`sniff`]).
#[derive(Debug, Clone, PartialEq)]
enum Kind {
    Pridb,
    Tradb,
    Parquet,
    Wav,
    Stream,
    Dta,
    Text(TextKind),
    Other(String),
}

fn ext_lower(p: &Path) -> String {
    p.extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default()
}

/// Every text reader's recogniser, in the order that breaks a tie no name breaks.
const TEXT_READERS: &[&sniff::Recogniser] = &[
    &super::waveexplorer::RECOGNISER,
    &super::aewin::HEADER_RECOGNISER,
    &super::vallen::txt::RECOGNISER,
    &super::aewin::HIT_LIST_RECOGNISER,
    &super::aewin::MACHINE_LOG_RECOGNISER,
    &super::csvfmt::RECOGNISER,
    &super::aewin::VALUES_RECOGNISER,
    &super::text::RECOGNISER,
];

fn detect_format(p: &Path, forced: FormatChoice) -> std::io::Result<Kind> {
    let ext = ext_lower(p);
    match ext.as_str() {
        "pridb" => return Ok(Kind::Pridb),
        "tradb" => return Ok(Kind::Tradb),
        "parquet" => return Ok(Kind::Parquet),
        "wav" => return Ok(Kind::Wav),
        "npy" => return Ok(Kind::Stream),
        // A raw stream is a file with its description beside it (`x.bin` + `x.bin.toml`).
        _ if super::stream::sidecar_path(p).is_file() => return Ok(Kind::Stream),
        "toml" if Path::new(&p.with_extension("")).is_file() => {
            return Ok(Kind::Other(format!(
                "the description of the raw stream {}",
                p.with_extension("").display()
            )))
        }
        "dta" => {
            use std::io::Read;
            let mut b = [0u8; 3];
            let n = std::fs::File::open(p)?.read(&mut b)?;
            return Ok(
                if dta::looks_like_dta(&b[..n]) || forced == FormatChoice::Mistras {
                    Kind::Dta
                } else {
                    Kind::Other(
                        "a .DTA file that does not start like a MISTRAS message stream".into(),
                    )
                },
            );
        }
        e if sniff::TEXT_EXTENSIONS.contains(&e) => {}
        _ => return Ok(Kind::Other(format!("unknown file type '.{ext}'"))),
    }
    let head = sniff::Head::read(p)?;
    Ok(match sniff::sniff(TEXT_READERS, &head, forced) {
        Ok(k) => Kind::Text(k),
        Err(why) => Kind::Other(why.0),
    })
}

/// Natural ordering for file names: digit runs compare as numbers (`hit_2` < `hit_10`).
pub(crate) fn natural_key(s: &str) -> Vec<(u8, u64, String)> {
    let mut out = Vec::new();
    let mut chars = s.chars().peekable();
    while let Some(&c) = chars.peek() {
        if c.is_ascii_digit() {
            let mut n = String::new();
            while let Some(&d) = chars.peek() {
                if d.is_ascii_digit() {
                    n.push(d);
                    chars.next();
                } else {
                    break;
                }
            }
            out.push((0, n.parse::<u64>().unwrap_or(u64::MAX), n));
        } else {
            let mut t = String::new();
            while let Some(&d) = chars.peek() {
                if d.is_ascii_digit() {
                    break;
                }
                t.push(d);
                chars.next();
            }
            out.push((1, 0, t));
        }
    }
    out
}

/// A file's identity on disk (device, inode), so that a folder or file reached through
/// several links is read once.
fn file_id(p: &Path) -> Option<(u64, u64)> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        std::fs::metadata(p).ok().map(|m| (m.dev(), m.ino()))
    }
    #[cfg(not(unix))]
    {
        let c = std::fs::canonicalize(p).ok()?;
        let mut h = std::collections::hash_map::DefaultHasher::new();
        std::hash::Hash::hash(&c, &mut h);
        Some((0, std::hash::Hasher::finish(&h)))
    }
}

/// Every file below `dir`, each folder visited once (a symlink loop ends at the folder it
/// leads back to, with a note in `skipped`).
fn walk(
    dir: &Path,
    seen: &mut std::collections::HashSet<(u64, u64)>,
    out: &mut Vec<PathBuf>,
    errs: &mut Vec<(PathBuf, String)>,
    skipped: &mut Vec<(PathBuf, String)>,
) {
    if let Some(id) = file_id(dir) {
        if !seen.insert(id) {
            skipped.push((
                dir.to_path_buf(),
                "folder already read through another path (a link back to it)".into(),
            ));
            return;
        }
    }
    let rd = match std::fs::read_dir(dir) {
        Ok(rd) => rd,
        Err(e) => {
            errs.push((dir.to_path_buf(), format!("cannot list folder: {e}")));
            return;
        }
    };
    let mut entries: Vec<PathBuf> = rd.flatten().map(|e| e.path()).collect();
    entries.sort();
    for p in entries {
        let name = p
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default();
        if name.starts_with('.') {
            continue; // hidden files, our own temporary files, virtualenvs
        }
        if p.is_dir() {
            walk(&p, seen, out, errs, skipped);
        } else {
            out.push(p);
        }
    }
}

fn stem(p: &Path) -> String {
    p.file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default()
}

fn dir_name(p: &Path) -> String {
    p.parent()
        .and_then(|d| d.file_name())
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_else(|| "experiment".into())
}

/// Find the sources in files and folders (folders searched recursively): walk the inputs,
/// tell each file's kind, group the files into sources, and name the sources uniquely.
pub fn discover(inputs: &[PathBuf], cfg: &IngestConfig) -> Discovery {
    let mut d = Discovery::default();
    let (files, roots) = walk_inputs(inputs, &mut d);
    let kinds = classify(files, cfg.format, &mut d);
    group(kinds, &mut d);
    unique_ids(&mut d.sources, &roots);
    d.sources
        .sort_by(|a, b| (&a.id, a.all_files().next()).cmp(&(&b.id, b.all_files().next())));
    d
}

/// The input folder each file was found in (its own folder for a file named explicitly):
/// colliding experiment ids are made unique by their path below it.
type Roots = std::collections::HashMap<PathBuf, PathBuf>;

/// Every file of the inputs, once (`(path, named explicitly?)`, sorted), and its input
/// folder; missing inputs and unreadable folders are rejects, links back to a folder and a
/// file reached twice are passed over.
fn walk_inputs(inputs: &[PathBuf], d: &mut Discovery) -> (Vec<(PathBuf, bool)>, Roots) {
    // (path, explicitly named?)
    let mut files: Vec<(PathBuf, bool)> = Vec::new();
    let mut roots: Roots = Default::default();
    let mut seen_dirs = std::collections::HashSet::new();
    for inp in inputs {
        if inp.is_dir() {
            let mut found = Vec::new();
            let mut errs = Vec::new();
            walk(inp, &mut seen_dirs, &mut found, &mut errs, &mut d.skipped);
            for (p, why) in errs {
                d.rejects.push(whole_file_reject(&p, Stage::Discover, why));
            }
            for p in &found {
                roots.entry(p.clone()).or_insert_with(|| inp.clone());
            }
            files.extend(found.into_iter().map(|p| (p, false)));
        } else if inp.exists() || inp.symlink_metadata().is_ok() {
            roots
                .entry(inp.clone())
                .or_insert_with(|| inp.parent().map(Path::to_path_buf).unwrap_or_default());
            files.push((inp.clone(), true));
        } else {
            d.rejects.push(whole_file_reject(
                inp,
                Stage::Discover,
                "no such file or folder".into(),
            ));
        }
    }
    files.sort();
    files.dedup_by(|a, b| a.0 == b.0);
    // The same file reached through two links is read once (the first path, in order).
    let mut seen_files = std::collections::HashSet::new();
    files.retain(|(p, _)| match file_id(p) {
        Some(id) => {
            let first = seen_files.insert(id);
            if !first {
                d.skipped.push((
                    p.clone(),
                    "the same file as one read through another path".into(),
                ));
            }
            first
        }
        None => true,
    });

    (files, roots)
}

/// Each file's kind from its name and head; what is not a recording is a reject when named
/// explicitly and passed over (with the reason) when found in a folder.
fn classify(
    files: Vec<(PathBuf, bool)>,
    forced: FormatChoice,
    d: &mut Discovery,
) -> Vec<(PathBuf, Kind)> {
    let mut kinds: Vec<(PathBuf, Kind)> = Vec::new();
    for (p, explicit) in files {
        let kind = match detect_format(&p, forced) {
            Ok(k) => k,
            Err(e) => {
                d.rejects.push(whole_file_reject(
                    &p,
                    Stage::Discover,
                    format!("cannot read: {e}"),
                ));
                continue;
            }
        };
        match kind {
            Kind::Other(why) => {
                if explicit {
                    d.rejects.push(whole_file_reject(
                        &p,
                        Stage::Discover,
                        format!("not a recording aepipe reads: {why}"),
                    ));
                } else {
                    d.skipped.push((p, why));
                }
            }
            k => kinds.push((p, k)),
        }
    }

    kinds
}

/// The files of a discovery, sorted by what they become.
#[derive(Default)]
struct Sorted {
    pairs: vallen::Pairs,
    /// Vallen TXT exports by their database's base path.
    exports: BTreeMap<PathBuf, Vec<PathBuf>>,
    /// One-hit-per-file groups by (folder, format, test): the test only for AEwin files.
    per_hit: BTreeMap<(PathBuf, Format, Option<String>), Vec<PathBuf>>,
    /// MISTRAS chains by (folder, base name).
    chains: BTreeMap<(PathBuf, String), Vec<PathBuf>>,
    /// Files that are a source each (WaveExplorer, a long CSV, a waveforms table).
    single: Vec<Source>,
    /// Companions waiting for their AEwin test.
    hit_lists: Vec<PathBuf>,
    logs: Vec<PathBuf>,
}

/// Each file to the group its kind says.
fn sort(kinds: Vec<(PathBuf, Kind)>) -> Sorted {
    let mut s = Sorted::default();
    for (p, k) in kinds {
        let parent = p.parent().map(Path::to_path_buf).unwrap_or_default();
        let group = match k {
            Kind::Pridb => {
                let base = p.with_extension("");
                s.pairs.entry(base).or_default().0 = Some(p);
                continue;
            }
            Kind::Tradb => {
                let base = p.with_extension("");
                s.pairs.entry(base).or_default().1 = Some(p);
                continue;
            }
            Kind::Parquet => {
                s.single
                    .push(Source::of(stem(&p), Format::Parquet, vec![p]));
                continue;
            }
            Kind::Stream => {
                s.single.push(Source::of(stem(&p), Format::Stream, vec![p]));
                continue;
            }
            Kind::Text(TextKind::WaveExplorer) => {
                s.single
                    .push(Source::of(stem(&p), Format::WaveExplorer, vec![p]));
                continue;
            }
            Kind::Text(TextKind::CsvLong) => {
                s.single
                    .push(Source::of(stem(&p), Format::CsvLong, vec![p]));
                continue;
            }
            Kind::Text(TextKind::VallenTxt { datafile }) => {
                s.exports.entry(parent.join(datafile)).or_default().push(p);
                continue;
            }
            Kind::Dta => {
                let key = (parent, dta::chain_key(&p).0);
                s.chains.entry(key).or_default().push(p);
                continue;
            }
            Kind::Text(TextKind::MachineLog) => {
                s.logs.push(p);
                continue;
            }
            Kind::Text(TextKind::AewinHitList) => {
                s.hit_lists.push(p);
                continue;
            }
            Kind::Wav => (Format::Wav, None),
            Kind::Text(TextKind::CsvPerHit) => (Format::CsvPerHit, None),
            Kind::Text(TextKind::Text) => (Format::Text, None),
            Kind::Text(TextKind::AewinWave { test }) => (Format::Aewin, test),
            Kind::Other(_) => unreachable!("filtered above"),
        };
        s.per_hit
            .entry((parent, group.0, group.1))
            .or_default()
            .push(p);
    }
    s
}

/// The files into sources, each format's way (its reader module groups them): Vallen
/// pairs with their companions by role, Vallen TXT exports by database (unless it is
/// read), MISTRAS chains, one-hit-per-file folders by (folder, format) — AEwin files by
/// (folder, test) with the test's hit list and machine log — and single-file sources.
fn group(kinds: Vec<(PathBuf, Kind)>, d: &mut Discovery) {
    let s = sort(kinds);
    d.sources.extend(s.single);
    d.sources
        .extend(vallen::pair_sources(&s.pairs, &mut d.skipped));
    d.sources.extend(vallen::txt::export_sources(
        s.exports,
        &s.pairs,
        &mut d.skipped,
    ));
    d.sources.extend(dta::chain_sources(s.chains));
    let mut used = BTreeSet::new();
    for ((dir, format, test), mut files) in s.per_hit {
        files.sort_by_key(|p| natural_key(&p.file_name().unwrap_or_default().to_string_lossy()));
        let id = test.unwrap_or_else(|| {
            dir.file_name()
                .map(|s| s.to_string_lossy().to_string())
                .unwrap_or_else(|| dir_name(&files[0]))
        });
        let mut src = Source::of(id, format, files);
        if format == Format::Aewin {
            aewin::adopt_companions(&mut src, &dir, &s.hit_lists, &s.logs, &mut used);
        }
        d.sources.push(src);
    }
    for l in s.logs.into_iter().filter(|l| !used.contains(l)) {
        d.skipped.push((
            l,
            "test-machine log with no AEwin experiment to attach to".into(),
        ));
    }
    for h in s.hit_lists.into_iter().filter(|h| !used.contains(h)) {
        d.skipped
            .push((h, "AEwin hit list with no waveform folder beside it".into()));
    }
}

/// The path that names a source: its folder for a folder of one-hit files, else its first
/// file without extension (a MISTRAS chain without its `__N`).
fn source_base(s: &Source) -> PathBuf {
    let Some(first) = s.all_files().next() else {
        return PathBuf::from(&s.id);
    };
    let dir = first.parent().map(Path::to_path_buf).unwrap_or_default();
    let own_name = dir.file_name().is_some_and(|n| n.to_string_lossy() == s.id);
    if s.format == Format::VallenTxt || (s.format == Format::Aewin && !own_name) {
        // Several tests (databases) in one folder: each its own base.
        dir.join(&s.id)
    } else if s.format.one_hit_per_file() {
        dir
    } else if s.format == Format::Mistras {
        dir.join(dta::chain_key(first).0)
    } else {
        first.with_extension("")
    }
}

fn slash_path(p: &Path) -> String {
    p.components()
        .map(|c| c.as_os_str().to_string_lossy().to_string())
        .filter(|c| !c.is_empty() && c != "/")
        .collect::<Vec<_>>()
        .join("/")
}

/// Experiment ids unique in a batch: sources whose names collide (`a/bearing.pridb` and
/// `b/bearing.pridb`) take their path relative to the input folder they were found in
/// (`a/bearing`, `b/bearing`); where that still collides (the same path below two input
/// folders), the shortest tail of the full path that tells them apart.
fn unique_ids(sources: &mut [Source], roots: &std::collections::HashMap<PathBuf, PathBuf>) {
    let mut by_id: std::collections::BTreeMap<String, Vec<usize>> = Default::default();
    for (i, s) in sources.iter().enumerate() {
        by_id.entry(s.id.clone()).or_default().push(i);
    }
    for group in by_id.into_values().filter(|g| g.len() > 1) {
        let bases: Vec<PathBuf> = group.iter().map(|&i| source_base(&sources[i])).collect();
        let rel: Vec<String> = group
            .iter()
            .zip(&bases)
            .map(|(&i, b)| {
                let root = sources[i]
                    .all_files()
                    .next()
                    .and_then(|f| roots.get(f))
                    .cloned()
                    .unwrap_or_default();
                slash_path(b.strip_prefix(&root).unwrap_or(b))
            })
            .collect();
        let distinct: std::collections::HashSet<&String> = rel.iter().collect();
        let ids = if distinct.len() == rel.len() {
            rel
        } else {
            // Grow the tail of each full path until the group's ids differ.
            let comps: Vec<Vec<String>> = bases
                .iter()
                .map(|b| slash_path(b).split('/').map(str::to_string).collect())
                .collect();
            let longest = comps.iter().map(Vec::len).max().unwrap_or(1);
            (1..=longest)
                .map(|k| {
                    comps
                        .iter()
                        .map(|c| c[c.len().saturating_sub(k)..].join("/"))
                        .collect::<Vec<_>>()
                })
                .find(|ids| ids.iter().collect::<std::collections::HashSet<_>>().len() == ids.len())
                .unwrap_or_else(|| comps.iter().map(|c| c.join("/")).collect())
        };
        // Two sources of one path (a folder of WAV and of CSV files): numbered.
        let mut seen: std::collections::HashMap<String, usize> = Default::default();
        for (&i, id) in group.iter().zip(ids) {
            let n = seen.entry(id.clone()).or_insert(0);
            *n += 1;
            sources[i].id = if *n == 1 { id } else { format!("{id}-{n}") };
        }
    }
}
