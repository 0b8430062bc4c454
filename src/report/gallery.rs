//! The report's CWT pictures: the gallery of the first hits of each class (Appendix B's
//! pictures, bounded), and the hits the SOM reads otherwise than the ch. 4.7 criteria
//! (Table 5.3 and Fig. 5.11).

use super::{esc, explore, img_swap};
use crate::store::HitKey;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;

/// A gallery hit's thumbnail (the window about the burst) and its whole record's picture.
pub type GalleryPicture = (PathBuf, PathBuf);

/// A CWT picture per chosen hit of each class (`None`: it could not be drawn).
#[derive(Default)]
pub struct Gallery {
    /// "SOM" or "criteria": which labels chose the hits.
    pub by: &'static str,
    /// Per class: each hit with its thumbnail (the window about the burst) and its whole
    /// record's picture, or None where it could not be drawn.
    pub classes: BTreeMap<String, Vec<(HitKey, Option<GalleryPicture>)>>,
}

/// The gallery's choice, the first `per` hits of each class in key order, made as the hits
/// stream by in any order: each class keeps the `per` smallest keys it has seen (a bounded max-heap), so memory holds `per` keys a class.
#[derive(Debug, Clone)]
pub struct GalleryChoice {
    per: usize,
    heaps: BTreeMap<String, std::collections::BinaryHeap<HitKey>>,
}

impl GalleryChoice {
    pub fn new(per: usize) -> GalleryChoice {
        GalleryChoice {
            per,
            heaps: BTreeMap::new(),
        }
    }

    pub fn offer(&mut self, key: &HitKey, class: &str) {
        if self.per == 0 {
            return;
        }
        if !self.heaps.contains_key(class) {
            self.heaps.insert(class.to_string(), Default::default());
        }
        let h = self.heaps.get_mut(class).expect("inserted");
        if h.len() < self.per {
            h.push(key.clone());
        } else if h.peek().is_some_and(|top| key < top) {
            h.pop();
            h.push(key.clone());
        }
    }

    pub fn chosen(self) -> BTreeMap<String, Vec<HitKey>> {
        self.heaps
            .into_iter()
            .map(|(c, h)| (c, h.into_sorted_vec()))
            .collect()
    }
}

pub(super) fn gallery_section(h: &mut String, g: &Gallery) {
    if g.classes.is_empty() {
        return;
    }
    let _ = match g.by {
        "cluster" => write!(h, "<h2>CWT gallery by cluster</h2>"),
        by => write!(h, "<h2>CWT gallery by {by} class (Appendix B)</h2>"),
    };
    for (class, pics) in &g.classes {
        let _ = write!(h, "<h3>{}</h3><div class=gallery>", esc(class));
        for (k, png) in pics {
            let cap = format!("{} ch{} hit {}", k.0, k.1, k.2);
            match png {
                Some((thumb, full)) => {
                    // The explorer opens a hit's picture by this key.
                    let pic = super::page::Pic::new(thumb, &cap, Some(270))
                        .swap(full)
                        .key(explore::key_text(k))
                        .marker();
                    let _ = write!(
                        h,
                        "<figure>{}<figcaption>{}</figcaption></figure>",
                        pic,
                        esc(&cap)
                    );
                }
                None => {
                    let _ = write!(h, "<p class=missing>{}: not drawn</p>", esc(&cap));
                }
            }
        }
        h.push_str("</div>");
    }
}

/// One hit the SOM reads otherwise than its reference label.
#[derive(Debug, Clone)]
pub struct Disagreement {
    pub key: HitKey,
    /// The reference label (the ch. 4.7 criteria's, by default) and the SOM's class.
    pub reference: String,
    pub som: String,
    /// Its best-matching node (row, column).
    pub node: (i32, i32),
}

