//! A page walk of a SQLite file, written here from the file format (not by the project's reader).

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// What a page walk of a SQLite file finds, written here from the file format: the page
/// size, and for every record of one table its rowid and the pages it occupies (its leaf
/// page and overflow chain), and the pages of each kind.
#[derive(Clone)]
pub(super) struct Walk {
    pub page: usize,
    pub records: BTreeMap<i64, Vec<u64>>,
    pub leaves: BTreeSet<u64>,
    pub interior: BTreeSet<u64>,
    pub overflow_mid: BTreeSet<u64>,
    pub overflow_last: BTreeSet<u64>,
}

fn be(b: &[u8], at: usize, n: usize) -> u64 {
    b[at..at + n].iter().fold(0, |v, x| (v << 8) | *x as u64)
}

fn varint(b: &[u8], at: usize) -> (u64, usize) {
    let mut v = 0u64;
    for i in 0..8 {
        v = (v << 7) | (b[at + i] & 0x7f) as u64;
        if b[at + i] < 0x80 {
            return (v, i + 1);
        }
    }
    ((v << 8) | b[at + 8] as u64, 9)
}

/// The walk of an intact file's `tr_data` tree (rooted where sqlite_master says).
pub(super) fn walk(file: &Path) -> Walk {
    walk_table(file, "tr_data")
}

pub(super) fn walk_table(file: &Path, table: &str) -> Walk {
    let root: i64 = rusqlite::Connection::open(file)
        .unwrap()
        .query_row(
            "SELECT rootpage FROM sqlite_master WHERE name = ?1",
            [table],
            |r| r.get(0),
        )
        .unwrap();
    let b = std::fs::read(file).unwrap();
    let page = match be(&b, 16, 2) {
        1 => 65536,
        p => p as usize,
    };
    let usable = page - b[20] as usize;
    let pg = |n: u64| &b[(n as usize - 1) * page..n as usize * page];
    let mut w = Walk {
        page,
        records: BTreeMap::new(),
        leaves: BTreeSet::new(),
        interior: BTreeSet::new(),
        overflow_mid: BTreeSet::new(),
        overflow_last: BTreeSet::new(),
    };
    let mut stack = vec![root as u64];
    while let Some(n) = stack.pop() {
        let p = pg(n);
        let h = if n == 1 { 100 } else { 0 };
        let cells = be(p, h + 3, 2) as usize;
        let interior = p[h] == 5;
        let ptrs = h + if interior { 12 } else { 8 };
        if interior {
            w.interior.insert(n);
            stack.push(be(p, h + 8, 4));
        } else {
            assert_eq!(p[h], 13);
            w.leaves.insert(n);
        }
        for i in 0..cells {
            let off = be(p, ptrs + 2 * i, 2) as usize;
            if interior {
                stack.push(be(p, off, 4));
                continue;
            }
            let (size, a) = varint(p, off);
            let (rowid, c) = varint(p, off + a);
            let size = size as usize;
            let x = usable - 35;
            let m = (usable - 12) * 32 / 255 - 23;
            let local = if size <= x {
                size
            } else {
                let k = m + (size - m) % (usable - 4);
                if k <= x {
                    k
                } else {
                    m
                }
            };
            let mut pages = vec![n];
            if size > local {
                let mut next = be(p, off + a + c + local, 4);
                let mut left = size - local;
                while left > 0 {
                    pages.push(next);
                    let o = pg(next);
                    left = left.saturating_sub(usable - 4);
                    if left > 0 {
                        w.overflow_mid.insert(next);
                    } else {
                        w.overflow_last.insert(next);
                    }
                    next = be(o, 0, 4);
                }
            }
            w.records.insert(rowid as i64, pages);
        }
    }
    w
}
