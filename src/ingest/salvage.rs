//! Salvage of SQLite files that SQLite refuses or reads only in part (issue 53): a
//! power cut, a full disk or a copy that stopped half-way leaves most of a Vallen database's
//! pages whole, but SQLite (and so vallenae and VisualAE) gives up on the file.
//!
//! The reader walks the file page by page, never writing to it, and trusts nothing it reads
//! before checking it against the bytes it has:
//!
//! * the 100-byte header's page size (a power of two, 512–65536) and reserved bytes; when
//!   the header is gone, the page size that makes the most pages read as b-tree pages;
//! * the schema (`sqlite_master`, rooted on page 1) when it is whole: each table's columns
//!   and root page; every leaf reached from a root belongs to that table;
//! * every other table-leaf page (its parent lost to the damage) by its records' shape: the
//!   one known table whose column count its records have, and whose every value fits the
//!   declared column ([`Shape`]);
//! * each cell's record with its overflow chain: taken only when the cell, every overflow
//!   page (in the file, not a b-tree page, not visited twice, the last one ending the chain,
//!   none of them all zeros) and every value are whole;
//! * pages on the freelist are never read as records (a deleted row is not salvaged).
//!
//! What it finds is rows by table; what a caller makes of them (a FLAC blob must decode to
//! its `Samples`) is the caller's check. Every size and pointer read from a page is checked
//! before it is used (`fuzz/fuzz_targets/sqlite_salvage.rs`).

use std::collections::{BTreeMap, BTreeSet, HashMap};

/// A value of a record, as SQLite stores it.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    Null,
    Int(i64),
    Real(f64),
    Text(String),
    Blob(Vec<u8>),
}

impl Value {
    pub fn int(&self) -> Option<i64> {
        match self {
            Value::Int(i) => Some(*i),
            _ => None,
        }
    }

    pub fn real(&self) -> Option<f64> {
        match self {
            Value::Int(i) => Some(*i as f64),
            Value::Real(f) => Some(*f),
            _ => None,
        }
    }
}

/// The storage class a column takes (its declared type's affinity, for the shape test).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Affinity {
    Integer,
    Real,
    Text,
    Blob,
    /// No declared type: anything.
    Any,
}

impl Affinity {
    /// SQLite's affinity rules (§3.1 of its datatype page), enough for Vallen's types.
    pub fn of_declared(t: &str) -> Affinity {
        let t = t.to_ascii_uppercase();
        if t.contains("INT") {
            Affinity::Integer
        } else if t.contains("CHAR") || t.contains("CLOB") || t.contains("TEXT") {
            Affinity::Text
        } else if t.contains("BLOB") {
            Affinity::Blob
        } else if t.contains("REAL") || t.contains("FLOA") || t.contains("DOUB") {
            Affinity::Real
        } else {
            Affinity::Any
        }
    }

    /// Whether a stored value fits a column of this affinity (NULL fits any).
    fn fits(self, v: &Value) -> bool {
        match (self, v) {
            (_, Value::Null) | (Affinity::Any, _) => true,
            // A numeric column keeps a value that does not convert losslessly as it is: an
            // INT column holds a REAL (Vallen's parametric PA0), a REAL column an integer.
            (Affinity::Integer | Affinity::Real, Value::Int(_) | Value::Real(_)) => true,
            (Affinity::Text, Value::Text(_)) => true,
            (Affinity::Blob, Value::Blob(_)) => true,
            _ => false,
        }
    }
}

/// A table's columns as declared: (name, affinity), and which one is the rowid
/// (`INTEGER PRIMARY KEY`, stored as NULL in the record).
#[derive(Debug, Clone, PartialEq)]
pub struct Shape {
    pub table: String,
    pub columns: Vec<(String, Affinity)>,
    pub rowid_column: Option<usize>,
}

