//! The SQLite salvage reader (issue 53) on any bytes: every size and pointer read from a
//! page is checked before use, so a damaged or hostile file neither panics, nor hangs (a
//! chain or a tree that loops is cut), nor makes it allocate beyond the file's own size.
#![no_main]
use aepipe::ingest::salvage::{salvage, Shape};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let shapes: Vec<Shape> = [
        "CREATE TABLE tr_data (\"SetID\" INTEGER PRIMARY KEY,\"Time\" INT,\"TRAI\" INT,\"Status\" INT,\"ParamID\" INT,\"Chan\" INT,\"Pretrigger\" INT,\"Thr\" INT,\"SampleRate\" INT,\"Samples\" INT,\"DataFormat\" INT,\"Data\" BLOB)",
        "CREATE TABLE tr_params (\"ID\" INTEGER PRIMARY KEY,\"SetupID\" INT,\"Chan\" INT,\"ADC_µV\" REAL,\"TR_mV\" REAL)",
    ]
    .iter()
    .filter_map(|s| Shape::from_sql(s))
    .collect();
    if let Ok(s) = salvage(data, &shapes) {
        // What it found is within the file: no more whole records than cells could hold.
        assert!(s.whole_records <= data.len() as u64);
        assert!(s.pages <= data.len() as u64 / 512);
    }
});
