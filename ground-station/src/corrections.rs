//! Tower-id corrections the operator sent, and what the edges answered (pure).

use towernav_protocol::{CorrectionAck, IdCorrection, NodeId};

#[derive(Debug, Clone, PartialEq)]
pub enum CorrectionState {
    Pending,
    Accepted,
    Rejected(String),
}

#[derive(Debug, Clone, PartialEq)]
pub struct SentCorrection {
    pub message: IdCorrection,
    /// The track's binding before this correction: what an undo restores.
    pub previous: Option<String>,
    pub state: CorrectionState,
    pub sent_at_s: f64,
    /// Whether this one undid an earlier correction (which cannot be undone twice).
    pub undone: bool,
}

#[derive(Debug, Clone, Default)]
pub struct Corrections {
    next_request_id: u64,
    /// Oldest first.
    pub sent: Vec<SentCorrection>,
}

impl Corrections {
    /// Request ids start at `first_request_id`: seed it from the clock so a
    /// restarted ground station does not reuse ids the edges already answered.
    pub fn starting_at(first_request_id: u64) -> Self {
        Self {
            next_request_id: first_request_id,
            sent: Vec::new(),
        }
    }

    /// Records a correction as pending and returns the message to publish.
    pub fn issue(
        &mut self,
        uav: &NodeId,
        track_id: u64,
        tower_id: Option<String>,
        previous: Option<String>,
        issued_by: &str,
        now_s: f64,
    ) -> IdCorrection {
        let message = IdCorrection {
            uav: uav.clone(),
            request_id: self.next_request_id,
            track_id,
            tower_id,
            issued_by: issued_by.to_owned(),
        };
        self.next_request_id += 1;
        self.sent.push(SentCorrection {
            message: message.clone(),
            previous,
            state: CorrectionState::Pending,
            sent_at_s: now_s,
            undone: false,
        });
        message
    }

    /// Undoes an accepted correction: pins the track back to what it was
    /// bound to before. `None` if there is nothing to undo.
    pub fn undo(&mut self, request_id: u64, issued_by: &str, now_s: f64) -> Option<IdCorrection> {
        let entry = self
            .sent
            .iter_mut()
            .find(|c| c.message.request_id == request_id)?;
        if entry.undone || entry.state != CorrectionState::Accepted {
            return None;
        }
        entry.undone = true;
        let (uav, track, restore, current) = (
            entry.message.uav.clone(),
            entry.message.track_id,
            entry.previous.clone(),
            entry.message.tower_id.clone(),
        );
        let message = self.issue(&uav, track, restore, current, issued_by, now_s);
        if let Some(last) = self.sent.last_mut() {
            last.undone = true; // An undo is not itself undone.
        }
        Some(message)
    }

    pub fn acknowledged(&mut self, ack: &CorrectionAck) {
        if let Some(entry) = self
            .sent
            .iter_mut()
            .find(|c| c.message.request_id == ack.request_id && c.message.uav == ack.uav)
        {
            entry.state = if ack.accepted {
                CorrectionState::Accepted
            } else {
                CorrectionState::Rejected(
                    ack.reason
                        .clone()
                        .unwrap_or_else(|| "no reason given".into()),
                )
            };
        }
    }

    /// The pending correction of a track, if one is in flight.
    pub fn pending_for(&self, uav: &NodeId, track_id: u64) -> Option<&SentCorrection> {
        self.sent.iter().rev().find(|c| {
            c.message.uav == *uav
                && c.message.track_id == track_id
                && c.state == CorrectionState::Pending
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn uav() -> NodeId {
        NodeId::new("u1").expect("valid")
    }

    fn ack(request_id: u64, accepted: bool, reason: Option<&str>) -> CorrectionAck {
        CorrectionAck {
            uav: uav(),
            request_id,
            accepted,
            reason: reason.map(Into::into),
        }
    }

    #[test]
    fn a_correction_goes_pending_then_accepted_and_undo_restores_the_old_binding() {
        let mut c = Corrections::starting_at(100);
        let m = c.issue(&uav(), 7, Some("B2".into()), Some("B1".into()), "op", 1.0);
        assert_eq!(m.request_id, 100);
        assert!(c.pending_for(&uav(), 7).is_some());
        assert_eq!(
            c.undo(100, "op", 2.0),
            None,
            "nothing to undo while pending"
        );
        c.acknowledged(&ack(100, true, None));
        assert_eq!(c.sent[0].state, CorrectionState::Accepted);
        assert!(c.pending_for(&uav(), 7).is_none());

        let undo = c.undo(100, "op", 3.0).expect("undo");
        assert_eq!(
            (undo.request_id, undo.track_id, undo.tower_id.as_deref()),
            (101, 7, Some("B1"))
        );
        assert_eq!(c.undo(100, "op", 4.0), None, "undone once only");
        assert_eq!(c.undo(101, "op", 4.0), None, "an undo is not undone");
    }

    #[test]
    fn a_rejection_keeps_its_reason_and_acks_for_others_are_ignored() {
        let mut c = Corrections::starting_at(1);
        c.issue(&uav(), 7, Some("Z9".into()), None, "op", 0.0);
        c.acknowledged(&CorrectionAck {
            uav: NodeId::new("other").expect("valid"),
            ..ack(1, true, None)
        });
        assert_eq!(c.sent[0].state, CorrectionState::Pending);
        c.acknowledged(&ack(1, false, Some("unknown tower Z9")));
        assert_eq!(
            c.sent[0].state,
            CorrectionState::Rejected("unknown tower Z9".into())
        );
    }
}
