//! VisualAE's event builder as vallenae 0.14's `EventBuilder` implements it
//! (`vallenae/processor/_event_builder.py`): hits in time order become events, one source
//! each.
//!
//! With no event open, every hit of a used channel restarts the "last seen" timer, and
//! opens an event only if its channel acts as normal, its status lacks the after-timeout
//! flag (bit 8) and more than FHCDT has passed since the previous hit seen. With an event
//! open, a hit more than DT1X after the event's first hit, or more than DTNX after its last,
//! closes it and is then tried as a start; a hit on a channel already in the event closes it
//! (unless duplicates are allowed), joins neither event and restarts the timer; any other hit
//! joins. When an event closes, "last seen" becomes its last hit's time. Comparisons are
//! strict (`>`), as in vallenae, so a gap of exactly FHCDT does not open an event.
//!
//! Beyond vallenae, each hit's [`Fate`] is recorded, so that a hit a guard sensor kept from
//! opening an event (directly, or through a chain of such hits of the same source) can be
//! counted as guard-suppressed.

use crate::model::ChannelRole;
use std::collections::BTreeMap;

/// vallenae's `HitFlags.AFTER_TIMEOUT`: the hit was started artificially after a hit timeout.
pub const AFTER_TIMEOUT: i64 = 1 << 8;

/// One hit as the builder sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HitIn {
    /// The caller's index of the hit (e.g. its row).
    pub index: usize,
    pub time_s: f64,
    pub channel: u32,
    /// The system's hit flags (0 when not recorded).
    pub status: i64,
}

/// The builder's parameters (seconds), checked by [`Params::new`].
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    pub fhcdt_s: f64,
    pub dt1x_max_s: f64,
    pub dtnx_max_s: f64,
    pub allow_duplicates: bool,
    /// Roles by channel; a channel not listed has `default_role`.
    pub roles: BTreeMap<u32, ChannelRole>,
    pub default_role: ChannelRole,
}

impl Params {
    /// Every channel normal.
    pub fn new(fhcdt_s: f64, dt1x_max_s: f64, dtnx_max_s: f64) -> Params {
        Params {
            fhcdt_s,
            dt1x_max_s,
            dtnx_max_s,
            allow_duplicates: false,
            roles: BTreeMap::new(),
            default_role: ChannelRole::Normal,
        }
    }

    pub fn role(&self, channel: u32) -> ChannelRole {
        self.roles
            .get(&channel)
            .copied()
            .unwrap_or(self.default_role)
    }
}

/// Why an event was closed (vallenae's `EventCloseReason`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CloseReason {
    Dt1xExpired,
    DtnxExpired,
    DuplicateChannel,
    EndOfStream,
}

impl CloseReason {
    pub fn as_str(self) -> &'static str {
        match self {
            CloseReason::Dt1xExpired => "dt1x_expired",
            CloseReason::DtnxExpired => "dtnx_expired",
            CloseReason::DuplicateChannel => "duplicate_channel",
            CloseReason::EndOfStream => "end_of_stream",
        }
    }
}

/// One event: its hits in time order (the first is the start of event).
#[derive(Debug, Clone, PartialEq)]
pub struct Event {
    pub hits: Vec<HitIn>,
    pub close: CloseReason,
}

impl Event {
    /// An event closed at the end of a part of the hits: the reason the next hit (time,
    /// channel) gives it, as [`EventBuilder::process`] would.
    pub fn close_by(&mut self, time_s: f64, channel: u32, p: &Params) {
        if self.close != CloseReason::EndOfStream || p.role(channel) == ChannelRole::Unused {
            return;
        }
        let (first, last) = (self.hits[0].time_s, self.hits[self.hits.len() - 1].time_s);
        if time_s - first > p.dt1x_max_s {
            self.close = CloseReason::Dt1xExpired;
        } else if time_s - last > p.dtnx_max_s {
            self.close = CloseReason::DtnxExpired;
        } else if !p.allow_duplicates && self.hits.iter().any(|h| h.channel == channel) {
            self.close = CloseReason::DuplicateChannel;
        }
    }

    pub fn time_s(&self) -> f64 {
        self.hits[0].time_s
    }
    pub fn first_hit_channel(&self) -> u32 {
        self.hits[0].channel
    }
}

/// What became of a hit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fate {
    /// In the event of this 0-based number.
    InEvent(usize),
    /// Its channel is unused.
    Unused,
    /// It could not open an event: after-timeout flag, or within FHCDT of the previous hit
    /// seen. `by_guard`: that previous hit was a guard's (or itself kept out by one).
    NotStarted { by_guard: bool },
    /// A guard (or a combined channel acting as one) with no event open.
    Guard,
    /// A second hit of a channel in the open event: closed it, joined neither.
    Duplicate,
}

/// Hits out of time order (vallenae raises `ValueError`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("hits must be time-sorted: got a hit at t={got} s after t={after} s")]
pub struct OutOfOrder {
    pub got: f64,
    pub after: f64,
}