impl Shape {
    /// A shape from a `CREATE TABLE name (col type, …)` statement; `None` for anything else
    /// (a view, an index, `WITHOUT ROWID`, a statement it cannot split).
    pub fn from_sql(sql: &str) -> Option<Shape> {
        let upper = sql.to_ascii_uppercase();
        if !upper.trim_start().starts_with("CREATE TABLE") || upper.contains("WITHOUT ROWID") {
            return None;
        }
        let open = sql.find('(')?;
        let close = sql.rfind(')')?;
        let name = unquote(sql[12..open].split_whitespace().last()?);
        let body = sql.get(open + 1..close)?;
        let mut parts = Vec::new();
        let (mut depth, mut start) = (0i32, 0usize);
        for (i, ch) in body.char_indices() {
            match ch {
                '(' => depth += 1,
                ')' => depth -= 1,
                ',' if depth == 0 => {
                    parts.push(&body[start..i]);
                    start = i + 1;
                }
                _ => {}
            }
        }
        parts.push(&body[start..]);
        let mut columns = Vec::new();
        let mut rowid_column = None;
        for p in parts {
            let p = p.trim();
            let first = p.split_whitespace().next()?;
            let kw = first.to_ascii_uppercase();
            if ["PRIMARY", "UNIQUE", "CHECK", "FOREIGN", "CONSTRAINT"].contains(&kw.as_str()) {
                continue;
            }
            let rest = p[first.len()..].to_ascii_uppercase();
            let declared = rest.split_whitespace().next().unwrap_or("");
            if declared == "INTEGER" && rest.contains("PRIMARY KEY") {
                rowid_column = Some(columns.len());
            }
            columns.push((unquote(first), Affinity::of_declared(declared)));
        }
        (!columns.is_empty()).then_some(Shape {
            table: name,
            columns,
            rowid_column,
        })
    }

    /// Whether a record of `values` can be a row of this table.
    fn fits(&self, values: &[Value]) -> bool {
        values.len() == self.columns.len()
            && values
                .iter()
                .zip(&self.columns)
                .enumerate()
                .all(|(i, (v, (_, a)))| {
                    if Some(i) == self.rowid_column {
                        *v == Value::Null
                    } else {
                        a.fits(v)
                    }
                })
    }
}

fn unquote(s: &str) -> String {
    s.trim_matches(|c| c == '"' || c == '`' || c == '[' || c == ']' || c == '\'')
        .to_string()
}

/// One salvaged row: its rowid and its values (the rowid column holds the rowid).
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    pub rowid: i64,
    pub values: Vec<Value>,
}

/// The rows of one table, and how its leaves were found.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TableRows {
    pub shape: Option<Shape>,
    /// By rowid: a row found twice the same is kept once; twice different, dropped.
    pub rows: BTreeMap<i64, Row>,
    /// Leaf pages reached from the table's root, and found by their records' shape.
    pub reached_leaves: u64,
    pub shaped_leaves: u64,
}

/// What a salvage found.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Salvage {
    pub page_size: usize,
    /// Whole pages in the file (a cut leaves a partial last page, not read), and the pages
    /// the header says the database has (0: not stated, or no header).
    pub pages: u64,
    pub declared_pages: u64,
    /// Whether the header and the schema page read whole.
    pub header_whole: bool,
    pub schema_whole: bool,
    pub tables: BTreeMap<String, TableRows>,
    /// Records seen whole, and cells whose record was not (a page, an overflow page or a
    /// value missing or damaged), over every table-leaf page.
    pub whole_records: u64,
    pub partial_records: u64,
    /// Table-leaf pages no table could be told for.
    pub unowned_leaves: u64,
    /// The schema's `CREATE TABLE` and `CREATE VIEW` statements, as read (none when the
    /// schema page is lost).
    pub statements: Vec<String>,
}

impl Salvage {
    pub fn rows(&self, table: &str) -> impl Iterator<Item = &Row> {
        self.tables
            .get(table)
            .into_iter()
            .flat_map(|t| t.rows.values())
    }

