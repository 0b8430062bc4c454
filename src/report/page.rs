//! The page's bound. The sections ask for pictures by marker; once every section is
//! written, the page is fitted into [`PAGE_BYTES`]: the text first, then the explorer's
//! points (what makes the page explorable), then the pictures in page order, then the
//! whole-record pictures a thumbnail swaps to. What does not fit is linked as the file it is
//! in the run folder, and the page says so at its top (the terminal too, from [`PageFit`]).

use super::esc;
use super::explore::{self, Explorer};
use crate::util::{base64, hex};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The report's bound, bytes.
pub const PAGE_BYTES: usize = 25_000_000;

/// Where the explorer goes, and where the page says what was left out.
pub(super) const EXPLORE_HERE: &str = "<!--aepipe:explore-->";
pub(super) const FIT_NOTE_HERE: &str = "<!--aepipe:fit-->";
const PIC_OPEN: &str = "<!--aepipe:pic ";
const PIC_CLOSE: &str = "-->";

/// A picture a section asks for: embedded if it fits, else a link to its file.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub(super) struct Pic {
    path: PathBuf,
    alt: String,
    width: Option<u32>,
    /// The whole picture a click on this thumbnail swaps to.
    full: Option<PathBuf>,
    /// A hit key the explorer opens this picture by (`data-key`).
    key: Option<String>,
}

impl Pic {
    pub(super) fn new(path: &Path, alt: &str, width: Option<u32>) -> Pic {
        Pic {
            path: path.to_path_buf(),
            alt: alt.to_string(),
            width,
            full: None,
            key: None,
        }
    }

    /// A thumbnail that a click swaps for `full` (and back).
    pub(super) fn swap(mut self, full: &Path) -> Pic {
        self.full = Some(full.to_path_buf());
        self
    }

    /// The explorer's key of the hit this picture shows.
    pub(super) fn key(mut self, key: String) -> Pic {
        self.key = Some(key);
        self
    }

    /// The marker the page holds until it is fitted.
    pub(super) fn marker(&self) -> String {
        let json = serde_json::to_vec(self).unwrap_or_default();
        format!("{PIC_OPEN}{}{PIC_CLOSE}", hex(&json))
    }

    fn from_marker(hexed: &str) -> Option<Pic> {
        let bytes: Option<Vec<u8>> = (0..hexed.len() / 2)
            .map(|i| u8::from_str_radix(hexed.get(2 * i..2 * i + 2)?, 16).ok())
            .collect();
        serde_json::from_slice(&bytes?).ok()
    }
}

/// What the fitting kept and what it left out.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PageFit {
    /// The page's size, bytes.
    pub bytes: usize,
    /// Pictures the sections asked for, and how many are embedded.
    pub pictures: usize,
    pub embedded: usize,
    /// The pictures linked instead (their files, as the page links them).
    pub linked: Vec<String>,
    /// Thumbnails whose whole-record picture opens only as its file.
    pub whole_linked: usize,
    /// The explorer's points, and the rows they stand for.
    pub explorer_points: usize,
    pub explorer_rows: usize,
}

impl PageFit {
    /// Whether anything the sections asked for is not on the page.
    pub fn left_out(&self) -> bool {
        !self.linked.is_empty()
            || self.whole_linked > 0
            || (self.explorer_rows > 0 && self.explorer_points == 0)
    }

    /// One line for the page and the terminal when something was left out.
    pub fn note(&self) -> Option<String> {
        if !self.left_out() {
            return None;
        }
        let mut parts = Vec::new();
        if self.explorer_rows > 0 {
            parts.push(if self.explorer_points == 0 {
                "the page's text leaves no room for the explorer's points".to_string()
            } else {
                format!("the explorer's {} points come first", self.explorer_points)
            });
        }
        parts.push(format!(
            "{} of {} pictures are embedded",
            self.embedded, self.pictures
        ));
        if !self.linked.is_empty() {
            parts.push(format!(
                "{} are linked as files of the run folder instead",
                self.linked.len()
            ));
        }
        if self.whole_linked > 0 {
            parts.push(format!(
                "{} thumbnails open their whole record as a file",
                self.whole_linked
            ));
        }
        Some(format!(
            "the report keeps within its {} MB bound: {}",
            PAGE_BYTES / 1_000_000,
            parts.join("; ")
        ))
    }
}

/// Bytes a picture's file takes embedded (base64), or `None` when it cannot be read.
fn embedded_len(p: &Path) -> Option<usize> {
    std::fs::metadata(p)
        .ok()
        .map(|m| (m.len() as usize).div_ceil(3) * 4)
}

/// `path` as the page links it: relative to the report's folder where it lies inside it.
fn link(path: &Path, report_dir: &Path) -> String {
    path.strip_prefix(report_dir)
        .unwrap_or(path)
        .to_string_lossy()
        .replace('\\', "/")
}

/// What the fitting decided for one picture.
#[derive(Clone, Copy, PartialEq)]
enum Place {
    Missing,
    Linked,
    Embedded { whole: bool },
}

