//! The ch. 4.7 criteria: label a hit from its CWT's dominant component, with the
//! acquisition faults of ch. 5.4 (Table 5.1 "erroneous data") checked first.
//!
//! * **erroneous** — empty (the threshold is never reached), clipped (a run of samples at
//!   the record's extreme value), triggered early (the signal exceeds the threshold well
//!   before the trigger: the front is before the record), or two separate bursts.
//! * **both** — a fibre-failure pulse (> 800 kHz, < 5 µs above half power, at the start)
//!   followed by a bond-like component (≈250 or ≈750 kHz) peaking later.
//! * **fibre_failure** — the dominant component is above 800 kHz, lasts < 5 µs above half
//!   power and arrives at the start of the record.
//! * **bond_failure** — the dominant component is ≈250 or ≈750 kHz; when both are present,
//!   the ≈250 kHz one lasts longer.
//! * **unclassified** — none of these.
//!
//! Every threshold is in `[criteria]` of the pipeline TOML; the numbers behind the decision
//! are returned so they can be stored beside the label.

use super::settings::CriteriaConfig;
use crate::dsp::hit::HitFeatures;
use crate::model::Mechanism;

/// A component of the CWT: the strongest frequency of a range, seen over the analysis window.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Component {
    pub freq_hz: f64,
    /// Peak |W|² over the window.
    pub peak_power: f64,
    /// Time of the peak from the trigger, s.
    pub peak_s: f64,
    /// Contiguous time around the peak with |W|² ≥ peak/2, s.
    pub duration_s: f64,
    /// First time the row reaches half its peak, from the trigger, s (the start of the
    /// peak's own run, or of an earlier burst of the same frequency).
    pub arrival_s: f64,
}

impl Component {
    /// From one CWT row (|W|² over the window, sample 0 = trigger).
    pub fn from_row(freq_hz: f64, row: &[f32], fs: f64) -> Option<Component> {
        let (ip, p) =
            row.iter().enumerate().fold(
                (0usize, 0.0f32),
                |m, (i, &v)| if v > m.1 { (i, v) } else { m },
            );
        if p <= 0.0 {
            return None;
        }
        let half = p / 2.0;
        let mut lo = ip;
        while lo > 0 && row[lo - 1] >= half {
            lo -= 1;
        }
        let mut hi = ip;
        while hi + 1 < row.len() && row[hi + 1] >= half {
            hi += 1;
        }
        // The component's first arrival: where its row first reaches half its peak (an
        // earlier, slightly weaker burst of the same frequency is where it arrives).
        let first = row.iter().position(|&v| v >= half).unwrap_or(lo);
        Some(Component {
            freq_hz,
            peak_power: p as f64,
            peak_s: ip as f64 / fs,
            duration_s: (hi + 1 - lo) as f64 / fs,
            arrival_s: first as f64 / fs,
        })
    }
}

/// The components the criteria look at.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Components {
    /// Where the CWT first shows the AE, as the thesis reads one: the first time any
    /// frequency's |W|² reaches `component_min_ratio` of the window's largest, from the
    /// trigger, s. "At the start of the record" is measured from here: a faint precursor
    /// that crosses the threshold (sound carried ahead along a fibre) is not the start.
    pub onset_s: f64,
    pub dominant: Option<Component>,
    /// Strongest within `bond_tolerance` of `bond_low_hz` (≈250 kHz).
    pub low: Option<Component>,
    /// Strongest within `bond_tolerance` of `bond_high_hz` (≈750 kHz).
    pub high: Option<Component>,
    /// Strongest above `fibre_min_hz`.
    pub fibre: Option<Component>,
}

/// A label and the reason, in words.
#[derive(Debug, Clone, PartialEq)]
pub struct Decision {
    pub label: Mechanism,
    pub reason: String,
}

/// The kind of an acquisition fault: `features.parquet`'s `quality_fault` column and what
/// the SOM stage reads the map's erroneous area by (see `som::classify::Reading`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultKind {
    /// The record never reaches the threshold.
    Empty,
    /// A run of samples at the record's extreme value (the ADC's rail).
    Clipped,
    /// Above the threshold well before the trigger (ch. 5.4, Fig. 5.8b).
    TriggeredEarly,
    /// The front comes well after the trigger (ch. 5.4, Fig. 5.8c).
    BeforeFront,
    /// Two separate bursts in one record.
    TwoBursts,
}