/// Table 5.3 and Fig. 5.11: the hits whose SOM class differs from their reference label
/// (hits the map calls unlike its references are not readings of a mechanism, and are left
/// out), counted per (reference, SOM) pair, the first `keep` in key order kept with their
/// node — a bounded set, made as the classification streams by in any order.
#[derive(Debug, Clone, Default)]
pub struct Disagreements {
    pub keep: usize,
    /// Hits per (reference label, SOM class), disagreeing only.
    pub counts: BTreeMap<(String, String), usize>,
    /// Hits with a reference label and a mechanism reading (the denominator).
    pub compared: usize,
    pub first: BTreeMap<HitKey, Disagreement>,
    /// Each kept hit's CWT thumbnail and whole picture (drawn by the workflow).
    pub pictures: BTreeMap<HitKey, (PathBuf, PathBuf)>,
}

impl Disagreements {
    pub fn new(keep: usize) -> Disagreements {
        Disagreements {
            keep,
            ..Default::default()
        }
    }

    /// Offer one classified hit.
    pub fn offer(&mut self, key: &HitKey, som: &str, reference: Option<&str>, node: (i32, i32)) {
        let Some(reference) = reference else {
            return;
        };
        if som == crate::model::UNLIKE_REFERENCES {
            return;
        }
        self.compared += 1;
        if som == reference {
            return;
        }
        *self
            .counts
            .entry((reference.to_string(), som.to_string()))
            .or_insert(0) += 1;
        if self.keep == 0 {
            return;
        }
        if self.first.len() == self.keep {
            match self.first.last_key_value() {
                Some((last, _)) if key < last => {
                    self.first.pop_last();
                }
                _ => return,
            }
        }
        self.first.insert(
            key.clone(),
            Disagreement {
                key: key.clone(),
                reference: reference.to_string(),
                som: som.to_string(),
                node,
            },
        );
    }

    pub fn total(&self) -> usize {
        self.counts.values().sum()
    }
}

/// The report's Table 5.3 / Fig. 5.11 section (nothing without a SOM stage).
pub(super) fn disagree_section(h: &mut String, d: &Disagreements, reference: &str) {
    if d.compared == 0 {
        return;
    }
    let _ = write!(
        h,
        "<h3>Hits the SOM reads otherwise than {} (Table 5.3, Fig. 5.11)</h3>\
         <p>{} of {} hits with a reference label and a mechanism reading ({:.1} %); hits \
         the map calls unlike its references are counted in the section above.</p>",
        esc(reference),
        d.total(),
        d.compared,
        100.0 * d.total() as f64 / d.compared as f64
    );
    if d.counts.is_empty() {
        return;
    }
    h.push_str(
        "<table><tr><th class=l>reference label</th><th class=l>SOM class</th><th>hits</th></tr>",
    );
    for ((r, s), n) in &d.counts {
        let _ = write!(
            h,
            "<tr><td class=l>{}</td><td class=l>{}</td><td>{n}</td></tr>",
            esc(r),
            esc(s)
        );
    }
    let _ = write!(
        h,
        "</table><p>The first {} in key order, with the node each falls on:</p>\
         <table><tr><th class=l>hit</th><th class=l>reference label</th><th class=l>SOM class</th><th>node (row, col)</th></tr>",
        d.first.len()
    );
    for x in d.first.values() {
        let _ = write!(
            h,
            "<tr><td class=l>{} ch{} hit {}</td><td class=l>{}</td><td class=l>{}</td><td>({}, {})</td></tr>",
            esc(&x.key.0),
            x.key.1,
            x.key.2,
            esc(&x.reference),
            esc(&x.som),
            x.node.0,
            x.node.1
        );
    }
    h.push_str("</table><div class=gallery>");
    for x in d.first.values() {
        let cap = format!(
            "{} ch{} hit {}: {} read as {}, node ({}, {})",
            x.key.0, x.key.1, x.key.2, x.reference, x.som, x.node.0, x.node.1
        );
        match d.pictures.get(&x.key) {
            Some((thumb, full)) => {
                let _ = write!(
                    h,
                    "<figure>{}<figcaption>{}</figcaption></figure>",
                    img_swap(thumb, full, &cap, 270),
                    esc(&cap)
                );
            }
            None => {
                let _ = write!(h, "<p class=missing>{}: not drawn</p>", esc(&cap));
            }
        }
    }
    h.push_str("</div>");
}

