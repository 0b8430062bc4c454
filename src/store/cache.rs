//! A content-addressed cache of things that are slow to make and fully decided by their
//! inputs: the reference libraries a run simulates and the maps it trains on them (issue 52:
//! a series of 15 tests paid the library and the map 15 times).
//!
//! An entry is a folder `ROOT/KIND/KEY/` holding the files it was given and `entry.json`,
//! which lists each file with its size and SHA-256. The key is the caller's: a hash of every
//! input that decides the entry, and of this build of aepipe ([`build_id`]). An entry is
//! written into a temporary folder and renamed into place, so a reader sees it whole or not at
//! all; an entry whose files do not match their checksums is removed and made again, never
//! used.

use crate::util::{file_digest, sha256_hex};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The cache root: `$XDG_CACHE_HOME/aepipe`, else `~/.cache/aepipe` (`None`: neither is set).
pub struct Cache {
    root: PathBuf,
}

/// What a lookup found.
#[derive(Debug)]
pub enum Lookup {
    /// A whole entry: its folder.
    Hit(PathBuf),
    /// No entry.
    Miss,
    /// An entry that failed its checks (the reason); it has been removed.
    Broken(String),
}

#[derive(Debug, Serialize, Deserialize)]
struct Entry {
    kind: String,
    key: String,
    /// (file name, size, sha256)
    files: Vec<(String, u64, String)>,
}

const ENTRY: &str = "entry.json";

impl Cache {
    /// The user's cache directory (XDG base directories).
    pub fn user() -> Option<Cache> {
        Cache::user_from(std::env::var_os("XDG_CACHE_HOME"), std::env::var_os("HOME"))
    }

    /// [`Cache::user`] from the two variables' values: `$XDG_CACHE_HOME/aepipe` when it is an
    /// absolute path (the XDG rule: a relative one is ignored), else `$HOME/.cache/aepipe`.
    fn user_from(
        xdg: Option<std::ffi::OsString>,
        home: Option<std::ffi::OsString>,
    ) -> Option<Cache> {
        let abs = |v: std::ffi::OsString| {
            let p = PathBuf::from(v);
            p.is_absolute().then_some(p)
        };
        let base = xdg
            .and_then(abs)
            .or_else(|| home.and_then(abs).map(|h| h.join(".cache")))?;
        Some(Cache::at(base.join("aepipe")))
    }

    /// A cache rooted at `root`.
    pub fn at(root: impl Into<PathBuf>) -> Cache {
        Cache { root: root.into() }
    }

    pub fn root(&self) -> &Path {
        &self.root
    }

    /// The folder of entry `kind`/`key` (whether or not it exists).
    pub fn entry_dir(&self, kind: &str, key: &str) -> PathBuf {
        self.root.join(kind).join(key)
    }

    /// The entry `kind`/`key`, checked: every listed file present with its size and SHA-256.
    pub fn get(&self, kind: &str, key: &str) -> Lookup {
        let dir = self.entry_dir(kind, key);
        if !dir.is_dir() {
            return Lookup::Miss;
        }
        match check(&dir, kind, key) {
            Ok(()) => Lookup::Hit(dir),
            Err(why) => {
                // A broken entry is never used; removing it lets the caller put a new one.
                let _ = std::fs::remove_dir_all(&dir);
                Lookup::Broken(format!("{}: {why}", dir.display()))
            }
        }
    }

    /// Store `files` (each copied from its path, under its file name) as entry `kind`/`key`.
    /// A concurrent writer of the same key may win the rename; its entry is as good.
    pub fn put(&self, kind: &str, key: &str, files: &[&Path]) -> std::io::Result<PathBuf> {
        let dir = self.entry_dir(kind, key);
        let parent = dir.parent().expect("kind/key has a parent");
        std::fs::create_dir_all(parent)?;
        let tmp = parent.join(format!(".{key}.{}.tmp", std::process::id()));
        let _ = std::fs::remove_dir_all(&tmp);
        std::fs::create_dir_all(&tmp)?;
        let mut entry = Entry {
            kind: kind.to_string(),
            key: key.to_string(),
            files: Vec::new(),
        };
        for f in files {
            let name = f
                .file_name()
                .and_then(|n| n.to_str())
                .ok_or_else(|| std::io::Error::other(format!("{}: no file name", f.display())))?
                .to_string();
            std::fs::copy(f, tmp.join(&name))?;
            let (size, sha) = file_digest(&tmp.join(&name))?;
            entry.files.push((name, size, sha));
        }
        let json = serde_json::to_string_pretty(&entry).expect("entry serialises");
        std::fs::write(tmp.join(ENTRY), json)?;
        let _ = std::fs::remove_dir_all(&dir);
        if std::fs::rename(&tmp, &dir).is_err() {
            let _ = std::fs::remove_dir_all(&tmp);
            if !dir.join(ENTRY).is_file() {
                return Err(std::io::Error::other(format!(
                    "{}: could not be put in place",
                    dir.display()
                )));
            }
        }
        Ok(dir)
    }
}

