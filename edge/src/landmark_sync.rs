//! Keeps the edge's landmark replica in step with the ground station, and on disk.

use std::path::{Path, PathBuf};
use std::time::Duration;

use towernav_protocol::{
    Keys, LandmarkChange, LandmarkSyncReply, LandmarkSyncRequest, NodeId, decode, encode,
};
use zenoh::Session;
use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::Subscriber;
use zenoh::sample::Sample;

use super::ShellError;
use towernav_core::replica::{Applied, Replica};

/// Where the landmarks in use came from at start.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    GroundStation,
    /// The ground station did not answer; the last saved replica is in use.
    SavedReplica,
}

pub struct LandmarkSync {
    session: Session,
    keys: Keys,
    path: PathBuf,
    replica: Replica,
    changes: Subscriber<FifoChannelHandler<Sample>>,
    timeout: Duration,
    /// Undecodable changes are warned about at most every ten seconds.
    garbage: towernav_core::log_limit::LogLimiter,
}

impl LandmarkSync {
    /// Loads the saved replica, subscribes to changes, then asks the ground station for what it missed.
    pub async fn start(
        session: &Session,
        fleet: NodeId,
        path: PathBuf,
        timeout: Duration,
    ) -> Result<(Self, Source), ShellError> {
        let keys = Keys::new(fleet);
        let (replica, set_aside) = load_or_set_aside(&path)?;
        let key = keys.landmark_changes();
        let changes = session
            .declare_subscriber(key.clone())
            .await
            .map_err(|e| ShellError::zenoh(format!("subscribing {key}"), e))?;
        let mut sync = Self {
            session: session.clone(),
            keys,
            path,
            replica,
            changes,
            timeout,
            garbage: Default::default(),
        };
        let source = if sync.query().await? {
            Source::GroundStation
        } else if sync.replica.is_empty() {
            let why = match &set_aside {
                Some(corrupt) => format!(
                    "the saved replica was unreadable (kept as {})",
                    corrupt.display()
                ),
                None => format!("there is no saved replica at {}", sync.path.display()),
            };
            return Err(ShellError::Landmarks(format!(
                "the ground station did not answer within {timeout:?} and {why}"
            )));
        } else {
            tracing::warn!(
                revision = sync.replica.revision,
                towers = sync.replica.len(),
                file = %sync.path.display(),
                "ground station not answering: starting from the saved landmark replica"
            );
            Source::SavedReplica
        };
        Ok((sync, source))
    }

    pub fn replica(&self) -> &Replica {
        &self.replica
    }

    /// Waits for the next landmark change to arrive (cancel-safe: nothing is
    /// applied here). `None` when the subscription has closed.
    pub async fn next_change(&self) -> Option<Sample> {
        self.changes.recv_async().await.ok()
    }

    /// Applies the changes that arrived; re-asks the ground station on a gap. Returns whether the set changed.
    pub async fn poll(&mut self) -> Result<bool, ShellError> {
        self.apply(None).await
    }

    /// Applies `first` (from `next_change`) and whatever else has arrived;
    /// re-asks the ground station on a gap. Returns whether the set changed.
    pub async fn apply(&mut self, first: Option<Sample>) -> Result<bool, ShellError> {
        let mut changed = false;
        let mut gap = false;
        let queued = std::iter::from_fn(|| self.changes.try_recv().ok().flatten());
        let samples: Vec<Sample> = first.into_iter().chain(queued).collect();
        for sample in samples {
            match decode::<LandmarkChange>(&sample.payload().to_bytes()) {
                Ok(change) => match self.replica.apply(&change) {
                    Applied::Applied => changed = true,
                    Applied::Stale => {}
                    Applied::Gap { have, got } => {
                        tracing::info!(have, got, "landmark change gap: asking the ground station");
                        gap = true;
                        break;
                    }
                },
                Err(e) => {
                    if let Some(held_back) = self.garbage.allow(std::time::Instant::now()) {
                        tracing::warn!(key = %sample.key_expr(), error = %e, held_back, "undecodable landmark change");
                    }
                }
            }
        }
        if gap {
            // What came after the gap is covered by the answer, or arrives again as stale.
            changed |= self.query().await?;
        }
        if changed {
            save(&self.path, &self.replica)?;
        }
        Ok(changed)
    }