/// The page with its markers replaced, within [`PAGE_BYTES`] where it can be: the text,
/// the explorer (thinned evenly if the text leaves it too little room), the pictures in page
/// order, then the whole records of the embedded thumbnails.
pub(super) fn fit(page: &str, ex: &Explorer, report_dir: &Path) -> (String, PageFit) {
    fit_within(page, ex, report_dir, PAGE_BYTES)
}

pub(super) fn fit_within(
    page: &str,
    ex: &Explorer,
    report_dir: &Path,
    bound: usize,
) -> (String, PageFit) {
    // The page between its markers, and the pictures in order.
    let mut text = Vec::new();
    let mut pics = Vec::new();
    let mut rest = page;
    while let Some(i) = rest.find(PIC_OPEN) {
        let after = &rest[i + PIC_OPEN.len()..];
        let Some(j) = after.find(PIC_CLOSE) else {
            break;
        };
        text.push(&rest[..i]);
        pics.push(Pic::from_marker(&after[..j]));
        rest = &after[j + PIC_CLOSE.len()..];
    }
    text.push(rest);
    // Each picture's tag without its data, a note a fitted page may carry, and the
    // explorer's script: counted before anything is placed.
    const TAG: usize = 160;
    const NOTE: usize = 600;
    let text_len: usize = text.iter().map(|t| t.len()).sum::<usize>() + pics.len() * TAG + NOTE;
    let room = bound.saturating_sub(text_len);
    let (fitted, json) = ex.fitted(room);
    let mut section = String::new();
    explore::section_with(&mut section, &fitted, &json);
    let mut left = room.saturating_sub(section.len());
    let mut place = vec![Place::Missing; pics.len()];
    for (k, p) in pics.iter().enumerate() {
        let Some(p) = p else { continue };
        place[k] = match embedded_len(&p.path) {
            Some(n) if n <= left => {
                left -= n;
                Place::Embedded { whole: false }
            }
            Some(_) => Place::Linked,
            None => Place::Missing,
        };
    }
    for (k, p) in pics.iter().enumerate() {
        let (Some(p), Place::Embedded { .. }) = (p, place[k]) else {
            continue;
        };
        let Some(full) = &p.full else { continue };
        if let Some(n) = embedded_len(full).filter(|&n| n + TAG <= left) {
            left -= n + TAG;
            place[k] = Place::Embedded { whole: true };
        }
    }
    let mut fit = PageFit {
        pictures: pics.len(),
        explorer_points: fitted.keys.len(),
        explorer_rows: ex.total,
        ..PageFit::default()
    };
    let mut out = String::with_capacity(bound.min(page.len() + bound / 4));
    for (k, t) in text.iter().enumerate() {
        out.push_str(t);
        let Some(p) = pics.get(k) else { continue };
        match (p, place[k]) {
            (Some(p), Place::Embedded { whole }) => {
                fit.embedded += 1;
                if p.full.is_some() && !whole {
                    fit.whole_linked += 1;
                }
                out.push_str(&embed(p, whole, report_dir));
            }
            (Some(p), Place::Linked) => {
                let href = link(&p.path, report_dir);
                let _ = write!(
                    out,
                    "<p class=missing><a href=\"{}\">{}</a> (not embedded: the page's bound)</p>",
                    esc(&href),
                    esc(&p.alt)
                );
                fit.linked.push(href);
            }
            (Some(p), Place::Missing) => {
                let e = std::fs::metadata(&p.path)
                    .err()
                    .map_or_else(|| "cannot be read".to_string(), |e| e.to_string());
                let _ = write!(
                    out,
                    "<p class=\"missing\">{}: {}</p>",
                    esc(&p.path.display().to_string()),
                    esc(&e)
                );
            }
            (None, _) => out.push_str("<p class=missing>a picture the page lost</p>"),
        }
    }
    let note = fit
        .note()
        .map(|n| format!("<p class=missing><b>{}.</b></p>", esc(&n)))
        .unwrap_or_default();
    let out = out
        .replacen(FIT_NOTE_HERE, &note, 1)
        .replacen(EXPLORE_HERE, &section, 1);
    fit.bytes = out.len();
    (out, fit)
}

