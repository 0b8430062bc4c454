//! The README and the user guide in `docs/`: every relative link resolves (a file, and a
//! `#anchor` that is one of its headings), the README stays short and links every guide
//! page as a `docs/…` path.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The Markdown files checked: the README, every guide page and the schema pages.
fn pages() -> Vec<PathBuf> {
    let mut v = vec![root().join("README.md")];
    for dir in ["docs", "data-schema"] {
        let mut p: Vec<PathBuf> = std::fs::read_dir(root().join(dir))
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|e| e == "md"))
            .collect();
        p.sort();
        v.extend(p);
    }
    v
}

/// `[text](target)` and `![alt](target)` targets outside code blocks and code spans.
fn links(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        // Drop code spans: a `](` inside backticks is not a link.
        let mut plain = String::new();
        for (i, part) in line.split('`').enumerate() {
            if i % 2 == 0 {
                plain.push_str(part);
            }
        }
        let mut rest = plain.as_str();
        while let Some(k) = rest.find("](") {
            let after = &rest[k + 2..];
            let Some(end) = after.find(')') else {
                break;
            };
            out.push(after[..end].trim().to_string());
            rest = &after[end..];
        }
    }
    out
}

/// GitHub's anchor of a heading: lower case, punctuation dropped, spaces to dashes.
fn anchor(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

fn anchors(page: &Path) -> BTreeSet<String> {
    let text = std::fs::read_to_string(page).unwrap();
    let mut fenced = false;
    let mut out = BTreeSet::new();
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
        } else if !fenced && line.starts_with('#') {
            out.insert(anchor(line.trim_start_matches('#')));
        }
    }
    out
}

#[test]
fn every_relative_link_of_the_readme_and_the_guide_resolves() {
    let mut bad = Vec::new();
    let mut n = 0;
    for page in pages() {
        let text = std::fs::read_to_string(&page).unwrap();
        for target in links(&text) {
            if target.starts_with("http://") || target.starts_with("https://") {
                continue;
            }
            n += 1;
            let (file, frag) = match target.split_once('#') {
                Some((f, a)) => (f, Some(a)),
                None => (target.as_str(), None),
            };
            let resolved = if file.is_empty() {
                page.clone()
            } else {
                page.parent().unwrap().join(file)
            };
            if !resolved.exists() {
                bad.push(format!("{}: {target} (no such file)", page.display()));
                continue;
            }
            if let Some(a) = frag {
                if resolved.extension().is_some_and(|e| e == "md")
                    && !anchors(&resolved).contains(a)
                {
                    bad.push(format!("{}: {target} (no such heading)", page.display()));
                }
            }
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
    assert!(n > 50, "only {n} links found: the link reader is broken");
}

#[test]
fn the_readme_is_short_and_links_every_guide_page() {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let lines = readme.lines().count();
    assert!(lines <= 300, "README.md has {lines} lines (at most 300)");
    let linked: BTreeSet<String> = links(&readme).into_iter().collect();
    for page in pages() {
        let rel = page
            .strip_prefix(root())
            .unwrap()
            .to_string_lossy()
            .to_string();
        if rel.starts_with("docs/") {
            assert!(
                linked
                    .iter()
                    .any(|l| l == &rel || l.starts_with(&format!("{rel}#"))),
                "README.md does not link {rel}"
            );
        }
    }
}

#[test]
fn the_link_reader_sees_links_and_skips_code() {
    let t = "a [x](docs/a.md) and ![p](f.png#k)\n`[y](no.md)`\n```\n[z](no.md)\n```\n";
    assert_eq!(links(t), ["docs/a.md", "f.png#k"]);
    assert_eq!(
        anchor(" Deviations from DESIGN.md, and why"),
        "deviations-from-designmd-and-why"
    );
}
