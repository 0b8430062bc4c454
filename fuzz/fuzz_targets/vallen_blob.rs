//! The Vallen `tr_data` blob decoder (raw int16 and FLAC) with a hostile `Samples` claim.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if data.len() < 5 {
        return;
    }
    // Byte 0 picks the DataFormat (mostly 0 and 2), bytes 1..5 the claimed sample count
    // (up to 4·10⁹: the decoder must check it against the blob, not reserve it).
    let format = match data[0] % 4 {
        0 | 1 => 0,
        2 => 2,
        _ => data[0] as i64 - 128,
    };
    let samples = u32::from_le_bytes([data[1], data[2], data[3], data[4]]) as usize;
    let blob = &data[5..];
    if let Ok(adc) = aepipe::ingest::vallen::decode_blob(format, blob, samples) {
        assert_eq!(adc.len(), samples);
    }
});