/// The state machine, fed one hit at a time.
#[derive(Debug, Clone)]
pub struct EventBuilder {
    p: Params,
    open: Option<Vec<HitIn>>,
    last_seen: f64,
    /// The hit that last restarted the timer was a guard's, or kept out by one.
    last_seen_guard: bool,
    last_input: Option<f64>,
    events: usize,
}

impl EventBuilder {
    pub fn new(p: Params) -> EventBuilder {
        EventBuilder {
            p,
            open: None,
            last_seen: f64::NEG_INFINITY,
            last_seen_guard: false,
            last_input: None,
            events: 0,
        }
    }

    /// Feed one hit: its fate, and the event it closed (if any). An `InEvent` fate names the
    /// number the hit's event has or will have.
    pub fn process(&mut self, hit: HitIn) -> Result<(Fate, Option<Event>), OutOfOrder> {
        if let Some(t) = self.last_input {
            if hit.time_s < t {
                return Err(OutOfOrder {
                    got: hit.time_s,
                    after: t,
                });
            }
        }
        self.last_input = Some(hit.time_s);
        let role = self.p.role(hit.channel);
        if role == ChannelRole::Unused {
            return Ok((Fate::Unused, None));
        }
        let Some(open) = &self.open else {
            return Ok((self.try_start(hit, role), None));
        };
        let reason = if hit.time_s - open[0].time_s > self.p.dt1x_max_s {
            Some(CloseReason::Dt1xExpired)
        } else if hit.time_s - open[open.len() - 1].time_s > self.p.dtnx_max_s {
            Some(CloseReason::DtnxExpired)
        } else {
            None
        };
        if let Some(r) = reason {
            let closed = self.close(r);
            return Ok((self.try_start(hit, role), Some(closed)));
        }
        if !self.p.allow_duplicates && open.iter().any(|h| h.channel == hit.channel) {
            let closed = self.close(CloseReason::DuplicateChannel);
            // Per VisualAE: used for neither event, but it restarts the timer.
            self.last_seen = hit.time_s;
            self.last_seen_guard = false;
            return Ok((Fate::Duplicate, Some(closed)));
        }
        self.open.as_mut().expect("open").push(hit);
        Ok((Fate::InEvent(self.events), None))
    }

    /// Close the open event at the end of the hits (if any) and start afresh.
    pub fn flush(&mut self) -> Option<Event> {
        let e = self
            .open
            .is_some()
            .then(|| self.close(CloseReason::EndOfStream));
        self.last_seen = f64::NEG_INFINITY;
        self.last_seen_guard = false;
        self.last_input = None;
        e
    }

    fn try_start(&mut self, hit: HitIn, role: ChannelRole) -> Fate {
        let prev = self.last_seen;
        self.last_seen = hit.time_s;
        if role != ChannelRole::Normal {
            // Guard, or combined as the would-be first hit: inhibits.
            self.last_seen_guard = true;
            return Fate::Guard;
        }
        if hit.status & AFTER_TIMEOUT != 0 {
            self.last_seen_guard = false;
            return Fate::NotStarted { by_guard: false };
        }
        if hit.time_s - prev <= self.p.fhcdt_s {
            // Keeps the guard mark of the hit before: the same source's chain.
            return Fate::NotStarted {
                by_guard: self.last_seen_guard,
            };
        }
        self.last_seen_guard = false;
        self.open = Some(vec![hit]);
        Fate::InEvent(self.events)
    }

    fn close(&mut self, reason: CloseReason) -> Event {
        let hits = self.open.take().expect("an open event");
        self.last_seen = hits[hits.len() - 1].time_s;
        self.last_seen_guard = false;
        self.events += 1;
        Event {
            hits,
            close: reason,
        }
    }
}

