//! Cutting a continuous recording into hits, the way an acquisition system defines a hit
//! (Vallen AMSY-6, MISTRAS AEwin): a streaming detector per channel, fed in blocks of any
//! size, that keeps only what a hit still needs (bounded memory whatever the stream's
//! length).
//!
//! The rules, in samples at the stream's rate (`[detect]`, [`settings`]):
//!
//! * A **crossing** is a sample with |x| ≥ threshold. A hit **starts** at the first crossing
//!   while the detector is armed.
//! * A later crossing k **continues** the hit when k ≤ last + `ddt` and k < first +
//!   `max_duration`. Otherwise the hit is **declared ended** at E = min(last + `ddt`, first +
//!   `max_duration`) (or at the stream's end).
//! * After E the detector is **blind** for `rearm` samples: E + 1 … E + `rearm` never start
//!   a hit; E + `rearm` + 1 is armed.
//! * The hit's **record** is [first − `pre`, last + `post`] (cut at the stream's start and
//!   end); its time is the stream's start + first / rate and its duration (last − first) /
//!   rate, the rule of `features.duration_s`.
//! * The **peak** is the largest |x| within `pdt` samples of the first crossing; rise time
//!   is first → peak, counts the rising edges through +threshold in [first, last], energy
//!   Σx²/rate over [first, last] in eu.
//! * A **floating threshold** is `floating_factor` × the RMS of the previous
//!   `floating_window` samples outside hits; the detector is not armed during the stream's
//!   first window (it has no noise estimate yet).
//! * With `split_gap`, a hit holding a run of at least that many samples below the
//!   threshold between two crossings is flagged as two bursts in one record.
//!
//! The threshold scan skips quiet stretches a chunk at a time (the largest |x| of 64
//! samples, which the compiler vectorises), so a quiet stream costs a pass over memory.

pub mod settings;
pub use settings::{DetectConfig, DetectMode, DetectSettingsError, ValidDetect};

use std::collections::VecDeque;

/// The detector's rules at one stream's rate, in samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Params {
    /// Volts; None: floating.
    pub threshold_v: Option<f64>,
    pub floating_factor: f64,
    pub floating_window: u64,
    pub ddt: u64,
    pub rearm: u64,
    pub max_duration: u64,
    pub pdt: u64,
    pub pre: u64,
    pub post: u64,
    pub split_gap: Option<u64>,
}

/// A sample type a stream holds: its magnitude in its own units (counts or volts).
pub trait Sample: Copy + Send + 'static {
    fn mag(self) -> f32;
    fn value(self) -> f32;
}

impl Sample for i16 {
    #[inline]
    fn mag(self) -> f32 {
        (self as f32).abs()
    }
    #[inline]
    fn value(self) -> f32 {
        self as f32
    }
}

impl Sample for f32 {
    #[inline]
    fn mag(self) -> f32 {
        self.abs()
    }
    #[inline]
    fn value(self) -> f32 {
        self
    }
}

/// A hit cut from a stream.
#[derive(Debug, Clone, PartialEq)]
pub struct Cut {
    /// Sample indices in the stream: the first and last crossing, the end's declaration,
    /// and the record's first sample.
    pub first: u64,
    pub last: u64,
    pub end: u64,
    pub start: u64,
    /// The record, volts.
    pub samples: Vec<f32>,
    pub threshold_v: f64,
    /// Ended by `max_duration` (not by `ddt`), or by the stream's end.
    pub by_max_duration: bool,
    pub at_stream_end: bool,
    /// A gap of at least `split_gap` below the threshold inside the hit.
    pub two_bursts: bool,
    /// Peak |x| within `pdt` of the first crossing, volts, and its index.
    pub peak_v: f64,
    pub peak: u64,
    pub counts: i64,
    pub energy_eu: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
enum State {
    Armed,
    InHit {
        first: u64,
        last: u64,
        gap: u64,
    },
    /// Blind up to and including this sample.
    Blind(u64),
}

/// A declared hit waiting for its post-trigger samples.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
struct Pending {
    first: u64,
    last: u64,
    end: u64,
    gap: u64,
    by_max: bool,
    at_end: bool,
    thr: f32,
}

/// One channel's detector.
pub struct Detector<T: Sample> {
    p: Params,
    /// Volts per unit of `T`, and the stream's rate.
    unit_v: f64,
    rate_hz: f64,
    /// The threshold in units of `T` (∞ until a floating threshold has its first window).
    thr: f32,
    hist: VecDeque<T>,
    hist_start: u64,
    pos: u64,
    state: State,
    pending: Vec<Pending>,
    /// Floating: the current window's sum of squares and samples outside hits, and where
    /// it ends.
    win_sq: f64,
    win_n: u64,
    win_end: u64,
}

/// A detector's state without its samples: what a watcher commits to go on after a restart
/// exactly where it stood (the samples it still held are read again from the stream).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Snapshot {
    /// The threshold in the stream's units; none while a floating threshold has no window.
    thr: Option<f32>,
    /// The first sample still held, and the samples fed.
    hist_start: u64,
    pos: u64,
    state: State,
    pending: Vec<Pending>,
    win_sq: f64,
    win_n: u64,
    win_end: u64,
}