    /// The tables found: `tr_data 277 (20 leaf pages from its root, 3 by record shape)`, ….
    pub fn describe_tables(&self) -> String {
        self.tables
            .iter()
            .map(|(name, t)| {
                format!(
                    "{name} {} ({} leaf page(s) from its root, {} by record shape)",
                    t.rows.len(),
                    t.reached_leaves,
                    t.shaped_leaves
                )
            })
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// A value of a row by column name.
    pub fn column(&self, table: &str, name: &str) -> Option<usize> {
        self.tables
            .get(table)?
            .shape
            .as_ref()?
            .columns
            .iter()
            .position(|(c, _)| c.eq_ignore_ascii_case(name))
    }
}

/// Write what was salvaged into a fresh SQLite file `to`: the schema's tables and views
/// (the file's own statements when its schema was whole, else `fallback`), and every
/// salvaged row under its rowid — a file any reader built for SQLite reads. Returns the rows
/// written.
pub fn rebuild(s: &Salvage, fallback: &[&str], to: &std::path::Path) -> rusqlite::Result<u64> {
    let _ = std::fs::remove_file(to);
    let mut c = rusqlite::Connection::open(to)?;
    let own: Vec<&str> = s.statements.iter().map(String::as_str).collect();
    let statements = if s.schema_whole && !own.is_empty() {
        own
    } else {
        fallback.to_vec()
    };
    for st in statements {
        c.execute_batch(st)?;
    }
    let tx = c.transaction()?;
    let mut n = 0;
    for (name, t) in &s.tables {
        let Some(shape) = &t.shape else { continue };
        let mut cols: Vec<String> = shape
            .columns
            .iter()
            .map(|c| format!("\"{}\"", c.0))
            .collect();
        if shape.rowid_column.is_none() {
            cols.insert(0, "rowid".into());
        }
        let sql = format!(
            "INSERT INTO \"{name}\" ({}) VALUES ({})",
            cols.join(","),
            vec!["?"; cols.len()].join(",")
        );
        let Ok(mut st) = tx.prepare(&sql) else {
            continue;
        };
        for r in t.rows.values() {
            let mut vals: Vec<rusqlite::types::Value> = r
                .values
                .iter()
                .map(|v| match v {
                    Value::Null => rusqlite::types::Value::Null,
                    Value::Int(i) => rusqlite::types::Value::Integer(*i),
                    Value::Real(f) => rusqlite::types::Value::Real(*f),
                    Value::Text(t) => rusqlite::types::Value::Text(t.clone()),
                    Value::Blob(b) => rusqlite::types::Value::Blob(b.clone()),
                })
                .collect();
            if shape.rowid_column.is_none() {
                vals.insert(0, rusqlite::types::Value::Integer(r.rowid));
            }
            st.execute(rusqlite::params_from_iter(vals))?;
            n += 1;
        }
    }
    tx.commit()?;
    Ok(n)
}

/// Why nothing could be salvaged.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SalvageError {
    #[error("shorter than one SQLite page")]
    TooShort,
    /// The header is lost and no page size makes a whole record of a table whose shape is
    /// known (the schema page, the file's header page, is lost with it).
    #[error(
        "its header and schema page are lost, and no page holds a whole record of a known table"
    )]
    NoPages,
}

const MAGIC: &[u8; 16] = b"SQLite format 3\0";

/// A big-endian integer of `n` bytes at `at`, if the bytes are there.
fn be(b: &[u8], at: usize, n: usize) -> Option<u64> {
    let s = b.get(at..at.checked_add(n)?)?;
    Some(s.iter().fold(0u64, |v, x| (v << 8) | *x as u64))
}

/// A varint at `at`: (value, length), if it ends inside `b`.
fn varint(b: &[u8], at: usize) -> Option<(u64, usize)> {
    let mut v = 0u64;
    for i in 0..9 {
        let x = *b.get(at.checked_add(i)?)?;
        if i == 8 {
            return Some(((v << 8) | x as u64, 9));
        }
        v = (v << 7) | (x & 0x7f) as u64;
        if x & 0x80 == 0 {
            return Some((v, i + 1));
        }
    }
    None
}

