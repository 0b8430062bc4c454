//! What a run counted: per experiment and record type, what the readers read and where it
//! went (rows, rejects), and the notes and acquisition setups they reported.

use crate::model::{AcquisitionSetup, MarkerKind, Note, RecordType, Reject, Tally};
use std::collections::BTreeMap;

/// One record type of one experiment: what the reader counted in its files, and what
/// became rows and rejects. The accounting rule: `read = rows + rejects`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct RecordCounts {
    /// What the reader counted in its files (SQL counts of a Vallen database, the messages of
    /// a MISTRAS stream, a header's event count); null where the format has no count of its
    /// own besides the records it yields (one record per file).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub read: Option<u64>,
    pub rows: u64,
    pub rejects: u64,
    /// Rows a transform added to what was read (a record cut by `[detect]` into m hits
    /// adds m − 1 transients and m hits).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub added: u64,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

impl RecordCounts {
    /// Whether every record read (and every row a transform added) is a row or a reject
    /// (true where nothing was counted).
    pub fn balanced(&self) -> bool {
        self.read
            .is_none_or(|r| r + self.added == self.rows + self.rejects)
    }
}

/// Counts of one experiment. The accounting rule: hits in = `hits` (rows of
/// `hits.parquet`); transients in = `rows` + `rejects`; per record type, `records`.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Counts {
    pub hits: u64,
    pub rows: u64,
    pub rejects: u64,
    /// Rows of `parametric.parquet` and `markers.parquet`.
    #[serde(default)]
    pub parametric: u64,
    #[serde(default)]
    pub markers: u64,
    /// By record type (`hit`, `transient`, `parametric`, `status`, `marker`, `file`).
    #[serde(default)]
    pub records: BTreeMap<RecordType, RecordCounts>,
}

impl Counts {
    fn add(&mut self, o: &Counts) {
        self.hits += o.hits;
        self.rows += o.rows;
        self.rejects += o.rejects;
        self.parametric += o.parametric;
        self.markers += o.markers;
        for (t, c) in &o.records {
            let e = self.records.entry(*t).or_default();
            e.read = match (e.read, c.read) {
                (None, None) => None,
                (a, b) => Some(a.unwrap_or(0) + b.unwrap_or(0)),
            };
            e.rows += c.rows;
            e.rejects += c.rejects;
            e.added += c.added;
        }
    }

    /// The record types whose `read` is not `rows + rejects`.
    pub fn unbalanced(&self) -> Vec<(RecordType, RecordCounts)> {
        self.records
            .iter()
            .filter(|(_, c)| !c.balanced())
            .map(|(t, c)| (*t, *c))
            .collect()
    }
}

/// At most this many notes are kept for the manifest.
pub const MAX_NOTES: usize = 1000;

/// What a streaming run did.
#[derive(Debug, Clone, Default)]
pub struct StreamStats {
    /// Records the readers produced (before validation).
    pub records_read: u64,
    /// Rows of `hits.parquet`.
    pub hits: u64,
    pub rows: u64,
    pub rejects: u64,
    /// Rows of `parametric.parquet` and `markers.parquet`.
    pub parametric: u64,
    pub markers: u64,
    pub by_experiment: BTreeMap<String, Counts>,
    /// Rejects by stage.
    pub by_stage: BTreeMap<String, u64>,
    /// The first few reject lines, for the terminal.
    pub first_rejects: Vec<String>,
    /// What readers had to assume (at most [`MAX_NOTES`], for the manifest).
    pub notes: Vec<Note>,
    /// What the recordings say of their acquisition settings, one per source file that says
    /// something.
    pub setups: Vec<AcquisitionSetup>,
    /// What the events step did, per experiment.
    pub events: Vec<crate::events::EventsSummary>,
    /// What each continuous recording gave (`[detect]`).
    pub streams: Vec<crate::model::StreamTally>,
    pub seconds: f64,
}

impl StreamStats {
    fn exp(&mut self, e: &str) -> &mut Counts {
        if !self.by_experiment.contains_key(e) {
            self.by_experiment.insert(e.to_string(), Counts::default());
        }
        self.by_experiment.get_mut(e).expect("inserted")
    }

    fn rec(&mut self, e: &str, t: RecordType) -> &mut RecordCounts {
        self.exp(e).records.entry(t).or_default()
    }

    pub(crate) fn add_reject(&mut self, r: &Reject) {
        self.rejects += 1;
        self.exp(&r.experiment).rejects += 1;
        self.rec(&r.experiment, r.record_type).rejects += 1;
        *self
            .by_stage
            .entry(r.stage.as_str().to_string())
            .or_default() += 1;
        if self.first_rejects.len() < 10 {
            let id = if r.record_id.is_empty() {
                String::new()
            } else {
                format!(" [{}]", r.record_id)
            };
            self.first_rejects
                .push(format!("{}{id}: {} ({})", r.source_file, r.reason, r.stage));
        }
    }

    pub(crate) fn add_row(&mut self, experiment: &str) {
        self.rows += 1;
        self.exp(experiment).rows += 1;
        self.rec(experiment, RecordType::Transient).rows += 1;
    }

    pub(crate) fn add_hit(&mut self, experiment: &str) {
        self.hits += 1;
        self.exp(experiment).hits += 1;
        self.rec(experiment, RecordType::Hit).rows += 1;
    }

    pub(crate) fn add_parametric(&mut self, experiment: &str) {
        self.parametric += 1;
        self.exp(experiment).parametric += 1;
        self.rec(experiment, RecordType::Parametric).rows += 1;
    }