/// A picture's `<img>`: its data, and for a thumbnail the whole record a click swaps to
/// (embedded when `whole`, else a link in its title).
fn embed(p: &Pic, whole: bool, report_dir: &Path) -> String {
    let Ok(bytes) = std::fs::read(&p.path) else {
        return format!(
            "<p class=\"missing\">{}: cannot be read</p>",
            esc(&p.path.display().to_string())
        );
    };
    let mut attrs = String::new();
    if let Some(k) = &p.key {
        let _ = write!(attrs, " data-key=\"{}\"", esc(k));
    }
    match (&p.full, whole) {
        // A whole record that cannot be read leaves the picture without its swap.
        (Some(full), true) => {
            if let Ok(b) = std::fs::read(full) {
                let _ = write!(
                    attrs,
                    " class=swap title=\"click: the whole record\" data-alt=\"data:image/png;base64,{}\" \
                     onclick=\"[this.src,this.dataset.alt]=[this.dataset.alt,this.src];\
                     this.closest('figure').classList.toggle('big');this.removeAttribute('width')\"",
                    base64(&b)
                );
            }
        }
        (Some(full), false) => {
            let _ = write!(
                attrs,
                " title=\"the whole record: {} (not embedded: the page's bound)\"",
                esc(&link(full, report_dir))
            );
        }
        (None, _) => {}
    }
    format!(
        "<img alt=\"{}\"{} src=\"data:image/png;base64,{}\"{}>",
        esc(&p.alt),
        attrs,
        base64(&bytes),
        p.width
            .map(|w| format!(" width=\"{w}\""))
            .unwrap_or_default()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn png(dir: &Path, name: &str, bytes: usize) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, vec![7u8; bytes]).unwrap();
        p
    }

    fn pictures_in(page: &str) -> usize {
        page.matches("src=\"data:image/png;base64,").count()
    }

    /// Room for all: every picture embedded with its whole record, no note. Room for the
    /// text, the explorer and two of three pictures: the explorer keeps every point, the
    /// first two pictures in page order are embedded, the third is linked by its path
    /// relative to the report's folder, whole records drop before any thumbnail, and the
    /// page and the fit say so. Plant: the old order (pictures first, the explorer given what
    /// they leave) is what this forbids — with a bound the pictures alone fill, the explorer
    /// must still hold all its points.
    #[test]
    fn the_explorer_comes_before_the_pictures_and_what_is_left_out_is_said() {
        let d = std::env::temp_dir().join(format!("aepipe-page-{}", std::process::id()));
        std::fs::create_dir_all(d.join("som")).unwrap();
        let a = png(&d, "som/a.png", 30_000);
        let b = png(&d, "som/b.png", 30_000);
        let c = png(&d, "som/c.png", 30_000);
        let full = png(&d, "som/a-full.png", 60_000);
        let ex = explore::tests::explorer(500);
        let page = format!(
            "<html>{FIT_NOTE_HERE}{EXPLORE_HERE}{}{}{}</html>",
            Pic::new(&a, "a", Some(270)).swap(&full).marker(),
            Pic::new(&b, "b", None).marker(),
            Pic::new(&c, "c", None).marker(),
        );
        let (all, f) = fit_within(&page, &ex, &d, 10_000_000);
        assert!(!f.left_out() && f.note().is_none(), "{f:?}");
        assert_eq!((f.pictures, f.embedded, pictures_in(&all)), (3, 3, 3));
        assert!(all.contains("data-alt=\"data:image/png;base64,"));
        assert_eq!(f.explorer_points, 500);
        // The explorer and two thumbnails fit, not the third nor the whole record.
        let section = {
            let (e, j) = ex.fitted(usize::MAX);
            let mut s = String::new();
            explore::section_with(&mut s, &e, &j);
            s.len()
        };
        let bound = 2_000 + section + 2 * 40_000 + 2 * 160 + 600 + 30_000;
        let (some, f) = fit_within(&page, &ex, &d, bound);
        assert_eq!(f.explorer_points, 500, "the explorer lost points: {f:?}");
        assert_eq!(
            (f.embedded, f.linked.clone()),
            (2, vec!["som/c.png".to_string()])
        );
        assert_eq!(f.whole_linked, 1);
        assert!(some.len() <= bound, "{} > {bound}", some.len());
        assert!(some.contains("<a href=\"som/c.png\">c</a>"));
        assert!(
            !some.contains("data-alt="),
            "a whole record fitted in place of a thumbnail"
        );
        let note = f.note().unwrap();
        assert!(
            some.contains(&esc(&note)),
            "the page does not say what it left out"
        );
        assert!(
            note.contains("2 of 3 pictures") && note.contains("1 are linked"),
            "{note}"
        );
        // Plant: a bound the pictures alone fill leaves the explorer whole.
        let (tight, f) = fit_within(&page, &ex, &d, 2_000 + section + 600 + 3 * 160 + 100);
        assert_eq!(f.explorer_points, 500);
        assert_eq!(f.embedded, 0);
        assert!(tight.contains("id=explore"));
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_marker_round_trips_any_path_and_text() {
        let p = Pic::new(Path::new("a --> b/\"c\".png"), "x <y> & -->", Some(3))
            .swap(Path::new("z.png"))
            .key("e\u{1f}1".into());
        let m = p.marker();
        assert!(m.starts_with(PIC_OPEN) && m.matches(PIC_CLOSE).count() == 1);
        assert_eq!(
            Pic::from_marker(&m[PIC_OPEN.len()..m.len() - PIC_CLOSE.len()]),
            Some(p)
        );
        assert_eq!(Pic::from_marker("zz"), None);
    }
}