impl FaultKind {
    pub const ALL: [FaultKind; 5] = [
        FaultKind::Empty,
        FaultKind::Clipped,
        FaultKind::TriggeredEarly,
        FaultKind::BeforeFront,
        FaultKind::TwoBursts,
    ];

    /// The column's spelling.
    pub fn as_str(self) -> &'static str {
        match self {
            FaultKind::Empty => "empty",
            FaultKind::Clipped => "clipped",
            FaultKind::TriggeredEarly => "triggered_early",
            FaultKind::BeforeFront => "before_front",
            FaultKind::TwoBursts => "two_bursts",
        }
    }
}

/// A time-domain acquisition fault: its kind and the numbers behind it, in words.
#[derive(Debug, Clone, PartialEq)]
pub struct Fault {
    pub kind: FaultKind,
    pub reason: String,
}

/// Time-domain acquisition faults; `None` when the record looks sound.
pub fn acquisition_fault(
    raw: &[f32],
    cond: &[f32],
    fs: f64,
    pretrigger: usize,
    hit: &HitFeatures,
    c: &CriteriaConfig,
) -> Option<Fault> {
    let fault = |kind, reason| Some(Fault { kind, reason });
    let Some(first) = hit.first_crossing else {
        return fault(
            FaultKind::Empty,
            format!(
                "empty: never reaches the threshold ({:.1} dB_AE)",
                crate::model::db_ae(hit.threshold_v)
            ),
        );
    };
    if let Some(f) = clipped(raw, c) {
        return Some(f);
    }
    if let Some(f) = mistimed(first, fs, pretrigger, c) {
        return Some(f);
    }
    two_bursts(cond, fs, hit, c)
}

/// The clipped fault: a long run or many samples at the extreme, far above the quantisation step.
fn clipped(raw: &[f32], c: &CriteriaConfig) -> Option<Fault> {
    let fault = |kind, reason| Some(Fault { kind, reason });
    // Clipped: a run of samples sitting at the raw record's extreme value, or many samples
    // at it (a fast wave clipped a little above its rail touches it for 2–3 samples a
    // half-cycle), where the extreme is far above the quantisation step (a weak record in
    // a few ADC steps repeats its top code by nature).
    let extreme = crate::dsp::max_from_zero(raw, f32::abs);
    if extreme > 0.0 {
        let (mut run, mut longest, mut count) = (0, 0, 0);
        // Most blocks hold no sample at the extreme: they are told apart by a branch-free
        // (vectorised) test, and only the others are walked for runs.
        for block in raw.chunks(64) {
            if !block.iter().fold(false, |a, v| a | (v.abs() == extreme)) {
                run = 0;
                continue;
            }
            for v in block {
                if v.abs() == extreme {
                    run += 1;
                    count += 1;
                    longest = longest.max(run);
                } else {
                    run = 0;
                }
            }
        }
        let by_run = c.clip_run > 1 && longest >= c.clip_run;
        let by_count = c.clip_count > 0 && count >= c.clip_count;
        if by_run || by_count {
            // Either way the extreme must stand far above the quantisation step.
            let step = quantisation_step(raw);
            let steps = if step > 0.0 {
                extreme as f64 / step as f64
            } else {
                f64::INFINITY
            };
            if steps >= c.clip_min_steps {
                let steps = if steps.is_finite() {
                    format!("{steps:.0}")
                } else {
                    "∞".into()
                };
                return fault(
                    FaultKind::Clipped,
                    if by_run {
                        format!("clipped: {longest} consecutive samples at {extreme:.6} V ({steps} quantisation steps)")
                    } else {
                        format!("clipped: {count} samples at ±{extreme:.6} V ({steps} quantisation steps)")
                    },
                );
            }
        }
    }
    None
}