/// The file as pages: size, usable bytes, how many whole.
struct Pages<'a> {
    bytes: &'a [u8],
    size: usize,
    usable: usize,
    count: u64,
}

impl<'a> Pages<'a> {
    /// Page `n` (1-based), if it is whole in the file.
    fn page(&self, n: u64) -> Option<&'a [u8]> {
        if n == 0 || n > self.count {
            return None;
        }
        let start = (n - 1).checked_mul(self.size as u64)? as usize;
        self.bytes.get(start..start + self.size)
    }

    /// Where page `n`'s b-tree header starts (after the file header on page 1).
    fn header_at(n: u64) -> usize {
        if n == 1 {
            100
        } else {
            0
        }
    }

    /// The b-tree page kind of page `n`: 2, 5, 10, 13, or `None`.
    fn kind(&self, n: u64) -> Option<u8> {
        let p = self.page(n)?;
        let k = *p.get(Self::header_at(n))?;
        matches!(k, 2 | 5 | 10 | 13).then_some(k)
    }

    /// The cell offsets of b-tree page `n`, each checked to lie in the page.
    fn cells(&self, n: u64) -> Option<Vec<usize>> {
        let p = self.page(n)?;
        let h = Self::header_at(n);
        let kind = self.kind(n)?;
        let count = be(p, h + 3, 2)? as usize;
        let ptrs = h + if kind == 2 || kind == 5 { 12 } else { 8 };
        if ptrs + 2 * count > self.usable {
            return None;
        }
        (0..count)
            .map(|i| {
                let off = be(p, ptrs + 2 * i, 2)? as usize;
                (off >= ptrs + 2 * count && off < self.usable).then_some(off)
            })
            .collect()
    }

    /// The children of interior table page `n` (its cells' left pointers, then the
    /// right-most pointer).
    fn children(&self, n: u64) -> Vec<u64> {
        let Some(p) = self.page(n) else {
            return vec![];
        };
        let h = Self::header_at(n);
        let mut out: Vec<u64> = self
            .cells(n)
            .unwrap_or_default()
            .into_iter()
            .filter_map(|off| be(p, off, 4))
            .collect();
        out.extend(be(p, h + 8, 4));
        out
    }
}

/// Every leaf page of the table b-tree rooted at `root` that is whole in the file.
fn leaves_of(pages: &Pages, root: u64, seen: &mut BTreeSet<u64>) -> Vec<u64> {
    let mut out = Vec::new();
    let mut stack = vec![root];
    while let Some(n) = stack.pop() {
        if !seen.insert(n) {
            continue;
        }
        match pages.kind(n) {
            Some(13) => out.push(n),
            Some(5) => stack.extend(pages.children(n).into_iter().rev()),
            _ => {}
        }
    }
    out
}

/// The pages of the freelist (trunk and leaf pages), from the header's pointer.
fn freelist(pages: &Pages, first: u64) -> BTreeSet<u64> {
    let mut out = BTreeSet::new();
    let mut trunk = first;
    while trunk != 0 && out.insert(trunk) {
        let Some(p) = pages.page(trunk) else { break };
        let n = be(p, 4, 4).unwrap_or(0) as usize;
        for i in 0..n.min(pages.usable / 4) {
            if let Some(leaf) = be(p, 8 + 4 * i, 4) {
                out.insert(leaf);
            }
        }
        trunk = be(p, 0, 4).unwrap_or(0);
    }
    out
}

/// Why a cell's record is not whole.
#[derive(Debug)]
struct Partial;