    /// Asks for what the replica lacks; `Ok(false)` when nobody answered.
    async fn query(&mut self) -> Result<bool, ShellError> {
        let key = self.keys.landmark_query();
        let since = (!self.replica.is_empty() || self.replica.revision > 0)
            .then_some(self.replica.revision);
        let replies = self
            .session
            .get(key.clone())
            .payload(encode(&LandmarkSyncRequest { since })?)
            .timeout(self.timeout)
            .await
            .map_err(|e| ShellError::zenoh(format!("querying {key}"), e))?;
        // One ground station owns the database: its first answer is the answer.
        if let Ok(reply) = replies.recv_async().await {
            let sample = match reply.result() {
                Ok(sample) => sample,
                Err(e) => {
                    let reason = String::from_utf8_lossy(&e.payload().to_bytes()).into_owned();
                    return Err(ShellError::Landmarks(format!(
                        "ground station refused the landmark query: {reason}"
                    )));
                }
            };
            let answer: LandmarkSyncReply = decode(&sample.payload().to_bytes())
                .map_err(|e| ShellError::Landmarks(format!("bad landmark sync reply: {e}")))?;
            if let Err(gap) = self.replica.apply_reply(&answer) {
                return Err(ShellError::Landmarks(format!(
                    "landmark sync reply skips revisions: {gap:?}"
                )));
            }
            save(&self.path, &self.replica)?;
            return Ok(true);
        }
        Ok(false)
    }
}

/// The saved replica, if there is one.
pub fn load(path: &Path) -> Result<Option<Replica>, ShellError> {
    match std::fs::read(path) {
        Ok(bytes) => serde_json::from_slice(&bytes).map(Some).map_err(|e| {
            ShellError::Landmarks(format!("replica {} is unreadable: {e}", path.display()))
        }),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(ShellError::Landmarks(format!(
            "cannot read replica {}: {e}",
            path.display()
        ))),
    }
}

/// The saved replica; an unreadable one (a disk that failed under it, a
/// file edited by hand) is moved aside to `<file>.corrupt`, said so in the
/// log, and replaced by an empty replica, which the ground station fills
/// again. Returns where the unreadable one went.
pub fn load_or_set_aside(path: &Path) -> Result<(Replica, Option<PathBuf>), ShellError> {
    match load(path) {
        Ok(replica) => Ok((replica.unwrap_or_default(), None)),
        Err(ShellError::Landmarks(reason)) if path.is_file() && reason.contains("unreadable") => {
            let mut aside = path.as_os_str().to_owned();
            aside.push(".corrupt");
            let aside = PathBuf::from(aside);
            std::fs::rename(path, &aside).map_err(|e| {
                ShellError::Landmarks(format!(
                    "{reason}; moving it to {} failed: {e}",
                    aside.display()
                ))
            })?;
            tracing::warn!(
                replica = %path.display(),
                kept_as = %aside.display(),
                "{reason}: set aside; fetching every tower from the ground station again"
            );
            Ok((Replica::default(), Some(aside)))
        }
        Err(e) => Err(e),
    }
}

/// Writes the replica atomically: a crash leaves the old file or the new one, never half of one.
pub fn save(path: &Path, replica: &Replica) -> Result<(), ShellError> {
    let fail = |e: std::io::Error| {
        ShellError::Landmarks(format!("cannot save replica {}: {e}", path.display()))
    };
    let tmp = path.with_extension("tmp");
    let bytes = serde_json::to_vec(replica).map_err(|e| ShellError::Landmarks(e.to_string()))?;
    {
        use std::io::Write;
        let mut file = std::fs::File::create(&tmp).map_err(fail)?;
        file.write_all(&bytes).map_err(fail)?;
        file.sync_all().map_err(fail)?;
    }
    std::fs::rename(&tmp, path).map_err(fail)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unreadable_replica_is_set_aside_and_started_afresh() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("replica.json");
        std::fs::write(&path, b"{\"revision\": 12, \"tow").expect("write");
        let (replica, aside) = load_or_set_aside(&path).expect("not fatal");
        assert!(replica.is_empty());
        let aside = aside.expect("set aside");
        assert_eq!(aside, dir.path().join("replica.json.corrupt"));
        assert!(
            aside.is_file() && !path.exists(),
            "kept for a look, out of the way"
        );
    }

    #[test]
    fn a_good_replica_loads_and_a_missing_one_is_empty() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("replica.json");
        assert!(load_or_set_aside(&path).expect("empty").0.is_empty());
        save(&path, &Replica::default()).expect("save");
        let (_, aside) = load_or_set_aside(&path).expect("loads");
        assert_eq!(aside, None);
        assert!(path.is_file());
    }
}
