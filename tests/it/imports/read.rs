//! Reading a Rust source file's code as a build outside tests sees it: comments and strings
//! blanked, the items `#[cfg(test)]` applies to dropped (their extent found by brace
//! matching over the blanked text), module-level `use` names, the modules only tests
//! compile.

use std::collections::BTreeSet;
use std::ops::Range;
use std::path::PathBuf;

/// `text` with its comments and the insides of its string and char literals blanked (each
/// byte a space, line ends kept, so every byte stays where it was): braces, attributes and
/// paths are then read from the code alone.
fn mask(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = b.to_vec();
    let blank = |out: &mut Vec<u8>, from: usize, to: usize| {
        for c in &mut out[from..to.min(b.len())] {
            if *c != b'\n' {
                *c = b' ';
            }
        }
    };
    // Whether a token starts at `k` (no identifier character before it).
    let starts = |k: usize| k == 0 || !(b[k - 1].is_ascii_alphanumeric() || b[k - 1] == b'_');
    let mut i = 0;
    while i < b.len() {
        let next = b.get(i + 1).copied();
        i = match b[i] {
            b'/' if next == Some(b'/') => {
                let end = text[i..].find('\n').map_or(b.len(), |e| i + e);
                blank(&mut out, i, end);
                end
            }
            b'/' if next == Some(b'*') => {
                let (mut depth, mut k) = (1, i + 2);
                while k < b.len() && depth > 0 {
                    if b[k..].starts_with(b"/*") {
                        (depth, k) = (depth + 1, k + 2);
                    } else if b[k..].starts_with(b"*/") {
                        (depth, k) = (depth - 1, k + 2);
                    } else {
                        k += 1;
                    }
                }
                blank(&mut out, i, k);
                k
            }
            // A raw string `r"…"`, `r#"…"#`, `br"…"`: no escapes, ends at its quote and hashes.
            b'r' if starts(i) || (b[i - 1] == b'b' && starts(i - 1)) => {
                let hashes = b[i + 1..].iter().take_while(|&&c| c == b'#').count();
                let open = i + 1 + hashes;
                if b.get(open) == Some(&b'"') {
                    let close = format!("\"{}", "#".repeat(hashes));
                    let end = text[open + 1..]
                        .find(&close)
                        .map_or(b.len(), |e| open + 1 + e);
                    blank(&mut out, open + 1, end);
                    end + close.len()
                } else {
                    i + 1
                }
            }
            b'"' => {
                let mut k = i + 1;
                while k < b.len() && b[k] != b'"' {
                    k += if b[k] == b'\\' { 2 } else { 1 };
                }
                blank(&mut out, i + 1, k);
                k + 1
            }
            // A char literal (`'x'`, `'\n'`, `'\u{7f}'`), not a lifetime or label (`'a`).
            b'\'' if next == Some(b'\\') => {
                let end = (i + 3..b.len()).find(|&k| b[k] == b'\'').unwrap_or(b.len());
                blank(&mut out, i + 1, end);
                end + 1
            }
            b'\'' => match text[i + 1..].chars().next() {
                Some(c) if b.get(i + 1 + c.len_utf8()) == Some(&b'\'') => {
                    blank(&mut out, i + 1, i + 1 + c.len_utf8());
                    i + 2 + c.len_utf8()
                }
                _ => i + 1,
            },
            _ => i + 1,
        };
    }
    String::from_utf8(out).expect("only whole characters are blanked")
}

/// The items `#[cfg(test)]` applies to in `code` (a [`mask`]ed text): each one's bytes from
/// its attribute to its end, and where the item itself starts (after its attributes). A
/// `#![cfg(test)]` makes the whole file one.
pub(crate) fn test_items(code: &str) -> Vec<(Range<usize>, usize)> {
    let b = code.as_bytes();
    if code.contains("#![cfg(test)]") {
        return vec![(0..b.len(), 0)];
    }
    let mut items = Vec::new();
    let mut from = 0;
    while let Some(k) = code[from..].find("#[cfg(test)]") {
        let start = from + k;
        let mut item = start + "#[cfg(test)]".len();
        // Its other attributes.
        loop {
            item += code[item..].len() - code[item..].trim_start().len();
            if !code[item..].starts_with("#[") {
                break;
            }
            item = close(b, item + 1);
        }
        let end = item_end(code, item);
        items.push((start..end, item));
        from = end.max(start + 1);
    }
    items
}

