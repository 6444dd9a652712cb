//! Tower-id corrections the operator sent, and what the edges answered (pure).
//!
//! A correction no edge answers within [`ANSWER_TIMEOUT_S`] (the UAV is
//! offline, the link dropped it) is marked so, to be resent or cancelled; an
//! answer that comes later still counts, since the edge did act on it.

use towernav_protocol::{CorrectionAck, IdCorrection, NodeId};

/// How long a correction waits for its answer; edges answer in well under a second.
pub const ANSWER_TIMEOUT_S: f64 = 5.0;

#[derive(Debug, Clone, PartialEq)]
pub enum CorrectionState {
    Pending,
    Accepted,
    Rejected(String),
    /// No answer within [`ANSWER_TIMEOUT_S`].
    NoAnswer,
    /// The operator stopped waiting for it (it was resent, or given up).
    Cancelled,
    /// Unanswered when its edge restarted: the track number it names now
    /// means another track, so it is neither resent nor applied.
    RunEnded,
}

#[derive(Debug, Clone, PartialEq)]
pub struct SentCorrection {
    /// 1, 2, 3... in the order sent: what the operator reads, not the
    /// clock-seeded request id.
    pub number: u64,
    pub message: IdCorrection,
    /// The track's binding before this correction: what an undo restores.
    pub previous: Option<String>,
    /// Whether that binding was an operator's pin; if not, an undo hands the
    /// track back to the edge instead of pinning it.
    pub previous_pinned: bool,
    pub state: CorrectionState,
    pub sent_at_s: f64,
    /// Whether this one undid an earlier correction (which cannot be undone twice).
    pub undone: bool,
}

