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
                    let pic = img_swap(thumb, full, &cap, 270).replacen(
                        "<img ",
                        &format!("<img data-key=\"{}\" ", esc(&explore::key_text(k))),
                        1,
                    );
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
