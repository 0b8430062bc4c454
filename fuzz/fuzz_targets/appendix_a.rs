//! The Appendix-A model file parser (sectioned text) and its size checks.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(m) = aepipe::sim::input::parse_sectioned(text, "fuzz.txt") {
        // A model that parses has passed its checks: its sizes are within the limits.
        let _ = m.check();
    }
});
