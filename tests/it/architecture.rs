//! The house's directions: every import between the library's top-level modules points down
//! the chain the README states (so no cycle either), clap stays in the command line, the
//! binary stays thin. Read from the source text (`crate::room` paths in the code outside
//! tests: the items `#[cfg(test)]` applies to dropped, the code after them read, files only
//! tests compile left out), so an import against the direction fails here before anyone has
//! to find it.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

pub(crate) fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

pub(crate) fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The top-level module a file belongs to (`src/som/tables.rs` → `som`).
fn room_of(file: &Path) -> Option<String> {
    let rel = file.strip_prefix(src()).ok()?;
    let first = rel
        .components()
        .next()?
        .as_os_str()
        .to_string_lossy()
        .to_string();
    let room = first.trim_end_matches(".rs").to_string();
    (room != "lib" && room != "main").then_some(room)
}

/// Top-level rooms named by `crate::x` (also inside `use crate::{x, y::z}`) in the code
/// outside tests: the first segment of every crate-rooted path the file-circle reader finds
/// ([`crate::imports::paths`]).
fn uses(text: &str) -> BTreeSet<String> {
    crate::imports::paths(text)
        .into_iter()
        .filter(|p| p.len() > 1 && p[0] == "crate")
        .map(|p| p[1].clone())
        .collect()
}

fn graph() -> BTreeMap<String, BTreeSet<String>> {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    let tests_only = crate::imports::test_only_files(&files);
    let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for f in files.iter().filter(|f| !tests_only.contains(*f)) {
        let Some(room) = room_of(f) else { continue };
        let text = std::fs::read_to_string(f).unwrap();
        let deps = g.entry(room.clone()).or_default();
        for u in uses(&text) {
            if u != room {
                deps.insert(u);
            }
        }
    }
    g
}

