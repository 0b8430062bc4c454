//! The hit features (CHIDs) of the MISTRAS message stream: sizes, names and scalings, from
//! Appendix II of the PCI-2/AEwin manuals ("PAC Message Definitions") and its AEwin 32-bit
//! supplement ("Hit Message Feature IDs"), as transcribed in `docs/SPEC.md` and
//! `docs/DTA_SPEC_supp.md` of the MIT-licensed `Rakurai/MistrasDTA` repository.

/// How many bytes a CHID takes in a hit (message 1) or time-driven channel block (message 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ChidSize {
    /// A fixed size the specification gives.
    Fixed(usize),
    /// Partial powers (CHID 22): one byte per segment of message 109.
    PartialPowers,
    /// The specification gives no size (reserved or undefined CHIDs, e.g. 16, 25–31): the
    /// message length must tell it, or the message's fields after it stay undecoded.
    Unknown,
}

/// The size of a CHID by the specification. CHIDs 14 and 15 are "tentative assignments"
/// with stated sizes (a 2-byte duration, a 6-byte time of test); 16's size would come from
/// message 12, which is reserved. CHID 31 is used by some AEwin systems but defined nowhere.
pub fn chid_size(chid: u8) -> ChidSize {
    match chid {
        1..=4 => ChidSize::Fixed(2),
        5 => ChidSize::Fixed(4),
        6..=11 => ChidSize::Fixed(1),
        12 => ChidSize::Fixed(4),
        13 | 14 => ChidSize::Fixed(2),
        15 => ChidSize::Fixed(6),
        17..=19 => ChidSize::Fixed(2),
        20 | 21 => ChidSize::Fixed(4),
        22 => ChidSize::PartialPowers,
        23 | 24 => ChidSize::Fixed(2),
        _ => ChidSize::Unknown,
    }
}

/// The vendor's short name of a CHID (AEwin's column headings; `CHID<n>` where it has none).
pub fn chid_name(chid: u8) -> String {
    match chid {
        1 => "RISE",
        2 => "PCNTS",
        3 => "COUN",
        4 => "ENER",
        5 => "DURATION",
        6 => "AMP",
        7 => "RMS8",
        8 => "ASL",
        9 => "GAIN",
        10 => "THR",
        11 => "PAC",
        12 => "LOST",
        13 => "A-FRQ",
        14 => "DUR16",
        15 => "TOT",
        17 => "RMS",
        18 => "R-FRQ",
        19 => "I-FRQ",
        20 => "SIG STRENGTH",
        21 => "ABS-ENERGY",
        22 => "PARTIAL POWER",
        23 => "FRQ-C",
        24 => "P-FRQ",
        n => return format!("CHID{n}"),
    }
    .to_string()
}

/// One RTOT tick, seconds.
pub const TICK_S: f64 = 0.25e-6;
/// Full scale of the waveform ADC, volts (MistrasDTA and the manual: ±10 V over ±32768),
/// used when the waveform setup does not state its own (`MXIN`).
pub const MAX_INPUT_V: f64 = 10.0;

/// A little-endian unsigned integer of up to 8 bytes.
pub fn le(b: &[u8]) -> u64 {
    b.iter().rev().fold(0u64, |a, &x| (a << 8) | x as u64)
}

/// Decode one feature to SI units: µs → s, kHz → Hz, RMS16/5000 → V, RMS8/20 → V, signal
/// strength ×3.05 → pV·s, absolute energy (f32) ×9.31e-4 → aJ; dB, counts and undefined
/// CHIDs as stored (unsigned little-endian).
pub fn feature_value(chid: u8, b: &[u8]) -> f64 {
    match chid {
        1 | 5 | 14 => le(b) as f64 * 1e-6,
        7 => b.first().copied().unwrap_or(0) as f64 / 20.0,
        13 | 18 | 19 | 23 | 24 => le(b) as f64 * 1e3,
        17 => le(b) as f64 / 5000.0,
        20 => le(b) as f64 * 3.05,
        21 if b.len() == 4 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64 * 9.31e-4,
        15 => le(b) as f64 * TICK_S,
        // Partial powers: the segments' percentages; the first as the value (the hit row
        // keeps them all under PARTIAL POWER 1…N).
        22 => b.first().copied().unwrap_or(0) as f64,
        _ => le(b) as f64,
    }
}