/// Appendix B's pages as written: where, how many hits drawn of how many.
#[derive(Debug, Clone)]
pub struct AppendixB {
    pub index: PathBuf,
    pub pages: usize,
    /// Hits shown (drawn or said not drawn) and the run's hits.
    pub shown: usize,
    pub drawn: usize,
    pub total: usize,
}

/// Thumbnails per page of Appendix B.
pub const APPENDIX_B_PAGE: usize = 100;

/// Write Appendix B: `dir/page-NNN.html`, 100 thumbnails each (linked, not embedded: a
/// page stays small however many hits), and `dir/index.html` listing the pages with their
/// first and last hits. `hits` in key order, each with its thumbnail if it was drawn.
pub fn write_appendix_b(
    dir: &std::path::Path,
    hits: &[(HitKey, Option<PathBuf>)],
    total: usize,
) -> std::io::Result<AppendixB> {
    std::fs::create_dir_all(dir)?;
    let pages: Vec<&[(HitKey, Option<PathBuf>)]> = hits.chunks(APPENDIX_B_PAGE).collect();
    let name = |k: usize| format!("page-{:03}.html", k + 1);
    let id = |k: &HitKey| format!("{} ch{} hit {}", k.0, k.1, k.2);
    let head = |title: &str| {
        format!(
            "<!doctype html><html><head><meta charset=utf-8><title>{t}</title><style>\
             body{{font-family:sans-serif;margin:1em}}figure{{display:inline-block;margin:4px}}\
             figcaption{{font-size:12px}}img{{width:270px}}</style></head><body><h1>{t}</h1>",
            t = esc(title)
        )
    };
    for (k, page) in pages.iter().enumerate() {
        let mut h = head(&format!("Appendix B, page {} of {}", k + 1, pages.len()));
        let _ = write!(h, "<p><a href=index.html>index</a>");
        if k > 0 {
            let _ = write!(h, " · <a href={}>previous</a>", name(k - 1));
        }
        if k + 1 < pages.len() {
            let _ = write!(h, " · <a href={}>next</a>", name(k + 1));
        }
        h.push_str("</p>");
        for (key, png) in page.iter() {
            match png {
                Some(p) => {
                    // Relative to the page: the run folder moves as one.
                    let rel = format!(
                        "../gallery/{}",
                        p.file_name()
                            .map(|f| f.to_string_lossy())
                            .unwrap_or_default()
                    );
                    let _ = write!(
                        h,
                        "<figure><img loading=lazy src=\"{}\" alt=\"{}\"><figcaption>{}</figcaption></figure>",
                        esc(&rel),
                        esc(&id(key)),
                        esc(&id(key))
                    );
                }
                None => {
                    let _ = write!(h, "<p class=missing>{}: not drawn</p>", esc(&id(key)));
                }
            }
        }
        h.push_str("</body></html>\n");
        std::fs::write(dir.join(name(k)), h)?;
    }
    let drawn = hits.iter().filter(|(_, p)| p.is_some()).count();
    let mut h = head("Appendix B: the CWT of every hit");
    let _ = write!(
        h,
        "<p>{} of the run's {total} hits, in key order ({drawn} drawn), {} to a page.</p><ul>",
        hits.len(),
        APPENDIX_B_PAGE
    );
    for (k, page) in pages.iter().enumerate() {
        let (a, b) = (&page[0].0, &page[page.len() - 1].0);
        let _ = write!(
            h,
            "<li><a href={}>page {}</a>: {} … {}</li>",
            name(k),
            k + 1,
            esc(&id(a)),
            esc(&id(b))
        );
    }
    h.push_str("</ul></body></html>\n");
    let index = dir.join("index.html");
    std::fs::write(&index, h)?;
    Ok(AppendixB {
        index,
        pages: pages.len(),
        shown: hits.len(),
        drawn,
        total,
    })
}

