//! The reference map and library made once (`workflow::mapcache`, `store::cache`). Whether
//! a run reused its map or a call its library is read from the cache folder and the run
//! folder, not from what the program says of itself: an entry reused is untouched (every
//! file's inode and modification time as before, no entry added), an entry made is the one
//! entry that changed; a run that trained computed the library's features
//! (`reference-features/`), one that reused did not; and the run's `model.json` is the
//! entry's, byte for byte. Each test has a cache of its own, so no test decides another's
//! path.

use crate::{aepipe_with_cache, real_data, TempDir};
use aepipe::sim::reference::{LibraryDir, ReferenceConfig, ReferenceFile};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// The cache's folder of map entries below `XDG_CACHE_HOME` (`workflow::mapcache`).
const MAPS: &str = "aepipe/som-map";

/// Each entry of a cache kind's folder: its name → each file's (inode, modification time).
/// Half-written entries (`.KEY.PID.tmp`) are not entries.
type Entries = BTreeMap<String, BTreeMap<String, (u64, SystemTime)>>;

fn entries(kind: &Path) -> Entries {
    use std::os::unix::fs::MetadataExt;
    let mut out = Entries::new();
    for e in std::fs::read_dir(kind).into_iter().flatten().flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') || !e.path().is_dir() {
            continue;
        }
        let files = std::fs::read_dir(e.path()).unwrap().flatten().map(|f| {
            let m = f.metadata().unwrap();
            let id = (m.ino(), m.modified().unwrap());
            (f.file_name().to_string_lossy().into_owned(), id)
        });
        out.insert(name, files.collect());
    }
    out
}

/// The entries that are new or were written again between two looks at the cache.
fn changed(before: &Entries, after: &Entries) -> Result<Vec<String>, String> {
    if let Some(gone) = before.keys().find(|k| !after.contains_key(*k)) {
        return Err(format!("entry {gone} was removed"));
    }
    Ok(after
        .iter()
        .filter(|(k, v)| before.get(*k) != Some(v))
        .map(|(k, _)| k.clone())
        .collect())
}

/// What a run left in the cache and its folder.
struct MapRun {
    before: Entries,
    after: Entries,
    maps: PathBuf,
    run: PathBuf,
}

impl MapRun {
    fn trained(&self) -> bool {
        self.run.join("reference-features").is_dir()
    }

    /// The run's map is `entry`'s, byte for byte.
    fn model_is(&self, entry: &str) -> Result<(), String> {
        let run =
            std::fs::read(self.run.join("som/model/model.json")).map_err(|e| e.to_string())?;
        let kept = std::fs::read(self.maps.join(entry).join("model.json"));
        match kept {
            Ok(k) if k == run => Ok(()),
            _ => Err(format!("the run's model.json is not entry {entry}'s")),
        }
    }

    /// The features stage's manifest.json names the run's map: `som_map` holds `entry`'s key
    /// (an entry's folder is its key) and whether the run reused it.
    fn manifest_names(&self, entry: &str, reused: bool) -> Result<(), String> {
        let path = self.run.join("features/manifest.json");
        let text =
            std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        let m: serde_json::Value = serde_json::from_str(&text).map_err(|e| e.to_string())?;
        let got = (
            m["som_map"]["cache_key"].as_str(),
            m["som_map"]["reused"].as_bool(),
        );
        if got != (Some(entry), Some(reused)) {
            return Err(format!(
                "manifest.json's som_map is {:?}, not ({entry}, {reused})",
                m["som_map"]
            ));
        }
        Ok(())
    }

    /// The map was reused: no entry added or written again, the library's features never
    /// computed, and the run's map an entry's, which the manifest names. The entry's name.
    fn reused(&self) -> Result<String, String> {
        let c = changed(&self.before, &self.after)?;
        if !c.is_empty() {
            return Err(format!("entries {c:?} were made or written again"));
        }
        if self.trained() {
            return Err("the run computed the library's features: it trained".into());
        }
        let of_run = self.after.keys().find(|k| self.model_is(k).is_ok());
        let k = of_run
            .cloned()
            .ok_or_else(|| "the run's model.json is no entry's".to_string())?;
        self.manifest_names(&k, true)?;
        Ok(k)
    }

    /// The map was trained and kept: exactly one entry new or written again, the others
    /// untouched, the library's features computed, and the run's map that entry's. Its name.
    fn made(&self) -> Result<String, String> {
        let c = changed(&self.before, &self.after)?;
        let [k] = c.as_slice() else {
            return Err(format!("{} entries made or written again: {c:?}", c.len()));
        };
        if !self.trained() {
            return Err("the run did not compute the library's features: it did not train".into());
        }
        self.model_is(k)?;
        self.manifest_names(k, false)?;
        Ok(k.clone())
    }
}

