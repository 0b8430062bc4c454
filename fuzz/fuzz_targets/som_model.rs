//! The SOM_PAK codebook reader: a codebook that parses classifies without a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(som) = aepipe::som::Som::from_cod(text) {
        let x = vec![0.5; som.codebook().ncols()];
        let _ = som.classify(&x);
    }
});