/// A track's binding when the operator chose to correct it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Before {
    pub tower: Option<String>,
    /// Pinned by an operator, rather than bound by the edge.
    pub pinned: bool,
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
    /// `session`: the edge run the track was picked in (`None`: unknown).
    #[allow(clippy::too_many_arguments)]
    pub fn issue(
        &mut self,
        uav: &NodeId,
        track_id: u64,
        session: Option<u64>,
        tower_id: Option<String>,
        before: Before,
        issued_by: &str,
        now_s: f64,
    ) -> IdCorrection {
        let message = IdCorrection {
            uav: uav.clone(),
            request_id: self.next_request_id,
            track_id,
            tower_id,
            issued_by: issued_by.to_owned(),
            release: false,
            session,
        };
        self.next_request_id += 1;
        self.sent.push(SentCorrection {
            number: self.sent.len() as u64 + 1,
            message: message.clone(),
            previous: before.tower,
            previous_pinned: before.pinned,
            state: CorrectionState::Pending,
            sent_at_s: now_s,
            undone: false,
        });
        message
    }

    /// Undoes an accepted correction: pins the track back to what an
    /// operator had pinned it to, or hands it back to the edge when the edge
    /// had bound it itself. `None` if there is nothing to undo.
    pub fn undo(&mut self, request_id: u64, issued_by: &str, now_s: f64) -> Option<IdCorrection> {
        let entry = self
            .sent
            .iter_mut()
            .find(|c| c.message.request_id == request_id)?;
        if entry.undone || entry.state != CorrectionState::Accepted {
            return None;
        }
        entry.undone = true;
        let (uav, track, restore, pinned, current) = (
            entry.message.uav.clone(),
            entry.message.track_id,
            entry.previous.clone(),
            entry.previous_pinned,
            entry.message.tower_id.clone(),
        );
        let release = !pinned;
        let before = Before {
            tower: current,
            pinned: true,
        };
        let restore = if release { None } else { restore };
        let session = entry.message.session;
        let mut message = self.issue(&uav, track, session, restore, before, issued_by, now_s);
        message.release = release;
        if let Some(last) = self.sent.last_mut() {
            last.undone = true; // An undo is not itself undone.
            last.message.release = release;
        }
        Some(message)
    }

    /// Marks the corrections that waited past [`ANSWER_TIMEOUT_S`] as unanswered.
    pub fn expire(&mut self, now_s: f64) {
        for c in &mut self.sent {
            if c.state == CorrectionState::Pending && now_s - c.sent_at_s > ANSWER_TIMEOUT_S {
                c.state = CorrectionState::NoAnswer;
            }
        }
    }

    /// Sends an unanswered or pending correction again under a new request
    /// id, the old one cancelled; `None` if it was answered.
    pub fn resend(&mut self, request_id: u64, issued_by: &str, now_s: f64) -> Option<IdCorrection> {
        let entry = self.sent.iter_mut().find(|c| {
            c.message.request_id == request_id
                && matches!(
                    c.state,
                    CorrectionState::Pending | CorrectionState::NoAnswer
                )
        })?;
        entry.state = CorrectionState::Cancelled;
        let (uav, track, tower, release, undone) = (
            entry.message.uav.clone(),
            entry.message.track_id,
            entry.message.tower_id.clone(),
            entry.message.release,
            entry.undone,
        );
        let before = Before {
            tower: entry.previous.clone(),
            pinned: entry.previous_pinned,
        };
        let session = entry.message.session;
        let mut message = self.issue(&uav, track, session, tower, before, issued_by, now_s);
        message.release = release;
        if let Some(last) = self.sent.last_mut() {
            last.undone = undone;
            last.message.release = release;
        }
        Some(message)
    }

    /// `uav`'s edge now runs as `session`: its corrections still waiting
    /// for an answer from an earlier run end, never to be resent.
    pub fn run_changed(&mut self, uav: &NodeId, session: u64) {
        for c in &mut self.sent {
            if c.message.uav == *uav
                && c.message.session.is_some_and(|s| s != session)
                && matches!(
                    c.state,
                    CorrectionState::Pending | CorrectionState::NoAnswer
                )
            {
                c.state = CorrectionState::RunEnded;
            }
        }
    }

    /// Stops waiting for a correction's answer; true if it was waiting.
    pub fn cancel(&mut self, request_id: u64) -> bool {
        match self.sent.iter_mut().find(|c| {
            c.message.request_id == request_id
                && matches!(
                    c.state,
                    CorrectionState::Pending | CorrectionState::NoAnswer
                )
        }) {
            Some(c) => {
                c.state = CorrectionState::Cancelled;
                true
            }
            None => false,
        }
    }

    /// The first answer of the UAV the correction went to counts; later ones
    /// (a replay, a forgery) do not overwrite it. `ack.uav` is the UAV of the
    /// key the answer came on, so another edge cannot answer for it.
    pub fn acknowledged(&mut self, ack: &CorrectionAck) {
        if let Some(entry) = self.sent.iter_mut().find(|c| {
            c.message.request_id == ack.request_id
                && c.message.uav == ack.uav
                && !matches!(
                    c.state,
                    CorrectionState::Accepted | CorrectionState::Rejected(_)
                )
        }) {
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

    fn pinned(tower: &str) -> Before {
        Before {
            tower: Some(tower.into()),
            pinned: true,
        }
    }

    #[test]
    fn a_correction_goes_pending_then_accepted_and_undo_restores_the_old_binding() {
        let mut c = Corrections::starting_at(100);
        let m = c.issue(&uav(), 7, None, Some("B2".into()), pinned("B1"), "op", 1.0);
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
            (
                undo.request_id,
                undo.track_id,
                undo.tower_id.as_deref(),
                undo.release
            ),
            (101, 7, Some("B1"), false),
            "an operator's earlier pin is pinned again"
        );
        assert_eq!(c.undo(100, "op", 4.0), None, "undone once only");
        assert_eq!(c.undo(101, "op", 4.0), None, "an undo is not undone");
    }

    #[test]
    fn undoing_a_correction_of_the_edges_own_binding_hands_the_track_back() {
        let mut c = Corrections::starting_at(1);
        let edge_bound = Before {
            tower: Some("B1".into()),
            pinned: false,
        };
        c.issue(&uav(), 7, None, Some("B2".into()), edge_bound, "op", 1.0);
        c.acknowledged(&ack(1, true, None));
        let undo = c.undo(1, "op", 2.0).expect("undo");
        assert!(undo.release, "not pinned to B1: released to the edge");
        assert_eq!(undo.tower_id, None);
    }

    #[test]
    fn an_unanswered_correction_times_out_then_resends_or_cancels_and_a_late_answer_counts() {
        let mut c = Corrections::starting_at(1_764_000_000_000);
        c.issue(&uav(), 7, None, Some("B2".into()), pinned("B1"), "op", 10.0);
        c.expire(10.0 + ANSWER_TIMEOUT_S - 0.1);
        assert_eq!(c.sent[0].state, CorrectionState::Pending);
        c.expire(10.0 + ANSWER_TIMEOUT_S + 0.1);
        assert_eq!(c.sent[0].state, CorrectionState::NoAnswer);
        assert!(c.pending_for(&uav(), 7).is_none(), "no longer in flight");

        let again = c.resend(1_764_000_000_000, "op", 20.0).expect("resent");
        assert_eq!(
            (again.request_id, again.track_id, again.tower_id.as_deref()),
            (1_764_000_000_001, 7, Some("B2"))
        );
        assert_eq!(c.sent[0].state, CorrectionState::Cancelled);
        assert_eq!((c.sent[0].number, c.sent[1].number), (1, 2));
        assert_eq!(c.sent[1].previous.as_deref(), Some("B1"));
        assert!(c.resend(1_764_000_000_000, "op", 21.0).is_none(), "once");

        assert!(c.cancel(1_764_000_000_001));
        assert!(!c.cancel(1_764_000_000_001));
        // The edge was only slow: its answer still says what it did.
        c.acknowledged(&ack(1_764_000_000_001, true, None));
        assert_eq!(c.sent[1].state, CorrectionState::Accepted);
    }

    #[test]
    fn a_rejection_keeps_its_reason_and_acks_for_others_are_ignored() {
        let mut c = Corrections::starting_at(1);
        c.issue(
            &uav(),
            7,
            None,
            Some("Z9".into()),
            Before::default(),
            "op",
            0.0,
        );
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
        // The first answer stands: a later one does not turn it around.
        c.acknowledged(&ack(1, true, None));
        assert_eq!(
            c.sent[0].state,
            CorrectionState::Rejected("unknown tower Z9".into())
        );
    }
}