impl Snapshot {
    /// The samples the detector held: `hist_start .. pos` of its channel.
    pub fn history(&self) -> std::ops::Range<u64> {
        self.hist_start..self.pos
    }
}

const CHUNK: usize = 64;

/// The first index of `x` with magnitude ≥ `thr`, skipping quiet chunks whole.
#[inline]
fn scan<T: Sample>(x: &[T], thr: f32) -> Option<usize> {
    let mut base = 0;
    for c in x.chunks(CHUNK) {
        let m = c.iter().fold(0.0f32, |m, v| m.max(v.mag()));
        if m >= thr {
            return c.iter().position(|v| v.mag() >= thr).map(|j| base + j);
        }
        base += c.len();
    }
    None
}

impl<T: Sample> Detector<T> {
    pub fn new(p: Params, unit_v: f64, rate_hz: f64) -> Detector<T> {
        let thr = match p.threshold_v {
            Some(v) => (v / unit_v) as f32,
            None => f32::INFINITY,
        };
        Detector {
            p,
            unit_v,
            rate_hz,
            thr,
            hist: VecDeque::new(),
            hist_start: 0,
            pos: 0,
            state: State::Armed,
            pending: Vec::new(),
            win_sq: 0.0,
            win_n: 0,
            win_end: p.floating_window,
        }
    }

    /// Samples fed so far.
    pub fn position(&self) -> u64 {
        self.pos
    }

    /// The first sample at which a hit not cut yet can start: every hit this detector will
    /// still cut has its first crossing here or later (the hit under way, the hits waiting
    /// for their post-trigger samples, else the next sample).
    pub fn frontier(&self) -> u64 {
        let mut f = match self.state {
            State::InHit { first, .. } => first,
            _ => self.pos,
        };
        for h in &self.pending {
            f = f.min(h.first);
        }
        f
    }

    /// The state to go on from later ([`Detector::restore`]).
    pub fn snapshot(&self) -> Snapshot {
        Snapshot {
            thr: self.thr.is_finite().then_some(self.thr),
            hist_start: self.hist_start,
            pos: self.pos,
            state: self.state,
            pending: self.pending.clone(),
            win_sq: self.win_sq,
            win_n: self.win_n,
            win_end: self.win_end,
        }
    }

    /// The detector of `s` again, given the samples it held (`s.history()`, read again
    /// from the stream): it cuts from here exactly as the one snapshotted would have. None
    /// when `history` is not as long as the snapshot says.
    pub fn restore(
        p: Params,
        unit_v: f64,
        rate_hz: f64,
        s: Snapshot,
        history: &[T],
    ) -> Option<Detector<T>> {
        if history.len() as u64 != s.pos.checked_sub(s.hist_start)? {
            return None;
        }
        Some(Detector {
            p,
            unit_v,
            rate_hz,
            thr: s.thr.unwrap_or(f32::INFINITY),
            hist: history.iter().copied().collect(),
            hist_start: s.hist_start,
            pos: s.pos,
            state: s.state,
            pending: s.pending,
            win_sq: s.win_sq,
            win_n: s.win_n,
            win_end: s.win_end,
        })
    }

    /// The threshold now, volts (None while a floating threshold has no window yet).
    pub fn threshold_v(&self) -> Option<f64> {
        self.thr
            .is_finite()
            .then_some(self.thr as f64 * self.unit_v)
    }

    fn at(&self, abs: u64) -> T {
        self.hist[(abs - self.hist_start) as usize]
    }

    /// Feed the next block; completed hits are appended to `out` in order.
    pub fn push(&mut self, block: &[T], out: &mut Vec<Cut>) {
        let base = self.pos;
        self.hist.extend(block.iter().copied());
        let n = block.len() as u64;
        let end = base + n;
        let mut i = base;
        while i < end {
            match self.state {
                State::Armed => {
                    let floating = self.p.threshold_v.is_none();
                    // Windows that ended during a hit or a blind time close now (the noise
                    // they saw outside hits, or the threshold kept).
                    while floating && self.win_end <= i {
                        self.next_window();
                    }
                    let seg = if floating { end.min(self.win_end) } else { end };
                    let x = &block[(i - base) as usize..(seg - base) as usize];
                    match scan(x, self.thr) {
                        Some(j) => {
                            let k = i + j as u64;
                            if floating {
                                self.noise(&x[..j]);
                            }
                            self.state = State::InHit {
                                first: k,
                                last: k,
                                gap: 0,
                            };
                            i = k + 1;
                        }
                        None => {
                            if floating {
                                self.noise(x);
                                if seg == self.win_end {
                                    self.next_window();
                                }
                            }
                            i = seg;
                        }
                    }
                }
                State::InHit { first, last, gap } => {
                    // The last sample at which a crossing still continues the hit.
                    let limit = (last + self.p.ddt).min(first + self.p.max_duration - 1);
                    let to = end.min(limit + 1);
                    if i < to {
                        let x = &block[(i - base) as usize..(to - base) as usize];
                        if let Some(j) = scan(x, self.thr) {
                            let k = i + j as u64;
                            self.state = State::InHit {
                                first,
                                last: k,
                                gap: gap.max(k - last - 1),
                            };
                            i = k + 1;
                            continue;
                        }
                        i = to;
                    }
                    if i > limit {
                        let by_max = first + self.p.max_duration <= last + self.p.ddt;
                        let e = if by_max {
                            first + self.p.max_duration
                        } else {
                            last + self.p.ddt
                        };
                        self.declare(first, last, e, gap, by_max);
                        i = i.max(e + 1);
                    }
                }
                State::Blind(until) => {
                    if until < end {
                        i = i.max(until + 1);
                        self.state = State::Armed;
                    } else {
                        i = end;
                    }
                }
            }
        }
        self.pos = end;
        self.emit(out, false);
        self.trim();
    }