/// The record of the table-leaf cell at `off` of page `n`: (rowid, values), if whole.
fn leaf_record(pages: &Pages, n: u64, off: usize) -> Result<(i64, Vec<Value>), Partial> {
    let p = pages.page(n).ok_or(Partial)?;
    let u = pages.usable;
    let (size, a) = varint(p, off).ok_or(Partial)?;
    let (rowid, b) = varint(p, off + a).ok_or(Partial)?;
    let start = off + a + b;
    // How much of the payload the page holds (the b-tree's own rule).
    let x = u - 35;
    let size = usize::try_from(size).map_err(|_| Partial)?;
    let local = if size <= x {
        size
    } else {
        let m = ((u - 12) * 32 / 255) - 23;
        let k = m + (size - m) % (u - 4);
        if k <= x {
            k
        } else {
            m
        }
    };
    if start + local > u {
        return Err(Partial);
    }
    let mut payload = Vec::with_capacity(size.min(pages.bytes.len()));
    payload.extend_from_slice(&p[start..start + local]);
    if size > local {
        let mut next = be(p, start + local, 4).ok_or(Partial)?;
        let mut visited = BTreeSet::new();
        while payload.len() < size {
            if !visited.insert(next) || pages.kind(next).is_some() {
                return Err(Partial);
            }
            let o = pages.page(next).ok_or(Partial)?;
            let take = (size - payload.len()).min(u - 4);
            let content = &o[4..4 + take];
            // A page zeroed by the crash reads as an empty chain link: samples are never
            // a whole page of exact zeros.
            if content.iter().all(|x| *x == 0) && take >= 64 {
                return Err(Partial);
            }
            payload.extend_from_slice(content);
            next = be(o, 0, 4).ok_or(Partial)?;
        }
        if next != 0 {
            return Err(Partial);
        }
    }
    let values = record(&payload).ok_or(Partial)?;
    Ok((rowid as i64, values))
}

/// A record's values, if its header and body are whole and agree.
fn record(b: &[u8]) -> Option<Vec<Value>> {
    let (hsize, mut at) = varint(b, 0)?;
    let hsize = usize::try_from(hsize).ok()?;
    if hsize > b.len() || hsize < at {
        return None;
    }
    let mut types = Vec::new();
    while at < hsize {
        let (t, l) = varint(b, at)?;
        types.push(t);
        at += l;
    }
    if at != hsize {
        return None;
    }
    let mut body = hsize;
    let mut values = Vec::with_capacity(types.len());
    for t in types {
        let (v, len) = match t {
            0 => (Value::Null, 0),
            1..=6 => {
                let n = [0, 1, 2, 3, 4, 6, 8][t as usize];
                let raw = be(b, body, n)?;
                let shift = 64 - 8 * n as u32;
                (Value::Int(((raw << shift) as i64) >> shift), n)
            }
            7 => (Value::Real(f64::from_bits(be(b, body, 8)?)), 8),
            8 => (Value::Int(0), 0),
            9 => (Value::Int(1), 0),
            10 | 11 => return None,
            t => {
                let n = usize::try_from((t - 12) / 2).ok()?;
                let s = b.get(body..body.checked_add(n)?)?;
                if t % 2 == 0 {
                    (Value::Blob(s.to_vec()), n)
                } else {
                    (Value::Text(String::from_utf8(s.to_vec()).ok()?), n)
                }
            }
        };
        body = body.checked_add(len)?;
        values.push(v);
    }
    (body == b.len()).then_some(values)
}

/// Salvage the rows of a SQLite file's tables. `known` are the shapes of the tables a
/// caller expects (the project's own knowledge of a format): they decide orphan leaves when
/// the schema page is lost, and stand in for it.
pub fn salvage(bytes: &[u8], known: &[Shape]) -> Result<Salvage, SalvageError> {
    if bytes.len() < 512 {
        return Err(SalvageError::TooShort);
    }
    let header_whole = bytes.starts_with(MAGIC);
    let declared = be(bytes, 16, 2).unwrap_or(0) as usize;
    let size = match declared {
        1 => 65536,
        s => s,
    };
    let reserved = bytes[20] as usize;
    if header_whole
        && size.is_power_of_two()
        && (512..=65536).contains(&size)
        && reserved < size - 480
    {
        return Ok(salvage_pages(bytes, size, reserved, true, known));
    }
    // The header is gone: the page size under which the most records read whole (a wrong
    // size splits or joins pages, and a record's payload then does not add up).
    let best = (9..=16)
        .map(|shift| salvage_pages(bytes, 1 << shift, 0, false, known))
        .filter(|s| s.whole_records > 0)
        .max_by_key(|s| (s.whole_records, std::cmp::Reverse(s.page_size)));
    best.ok_or(SalvageError::NoPages)
}