/// Parametric counts → volts (±10 V full scale over a signed 16-bit value).
pub fn param_volts(lo: u8, hi: u8) -> f64 {
    i16::from_le_bytes([lo, hi]) as f64 * MAX_INPUT_V / 32768.0
}

/// Hit or time-driven parametric block: `PID, V lo, V hi` (3 bytes each; 4 when every
/// entry carries the cycle-counter MSB byte).
pub fn parametric_block(b: &[u8]) -> Vec<(u8, f64)> {
    let step = if !b.is_empty() && !b.len().is_multiple_of(3) && b.len().is_multiple_of(4) {
        4
    } else {
        3
    };
    b.chunks_exact(step)
        .map(|c| (c[0], param_volts(c[1], c[2])))
        .collect()
}

/// The sizes of a list of CHIDs in a message whose feature bytes are `avail` long: the
/// specification's sizes, and where exactly one CHID has none, the bytes that are left
/// (`Err` with the first undecodable CHID otherwise).
pub fn sizes(chids: &[u8], pp: usize, overrides: &[(u8, usize)], avail: usize) -> Sizes {
    let fixed = |c: u8| -> Option<usize> {
        if let Some(&(_, n)) = overrides.iter().find(|o| o.0 == c) {
            return Some(n);
        }
        match chid_size(c) {
            ChidSize::Fixed(n) => Some(n),
            ChidSize::PartialPowers => Some(pp),
            ChidSize::Unknown => None,
        }
    };
    let known: usize = chids.iter().filter_map(|&c| fixed(c)).sum();
    let unknown: Vec<usize> = (0..chids.len())
        .filter(|&i| fixed(chids[i]).is_none())
        .collect();
    match unknown.len() {
        0 => Sizes::All(chids.iter().map(|&c| fixed(c).unwrap_or(0)).collect()),
        1 if avail >= known => {
            let mut v: Vec<usize> = chids.iter().map(|&c| fixed(c).unwrap_or(0)).collect();
            v[unknown[0]] = avail - known;
            Sizes::FromLength(v, chids[unknown[0]], avail - known)
        }
        _ => Sizes::StopAt(
            chids[..unknown[0]]
                .iter()
                .map(|&c| fixed(c).unwrap_or(0))
                .collect(),
            chids[unknown[0]],
        ),
    }
}

/// What [`sizes`] found.
#[derive(Debug, Clone, PartialEq)]
pub enum Sizes {
    /// Every size is known.
    All(Vec<usize>),
    /// One CHID's size came from the message length: (sizes, that CHID, its size).
    FromLength(Vec<usize>, u8, usize),
    /// Decoding stops at this CHID: its size is unknown and the length cannot tell it; the
    /// sizes of the CHIDs before it.
    StopAt(Vec<usize>, u8),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_unknown_chid_takes_what_the_length_leaves() {
        // RISE (2), CHID 31 (?), AMP (1) in 7 bytes: CHID 31 has 4.
        assert_eq!(
            sizes(&[1, 31, 6], 0, &[], 7),
            Sizes::FromLength(vec![2, 4, 1], 31, 4)
        );
        // Two unknowns: stop at the first.
        assert_eq!(
            sizes(&[1, 31, 16, 6], 0, &[], 9),
            Sizes::StopAt(vec![2], 31)
        );
        // A size from the pipeline TOML counts as known.
        assert_eq!(
            sizes(&[1, 31, 16], 0, &[(31, 2)], 5),
            Sizes::FromLength(vec![2, 2, 1], 16, 1)
        );
        // Partial powers take the segment count.
        assert_eq!(sizes(&[22, 6], 4, &[], 5), Sizes::All(vec![4, 1]));
    }

    #[test]
    fn every_defined_chid_has_a_name_and_a_size() {
        for c in (1..=24u8).filter(|c| *c != 16) {
            assert!(!chid_name(c).starts_with("CHID"), "{c}");
            assert_ne!(chid_size(c), ChidSize::Unknown, "{c}");
        }
        assert_eq!(chid_name(31), "CHID31");
        assert_eq!(chid_size(31), ChidSize::Unknown);
    }
}