/// `aepipe run` of `args` (besides `--out`) into `dir/out` with the cache `xdg`: what it
/// left, and its stderr.
fn run_looked_at(xdg: &Path, dir: &Path, out: &str, args: &[&str]) -> (MapRun, String) {
    let maps = xdg.join(MAPS);
    let run = dir.join(out);
    let before = entries(&maps);
    let mut a = vec!["run", "--out", run.to_str().unwrap()];
    a.extend_from_slice(args);
    let (code, so, se) = aepipe_with_cache(&a, xdg);
    assert_eq!(code, 0, "{so}{se}");
    let after = entries(&maps);
    let r = MapRun {
        before,
        after,
        maps,
        run,
    };
    (r, se)
}

/// Flip one digit of `file` (same size: only its checksum can tell).
fn corrupt(file: &Path) {
    let mut b = std::fs::read(file).unwrap();
    let i = b.iter().position(|c| c.is_ascii_digit()).unwrap();
    b[i] = if b[i] == b'9' { b'8' } else { b[i] + 1 };
    std::fs::write(file, &b).unwrap();
}

/// A map's key is what shapes it, read from the cache and the run folders: the same
/// settings reuse the map, a changed `[report]` reuses it too (it shows the run, it does
/// not shape the map), a changed `[dsp]` (it shapes the library's features) and a changed
/// library file (other signals at the same path) train a new one; `--no-cache` trains and
/// keeps nothing; a corrupted entry (one digit of its `model.json`) is trained again, said
/// on stderr, never used. A small named library and a synthetic Vallen test, so it needs
/// no data and runs in seconds.
///
/// Plants: the `[dsp]` run's evidence fed to the reuse check (an entry was made), the
/// `--no-cache` run's (the cache untouched, but it trained), and the `[report]` run's fed
/// to the check that a map was made — each fails.
#[test]
fn the_map_is_reused_for_the_same_settings_and_report_and_made_for_new_dsp_or_library() {
    let t = TempDir::new("map-key");
    let xdg = t.path().join("xdg");
    let d = t.path();
    let lib_a = crate::e2e::small_library_seeded(d, "lib-a", 2008, 1);
    let lib_b = crate::e2e::small_library_seeded(d, "lib-b", 2009, 1);
    let named = d.join("named.parquet");
    std::fs::copy(&lib_a, &named).unwrap();
    crate::vallen_fixture(&d.join("data"), "exp", 40, 3);
    let base = format!(
        "[som]\nreference_library = \"{}\"\n[report]\nenabled = false\n",
        named.display()
    );
    let config = |name: &str, extra: &str| {
        let p = d.join(name);
        std::fs::write(&p, format!("{base}{extra}")).unwrap();
        p.to_str().unwrap().to_string()
    };
    let (cfg, report) = (
        config("base.toml", ""),
        config("report.toml", "gallery_per_class = 3\n"),
    );
    let dsp = config("dsp.toml", "[dsp.cwt]\nfwhm_periods = 2.5\n");
    let data = d.join("data");
    let data = data.to_str().unwrap();
    let run = |out: &str, cfg: &str, extra: &[&str]| {
        let mut a = vec!["--config", cfg, data];
        a.extend_from_slice(extra);
        run_looked_at(&xdg, d, out, &a)
    };
    let k1 = run("r1", &cfg, &[]).0.made().unwrap();
    assert_eq!(run("r2", &cfg, &[]).0.reused(), Ok(k1.clone()));
    let (r_report, _) = run("r-report", &report, &[]);
    assert_eq!(r_report.reused(), Ok(k1.clone()));
    let (r_dsp, _) = run("r-dsp", &dsp, &[]);
    let k_dsp = r_dsp.made().unwrap();
    assert_ne!(k_dsp, k1);
    std::fs::copy(&lib_b, &named).unwrap();
    let k_lib = run("r-lib", &cfg, &[]).0.made().unwrap();
    assert!(k_lib != k1 && k_lib != k_dsp, "{k_lib}");
    let (r_none, _) = run("r-none", &cfg, &["--no-cache"]);
    assert!(r_none.trained() && changed(&r_none.before, &r_none.after) == Ok(vec![]));
    // The plants: each run's evidence fed to the check it must fail.
    assert!(r_dsp
        .reused()
        .unwrap_err()
        .contains("were made or written again"));
    assert!(r_none.reused().unwrap_err().contains("it trained"));
    assert!(r_report.made().unwrap_err().contains("0 entries made"));
    // A corrupted entry is made again under its own key, and the run's map is sound.
    let model = xdg.join(MAPS).join(&k_lib).join("model.json");
    corrupt(&model);
    let broken = std::fs::read(&model).unwrap();
    let (r_bad, se) = run("r-bad", &cfg, &[]);
    assert!(
        se.contains("model.json fails its checksum") && se.contains("made again"),
        "{se}"
    );
    assert_eq!(r_bad.made(), Ok(k_lib.clone()));
    assert_ne!(std::fs::read(&model).unwrap(), broken);
}

