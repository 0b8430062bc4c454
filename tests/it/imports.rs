//! Import circles between files, inside a room as between rooms: a file that uses a sibling
//! which uses it back (directly or round a longer circle) is a knot a reader cannot start
//! from either end of. `architecture.rs` keeps the rooms' direction; this keeps the files'.
//!
//! Each file is a module (`src/sim/paper.rs` → `sim::paper`, `src/sim/mod.rs` → `sim`); an
//! edge is a path it names through `crate::`, `super::` or `self::` (grouped imports
//! expanded), to the deepest module file the path reaches. A parent's edges to its own
//! descendants are not counted: declaring and re-exporting its children is what a `mod.rs`
//! is for. A child's use of its parent's items is counted, so a circle through a `mod.rs`
//! is still found.

use crate::architecture::{find_cycle, rust_files, src};
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// The module path of a file under `src/` (`["sim", "paper"]`; `[]` for lib.rs).
fn module_of(file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src()).unwrap();
    let mut m: Vec<String> = rel
        .components()
        .map(|c| {
            c.as_os_str()
                .to_string_lossy()
                .trim_end_matches(".rs")
                .to_string()
        })
        .collect();
    if matches!(m.last().map(String::as_str), Some("mod" | "lib" | "main")) {
        m.pop();
    }
    m
}

/// Every path a text names from `crate::`, `super::` or `self::`, as segments after the
/// root word (`super::{a::X, b}` → `["super", "a", "X"]`, `["super", "b"]`), in the code
/// before any `#[cfg(test)]`, comments dropped.
pub(crate) fn paths(text: &str) -> Vec<Vec<String>> {
    let code: String = text
        .split("#[cfg(test)]")
        .next()
        .unwrap_or("")
        .lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n");
    let b = code.as_bytes();
    let mut out = Vec::new();
    for root in ["crate::", "super::", "self::"] {
        for (i, _) in code.match_indices(root) {
            // Not the tail of a longer path (`super::super::` is read from its first word).
            if i >= 2 && &code[i - 2..i] == "::" {
                continue;
            }
            if i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_') {
                continue;
            }
            let first = root.trim_end_matches("::").to_string();
            expand(&code[i + root.len()..], vec![first], &mut out);
        }
    }
    out
}

/// The paths of `rest` (what follows `prefix::`): a name, a `name::…` chain, or a `{…}`
/// group of them.
fn expand(rest: &str, prefix: Vec<String>, out: &mut Vec<Vec<String>>) {
    if let Some(group) = rest.strip_prefix('{') {
        let mut depth = 0;
        let mut start = 0;
        for (k, ch) in group.char_indices() {
            match ch {
                '{' => depth += 1,
                '}' if depth == 0 => {
                    expand(group[start..k].trim(), prefix.clone(), out);
                    return;
                }
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    expand(group[start..k].trim(), prefix.clone(), out);
                    start = k + 1;
                }
                _ => {}
            }
        }
        return;
    }
    let name: String = rest
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
        .collect();
    if name.is_empty() {
        out.push(prefix);
        return;
    }
    let mut p = prefix;
    let after = &rest[name.len()..];
    p.push(name);
    match after.strip_prefix("::") {
        Some(more) => expand(more, p, out),
        None => out.push(p),
    }
}