    pub(crate) fn add_marker(&mut self, experiment: &str, kind: MarkerKind) {
        self.markers += 1;
        self.exp(experiment).markers += 1;
        let t = if kind == MarkerKind::Status {
            RecordType::Status
        } else {
            RecordType::Marker
        };
        self.rec(experiment, t).rows += 1;
    }

    pub(crate) fn add_tally(&mut self, t: &Tally) {
        for (ty, n) in &t.read {
            let r = self.rec(&t.experiment, *ty);
            r.read = Some(r.read.unwrap_or(0) + n);
        }
        for (ty, n) in &t.added {
            self.rec(&t.experiment, *ty).added += n;
        }
        if let Some(s) = &t.stream {
            self.streams.push((**s).clone());
        }
    }

    /// The notes said on the terminal too (a fact about a whole experiment), in order.
    pub fn said(&self) -> Vec<&str> {
        self.notes
            .iter()
            .filter(|n| n.said)
            .map(|n| n.message.as_str())
            .collect()
    }

    /// [`StreamStats::said`] as terminal lines, at most `max`, then how many more there are.
    pub fn said_lines(&self, max: usize) -> Vec<String> {
        let said = self.said();
        let mut l: Vec<String> = said.iter().take(max).map(|m| format!("  {m}")).collect();
        if said.len() > max {
            l.push(format!(
                "  … {} more such lines in the manifest",
                said.len() - max
            ));
        }
        l
    }

    pub(crate) fn add_note(&mut self, n: Note) {
        if self.notes.len() < MAX_NOTES {
            self.notes.push(n);
        }
    }

    /// Every experiment's record types whose `read` is not `rows + rejects`.
    pub fn unbalanced(&self) -> Vec<(String, RecordType, RecordCounts)> {
        self.by_experiment
            .iter()
            .flat_map(|(e, c)| c.unbalanced().into_iter().map(|(t, r)| (e.clone(), t, r)))
            .collect()
    }
}

/// The counts of one part (the serialisable half of [`StreamStats`]).
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize, PartialEq)]
pub(crate) struct PartStats {
    records_read: u64,
    hits: u64,
    rows: u64,
    rejects: u64,
    #[serde(default)]
    parametric: u64,
    #[serde(default)]
    markers: u64,
    by_experiment: BTreeMap<String, Counts>,
    by_stage: BTreeMap<String, u64>,
    first_rejects: Vec<String>,
    notes: Vec<Note>,
    #[serde(default)]
    setups: Vec<AcquisitionSetup>,
    #[serde(default)]
    pub(crate) events: Option<crate::events::EventsSummary>,
    #[serde(default)]
    streams: Vec<crate::model::StreamTally>,
}

impl PartStats {
    pub(crate) fn of(s: &StreamStats) -> PartStats {
        PartStats {
            records_read: s.records_read,
            hits: s.hits,
            rows: s.rows,
            rejects: s.rejects,
            parametric: s.parametric,
            markers: s.markers,
            by_experiment: s.by_experiment.clone(),
            by_stage: s.by_stage.clone(),
            first_rejects: s.first_rejects.clone(),
            notes: s.notes.clone(),
            setups: s.setups.clone(),
            events: None,
            streams: s.streams.clone(),
        }
    }

    /// Add this part's counts to the batch's.
    pub(crate) fn add_to(&self, st: &mut StreamStats) {
        st.records_read += self.records_read;
        st.hits += self.hits;
        st.rows += self.rows;
        st.rejects += self.rejects;
        st.parametric += self.parametric;
        st.markers += self.markers;
        for (k, c) in &self.by_experiment {
            st.exp(k).add(c);
        }
        for (k, n) in &self.by_stage {
            *st.by_stage.entry(k.clone()).or_default() += n;
        }
        for r in &self.first_rejects {
            if st.first_rejects.len() < 10 {
                st.first_rejects.push(r.clone());
            }
        }
        for n in &self.notes {
            st.add_note(n.clone());
        }
        st.setups.extend(self.setups.iter().cloned());
        st.events.extend(self.events.iter().cloned());
        st.streams.extend(self.streams.iter().cloned());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_type_balances_when_read_is_rows_plus_rejects() {
        let mut st = StreamStats::default();
        let mut read = BTreeMap::new();
        read.insert(RecordType::Transient, 3);
        read.insert(RecordType::Parametric, 2);
        st.add_tally(&Tally {
            experiment: "e".into(),
            read,
            ..Default::default()
        });
        st.add_row("e");
        st.add_row("e");
        st.add_parametric("e");
        st.add_parametric("e");
        st.add_reject(&Reject {
            experiment: "e".into(),
            source_file: "f".into(),
            record_id: "x".into(),
            stage: crate::model::Stage::Read,
            reason: "bad".into(),
            record_type: RecordType::Transient,
        });
        assert!(st.unbalanced().is_empty(), "{:?}", st.unbalanced());
        st.add_parametric("e");
        let u = st.unbalanced();
        assert_eq!(u.len(), 1);
        assert_eq!(
            (u[0].1, u[0].2.read, u[0].2.rows),
            (RecordType::Parametric, Some(2), 3)
        );
        // Counts add up across parts, `read` only where counted.
        let mut sum = StreamStats::default();
        PartStats::of(&st).add_to(&mut sum);
        PartStats::of(&st).add_to(&mut sum);
        let c = &sum.by_experiment["e"].records[&RecordType::Transient];
        assert_eq!((c.read, c.rows, c.rejects), (Some(6), 4, 2));
        assert_eq!(
            sum.by_experiment["e"].records[&RecordType::Transient].read,
            Some(6)
        );
    }
}
