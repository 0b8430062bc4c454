//! Import circles between files, inside a room as between rooms: a file that uses a sibling
//! which uses it back (directly or round a longer circle) is a knot a reader cannot start
//! from either end of. `architecture.rs` keeps the rooms' direction; this keeps the files'.
//!
//! Each file is a module (`src/sim/paper.rs` → `sim::paper`, `src/sim/mod.rs` → `sim`); an
//! edge is a path it names through `crate::`, `super::` or `self::` (grouped imports
//! expanded) in its code outside tests (the items `#[cfg(test)]` applies to dropped, the code
//! after them read; comments and strings blanked), to the file that defines what the path
//! names: the deepest module file the path reaches, or, where the path goes on through a name
//! that file brings in with a `use` (a `mod.rs`'s `pub use self::b::Thing`), the file the
//! name comes from. A parent's own edges to its descendants are not counted: declaring and
//! re-exporting its children is what a `mod.rs` is for. A child's use of its parent's items
//! is counted, and a path through a parent's re-export goes to the file that defines the
//! item, so a circle through a `mod.rs` is still found. Files only tests compile
//! (`#[cfg(test)] mod tests;`) are left out.

use crate::architecture::{find_cycle, rust_files, src};
use std::collections::{BTreeMap, BTreeSet};
use std::ops::Range;
use std::path::Path;

mod read;
use read::{code_of, declares, drop_spans, module_uses, test_items, test_modules};
pub(crate) use read::{test_only_files, without_tests};

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
/// root word (`super::{a::X, b}` → `["super", "a", "X"]`, `["super", "b"]`), in its code
/// outside tests ([`code_of`]: the items `#[cfg(test)]` applies to dropped, comments and
/// strings blanked).
pub(crate) fn paths(text: &str) -> Vec<Vec<String>> {
    paths_in(&code_of(text))
}

/// [`paths`] of code already prepared.
fn paths_in(code: &str) -> Vec<Vec<String>> {
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

/// The absolute module path of `path` as file `m` writes it: from `crate`, `self` or
/// `super`, or (in a `use`) from one of `m`'s own child modules; None for another crate's.
fn absolute(
    m: &[String],
    path: &[String],
    files: &BTreeMap<Vec<String>, String>,
) -> Option<Vec<String>> {
    let mut segs = path.iter().peekable();
    let mut abs: Vec<String> = match segs.peek().map(|s| s.as_str()) {
        Some("crate") => {
            segs.next();
            Vec::new()
        }
        Some("self") => {
            segs.next();
            m.to_vec()
        }
        Some("super") => {
            let mut abs = m.to_vec();
            while segs.peek().is_some_and(|s| *s == "super") {
                segs.next();
                abs.pop();
            }
            abs
        }
        Some(child) if files.contains_key(&[m.to_vec(), vec![child.to_string()]].concat()) => {
            m.to_vec()
        }
        _ => return None,
    };
    abs.extend(segs.cloned());
    Some(abs)
}

/// What the resolver knows of each module file: its code and the names its `use`
/// declarations bring in (absolute paths; names from other crates left out).
struct Modules<'a> {
    files: &'a BTreeMap<Vec<String>, String>,
    code: BTreeMap<Vec<String>, String>,
    uses: BTreeMap<Vec<String>, Vec<(Vec<String>, String)>>,
}

impl<'a> Modules<'a> {
    fn new(files: &'a BTreeMap<Vec<String>, String>) -> Self {
        let code = files.iter().map(|(m, t)| (m.clone(), code_of(t))).collect();
        let uses = files
            .iter()
            .map(|(m, t)| {
                let abs = module_uses(t)
                    .into_iter()
                    .filter_map(|(p, name)| Some((absolute(m, &p, files)?, name)))
                    .collect();
                (m.clone(), abs)
            })
            .collect();
        Modules { files, code, uses }
    }

    /// The deepest module file on an absolute path.
    fn file_of(&self, abs: &[String]) -> Option<Vec<String>> {
        (0..=abs.len())
            .rev()
            .map(|k| abs[..k].to_vec())
            .find(|k| self.files.contains_key(k))
    }

