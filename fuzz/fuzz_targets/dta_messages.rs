//! The MISTRAS `.DTA` message walker: every message length is checked against what is left.
#![no_main]
use aepipe::ingest::dta::MessageReader;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut r = MessageReader::new(std::io::Cursor::new(data), data.len() as u64);
    let mut n = 0usize;
    while let Some(m) = r.next_message() {
        n += 1;
        // Each message consumes at least its 2-byte length: the walk ends.
        assert!(n <= data.len() / 2 + 1, "more messages than the file can hold");
        if m.is_err() {
            break;
        }
    }
    assert!(r.offset() <= data.len() as u64);
});