    fn declare(&mut self, first: u64, last: u64, e: u64, gap: u64, by_max: bool) {
        self.pending.push(Pending {
            first,
            last,
            end: e,
            gap,
            by_max,
            at_end: false,
            thr: self.thr,
        });
        self.state = State::Blind(e + self.p.rearm);
    }

    /// Add samples outside hits to the floating threshold's window.
    fn noise(&mut self, x: &[T]) {
        for v in x.iter().map(|v| v.value() as f64).filter(|v| v.is_finite()) {
            self.win_sq += v * v;
            self.win_n += 1;
        }
    }

    fn next_window(&mut self) {
        let rms = (self.win_sq / self.win_n as f64).sqrt();
        // A window without noise samples (all in hits) or with a non-finite sample keeps
        // the threshold it had.
        if self.win_n > 0 && rms.is_finite() {
            self.thr = ((self.p.floating_factor * rms) as f32).max(f32::MIN_POSITIVE);
        }
        self.win_sq = 0.0;
        self.win_n = 0;
        self.win_end += self.p.floating_window;
    }

    /// Cut the pending hits whose records are complete (all of them at the stream's end).
    fn emit(&mut self, out: &mut Vec<Cut>, at_end: bool) {
        let avail = self.pos;
        let mut keep = Vec::new();
        for h in std::mem::take(&mut self.pending) {
            let stop = h.last + self.p.post;
            if stop < avail || at_end {
                out.push(self.cut(&h, stop.min(avail.saturating_sub(1))));
            } else {
                keep.push(h);
            }
        }
        self.pending = keep;
    }

    fn cut(&self, h: &Pending, stop: u64) -> Cut {
        let start = h.first.saturating_sub(self.p.pre);
        let u = self.unit_v;
        let samples: Vec<f32> = (start..=stop)
            .map(|k| (self.at(k).value() as f64 * u) as f32)
            .collect();
        let peak_to = (h.first + self.p.pdt).min(h.last);
        let (mut peak, mut peak_m) = (h.first, 0.0f32);
        for k in h.first..=peak_to {
            let m = self.at(k).mag();
            if m > peak_m {
                peak_m = m;
                peak = k;
            }
        }
        let (mut counts, mut sq) = (0i64, 0.0f64);
        // The sample before the first crossing (none at the stream's start: below).
        let mut prev = match h.first > self.hist_start {
            true => self.at(h.first - 1).value(),
            false => f32::NEG_INFINITY,
        };
        for k in h.first..=h.last {
            let v = self.at(k).value();
            if v >= h.thr && prev < h.thr {
                counts += 1;
            }
            prev = v;
            sq += (v as f64 * u).powi(2);
        }
        Cut {
            first: h.first,
            last: h.last,
            end: h.end,
            start,
            samples,
            threshold_v: h.thr as f64 * u,
            by_max_duration: h.by_max,
            at_stream_end: h.at_end,
            two_bursts: self.p.split_gap.is_some_and(|g| h.gap >= g),
            peak_v: peak_m as f64 * u,
            peak,
            counts,
            energy_eu: sq / self.rate_hz * 1e14,
        }
    }

    /// The stream ended: a hit under way ends at the last sample; every hit is cut.
    pub fn finish(&mut self, out: &mut Vec<Cut>) {
        if let State::InHit { first, last, gap } = self.state {
            let e = self.pos.saturating_sub(1);
            self.declare(first, last, e, gap, false);
            if let Some(p) = self.pending.last_mut() {
                p.at_end = true;
            }
        }
        self.emit(out, true);
        self.state = State::Armed;
    }

    /// Drop the samples no hit can still need.
    fn trim(&mut self) {
        // The pretrigger and one sample more (the one before a first crossing, for counts).
        let back = self.p.pre + 1;
        let mut keep = self.pos.saturating_sub(back);
        if let State::InHit { first, .. } = self.state {
            keep = keep.min(first.saturating_sub(back));
        }
        for h in &self.pending {
            keep = keep.min(h.first.saturating_sub(back));
        }
        if keep > self.hist_start {
            let k = ((keep - self.hist_start) as usize).min(self.hist.len());
            self.hist.drain(..k);
            self.hist_start += k as u64;
        }
    }
}

#[cfg(test)]
mod tests;