    /// The file that defines what `abs` names. The deepest module file on the path, unless
    /// the path goes on through a name that file brings in with a `use` (a `mod.rs`'s `pub
    /// use self::b::Thing`, or a glob whose module has the name): then the file that name
    /// comes from, followed as far as it goes.
    fn resolve(&self, abs: &[String], hops: usize) -> Option<Vec<String>> {
        let file = self.file_of(abs)?;
        if hops > 16 || file.len() == abs.len() {
            return Some(file);
        }
        let (name, rest) = (&abs[file.len()], &abs[file.len() + 1..]);
        let uses = &self.uses[&file];
        let via = |to: &[String]| [to, rest].concat();
        if let Some((to, _)) = uses.iter().find(|(_, n)| n == name) {
            return self.resolve(&via(to), hops + 1).or(Some(file));
        }
        if !declares(&self.code[&file], name) {
            for (from, _) in uses.iter().filter(|(_, n)| n == "*") {
                let has = |m: &Vec<String>| {
                    declares(&self.code[m], name) || self.uses[m].iter().any(|(_, n)| n == name)
                };
                if self.file_of(from).is_some_and(|m| m == *from && has(&m)) {
                    let to = [from.as_slice(), std::slice::from_ref(name)].concat();
                    return self.resolve(&via(&to), hops + 1).or(Some(file));
                }
            }
        }
        Some(file)
    }
}

/// The file graph: a file's module path → the module files it names, each path resolved
/// through the `use` declarations it passes ([`Modules::resolve`]).
fn file_graph(files: &BTreeMap<Vec<String>, String>) -> BTreeMap<String, BTreeSet<String>> {
    file_graph_by(files, true)
}