/// The real AEwin test (EXP2009), in a cache of the test's own: the second run reuses the
/// map (read from the cache and run folders, see [`MapRun::reused`]) and classifies byte
/// for byte as the first, its `run.json` names the entry; a corrupted entry is made again,
/// with a note, and classifies as the first — trained on the library entry the first run
/// kept, which it leaves untouched.
///
/// Plant: the first run's evidence fed to the reuse check (it made the entry) fails.
#[test]
fn the_map_is_made_once_per_settings_and_a_broken_entry_is_made_again() {
    let Some(real) = real_data("the_map_is_made_once_per_settings") else {
        return;
    };
    let t = TempDir::new("map-cache");
    let xdg = t.path().join("cache");
    let data = real.join("aewin_cfrp_tensile");
    let cfg = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/aewin-cfrp.toml");
    let args = ["--config", cfg.to_str().unwrap(), data.to_str().unwrap()];
    let run = |out: &str| {
        let (r, se) = run_looked_at(&xdg, t.path(), out, &args);
        let class = std::fs::read(r.run.join("som/classification.parquet")).unwrap();
        (r, se, class)
    };
    let libraries = xdg.join("aepipe/reference-library");
    let (r1, _, c1) = run("r1");
    let k1 = r1.made().unwrap();
    let lib1 = entries(&libraries);
    assert_eq!(
        lib1.len(),
        1,
        "the embedded library is not kept once: {lib1:?}"
    );
    let (r2, _, c2) = run("r2");
    assert_eq!(r2.reused(), Ok(k1.clone()));
    assert!(r1.reused().is_err(), "the plant passed the reuse check");
    assert_eq!(c1, c2, "the cached map classifies otherwise");
    let json = std::fs::read_to_string(r2.run.join("run.json")).unwrap();
    assert!(json.contains(&k1), "run.json does not name the map {k1}");
    corrupt(&xdg.join(MAPS).join(&k1).join("model.json"));
    let (r3, se3, c3) = run("r3");
    assert!(
        se3.contains("model.json fails its checksum") && se3.contains("made again"),
        "{se3}"
    );
    assert_eq!(r3.made(), Ok(k1));
    assert_eq!(c1, c3);
    // The map was trained again on the library already simulated: its entry untouched, and
    // the run's library that entry's bytes.
    assert_eq!(changed(&lib1, &entries(&libraries)), Ok(vec![]));
    let (lib_k, _) = lib1.first_key_value().unwrap();
    let kept = std::fs::read(libraries.join(lib_k).join("waveforms.parquet")).unwrap();
    assert!(std::fs::read(r3.run.join("reference/waveforms.parquet")).unwrap() == kept);
}

/// What a call of the library cache is: cache root, definition, library folder.
type LibFn<'a> = dyn Fn(&Path, &ReferenceConfig, &LibraryDir) -> Result<(), String> + 'a;

/// A library of one bond failure heard by one sensor, seeded: seconds to simulate.
fn tiny_library(seed: u64) -> ReferenceConfig {
    let text = format!(
        "[reference]\nseed = {seed}\nsensors = [[125, 100]]\n\
         [[reference.scenario]]\nname = \"mesh3x3-bond-failure\"\n\
         params = {{ t2 = [-1], iterations = [2000] }}\n"
    );
    ReferenceFile::parse(&text, Path::new("tiny.toml"))
        .unwrap()
        .reference
}