/// [`salvage`] with the page geometry decided.
fn salvage_pages(
    bytes: &[u8],
    size: usize,
    reserved: usize,
    header_whole: bool,
    known: &[Shape],
) -> Salvage {
    let pages = Pages {
        bytes,
        size,
        usable: size - reserved,
        count: (bytes.len() / size) as u64,
    };
    let mut out = Salvage {
        page_size: size,
        pages: pages.count,
        header_whole,
        ..Default::default()
    };
    let mut free = BTreeSet::new();
    if header_whole {
        out.declared_pages = be(bytes, 28, 4).unwrap_or(0);
        free = freelist(&pages, be(bytes, 32, 4).unwrap_or(0));
    }
    let mut seen = BTreeSet::new();
    let (roots, schema_whole, statements) = if header_whole {
        schema(&pages, &mut seen)
    } else {
        (Vec::new(), false, Vec::new())
    };
    out.schema_whole = schema_whole;
    out.statements = statements;
    let mut by_page: HashMap<u64, String> = HashMap::new();
    for (shape, root) in &roots {
        let leaves = leaves_of(&pages, *root, &mut seen);
        let t = out.tables.entry(shape.table.clone()).or_default();
        t.shape = Some(shape.clone());
        t.reached_leaves += leaves.len() as u64;
        for l in leaves {
            by_page.insert(l, shape.table.clone());
        }
    }
    // The shapes orphan leaves are told by: the schema's, else the caller's.
    let mut shapes: Vec<Shape> = roots.iter().map(|r| r.0.clone()).collect();
    for k in known {
        if !shapes.iter().any(|s| s.table == k.table) {
            shapes.push(k.clone());
        }
    }
    let mut conflicts: BTreeSet<(String, i64)> = BTreeSet::new();
    for n in 1..=pages.count {
        if pages.kind(n) != Some(13) || free.contains(&n) || (n == 1 && header_whole) {
            continue;
        }
        let Some(cells) = pages.cells(n) else {
            continue;
        };
        let records: Vec<Result<(i64, Vec<Value>), Partial>> = cells
            .iter()
            .map(|off| leaf_record(&pages, n, *off))
            .collect();
        let table = match by_page.get(&n) {
            Some(t) => Some(t.clone()),
            None => shape_of(&records, &shapes),
        };
        let Some(table) = table else {
            out.unowned_leaves += 1;
            continue;
        };
        let shape = shapes.iter().find(|s| s.table == table).cloned();
        let t = out.tables.entry(table.clone()).or_default();
        if !by_page.contains_key(&n) {
            t.shaped_leaves += 1;
        }
        if t.shape.is_none() {
            t.shape = shape.clone();
        }
        let (whole, partial) = take_records(t, &table, shape.as_ref(), records, &mut conflicts);
        out.whole_records += whole;
        out.partial_records += partial;
    }
    for (table, rowid) in conflicts {
        if let Some(t) = out.tables.get_mut(&table) {
            t.rows.remove(&rowid);
        }
    }
    out
}

/// One table-leaf page's records into its table `t`: each whole one that fits the table's
/// shape, under its rowid (a rowid found twice with different values goes to `conflicts`,
/// dropped at the end). (whole, partial) records.
fn take_records(
    t: &mut TableRows,
    table: &str,
    shape: Option<&Shape>,
    records: Vec<Result<(i64, Vec<Value>), Partial>>,
    conflicts: &mut BTreeSet<(String, i64)>,
) -> (u64, u64) {
    let (mut whole, mut partial) = (0, 0);
    for r in records {
        let Ok((rowid, mut values)) = r else {
            partial += 1;
            continue;
        };
        if shape.is_some_and(|s| !s.fits(&values)) {
            partial += 1;
            continue;
        }
        if let Some(i) = shape.and_then(|s| s.rowid_column) {
            values[i] = Value::Int(rowid);
        }
        whole += 1;
        let row = Row { rowid, values };
        match t.rows.get(&rowid) {
            Some(old) if *old != row => {
                conflicts.insert((table.to_string(), rowid));
            }
            _ => {
                t.rows.insert(rowid, row);
            }
        }
    }
    (whole, partial)
}