fn check(dir: &Path, kind: &str, key: &str) -> Result<(), String> {
    let text = std::fs::read_to_string(dir.join(ENTRY)).map_err(|e| format!("{ENTRY}: {e}"))?;
    let e: Entry = serde_json::from_str(&text).map_err(|e| format!("{ENTRY}: {e}"))?;
    if e.kind != kind || e.key != key {
        return Err(format!("{ENTRY} names {}/{}", e.kind, e.key));
    }
    for (name, size, sha) in &e.files {
        let (s, h) = file_digest(&dir.join(name)).map_err(|e| format!("{name}: {e}"))?;
        if s != *size || h != *sha {
            return Err(format!("{name} fails its checksum"));
        }
    }
    Ok(())
}

/// This build of aepipe: its version and its executable's size and modification time, so
/// that a rebuilt binary (whose simulator or features may have changed) never reuses what an
/// older one made.
pub fn build_id() -> String {
    let exe = std::env::current_exe()
        .and_then(std::fs::metadata)
        .map(|m| {
            let t = m
                .modified()
                .ok()
                .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                .map_or(0, |d| d.as_nanos());
            format!("{}:{t}", m.len())
        })
        .unwrap_or_default();
    format!("{} {exe}", env!("CARGO_PKG_VERSION"))
}

/// A cache key: SHA-256 of the parts (each length-prefixed, so no two lists collide) and
/// [`build_id`], first 32 hex digits.
pub fn key(parts: &[&[u8]]) -> String {
    let mut all = Vec::new();
    for p in parts.iter().copied().chain([build_id().as_bytes()]) {
        all.extend_from_slice(&(p.len() as u64).to_le_bytes());
        all.extend_from_slice(p);
    }
    sha256_hex(&all)[..32].to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The XDG rule, worked by hand: an absolute `XDG_CACHE_HOME` wins, a relative one is
    /// ignored for `HOME`'s `.cache`, and neither set is no cache.
    #[test]
    fn the_user_cache_follows_the_xdg_rule() {
        let root = |x: Option<&str>, h: Option<&str>| {
            Cache::user_from(x.map(Into::into), h.map(Into::into)).map(|c| c.root)
        };
        assert_eq!(
            root(Some("/x"), Some("/h")),
            Some(PathBuf::from("/x/aepipe"))
        );
        assert_eq!(
            root(Some("rel"), Some("/h")),
            Some(PathBuf::from("/h/.cache/aepipe"))
        );
        assert_eq!(
            root(None, Some("/h")),
            Some(PathBuf::from("/h/.cache/aepipe"))
        );
        assert_eq!(root(None, Some("h")), None);
        assert_eq!(root(None, None), None);
    }

    /// The build id names this crate's version and this executable's size, so a rebuilt
    /// binary of another size makes a new key.
    #[test]
    fn the_build_id_names_the_version_and_the_executable() {
        let id = build_id();
        let len = std::fs::metadata(std::env::current_exe().unwrap())
            .unwrap()
            .len();
        let (version, exe) = id.split_once(' ').unwrap();
        assert_eq!(version, env!("CARGO_PKG_VERSION"));
        assert_eq!(exe.split(':').next().unwrap(), len.to_string(), "{id}");
    }

    #[test]
    fn an_entry_is_found_whole_and_a_corrupted_one_is_removed() {
        let t = std::env::temp_dir().join(format!("aepipe-cache-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&t);
        std::fs::create_dir_all(&t).unwrap();
        let f = t.join("model.json");
        std::fs::write(&f, b"{\"a\": 1}").unwrap();
        let c = Cache::at(t.join("cache"));
        let k = key(&[b"som", b"rows=10"]);
        assert_ne!(k, key(&[b"som", b"rows=11"]));
        assert_ne!(key(&[b"ab", b"c"]), key(&[b"a", b"bc"]));
        assert!(matches!(c.get("map", &k), Lookup::Miss));
        let dir = c.put("map", &k, &[&f]).unwrap();
        match c.get("map", &k) {
            Lookup::Hit(d) => {
                assert_eq!(std::fs::read(d.join("model.json")).unwrap(), b"{\"a\": 1}")
            }
            other => panic!("{other:?}"),
        }
        // One byte changed, same size: the checksum, not the size, catches it.
        std::fs::write(dir.join("model.json"), b"{\"a\": 2}").unwrap();
        match c.get("map", &k) {
            Lookup::Broken(why) => assert!(why.contains("model.json fails its checksum"), "{why}"),
            other => panic!("{other:?}"),
        }
        assert!(!dir.exists());
        assert!(matches!(c.get("map", &k), Lookup::Miss));
        // An entry filed under another key is not this one.
        let d2 = c.put("map", "other", &[&f]).unwrap();
        std::fs::create_dir_all(c.entry_dir("map", &k)).unwrap();
        std::fs::copy(d2.join(ENTRY), c.entry_dir("map", &k).join(ENTRY)).unwrap();
        std::fs::copy(&f, c.entry_dir("map", &k).join("model.json")).unwrap();
        assert!(matches!(c.get("map", &k), Lookup::Broken(_)));
        let _ = std::fs::remove_dir_all(&t);
    }
}