/// The library cache's rules, checked on `lib` in `dir`: a definition's first call makes
/// one entry of the signals it wrote; another definition makes another and leaves the
/// first; the same definition again changes no entry and writes the entry's bytes; an entry
/// marked with other (checksummed) signals is what the same definition then writes, so it
/// copied and did not simulate; a corrupted entry is simulated again (the signals of the
/// first call) and kept again. The first rule broken, or Ok.
fn library_cache_holds(lib: &LibFn<'_>, dir: &Path) -> Result<(), String> {
    let root = dir.join("cache");
    let kind = root.join("reference-library");
    let (a, b) = (tiny_library(2008), tiny_library(2009));
    let mut n = 0;
    let mut call = |def: &ReferenceConfig| -> Result<(Vec<String>, Vec<u8>), String> {
        n += 1;
        let out = LibraryDir::new(dir.join(format!("out-{n}")));
        let before = entries(&kind);
        lib(&root, def, &out)?;
        let c = changed(&before, &entries(&kind))?;
        let w = std::fs::read(out.waveforms()).map_err(|e| e.to_string())?;
        Ok((c, w))
    };
    let in_entry = |k: &str| std::fs::read(kind.join(k).join("waveforms.parquet")).ok();
    let (c, w_a) = call(&a)?;
    let [k_a] = c.as_slice() else {
        return Err(format!("the first call made {c:?}"));
    };
    if in_entry(k_a).as_ref() != Some(&w_a) || w_a.len() < 1000 {
        return Err("the entry is not the library the call wrote".into());
    }
    let (c, w_b) = call(&b)?;
    let [k_b] = c.as_slice() else {
        return Err(format!("another definition made {c:?}"));
    };
    if k_b == k_a || in_entry(k_b).as_ref() != Some(&w_b) || w_b == w_a {
        return Err("another definition was not kept apart".into());
    }
    let (c, w) = call(&a)?;
    if !c.is_empty() || w != w_a {
        return Err(format!("the same definition again: entries {c:?} written"));
    }
    // The mark: entry a holds b's signals, with checksums that match.
    let files: Vec<PathBuf> = ["waveforms.parquet", "library.json"]
        .iter()
        .map(|f| kind.join(k_b).join(f))
        .collect();
    let refs: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
    aepipe::store::cache::Cache::at(&root)
        .put("reference-library", k_a, &refs)
        .unwrap();
    if call(&a)?.1 != w_b {
        return Err("the library was simulated again, not copied from its entry".into());
    }
    corrupt_byte(&kind.join(k_a).join("waveforms.parquet"));
    let (c, w) = call(&a)?;
    let rows = |w: &[u8]| {
        let p = dir.join("rows.parquet");
        std::fs::write(&p, w).unwrap();
        crate::table_rows(&p)
    };
    if c != [k_a.clone()] || w == w_b || rows(&w) != rows(&w_a) || in_entry(k_a) != Some(w) {
        return Err("a corrupted entry was not simulated and kept again".into());
    }
    Ok(())
}

/// Flip the middle byte of `file`.
fn corrupt_byte(file: &Path) {
    let mut b = std::fs::read(file).unwrap();
    let i = b.len() / 2;
    b[i] ^= 0x55;
    std::fs::write(file, &b).unwrap();
}

/// The reference library is simulated once per definition and copied after
/// ([`library_cache_holds`]), on a tiny definition of the test's own, in-process.
///
/// Plants, wrong copies of `mapcache::library`: one whose entry is removed before each call
/// (a cache written, never read), one that copies the first entry it finds whatever the
/// definition (a key that every definition shares), one that copies an entry's files
/// without checking them — each fails its rule.
#[test]
fn a_library_is_simulated_once_per_definition_and_a_broken_entry_again() {
    use aepipe::workflow::mapcache::library;
    let t = TempDir::new("library-cache");
    let real: &LibFn<'_> = &|root, def, dir| {
        library(Some(root), def, dir, false).map_err(|e| e.to_string())?;
        Ok(())
    };
    library_cache_holds(real, &t.path().join("real")).unwrap();
    // The library entry's key, as mapcache derives it (if it drifts, the plants below stop
    // removing or finding their entries and pass, and this test fails).
    let entry_of = |root: &Path, def: &ReferenceConfig| {
        let text = serde_json::to_string(def).unwrap();
        let k = aepipe::store::cache::key(&[b"aepipe reference library v1", text.as_bytes()]);
        root.join("reference-library").join(k)
    };
    let copy_all = |from: &Path, to: &LibraryDir| {
        std::fs::create_dir_all(to.path()).unwrap();
        for f in std::fs::read_dir(from).unwrap().flatten() {
            std::fs::copy(f.path(), to.path().join(f.file_name())).unwrap();
        }
    };
    let never_read: &LibFn<'_> = &|root, def, dir| {
        let _ = std::fs::remove_dir_all(entry_of(root, def));
        real(root, def, dir)
    };
    let shared_key: &LibFn<'_> = &|root, def, dir| {
        let first = entries(&root.join("reference-library")).into_keys().next();
        match first {
            Some(k) => copy_all(&root.join("reference-library").join(k), dir),
            None => real(root, def, dir)?,
        }
        Ok(())
    };
    let unchecked: &LibFn<'_> = &|root, def, dir| {
        let e = entry_of(root, def);
        match e.is_dir() {
            true => copy_all(&e, dir),
            false => real(root, def, dir)?,
        }
        Ok(())
    };
    for (i, (plant, rule)) in [
        (never_read, "the same definition again"),
        (shared_key, "another definition made []"),
        (unchecked, "a corrupted entry was not simulated"),
    ]
    .into_iter()
    .enumerate()
    {
        let got = library_cache_holds(plant, &t.path().join(format!("plant-{i}")));
        assert!(got.as_ref().is_err_and(|e| e.starts_with(rule)), "{got:?}");
    }
}