/// A cycle through `start`, if any (depth-first search).
pub(crate) fn find_cycle(g: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        n: &str,
        g: &BTreeMap<String, BTreeSet<String>>,
        state: &mut BTreeMap<String, u8>,
        stack: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        state.insert(n.to_string(), 1);
        stack.push(n.to_string());
        for d in g.get(n).into_iter().flatten() {
            match state.get(d.as_str()).copied().unwrap_or(0) {
                1 => {
                    let i = stack.iter().position(|s| s == d).unwrap();
                    let mut c = stack[i..].to_vec();
                    c.push(d.clone());
                    return Some(c);
                }
                0 => {
                    if let Some(c) = visit(d, g, state, stack) {
                        return Some(c);
                    }
                }
                _ => {}
            }
        }
        stack.pop();
        state.insert(n.to_string(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for n in g.keys() {
        if state.get(n.as_str()).copied().unwrap_or(0) == 0 {
            if let Some(c) = visit(n, g, &mut state, &mut Vec::new()) {
                return Some(c);
            }
        }
    }
    None
}

#[test]
fn the_cycle_finder_finds_a_planted_cycle_and_reads_grouped_imports() {
    // The checker itself must be able to fail.
    // The signature check: a map with String values is fine, a String error is not.
    let sig = |s: &str| {
        s.find("-> Result<")
            .map(|k| s[k..].trim_end())
            .is_some_and(|r| r.ends_with(", String>"))
    };
    assert!(sig("pub fn f(x: u8) -> Result<Vec<u8>, String> "));
    assert!(!sig("pub fn f(x: u8) -> BTreeMap<u8, String> "));
    assert!(!sig("pub fn f(x: u8) -> Result<BTreeMap<u8, String>, E> "));
    // A test-only import is not read, the code after it is.
    let u = uses("use crate::{config::X, util::{a, b}};\nfn f() { crate::store::g() }\n#[cfg(test)]\nuse crate::synth;\nfn g() { crate::events::h() }");
    assert_eq!(
        u.into_iter().collect::<Vec<_>>(),
        vec!["config", "events", "store", "util"]
    );
    let mut g = BTreeMap::new();
    g.insert("a".to_string(), BTreeSet::from(["b".to_string()]));
    g.insert("b".to_string(), BTreeSet::from(["c".to_string()]));
    g.insert("c".to_string(), BTreeSet::from(["a".to_string()]));
    assert_eq!(find_cycle(&g).unwrap().len(), 4);
    g.get_mut("c").unwrap().clear();
    assert!(find_cycle(&g).is_none());
}

#[test]
fn no_import_cycle_between_top_level_modules() {
    let g = graph();
    assert!(g.len() > 10, "read {} rooms", g.len());
    if let Some(c) = find_cycle(&g) {
        panic!("import cycle: {}", c.join(" → "));
    }
    // The leaves stay leaves.
    for leaf in ["util", "model"] {
        assert!(
            g.get(leaf).is_none_or(|d| d.is_empty()),
            "{leaf} uses {:?}",
            g[leaf]
        );
    }
    // The pipeline file gathers the rooms' settings: it stands above them, below the
    // rooms that read the whole of it.
    for above in ["pipeline", "workflow", "live", "report", "cli", "inspect"] {
        assert!(!g["config"].contains(above), "config uses {above}");
    }
    // The report renders what it is handed: it reads no inputs and knows no workflow.
    for far in ["workflow", "ingest", "features", "cli"] {
        assert!(!g["report"].contains(far), "report uses {far}");
    }
}

/// The README's direction: `a, b ← c ← …` (each room uses only rooms to its left), read from
/// its `Code layout` section; room → tier.
fn readme_tiers() -> BTreeMap<String, usize> {
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    let line = readme
        .lines()
        .find(|l| l.starts_with("util, model ←"))
        .expect("the README states the direction as `util, model ← …`");
    let mut tiers = BTreeMap::new();
    for (k, tier) in line.split('←').enumerate() {
        for room in tier.split(',').map(str::trim).filter(|r| !r.is_empty()) {
            if room != "main.rs" {
                tiers.insert(room.to_string(), k);
            }
        }
    }
    tiers
}

/// Imports inside one tier that the README names (`a uses b`), allowed like downward ones.
const SAME_TIER: &[(&str, &str)] = &[];

/// The imports that go against the direction: to a room of the same or a later tier (other
/// than [`SAME_TIER`]), or from or to a room the direction does not name.
fn against_direction(
    g: &BTreeMap<String, BTreeSet<String>>,
    tiers: &BTreeMap<String, usize>,
) -> Vec<String> {
    let mut bad = Vec::new();
    for (from, deps) in g {
        let Some(&tf) = tiers.get(from) else {
            bad.push(format!("{from} is not in the README's direction"));
            continue;
        };
        for to in deps {
            match tiers.get(to) {
                None => bad.push(format!("{from} → {to}: {to} is not in the direction")),
                Some(&tt) if tt < tf => {}
                Some(_) if SAME_TIER.contains(&(from.as_str(), to.as_str())) => {}
                Some(&tt) => bad.push(format!(
                    "{from} (tier {tf}) uses {to} (tier {tt}): against the direction"
                )),
            }
        }
    }
    bad
}

#[test]
fn every_import_points_down_the_readmes_direction() {
    let tiers = readme_tiers();
    assert!(tiers.len() >= 19, "{tiers:?}");
    let g = graph();
    let bad = against_direction(&g, &tiers);
    assert!(bad.is_empty(), "{}", bad.join("\n"));
    // A planted violation is caught: the store reading the pipeline's parts, a room of its
    // own tier, and a room the direction does not know.
    let mut planted = g.clone();
    planted.get_mut("store").unwrap().insert("pipeline".into());
    planted.get_mut("features").unwrap().insert("events".into());
    planted.insert("gallery".into(), ["model".to_string()].into());
    let found = against_direction(&planted, &tiers);
    assert_eq!(found.len(), 3, "{found:?}");
    assert!(
        found
            .iter()
            .any(|b| b.starts_with("store (tier 1) uses pipeline")),
        "{found:?}"
    );
    assert!(
        found.iter().any(|b| b.starts_with(&format!(
            "features (tier {}) uses events",
            tiers["features"]
        ))),
        "{found:?}"
    );
}

/// The rooms that own settings stand below `config`, which only gathers them: the
/// algorithm rooms and the readers never import it (they take their own settings).
#[test]
fn algorithm_rooms_and_readers_never_import_the_pipeline_file() {
    let g = graph();
    for room in [
        "dsp", "som", "analysis", "store", "events", "ingest", "features", "sim",
    ] {
        assert!(
            !g[room].contains("config"),
            "{room} imports config: it should take its own settings ({room}::settings)"
        );
    }
    let tiers = readme_tiers();
    for room in [
        "dsp", "som", "analysis", "store", "events", "ingest", "features",
    ] {
        assert!(
            tiers[room] < tiers["config"],
            "{room} must stand below config"
        );
    }
}

#[test]
fn clap_stays_in_the_command_line() {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    let bad: Vec<String> = files
        .iter()
        .filter(|f| {
            let r = room_of(f);
            r.as_deref() != Some("cli") && r.is_some()
        })
        .filter(|f| {
            let t = std::fs::read_to_string(f).unwrap();
            t.contains("clap::") || t.contains("#[arg(") || t.contains("ValueEnum")
        })
        .map(|f| f.display().to_string())
        .collect();
    assert!(bad.is_empty(), "clap outside src/cli: {bad:?}");
}

/// The core knows nothing of Python (polars' and tokenizers' way): no pyo3 or numpy in
/// `src/` or in the root package's dependencies; the bindings crate only converts, calling
/// the core through `aepipe::`, never reaching into its files.
#[test]
fn python_stays_in_the_bindings_crate() {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    let bad: Vec<String> = files
        .iter()
        .filter(|f| {
            let t = std::fs::read_to_string(f).unwrap();
            t.contains("pyo3") || t.contains("numpy::") || t.contains("#[pyclass")
        })
        .map(|f| f.display().to_string())
        .collect();
    assert!(bad.is_empty(), "Python in the core: {bad:?}");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let manifest = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    let deps = manifest
        .split("[dependencies]")
        .nth(1)
        .and_then(|d| d.split("\n[").next())
        .unwrap();
    assert!(
        !deps.contains("pyo3") && !deps.contains("numpy"),
        "the core depends on Python crates"
    );
    // `cargo test` at the root builds the root package only.
    assert!(manifest.contains("default-members = [\".\"]"), "{manifest}");
    let mut py = Vec::new();
    rust_files(&root.join("crates/aepipe-py/src"), &mut py);
    assert!(!py.is_empty());
    for f in py {
        let t = std::fs::read_to_string(&f).unwrap();
        assert!(
            !t.contains("#[path") && !t.contains("include!("),
            "{} reaches into the core's files",
            f.display()
        );
    }
}

#[test]
fn lib_rs_names_every_room() {
    let lib = std::fs::read_to_string(src().join("lib.rs")).unwrap();
    let g = graph();
    for room in g.keys() {
        assert!(
            lib.contains(&format!("pub mod {room};")),
            "{room} is not a module of lib.rs"
        );
        assert!(
            lib.lines()
                .any(|l| l.starts_with("//!") && l.contains(&format!("[`{room}`]"))),
            "lib.rs's doc has no line for {room}"
        );
    }
}

#[test]
fn the_binary_only_parses_and_dispatches() {
    let main = std::fs::read_to_string(src().join("main.rs")).unwrap();
    assert!(
        main.lines().count() <= 150,
        "{} lines",
        main.lines().count()
    );
}

#[test]
fn no_string_errors_in_public_functions() {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    let mut bad = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(&f).unwrap();
        let code = crate::imports::without_tests(&text);
        // Signatures may span lines: join each `pub fn` (or `pub(crate) fn`) up to its body.
        let starts = code
            .match_indices("pub fn ")
            .chain(code.match_indices("pub(crate) fn "));
        for (i, _) in starts {
            let sig = &code[i..code[i..].find('{').map_or(code.len(), |e| i + e)];
            let ret = sig.find("-> Result<").map(|k| sig[k..].trim_end());
            if ret.is_some_and(|r| r.ends_with(", String>")) {
                bad.push(format!(
                    "{}: {}",
                    f.display(),
                    sig.lines().next().unwrap_or("")
                ));
            }
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// The code of a file outside its tests (the items `#[cfg(test)]` applies to dropped, the
/// code after them kept; none for a `tests.rs`), comments kept.
fn code_without_tests(f: &Path) -> String {
    if f.file_name().is_some_and(|n| n == "tests.rs") {
        return String::new();
    }
    crate::imports::without_tests(&std::fs::read_to_string(f).unwrap())
}

/// Each function's length in lines, from its `fn` line to its closing brace (comments
/// included; braces inside strings, chars and `//` comments do not count).
fn function_lengths(code: &str) -> Vec<(String, usize)> {
    let lines: Vec<&str> = code.lines().collect();
    let mut out = Vec::new();
    for (i, l) in lines.iter().enumerate() {
        let t = l.trim_start();
        let head = t
            .trim_start_matches("pub(crate) ")
            .trim_start_matches("pub(super) ")
            .trim_start_matches("pub ")
            .trim_start_matches("const ")
            .trim_start_matches("unsafe ");
        let Some(rest) = head.strip_prefix("fn ") else {
            continue;
        };
        let name: String = rest
            .chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect();
        let (mut depth, mut started) = (0i64, false);
        for (j, line) in lines.iter().enumerate().skip(i) {
            let mut in_str = false;
            let mut prev = ' ';
            let body = line.split("//").next().unwrap_or("");
            for c in body.chars() {
                match c {
                    '"' if prev != '\\' => in_str = !in_str,
                    '{' if !in_str => {
                        depth += 1;
                        started = true;
                    }
                    '}' if !in_str => depth -= 1,
                    _ => {}
                }
                prev = c;
            }
            if started && depth == 0 {
                out.push((name.clone(), j - i + 1));
                break;
            }
            if !started && body.trim_end().ends_with(';') {
                break;
            }
        }
    }
    out
}

/// A function a newcomer has to read whole fits on a screen or two: none is longer than
/// 120 lines (a long one is split into named steps).
#[test]
fn no_function_is_longer_than_120_lines() {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    let mut long = Vec::new();
    for f in &files {
        for (name, n) in function_lengths(&code_without_tests(f)) {
            if n > 120 {
                long.push(format!("{}: {name} {n} lines", f.display()));
            }
        }
    }
    assert!(long.is_empty(), "{}", long.join("\n"));
    // The measure itself: a planted 130-line function is found, a brace in a string is not
    // counted.
    let planted = format!(
        "fn big() {{\n    let s = \"}}\";\n{}}}\n",
        "    x();\n".repeat(127)
    );
    assert_eq!(function_lengths(&planted), [("big".to_string(), 130)]);
}

/// A file grows into a room before it passes 900 lines of code (its tests aside).
#[test]
fn no_source_file_is_longer_than_900_lines_without_its_tests() {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    let long: Vec<String> = files
        .iter()
        .map(|f| (f, code_without_tests(f).lines().count()))
        .filter(|(_, n)| *n > 900)
        .map(|(f, n)| format!("{}: {n} lines", f.display()))
        .collect();
    assert!(long.is_empty(), "{}", long.join("\n"));
}

/// The mechanisms' names are spelled only in `model` (`Mechanism::as_str`, the column
/// constants): elsewhere the code names the variant.
#[test]
fn class_names_come_only_from_model() {
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    let mut found = Vec::new();
    for f in files.iter().filter(|f| !f.starts_with(src().join("model"))) {
        for l in code_without_tests(f).lines() {
            if l.trim_start().starts_with("//") {
                continue;
            }
            for name in [
                "bond_failure",
                "fibre_failure",
                "erroneous",
                "both",
                "criteria_label",
                "unlike_references",
            ] {
                if l.contains(&format!("\"{name}\"")) {
                    found.push(format!("{}: {}", f.display(), l.trim()));
                }
            }
        }
    }
    assert!(found.is_empty(), "{}", found.join("\n"));
}

/// docs/design.md is read against the code, so it cannot fall behind unseen: its direction
/// line is the README's, its room table names exactly the rooms of `src/lib.rs`, lib.rs's
/// doc lists the rooms in the direction's order, its error list names every public error type
/// of `src/` (enum or struct; none that is gone), and every file it cites exists.
#[test]
fn design_md_is_true_to_the_code() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let design = std::fs::read_to_string(root.join("docs/design.md")).unwrap();
    let problems = design_problems(&design, root);
    assert!(problems.is_empty(), "docs/design.md: {problems:#?}");
    // The checks can fail: a design.md that has fallen behind is caught on each count.
    let stale = design
        .replace("demo, bench, live, thesis ←", "demo, bench, live ←")
        .replace("| `export` |", "| `exported` |")
        .replace("`ThesisError`", "`ThesesError`")
        .replace("`src/synth/mod.rs`", "`src/synth.rs`");
    let found = design_problems(&stale, root).join("\n");
    for want in [
        "direction line",
        "room table: exported",
        "ThesisError",
        "ThesesError",
        "src/synth.rs",
    ] {
        assert!(
            found.contains(want),
            "a stale {want} was not caught:\n{found}"
        );
    }
}

/// What in `design` (docs/design.md's text) disagrees with the code under `root`.
fn design_problems(design: &str, root: &Path) -> Vec<String> {
    let mut bad = Vec::new();
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let direction = |t: &str| {
        t.lines()
            .find(|l| l.starts_with("util, model ←"))
            .map(str::to_string)
    };
    if direction(design) != direction(&readme) {
        bad.push("its direction line is not the README's".into());
    }
    // The room table: the first cell of each row, a room in backticks.
    let lib = std::fs::read_to_string(root.join("src/lib.rs")).unwrap();
    let rooms: BTreeSet<String> = lib
        .lines()
        .filter_map(|l| l.trim().strip_prefix("pub mod "))
        .map(|m| m.trim_end_matches(';').to_string())
        .collect();
    let table: BTreeSet<String> = design
        .lines()
        .filter_map(|l| l.strip_prefix("| `"))
        .filter_map(|l| l.split(" |").next())
        .flat_map(|cell| {
            cell.split(", ")
                .map(|r| r.trim_matches('`').to_string())
                .collect::<Vec<_>>()
        })
        .filter(|r| r != "main.rs" && !r.starts_with("crates/"))
        .collect();
    for r in rooms.symmetric_difference(&table) {
        bad.push(format!(
            "room table: {r} (lib.rs has: {})",
            rooms.contains(r)
        ));
    }
    // lib.rs's doc lists the rooms in the direction's order.
    let tiers = readme_tiers();
    let listed: Vec<&str> = lib
        .lines()
        .filter_map(|l| l.strip_prefix("//! - [`"))
        .filter_map(|l| l.split('`').next())
        .collect();
    for w in listed.windows(2) {
        if tiers.get(w[0]) > tiers.get(w[1]) {
            bad.push(format!("lib.rs lists {} before {}", w[0], w[1]));
        }
    }
    // Every error enum of src/ is named, and every one named exists.
    let mut files = Vec::new();
    rust_files(&src(), &mut files);
    let mut enums = BTreeSet::new();
    for f in &files {
        let code = std::fs::read_to_string(f).unwrap();
        let decls = code
            .match_indices("pub enum ")
            .chain(code.match_indices("pub struct "));
        for (i, word) in decls {
            let name: String = code[i + word.len()..]
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            let head = &code[..i];
            let derive = head.rfind("#[derive(").map_or("", |d| &head[d..]);
            if name.ends_with("Error") && derive.contains("Error") {
                enums.insert(name);
            }
        }
    }
    let named: BTreeSet<String> = design
        .split('`')
        .skip(1)
        .step_by(2)
        .filter(|w| w.ends_with("Error") && w.chars().all(|c| c.is_ascii_alphanumeric()))
        .map(str::to_string)
        .collect();
    for e in enums.difference(&named) {
        bad.push(format!("the error type {e} is not named"));
    }
    for e in named.difference(&enums) {
        bad.push(format!("{e} is named but no such error type exists"));
    }
    // Every file it cites exists.
    for cited in design.split('`').skip(1).step_by(2) {
        let is_path = [
            "src/",
            "tests/",
            "docs/",
            "data-schema/",
            "pipelines/",
            "crates/",
            "python/",
        ]
        .iter()
        .any(|p| cited.starts_with(p))
            && !cited.contains(' ')
            && cited.contains('.');
        if is_path && !root.join(cited).exists() {
            bad.push(format!("it cites {cited}, which does not exist"));
        }
    }
    bad
}
