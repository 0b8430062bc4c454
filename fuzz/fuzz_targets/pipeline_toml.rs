//! The pipeline TOML: what parses and validates must round-trip through `to_toml`.
#![no_main]
use aepipe::config::PipelineConfig;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(c) = PipelineConfig::from_toml(text) {
        let again = PipelineConfig::from_toml(&c.to_toml()).expect("own TOML re-reads");
        assert_eq!(c.hash(), again.hash());
    }
});