/// Build the events of hits in time order: the events, and each hit's fate in input order.
pub fn build(hits: &[HitIn], p: &Params) -> Result<(Vec<Event>, Vec<Fate>), OutOfOrder> {
    let mut b = EventBuilder::new(p.clone());
    let mut events = Vec::new();
    let mut fates = Vec::with_capacity(hits.len());
    for h in hits {
        let (fate, closed) = b.process(*h)?;
        events.extend(closed);
        fates.push(fate);
    }
    events.extend(b.flush());
    Ok((events, fates))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn h(i: usize, t_us: f64, ch: u32) -> HitIn {
        HitIn {
            index: i,
            time_s: t_us * 1e-6,
            channel: ch,
            status: 0,
        }
    }

    fn p() -> Params {
        Params::new(100e-6, 50e-6, 30e-6)
    }

    fn channels(e: &Event) -> Vec<u32> {
        e.hits.iter().map(|h| h.channel).collect()
    }

    #[test]
    fn one_source_heard_by_three_sensors_is_one_event() {
        let hits = [h(0, 1000.0, 2), h(1, 1010.0, 1), h(2, 1030.0, 3)];
        let (ev, fate) = build(&hits, &p()).unwrap();
        assert_eq!(ev.len(), 1);
        assert_eq!(channels(&ev[0]), vec![2, 1, 3]);
        assert_eq!(ev[0].close, CloseReason::EndOfStream);
        assert!(fate.iter().all(|f| *f == Fate::InEvent(0)));
    }

    /// Hits built in two parts cut where the next hit comes beyond every window, the first
    /// part's last event closed by that next hit: the events of the whole.
    #[test]
    fn parts_cut_at_a_quiet_gap_give_the_whole_experiments_events() {
        let hits = [
            h(0, 0.0, 1),
            h(1, 20.0, 2),
            h(2, 40.0, 3),
            h(3, 400.0, 2),
            h(4, 420.0, 1),
        ];
        let (whole, _) = build(&hits, &p()).unwrap();
        let (mut a, _) = build(&hits[..3], &p()).unwrap();
        assert_eq!(a[0].close, CloseReason::EndOfStream);
        a[0].close_by(hits[3].time_s, hits[3].channel, &p());
        let (b, _) = build(&hits[3..], &p()).unwrap();
        a.extend(b);
        assert_eq!(a, whole);
        assert_eq!(whole[0].close, CloseReason::Dt1xExpired);
    }

    #[test]
    fn windows_close_events_strictly() {
        // DTNX: 30 µs after the last hit is still in (strict >), 31 is out.
        let (ev, _) = build(&[h(0, 0.0, 1), h(1, 30.0, 2)], &p()).unwrap();
        assert_eq!(ev.len(), 1);
        let (ev, fate) = build(&[h(0, 0.0, 1), h(1, 31.0, 2)], &p()).unwrap();
        assert_eq!(ev[0].close, CloseReason::DtnxExpired);
        // The closing hit is tried as a start: within FHCDT of the event's last hit.
        assert_eq!(fate[1], Fate::NotStarted { by_guard: false });
        // DT1X: 25 + 25 = 50 µs is in, the next at 75 is out.
        let (ev, _) = build(
            &[h(0, 0.0, 1), h(1, 25.0, 2), h(2, 50.0, 3), h(3, 75.0, 4)],
            &p(),
        )
        .unwrap();
        assert_eq!(ev[0].hits.len(), 3);
        assert_eq!(ev[0].close, CloseReason::Dt1xExpired);
        // After more than FHCDT of quiet a hit opens an event again.
        let (ev, _) = build(&[h(0, 0.0, 1), h(1, 100.0, 2), h(2, 200.1, 2)], &p()).unwrap();
        assert_eq!(
            ev.len(),
            2,
            "100 µs later is not > FHCDT after the event's last hit at 0"
        );
    }

    #[test]
    fn duplicates_close_and_join_neither() {
        let hits = [h(0, 0.0, 1), h(1, 10.0, 2), h(2, 20.0, 1), h(3, 25.0, 3)];
        let (ev, fate) = build(&hits, &p()).unwrap();
        assert_eq!(ev.len(), 1);
        assert_eq!(ev[0].close, CloseReason::DuplicateChannel);
        assert_eq!(fate[2], Fate::Duplicate);
        // Hit 3 comes 5 µs after the duplicate restarted the timer: no event.
        assert_eq!(fate[3], Fate::NotStarted { by_guard: false });
        let mut q = p();
        q.allow_duplicates = true;
        let (ev, _) = build(&hits, &q).unwrap();
        assert_eq!(channels(&ev[0]), vec![1, 2, 1, 3]);
    }

    #[test]
    fn a_guard_keeps_grip_noise_out_and_joins_open_events() {
        let mut q = p();
        q.roles.insert(9, ChannelRole::Guard);
        q.roles.insert(7, ChannelRole::Unused);
        // Grip noise: the guard hears it first, then the two gauge sensors.
        let hits = [h(0, 0.0, 9), h(1, 12.0, 1), h(2, 40.0, 7), h(3, 60.0, 2)];
        let (ev, fate) = build(&hits, &q).unwrap();
        assert!(ev.is_empty());
        assert_eq!(
            fate,
            vec![
                Fate::Guard,
                Fate::NotStarted { by_guard: true },
                Fate::Unused,
                Fate::NotStarted { by_guard: true }
            ]
        );
        // A source in the gauge section: the guard hears it last and joins.
        let hits = [h(0, 1000.0, 1), h(1, 1010.0, 2), h(2, 1020.0, 9)];
        let (ev, _) = build(&hits, &q).unwrap();
        assert_eq!(channels(&ev[0]), vec![1, 2, 9]);
        // Combined: a guard when first, normal after.
        q.roles.insert(5, ChannelRole::Combined);
        let (ev, fate) = build(&[h(0, 0.0, 5)], &q).unwrap();
        assert!(ev.is_empty() && fate[0] == Fate::Guard);
        let (ev, _) = build(&[h(0, 0.0, 1), h(1, 5.0, 5)], &q).unwrap();
        assert_eq!(channels(&ev[0]), vec![1, 5]);
    }

    #[test]
    fn after_timeout_hits_never_open_and_order_is_checked() {
        let mut a = h(0, 0.0, 1);
        a.status = AFTER_TIMEOUT;
        let (ev, fate) = build(&[a, h(1, 500.0, 1)], &p()).unwrap();
        assert_eq!(fate[0], Fate::NotStarted { by_guard: false });
        assert_eq!(ev.len(), 1);
        assert!(build(&[h(0, 5.0, 1), h(1, 4.0, 2)], &p()).is_err());
    }
}
