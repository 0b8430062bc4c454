//! The file readers that take text or WAV (WaveExplorer, AEwin waveform text with or without
//! a header, Vallen TXT exports, plain text, CSV per hit and long, WAV, MISTRAS .DTA),
//! through discovery and its sniffer, as the pipeline calls them.
#![no_main]
use aepipe::config::{IngestConfig, LoadConfig};
use aepipe::ingest::{discover, open};
use aepipe::model::Item;
use libfuzzer_sys::fuzz_target;

const NAMES: [&str; 9] = [
    "x_wave.txt",
    "hit.txt",
    "hit.csv",
    "long.csv",
    "hit.wav",
    "run.DTA",
    "x_1_20_300.txt",
    "values.dat",
    "export.asc",
];

fuzz_target!(|data: &[u8]| {
    if data.is_empty() {
        return;
    }
    let name = NAMES[data[0] as usize % NAMES.len()];
    let dir = std::env::temp_dir().join(format!("aepipe-fuzz-{}", std::process::id()));
    let exp = dir.join("exp");
    std::fs::create_dir_all(&exp).unwrap();
    let f = exp.join(name);
    std::fs::write(&f, &data[1..]).unwrap();
    let cfg = IngestConfig {
        // The limit a lab would set on a small machine; the fuzzer must not find a way past it.
        max_samples_per_record: 1 << 20,
        ..IngestConfig::default()
    };
    let d = discover(&[exp.clone()], &cfg);
    let load = LoadConfig::default();
    for s in &d.sources {
        for item in open(s, &cfg, &load).take(100_000) {
            if let Item::Record(r) = item {
                assert!(r.samples.len() <= 1 << 20, "{} samples past the limit", r.samples.len());
            }
        }
    }
    let _ = std::fs::remove_file(&f);
});