/// The trigger-timing faults: the threshold first reached well before or after the trigger.
fn mistimed(first: usize, fs: f64, pretrigger: usize, c: &CriteriaConfig) -> Option<Fault> {
    let fault = |kind, reason| Some(Fault { kind, reason });
    let early = (c.early_trigger_s * fs).round() as usize;
    if pretrigger > early && first < pretrigger - early {
        return fault(
            FaultKind::TriggeredEarly,
            format!(
                "triggered early: above threshold {:.1} µs before the trigger",
                (pretrigger - first) as f64 / fs * 1e6
            ),
        );
    }
    let late = (c.late_front_s * fs).round() as usize;
    if first > pretrigger + late {
        return fault(
            FaultKind::BeforeFront,
            format!(
                "triggered before the front: the signal first reaches the threshold {:.1} µs after the trigger",
                (first - pretrigger) as f64 / fs * 1e6
            ),
        );
    }
    None
}

/// The two-bursts fault: a second burst after a quiet gap on the conditioned 1 µs envelope.
fn two_bursts(cond: &[f32], fs: f64, hit: &HitFeatures, c: &CriteriaConfig) -> Option<Fault> {
    let fault = |kind, reason| Some(Fault { kind, reason });
    // Two bursts, on a 1 µs block-maximum envelope.
    let block = ((1e-6 * fs).round() as usize).max(1);
    let env = cond
        .chunks(block)
        .map(|b| b.iter().fold(0.0f32, |m, v| m.max(v.abs())));
    let peak = hit.amplitude_v as f32;
    let (level, quiet) = (
        c.burst_level_ratio as f32 * peak,
        c.burst_quiet_ratio as f32 * peak,
    );
    let gap_blocks = ((c.burst_gap_s * fs) / block as f64).ceil() as usize;
    let (mut in_burst, mut quiet_run, mut bursts, mut first_end) = (false, 0usize, 0, 0usize);
    for (i, e) in env.enumerate() {
        if e >= level {
            if !in_burst && (bursts == 0 || quiet_run >= gap_blocks) {
                bursts += 1;
                if bursts == 2 {
                    return fault(
                        FaultKind::TwoBursts,
                        format!(
                            "two bursts: a second one starts {:.1} µs after the first ended",
                            (i - first_end) as f64 * block as f64 / fs * 1e6
                        ),
                    );
                }
            }
            in_burst = true;
            quiet_run = 0;
        } else if e < quiet {
            if in_burst {
                first_end = i;
            }
            in_burst = false;
            quiet_run += 1;
        } else if in_burst {
            // between the two levels: still the same burst (hysteresis)
        }
    }
    None
}

/// The record's quantisation step: the smallest gap between two distinct sample values
/// (0 for fewer than two distinct values). Sorts a copy: called only for a record that
/// already sits at its extreme `clip_run` times in a row or `clip_count` times in all.
fn quantisation_step(raw: &[f32]) -> f32 {
    let mut v: Vec<f32> = raw.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f32::total_cmp);
    v.windows(2)
        .map(|w| w[1] - w[0])
        .filter(|&d| d > 0.0)
        .fold(0.0f32, |m, d| if m == 0.0 || d < m { d } else { m })
}

fn near(f: f64, target: f64, tol: f64) -> bool {
    (f - target).abs() <= tol
}