/// The report's link to Appendix B (nothing when it was not asked for).
pub(super) fn appendix_b_section(h: &mut String, a: Option<&AppendixB>) {
    let Some(a) = a else {
        return;
    };
    let _ = write!(
        h,
        "<h2>Appendix B</h2><p>The CWT of {} of the run's {} hits in key order ({} drawn), \
         on {} pages of {}: <a href=\"appendix-b/index.html\">appendix-b/index.html</a> \
         (beside this report; the pages link the thumbnails in <code>gallery/</code>).{}</p>",
        a.shown,
        a.total,
        a.drawn,
        a.pages,
        APPENDIX_B_PAGE,
        if a.shown < a.total {
            format!(
                " The rest are left out by <code>[report] appendix_b_hits = {}</code>.",
                a.shown
            )
        } else {
            String::new()
        }
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gallery_takes_the_first_hits_of_each_class() {
        let k = |h: i64| ("e".to_string(), 1, h);
        // Offered out of key order, as the classification streams them.
        let mut g = GalleryChoice::new(2);
        for (key, class) in [(k(3), "b"), (k(1), "a"), (k(4), "b"), (k(2), "b")] {
            g.offer(&key, class);
        }
        let c = g.chosen();
        assert_eq!(c["a"], vec![k(1)]);
        assert_eq!(c["b"], vec![k(2), k(3)]);
    }

    #[test]
    fn appendix_b_pages_hold_a_hundred_hits_each_and_link_their_thumbnails() {
        let dir = std::env::temp_dir().join(format!("aepipe-appendix-b-{}", std::process::id()));
        let hits: Vec<(HitKey, Option<PathBuf>)> = (1..=250)
            .map(|h| {
                let png =
                    (h % 50 != 0).then(|| PathBuf::from(format!("/run/gallery/e_ch1_hit{h}.png")));
                (("e".to_string(), 1, h as i64), png)
            })
            .collect();
        let a = write_appendix_b(&dir, &hits, 300).unwrap();
        assert_eq!((a.pages, a.shown, a.drawn, a.total), (3, 250, 245, 300));
        let page =
            |k: usize| std::fs::read_to_string(dir.join(format!("page-{k:03}.html"))).unwrap();
        // Hits 50 and 100 were not drawn: said, in their place.
        assert_eq!(page(1).matches("<figure>").count(), 98);
        assert_eq!(page(1).matches("not drawn").count(), 2);
        assert_eq!(
            page(3).matches("<figure>").count() + page(3).matches("not drawn").count(),
            50
        );
        assert!(
            page(2).contains("src=\"../gallery/e_ch1_hit101.png\""),
            "{}",
            page(2)
        );
        assert!(page(2).contains("e ch1 hit 150: not drawn"));
        let index = std::fs::read_to_string(&a.index).unwrap();
        assert!(
            index.contains("250 of the run's 300 hits")
                && index.contains("e ch1 hit 201 … e ch1 hit 250"),
            "{index}"
        );
        let mut h = String::new();
        appendix_b_section(&mut h, Some(&a));
        assert!(h.contains("appendix_b_hits = 250"), "{h}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn disagreements_count_every_pair_and_keep_the_first_hits() {
        let k = |h: i64| ("e".to_string(), 1, h);
        let mut d = Disagreements::new(2);
        for (h, som, r) in [
            (5, "fibre_failure", Some("bond_failure")),
            (1, "bond_failure", Some("bond_failure")),
            (4, "bond_failure", Some("both")),
            (3, crate::model::UNLIKE_REFERENCES, Some("bond_failure")),
            (2, "fibre_failure", None),
            (6, "fibre_failure", Some("bond_failure")),
        ] {
            d.offer(&k(h), som, r, (h as i32, 0));
        }
        assert_eq!(d.compared, 4);
        assert_eq!(d.total(), 3);
        assert_eq!(
            d.counts[&("bond_failure".into(), "fibre_failure".into())],
            2
        );
        let kept: Vec<i64> = d.first.keys().map(|k| k.2).collect();
        assert_eq!(kept, vec![4, 5]);
        let mut h = String::new();
        disagree_section(&mut h, &d, "criteria_label");
        assert!(
            h.contains("3 of 4 hits") && h.contains("e ch1 hit 4"),
            "{h}"
        );
        assert!(!h.contains("hit 6"), "{h}");
    }
}