/// The file graph: a file's module path → the module files it names.
fn file_graph(files: &BTreeMap<Vec<String>, String>) -> BTreeMap<String, BTreeSet<String>> {
    let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (m, text) in files {
        let from = m.join("::");
        let deps = g.entry(from.clone()).or_default();
        for p in paths(text) {
            // The absolute module path the path starts from.
            let mut abs: Vec<String> = Vec::new();
            let mut segs = p.iter().peekable();
            match segs.next().map(String::as_str) {
                Some("crate") => {}
                Some("self") => abs = m.clone(),
                Some("super") => {
                    abs = m.clone();
                    abs.pop();
                    while segs.peek().is_some_and(|s| *s == "super") {
                        segs.next();
                        abs.pop();
                    }
                }
                _ => continue,
            }
            abs.extend(segs.cloned());
            // The deepest module file the path reaches.
            let target = (0..=abs.len())
                .rev()
                .map(|k| abs[..k].to_vec())
                .find(|k| files.contains_key(k));
            let Some(target) = target else { continue };
            // Not itself, nor a parent's child (see the module doc).
            if target == *m || target.starts_with(m) {
                continue;
            }
            deps.insert(target.join("::"));
        }
    }
    g
}

fn src_files() -> BTreeMap<Vec<String>, String> {
    let mut list = Vec::new();
    rust_files(&src(), &mut list);
    list.into_iter()
        .filter(|f| !f.ends_with("main.rs"))
        .map(|f| (module_of(&f), std::fs::read_to_string(&f).unwrap()))
        .collect()
}

#[test]
fn no_import_circle_between_files() {
    let files = src_files();
    assert!(files.len() > 100, "read {} files", files.len());
    let mut g = file_graph(&files);
    // Every circle, one at a time: each found is reported and one of its edges set aside.
    let mut circles = Vec::new();
    while let Some(c) = find_cycle(&g) {
        circles.push(c.join(" → "));
        g.get_mut(&c[c.len() - 2]).unwrap().remove(&c[c.len() - 1]);
    }
    assert!(
        circles.is_empty(),
        "import circles between files:\n{}",
        circles.join("\n")
    );
}

/// The finder reads grouped and relative imports and finds a planted circle: two siblings
/// using each other, and a child using its parent's item while the parent uses a file that
/// uses the child.
#[test]
fn the_file_circle_finder_finds_a_planted_circle() {
    let p = paths("use super::{a::X, b::{c, d::E}};\nfn f() { crate::x::y::z(); self::k::m(); }");
    let want: Vec<Vec<String>> = [
        "crate x y z",
        "super a X",
        "super b c",
        "super b d E",
        "self k m",
    ]
    .iter()
    .map(|s| s.split(' ').map(String::from).collect())
    .collect();
    for w in &want {
        assert!(p.contains(w), "{w:?} not in {p:?}");
    }
    let file = |m: &str, text: &str| {
        (
            m.split("::")
                .filter(|s| !s.is_empty())
                .map(String::from)
                .collect::<Vec<_>>(),
            text.to_string(),
        )
    };
    let sound: BTreeMap<Vec<String>, String> = [
        file("", "pub mod sim;"),
        file("sim", "mod a; mod b; pub use a::A; pub struct P;"),
        file("sim::a", "use super::P; use super::b::B;"),
        file("sim::b", "use crate::sim::P;"),
    ]
    .into_iter()
    .collect();
    assert_eq!(find_cycle(&file_graph(&sound)), None);
    let mut planted = sound.clone();
    planted.insert(
        file("sim::b", "use crate::sim::{P, a::A};").0,
        "use crate::sim::{P, a::A};".into(),
    );
    let c = find_cycle(&file_graph(&planted)).expect("the planted circle a ↔ b");
    assert!(
        c.contains(&"sim::a".to_string()) && c.contains(&"sim::b".to_string()),
        "{c:?}"
    );
    // Through a mod.rs: a uses its parent's P; the parent uses `other`, which uses a.
    let mut through_parent = sound;
    through_parent.insert(
        vec!["sim".into()],
        "mod a; mod b; pub struct P(crate::other::O);".into(),
    );
    through_parent.insert(
        vec!["other".into()],
        "pub struct O(crate::sim::a::A);".into(),
    );
    let c = find_cycle(&file_graph(&through_parent)).expect("a → sim → other → a");
    assert!(
        c.contains(&"other".to_string()) && c.contains(&"sim".to_string()),
        "{c:?}"
    );
}