/// Decide the label from the components (after [`acquisition_fault`] found nothing).
pub fn decide(k: &Components, c: &CriteriaConfig) -> Decision {
    let Some(d) = k.dominant else {
        return Decision {
            label: Mechanism::Erroneous,
            reason: "no power in the analysis window".into(),
        };
    };
    let present =
        |x: &Option<Component>| x.filter(|x| x.peak_power >= c.component_min_ratio * d.peak_power);
    let is_pulse = |x: &Component| {
        x.freq_hz > c.fibre_min_hz
            && x.duration_s < c.fibre_max_duration_s
            && x.arrival_s - k.onset_s <= c.fibre_max_arrival_s
    };
    let fibre = present(&k.fibre).filter(is_pulse);
    if let Some(f) = fibre {
        let later = [present(&k.low), present(&k.high)]
            .into_iter()
            .flatten()
            .filter(|b| b.peak_s >= f.peak_s + c.both_min_delay_s)
            .max_by(|a, b| a.peak_power.total_cmp(&b.peak_power));
        let comparable = f.peak_power >= c.both_min_ratio * d.peak_power;
        if let (Some(b), true) = (later, comparable) {
            return Decision {
                label: Mechanism::Both,
                reason: format!(
                    "pulse at {:.0} kHz ({:.1} µs) then a {:.0} kHz wave peaking {:.1} µs later",
                    f.freq_hz / 1e3,
                    f.duration_s * 1e6,
                    b.freq_hz / 1e3,
                    (b.peak_s - f.peak_s) * 1e6
                ),
            };
        }
        if is_pulse(&d) {
            return Decision {
                label: Mechanism::FibreFailure,
                reason: format!(
                    "pulse at {:.0} kHz lasting {:.1} µs from {:.1} µs after the onset",
                    d.freq_hz / 1e3,
                    d.duration_s * 1e6,
                    (d.arrival_s - k.onset_s) * 1e6
                ),
            };
        }
    }
    let tol = c.bond_tolerance_hz;
    if near(d.freq_hz, c.bond_low_hz, tol) || near(d.freq_hz, c.bond_high_hz, tol) {
        if let (Some(lo), Some(hi)) = (present(&k.low), present(&k.high)) {
            if lo.duration_s < hi.duration_s {
                return Decision {
                    label: Mechanism::Unclassified,
                    reason: format!(
                        "bond-like frequencies but the {:.0} kHz part ({:.1} µs) is shorter than the {:.0} kHz part ({:.1} µs)",
                        lo.freq_hz / 1e3,
                        lo.duration_s * 1e6,
                        hi.freq_hz / 1e3,
                        hi.duration_s * 1e6
                    ),
                };
            }
        }
        return Decision {
            label: Mechanism::BondFailure,
            reason: format!(
                "dominant {:.0} kHz wave lasting {:.1} µs",
                d.freq_hz / 1e3,
                d.duration_s * 1e6
            ),
        };
    }
    Decision {
        label: Mechanism::Unclassified,
        reason: format!(
            "dominant {:.0} kHz component lasting {:.1} µs from {:.1} µs after the onset matches no criterion",
            d.freq_hz / 1e3,
            d.duration_s * 1e6,
            (d.arrival_s - k.onset_s) * 1e6
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn comp(f: f64, p: f64, peak_us: f64, dur_us: f64, arr_us: f64) -> Option<Component> {
        Some(Component {
            freq_hz: f * 1e3,
            peak_power: p,
            peak_s: peak_us * 1e-6,
            duration_s: dur_us * 1e-6,
            arrival_s: arr_us * 1e-6,
        })
    }

    /// A burst at `f` Hz decaying with time constant `tau` from the trigger (10 MHz, 500
    /// samples of pretrigger), quantised to `step` volts.
    fn burst(f: f64, tau: f64, amp: f64, step: f64) -> Vec<f32> {
        (0..4096)
            .map(|i| {
                let t = (i as f64 - 500.0) / 10e6;
                let v = if t < 0.0 {
                    0.0
                } else {
                    amp * (-t / tau).exp() * (2.0 * std::f64::consts::PI * f * t).sin()
                };
                ((v / step).round() * step) as f32
            })
            .collect()
    }

    fn fault_of(x: &[f32], c: &CriteriaConfig) -> Option<FaultKind> {
        let mut cond = Vec::new();
        crate::dsp::condition(x, 500, &mut cond);
        let hit = crate::dsp::hit::hit_features(&cond, 10e6, 1e-4);
        acquisition_fault(x, &cond, 10e6, 500, &hit, c).map(|f| f.kind)
    }

    #[test]
    fn a_wave_clipped_just_below_its_peak_is_clipped_and_a_coarse_weak_one_is_not() {
        let c = CriteriaConfig::default();
        // The bond wave's 750 kHz part: 13.3 samples a period.
        let w = burst(750e3, 50e-6, 0.01, 1e-6);
        assert_eq!(fault_of(&w, &c), None);
        // The ADC's rail at 90 % of the peak: at most 2 samples a half-cycle sit on it in a
        // row, so a run of clip_run = 3 is not reached; the count is.
        let rail = 0.9 * w.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let clipped: Vec<f32> = w.iter().map(|v| v.clamp(-rail, rail)).collect();
        let at = clipped.iter().filter(|v| v.abs() == rail).count();
        assert!(at >= c.clip_count, "{at} samples at the rail");
        assert_eq!(fault_of(&clipped, &c), Some(FaultKind::Clipped));
        let runs_only = CriteriaConfig {
            clip_count: 0,
            ..c.clone()
        };
        assert_eq!(fault_of(&clipped, &runs_only), None, "runs of 2–3 only");
        // A weak record spanning 7 ADC steps repeats its top code, in runs too, without being
        // clipped: both rules hold back below clip_min_steps (default configuration).
        let coarse = burst(250e3, 300e-6, 2e-4, 2e-4 / 7.0);
        let top = coarse.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let repeats = coarse.iter().filter(|v| v.abs() == top).count();
        assert!(repeats >= c.clip_count, "{repeats}");
        assert_eq!(fault_of(&coarse, &c), None);
        let no_guard = CriteriaConfig {
            clip_min_steps: 0.0,
            ..c.clone()
        };
        assert_eq!(fault_of(&coarse, &no_guard), Some(FaultKind::Clipped));
        assert!((quantisation_step(&coarse) - 2e-4 / 7.0).abs() < 1e-9);
    }

    #[test]
    fn component_half_power_run() {
        let row = [0.0f32, 0.1, 0.6, 1.0, 0.8, 0.4, 0.9];
        let c = Component::from_row(250e3, &row, 1e6).unwrap();
        assert_eq!(c.peak_s, 3e-6);
        assert_eq!(c.arrival_s, 2e-6);
        assert_eq!(c.duration_s, 3e-6); // samples 2, 3, 4 (6 is a separate run)
    }

    #[test]
    fn decisions_from_components() {
        let c = CriteriaConfig::default();
        let bond = Components {
            onset_s: 0.0,
            dominant: comp(250.0, 1.0, 8.0, 12.0, 2.0),
            low: comp(250.0, 1.0, 8.0, 12.0, 2.0),
            high: comp(750.0, 0.5, 4.0, 5.0, 1.0),
            fibre: comp(900.0, 0.01, 5.0, 3.0, 1.0),
        };
        assert_eq!(decide(&bond, &c).label, Mechanism::BondFailure);
        let inverted = Components {
            low: comp(250.0, 0.5, 8.0, 3.0, 2.0),
            high: comp(750.0, 1.0, 4.0, 8.0, 1.0),
            dominant: comp(750.0, 1.0, 4.0, 8.0, 1.0),
            ..bond
        };
        assert_eq!(decide(&inverted, &c).label, Mechanism::Unclassified);
        let fibre = Components {
            onset_s: 0.0,
            dominant: comp(1200.0, 1.0, 2.0, 2.5, 1.0),
            fibre: comp(1200.0, 1.0, 2.0, 2.5, 1.0),
            low: comp(250.0, 0.01, 20.0, 5.0, 10.0),
            high: None,
        };
        assert_eq!(decide(&fibre, &c).label, Mechanism::FibreFailure);
        let both = Components {
            low: comp(250.0, 0.5, 15.0, 10.0, 8.0),
            ..fibre
        };
        assert_eq!(decide(&both, &c).label, Mechanism::Both);
        let long_hf = Components {
            onset_s: 0.0,
            dominant: comp(1200.0, 1.0, 10.0, 20.0, 1.0),
            fibre: comp(1200.0, 1.0, 10.0, 20.0, 1.0),
            low: None,
            high: None,
        };
        assert_eq!(decide(&long_hf, &c).label, Mechanism::Unclassified);
        let late_pulse = Components {
            onset_s: 0.0,
            dominant: comp(1200.0, 1.0, 22.0, 2.0, 21.0),
            fibre: comp(1200.0, 1.0, 22.0, 2.0, 21.0),
            low: None,
            high: None,
        };
        assert_eq!(decide(&late_pulse, &c).label, Mechanism::Unclassified);
    }
}