/// [`file_graph`], or with `follow_uses` false each path taken to the deepest module file
/// it reaches (the reader that missed circles through a `mod.rs`'s re-export; kept as the
/// plant its test runs).
fn file_graph_by(
    files: &BTreeMap<Vec<String>, String>,
    follow_uses: bool,
) -> BTreeMap<String, BTreeSet<String>> {
    let modules = Modules::new(files);
    let mut g: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (m, text) in files {
        let deps = g.entry(m.join("::")).or_default();
        for p in paths(text) {
            let Some(abs) = absolute(m, &p, files) else {
                continue;
            };
            let target = if follow_uses {
                modules.resolve(&abs, 0)
            } else {
                modules.file_of(&abs)
            };
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
    let tests_only = test_only_files(&list);
    list.into_iter()
        .filter(|f| !f.ends_with("main.rs") && !tests_only.contains(f))
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

/// The reader drops only the item `#[cfg(test)]` applies to (here a `mod tests { … }` block,
/// a test-only function with generics and a `where` clause, a test-only import) and reads
/// the code after it; braces in strings, chars and comments inside the dropped block do not
/// end it early, and paths in strings and comments are not read. It finds module-level
/// `use` names (grouped, renamed, globs; not a function's own) and test-only module files.
/// Plant: the reader that stopped at a file's first `#[cfg(test)]` (it reads neither `y`
/// nor `z`), and a brace matcher that does not skip strings, chars and comments (the test
/// module's `x2` leaks out), each fail the same check.
#[test]
fn the_reader_drops_only_the_test_item_and_reads_on() {
    let text = r#"use crate::a;
#[cfg(test)]
mod tests {
    use crate::x;
    fn f() { let s = "}}"; let c = '}'; /* } */ // }
    }
    use crate::x2::Z;
}
#[cfg(test)]
fn helper<A, B>() where A: Into<B>, B: Copy { crate::x3::q(); }
#[cfg(test)] use crate::x4;
pub use crate::y;
const S: &str = "crate::s"; // crate::comment
fn g() { crate::z::h(); }
"#;
    let check = |found: &[Vec<String>]| -> Vec<String> {
        let has = |m: &str| found.iter().any(|p| p.len() > 1 && p[1] == m);
        let mut bad: Vec<String> = ["a", "y", "z"]
            .into_iter()
            .filter(|m| !has(m))
            .map(|m| format!("{m} not read"))
            .collect();
        bad.extend(
            ["x", "x2", "x3", "x4", "s", "comment"]
                .into_iter()
                .filter(|m| has(m))
                .map(|m| format!("{m} read")),
        );
        bad
    };
    assert_eq!(check(&paths(text)), Vec::<String>::new());
    let first_only = paths(text.split("#[cfg(test)]").next().unwrap());
    let bad = check(&first_only);
    assert!(bad.contains(&"y not read".to_string()), "{bad:?}");
    let unmasked: Vec<Range<usize>> = test_items(text).into_iter().map(|s| s.0).collect();
    let bad = check(&paths_in(&drop_spans(text, &unmasked)));
    assert!(bad.contains(&"x2 read".to_string()), "{bad:?}");
    // The whole non-test text is kept, comments and strings too.
    let kept = without_tests(text);
    assert!(kept.contains("\"crate::s\"") && kept.contains("fn g()") && !kept.contains("x2"));
    let uses = module_uses(
        "pub use self::b::{Thing, Other as O, c::*};\npub(crate) use settings::X;\n\
         fn f() { use crate::inner::Y; }\n#[cfg(test)]\nuse crate::t::T;",
    );
    let want: Vec<(Vec<String>, String)> = [
        ("self b Thing", "Thing"),
        ("self b Other", "O"),
        ("self b c", "*"),
        ("settings X", "X"),
    ]
    .iter()
    .map(|(p, n)| (p.split(' ').map(String::from).collect(), n.to_string()))
    .collect();
    assert_eq!(uses, want);
    assert_eq!(
        test_modules("#[cfg(test)]\nmod tests;\nmod real;\n#[cfg(test)]\nmod inline { }"),
        ["tests"]
    );
}

/// A file set from `(module, text)` pairs (`""` the crate root).
fn file_set(list: &[(&str, &str)]) -> BTreeMap<Vec<String>, String> {
    list.iter()
        .map(|(m, text)| {
            let m = m.split("::").filter(|s| !s.is_empty()).map(String::from);
            (m.collect(), text.to_string())
        })
        .collect()
}

/// A circle through a `mod.rs`'s re-export is found: `a::b` uses `c`, which names
/// `crate::a::Thing`, an item `a/mod.rs` re-exports from `a::b` — by `pub use self::b::Thing`,
/// a bare renamed `pub use b::{Thing as Alias}`, a glob `pub use b::*`, a second re-export
/// (`top` passing on `a`'s), and a sibling's `use super::Thing`. Names `a` defines itself,
/// or a glob's module does not have, stay with `a` (whose edges to `a::b` are not counted),
/// so the sound sets have no circle.
/// Plant: the reader that takes `crate::a::Thing` to `a`, the deepest file on the path
/// ([`file_graph_by`] not following `use`s), finds none of the circles.
#[test]
fn a_circle_through_a_re_export_is_found() {
    let b = "pub struct Thing; pub fn f() { crate::c::g(); }";
    let circles = [
        (
            "mod b; pub use self::b::Thing;",
            "pub fn g() -> crate::a::Thing { todo!() }",
        ),
        (
            "mod b; pub use b::{Thing as Alias};",
            "use crate::a::Alias;",
        ),
        ("mod b; pub use b::*;", "use crate::a::Thing;"),
        ("mod b; pub use self::b::Thing;", "use crate::top::Thing;"),
    ];
    for (a, c) in circles {
        let files = file_set(&[
            ("", "pub mod a; pub mod c; pub mod top;"),
            ("a", a),
            ("a::b", b),
            ("c", c),
            ("top", "pub use crate::a::Thing;"),
        ]);
        let found = find_cycle(&file_graph(&files));
        assert!(
            found
                .as_ref()
                .is_some_and(|c| c.contains(&"a::b".to_string()) && c.contains(&"c".to_string())),
            "{a} / {c}: {found:?}"
        );
        assert_eq!(find_cycle(&file_graph_by(&files, false)), None, "{a} / {c}");
    }
    let sibling = file_set(&[
        ("", "pub mod a;"),
        ("a", "mod b; mod d; pub use self::b::Thing;"),
        ("a::b", "pub struct Thing; fn f() { super::d::g(); }"),
        ("a::d", "use super::Thing; pub fn g() {}"),
    ]);
    let found = find_cycle(&file_graph(&sibling)).expect("a::b → a::d → a::b");
    assert!(found.contains(&"a::d".to_string()), "{found:?}");
    assert_eq!(find_cycle(&file_graph_by(&sibling, false)), None);
    let sound = [
        (
            "mod b; pub use self::b::Thing; pub struct Own;",
            "use crate::a::Own;",
        ),
        (
            "mod b; pub use b::*; pub struct Thing2;",
            "use crate::a::Thing2;",
        ),
        ("mod b; pub use b::*;", "use crate::a::Other;"),
    ];
    for (a, c) in sound {
        let files = file_set(&[
            ("", "pub mod a; pub mod c;"),
            ("a", a),
            ("a::b", b),
            ("c", c),
        ]);
        let g = file_graph(&files);
        assert_eq!(find_cycle(&g), None, "{a} / {c}: {g:?}");
        assert!(g["c"].contains("a"), "{a} / {c}: {g:?}");
    }
}