/// Just after the bracket that closes the one opening at `open`.
fn close(b: &[u8], open: usize) -> usize {
    let mut depth = 0;
    for (k, c) in b.iter().enumerate().skip(open) {
        match c {
            b'(' | b'[' | b'{' => depth += 1,
            b')' | b']' | b'}' => {
                depth -= 1;
                if depth == 0 {
                    return k + 1;
                }
            }
            _ => {}
        }
    }
    b.len()
}

/// Where the item starting at `at` ends: a `fn`, `mod`, `impl`, type or macro definition at
/// its `;` or closing brace, a `const`, `static`, `let`, `type` or `use` at its `;`, anything
/// else (a field, variant, match arm or statement) also at a `,` outside `<…>`; and every
/// one before a bracket that closes what it stands in.
fn item_end(code: &str, at: usize) -> usize {
    let b = code.as_bytes();
    let words: Vec<&str> = code[at..]
        .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .filter(|w| !w.is_empty())
        .take(6)
        .collect();
    let qualifier = [
        "pub", "crate", "super", "self", "in", "unsafe", "async", "extern",
    ];
    let mut kind = words.iter().copied().skip_while(|w| qualifier.contains(w));
    let (first, second) = (kind.next().unwrap_or(""), kind.next().unwrap_or(""));
    let block = [
        "fn",
        "mod",
        "impl",
        "struct",
        "enum",
        "union",
        "trait",
        "macro_rules",
    ];
    let (block, to_semicolon) = if block.contains(&first) || (first == "const" && second == "fn") {
        (true, false)
    } else {
        (
            false,
            ["const", "static", "let", "type", "use"].contains(&first),
        )
    };
    let (mut depth, mut angle) = (0i32, 0i32);
    for k in at..b.len() {
        let prev = if k > 0 { b[k - 1] } else { b' ' };
        match b[k] {
            b'(' | b'[' | b'{' => depth += 1,
            b')' | b']' | b'}' if depth == 0 => return k,
            c @ (b')' | b']' | b'}') => {
                depth -= 1;
                if c == b'}' && depth == 0 && !to_semicolon {
                    return k + 1;
                }
            }
            b'<' if prev.is_ascii_alphanumeric() || prev == b'_' || prev == b':' => angle += 1,
            b'>' if angle > 0 && prev != b'-' && prev != b'=' => angle -= 1,
            b';' if depth == 0 => return k + 1,
            b',' if depth == 0 && angle == 0 && !block && !to_semicolon => return k + 1,
            _ => {}
        }
    }
    b.len()
}

/// `text` without the items `#[cfg(test)]` applies to (a `mod tests { … }` block, a
/// test-only function or import): the code a build outside tests compiles, comments and
/// strings kept.
pub(crate) fn without_tests(text: &str) -> String {
    let spans: Vec<Range<usize>> = test_items(&mask(text)).into_iter().map(|s| s.0).collect();
    drop_spans(text, &spans)
}

/// `text` without the byte ranges `spans` (in order, apart).
pub(crate) fn drop_spans(text: &str, spans: &[Range<usize>]) -> String {
    let mut out = String::with_capacity(text.len());
    let mut at = 0;
    for span in spans {
        out.push_str(&text[at..span.start]);
        at = span.end;
    }
    out.push_str(&text[at..]);
    out
}

/// [`without_tests`] of the [`mask`]ed text: the code alone.
pub(crate) fn code_of(text: &str) -> String {
    without_tests(&mask(text))
}

/// The modules a text declares for tests only (`#[cfg(test)] mod tests;`): their files
/// hold no code outside tests.
pub(crate) fn test_modules(text: &str) -> Vec<String> {
    let code = mask(text);
    test_items(&code)
        .into_iter()
        .filter_map(|(span, item)| {
            let decl = code[item..span.end].trim();
            let decl = decl.strip_prefix("pub ").unwrap_or(decl);
            let name = decl.strip_prefix("mod ")?.strip_suffix(';')?.trim();
            name.chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_')
                .then(|| name.to_string())
        })
        .collect()
}

