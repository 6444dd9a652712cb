//! A listener that gathers every pose of a fleet, as a ground station would see them.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use towernav_protocol::{Keys, NodeId, PoseEstimate, decode_on_key};
use zenoh::Session;

use super::ShellError;

pub struct PoseCollector {
    poses: Arc<Mutex<Vec<PoseEstimate>>>,
    rejected: Arc<Mutex<usize>>,
    _task: tokio::task::JoinHandle<()>,
}

impl PoseCollector {
    pub async fn start(session: &Session, fleet: NodeId) -> Result<Self, ShellError> {
        let key = Keys::new(fleet).all_uavs_of::<PoseEstimate>();
        let subscriber = session
            .declare_subscriber(key.clone())
            .await
            .map_err(|e| ShellError::zenoh(format!("subscribing {key}"), e))?;
        let poses = Arc::new(Mutex::new(Vec::new()));
        let rejected = Arc::new(Mutex::new(0));
        let (sink, bad) = (poses.clone(), rejected.clone());
        let task = tokio::spawn(async move {
            // One warning per ten seconds, with how many were held back.
            let mut log = towernav_core::log_limit::LogLimiter::default();
            while let Ok(sample) = subscriber.recv_async().await {
                // The UAV is the key's: a pose naming another UAV is refused.
                match decode_on_key::<PoseEstimate>(
                    sample.key_expr().as_str(),
                    &sample.payload().to_bytes(),
                ) {
                    Ok(p) => sink.lock().unwrap_or_else(|e| e.into_inner()).push(p),
                    Err(e) => {
                        if let Some(held_back) = log.allow(std::time::Instant::now()) {
                            tracing::warn!(error = %e, held_back, "pose refused");
                        }
                        *bad.lock().unwrap_or_else(|e| e.into_inner()) += 1;
                    }
                }
            }
        });
        Ok(Self {
            poses,
            rejected,
            _task: task,
        })
    }

    pub fn count(&self) -> usize {
        self.poses.lock().unwrap_or_else(|e| e.into_inner()).len()
    }

    pub fn rejected(&self) -> usize {
        *self.rejected.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Waits until `expected` poses arrived or `timeout` passed; returns what arrived.
    pub async fn drain(&self, expected: usize, timeout: Duration) -> Vec<PoseEstimate> {
        let deadline = tokio::time::Instant::now() + timeout;
        while self.count() < expected && tokio::time::Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        self.poses.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }
}