/// The tables of the schema (`sqlite_master`, rooted on page 1) with their root pages, and
/// whether every schema record was whole.
fn schema(pages: &Pages, seen: &mut BTreeSet<u64>) -> (Vec<(Shape, u64)>, bool, Vec<String>) {
    let mut roots = Vec::new();
    let mut statements = Vec::new();
    let leaves = leaves_of(pages, 1, seen);
    let mut whole = !leaves.is_empty();
    for n in &leaves {
        for off in pages.cells(*n).unwrap_or_default() {
            match leaf_record(pages, *n, off) {
                Ok((_, v)) if v.len() == 5 => {
                    if let (Value::Text(kind), Some(root), Value::Text(sql)) =
                        (&v[0], v[3].int(), &v[4])
                    {
                        if kind == "table" || kind == "view" {
                            statements.push(sql.clone());
                        }
                        if kind == "table" {
                            if let Some(s) = Shape::from_sql(sql) {
                                roots.push((s, root.max(0) as u64));
                            }
                        }
                    }
                }
                _ => whole = false,
            }
        }
    }
    (roots, whole, statements)
}

/// The one shape all whole records of an orphan leaf fit (and at least one does).
fn shape_of(records: &[Result<(i64, Vec<Value>), Partial>], shapes: &[Shape]) -> Option<String> {
    let whole: Vec<&Vec<Value>> = records
        .iter()
        .filter_map(|r| r.as_ref().ok())
        .map(|r| &r.1)
        .collect();
    if whole.is_empty() {
        return None;
    }
    let fit: Vec<&Shape> = shapes
        .iter()
        .filter(|s| whole.iter().all(|v| s.fits(v)))
        .collect();
    (fit.len() == 1).then(|| fit[0].table.clone())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn varints_and_records_decode_and_refuse_what_is_not_there() {
        assert_eq!(varint(&[0x81, 0x00], 0), Some((128, 2)));
        assert_eq!(varint(&[0x81], 0), None);
        assert_eq!(varint(&[0xff; 9], 0), Some((u64::MAX, 9)));
        // Header 4 bytes: int8, text of 2, float; body.
        let mut r = vec![4, 1, 17, 7, 0xfe, b'h', b'i'];
        r.extend(1.5f64.to_bits().to_be_bytes());
        assert_eq!(
            record(&r),
            Some(vec![
                Value::Int(-2),
                Value::Text("hi".into()),
                Value::Real(1.5)
            ])
        );
        assert_eq!(record(&r[..r.len() - 1]), None);
        assert_eq!(record(&[4, 1, 17, 7]), None);
    }

    #[test]
    fn shapes_come_from_create_table() {
        let s = Shape::from_sql(
            "CREATE TABLE tr_data (\"SetID\" INTEGER PRIMARY KEY,\"Time\" INT,\"Data\" BLOB, x)",
        )
        .unwrap();
        assert_eq!(s.table, "tr_data");
        assert_eq!(s.rowid_column, Some(0));
        assert_eq!(
            s.columns.iter().map(|c| c.1).collect::<Vec<_>>(),
            [
                Affinity::Integer,
                Affinity::Integer,
                Affinity::Blob,
                Affinity::Any
            ]
        );
        assert!(Shape::from_sql("CREATE VIEW v as select 1").is_none());
        let g = Shape::from_sql(
            "CREATE TABLE data_integrity(TableName TEXT PRIMARY KEY UNIQUE, HashV1 INT)",
        )
        .unwrap();
        assert_eq!(g.rowid_column, None);
    }
}