/// The files among `files` that only tests compile: those of modules declared
/// `#[cfg(test)] mod name;`, and everything under them.
pub(crate) fn test_only_files(files: &[PathBuf]) -> BTreeSet<PathBuf> {
    let mut dirs = Vec::new();
    for f in files {
        let text = std::fs::read_to_string(f).unwrap();
        let own = match f.file_name().and_then(|n| n.to_str()) {
            Some("mod.rs" | "lib.rs" | "main.rs") => f.parent().unwrap().to_path_buf(),
            _ => f.with_extension(""),
        };
        dirs.extend(test_modules(&text).into_iter().map(|m| own.join(m)));
    }
    files
        .iter()
        .filter(|f| {
            dirs.iter()
                .any(|d| f.starts_with(d) || **f == d.with_extension("rs"))
        })
        .cloned()
        .collect()
}

/// The names a text's module-level `use` declarations bring in (outside tests), each with the
/// path it names as written (`pub use self::b::{Thing, Other as O}` → `(["self", "b",
/// "Thing"], "Thing")`, `(["self", "b", "Other"], "O")`; a glob's name is `*`).
pub(crate) fn module_uses(text: &str) -> Vec<(Vec<String>, String)> {
    let code = code_of(text);
    let b = code.as_bytes();
    let mut out = Vec::new();
    let mut depth = 0;
    for (k, &c) in b.iter().enumerate() {
        match c {
            b'{' => depth += 1,
            b'}' => depth -= 1,
            b'u' if depth == 0
                && code[k..].starts_with("use ")
                && (k == 0 || b[k - 1].is_ascii_whitespace() || b[k - 1] == b')') =>
            {
                let tree = &code[k + 4..code[k..].find(';').map_or(b.len(), |e| k + e)];
                use_tree(tree.trim(), Vec::new(), &mut out);
            }
            _ => {}
        }
    }
    out
}

/// The (path, name) pairs of a use tree (`a::{b, c as d, e::*}`) under `prefix`.
fn use_tree(tree: &str, prefix: Vec<String>, out: &mut Vec<(Vec<String>, String)>) {
    if let Some(group) = tree.strip_prefix('{') {
        let (mut depth, mut start) = (0, 0);
        for (k, ch) in group.char_indices() {
            match ch {
                '{' => depth += 1,
                '}' if depth > 0 => depth -= 1,
                ',' | '}' if depth == 0 => {
                    use_tree(group[start..k].trim(), prefix.clone(), out);
                    start = k + 1;
                }
                _ => {}
            }
        }
        return;
    }
    if tree == "*" {
        out.push((prefix, "*".into()));
        return;
    }
    let name: String = tree
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
        .collect();
    if name.is_empty() {
        return;
    }
    let after = tree[name.len()..].trim_start();
    if let Some(more) = after.strip_prefix("::") {
        let mut p = prefix;
        p.push(name);
        return use_tree(more.trim_start(), p, out);
    }
    let alias = after.strip_prefix("as ").map(|a| a.trim().to_string());
    let mut p = prefix;
    let bound = if name == "self" {
        p.last().cloned()
    } else {
        p.push(name.clone());
        Some(name)
    };
    if let Some(bound) = alias.or(bound) {
        out.push((p, bound));
    }
}

/// Whether `code` declares an item called `name` itself.
pub(crate) fn declares(code: &str, name: &str) -> bool {
    let kinds = [
        "fn", "struct", "enum", "trait", "type", "const", "static", "union", "mod",
    ];
    kinds
        .iter()
        .map(|k| format!("{k} {name}"))
        .chain([format!("macro_rules! {name}")])
        .any(|decl| {
            code.match_indices(&decl).any(|(i, _)| {
                let b = code.as_bytes();
                let word = |c: u8| c.is_ascii_alphanumeric() || c == b'_';
                (i == 0 || !word(b[i - 1])) && b.get(i + decl.len()).is_none_or(|&c| !word(c))
            })
        })
}
