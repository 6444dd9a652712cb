//! The edge's copy of the ground station's landmark database (pure).
//!
//! Changes apply strictly in revision order; a change that skips a revision is a
//! gap, and the shell answers a gap by asking the ground station again.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};
use towernav_protocol::{LandmarkChange, LandmarkChangeOp, LandmarkRecord, LandmarkSyncReply};

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Replica {
    /// Revision of the last change applied.
    pub revision: u64,
    records: BTreeMap<String, LandmarkRecord>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Applied {
    /// The change moved the replica one revision on.
    Applied,
    /// Already had it (a duplicate or a late delivery).
    Stale,
    /// A revision in between is missing: the replica is at `have`, the change is `got`.
    Gap { have: u64, got: u64 },
}

impl Replica {
    pub fn records(&self) -> Vec<LandmarkRecord> {
        self.records.values().cloned().collect()
    }

    pub fn len(&self) -> usize {
        self.records.len()
    }

    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    pub fn apply(&mut self, change: &LandmarkChange) -> Applied {
        if change.revision <= self.revision {
            return Applied::Stale;
        }
        if change.revision != self.revision + 1 {
            return Applied::Gap {
                have: self.revision,
                got: change.revision,
            };
        }
        match &change.change {
            LandmarkChangeOp::Upsert { record } => {
                self.records.insert(record.id.clone(), (**record).clone());
            }
            LandmarkChangeOp::Remove { id } => {
                self.records.remove(id);
            }
        }
        self.revision = change.revision;
        Applied::Applied
    }

    /// Applies a sync reply; returns whether anything changed, or the gap it found.
    pub fn apply_reply(&mut self, reply: &LandmarkSyncReply) -> Result<bool, Applied> {
        if let Some(full) = &reply.full {
            let changed = self.revision != reply.revision || self.records() != *full;
            self.records = full.iter().map(|r| (r.id.clone(), r.clone())).collect();
            self.revision = reply.revision;
            return Ok(changed);
        }
        let mut changed = false;
        for change in &reply.changes {
            match self.apply(change) {
                Applied::Applied => changed = true,
                Applied::Stale => {}
                gap @ Applied::Gap { .. } => return Err(gap),
            }
        }
        Ok(changed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use towernav_protocol::TowerType;

    fn upsert(revision: u64, id: &str, h: f64) -> LandmarkChange {
        LandmarkChange {
            revision,
            change: LandmarkChangeOp::Upsert {
                record: Box::new(LandmarkRecord::new(id, TowerType::A, 30.5, 114.3, 20.0, h)),
            },
        }
    }

    #[test]
    fn applies_in_order_and_detects_gaps_and_duplicates() {
        let mut r = Replica::default();
        assert_eq!(r.apply(&upsert(1, "A1", 30.0)), Applied::Applied);
        assert_eq!(r.apply(&upsert(1, "A1", 30.0)), Applied::Stale);
        assert_eq!(
            r.apply(&upsert(3, "A2", 30.0)),
            Applied::Gap { have: 1, got: 3 }
        );
        assert_eq!(r.len(), 1, "a gap applies nothing");
        assert_eq!(r.apply(&upsert(2, "A1", 31.0)), Applied::Applied);
        assert_eq!(
            r.apply(&LandmarkChange {
                revision: 3,
                change: LandmarkChangeOp::Remove { id: "A1".into() }
            }),
            Applied::Applied
        );
        assert!(r.is_empty());
        assert_eq!(r.revision, 3);
    }

    #[test]
    fn a_full_reply_replaces_everything() {
        let mut r = Replica::default();
        r.apply(&upsert(1, "OLD", 30.0));
        let full = vec![LandmarkRecord::new(
            "B1",
            TowerType::B,
            30.5,
            114.3,
            20.0,
            35.0,
        )];
        let reply = LandmarkSyncReply {
            revision: 7,
            full: Some(full.clone()),
            changes: vec![],
        };
        assert_eq!(r.apply_reply(&reply), Ok(true));
        assert_eq!((r.revision, r.records()), (7, full));
        let gap = LandmarkSyncReply {
            revision: 9,
            full: None,
            changes: vec![upsert(9, "X", 30.0)],
        };
        assert_eq!(r.apply_reply(&gap), Err(Applied::Gap { have: 7, got: 9 }));
    }
}
