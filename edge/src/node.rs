//! An edge's presence on Zenoh: publishes poses, tracks, detections, previews
//! and status; holds a liveliness token while it runs; receives corrections.
//!
//! Poses go out through zenoh-ext's advanced publisher: it keeps the last
//! samples in a cache and sends sequence heartbeats, so a ground station that
//! joins late or misses samples can detect the gap and fetch them.

use std::time::Duration;
use towernav_protocol::session::{Endpoints, client_config, session_config};

use towernav_protocol::{
    CorrectionAck, DetectionReport, IdCorrection, Keys, Message, NodeId, PoseEstimate, Preview,
    StatusHeartbeat, TrackReport, TruthPose, decode_on_key, encode,
};
use zenoh::Session;
use zenoh::handlers::FifoChannelHandler;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::sample::Sample;
use zenoh_ext::{AdvancedPublisher, AdvancedPublisherBuilderExt, CacheConfig, MissDetectionConfig};

use super::ShellError;
use crate::daemon::config::ZenohMode;

pub async fn open_session(endpoints: &Endpoints) -> Result<Session, ShellError> {
    open_session_as(endpoints, ZenohMode::Peer).await
}

/// A session in the given mode: `Client` talks only through the router it connects to.
pub async fn open_session_as(
    endpoints: &Endpoints,
    mode: ZenohMode,
) -> Result<Session, ShellError> {
    let config = match mode {
        ZenohMode::Peer => session_config(endpoints)?,
        ZenohMode::Client => client_config(endpoints)?,
    };
    zenoh::open(config)
        .await
        .map_err(|e| ShellError::zenoh(format!("opening session {endpoints:?}"), e))
}

pub struct EdgeNode {
    session: Session,
    uav: NodeId,
    keys: Keys,
    pose: AdvancedPublisher<'static>,
    tracks: Publisher<'static>,
    status: Publisher<'static>,
    detections: Publisher<'static>,
    preview: Publisher<'static>,
    truth: Publisher<'static>,
    corrections: Subscriber<FifoChannelHandler<Sample>>,
    /// Undecodable corrections are warned about at most every ten seconds.
    garbage: std::sync::Mutex<towernav_core::log_limit::LogLimiter>,
    _alive: LivelinessToken,
}

/// Poses kept for late joiners: ten seconds at 30 Hz.
const POSE_CACHE: usize = 300;

impl EdgeNode {
    pub async fn new(session: Session, fleet: NodeId, uav: NodeId) -> Result<Self, ShellError> {
        let keys = Keys::new(fleet);
        let publisher = |key: String| {
            let session = session.clone();
            async move {
                session
                    .declare_publisher(key.clone())
                    .await
                    .map_err(|e| ShellError::zenoh(format!("declaring publisher {key}"), e))
            }
        };
        // Poses must not vanish under load: block the sender rather than drop a fix.
        // Tracks and status keep zenoh's default (drop), where only the latest matters.
        let pose_key = keys.uav_key::<PoseEstimate>(&uav);
        let pose = session
            .declare_publisher(pose_key.clone())
            .congestion_control(zenoh::qos::CongestionControl::Block)
            .advanced()
            .cache(CacheConfig::default().max_samples(POSE_CACHE))
            .sample_miss_detection(
                MissDetectionConfig::default().heartbeat(Duration::from_millis(500)),
            )
            .publisher_detection()
            .await
            .map_err(|e| ShellError::zenoh(format!("declaring publisher {pose_key}"), e))?;
        let tracks = publisher(keys.uav_key::<TrackReport>(&uav)).await?;
        let status = publisher(keys.uav_key::<StatusHeartbeat>(&uav)).await?;
        let detections = publisher(keys.uav_key::<DetectionReport>(&uav)).await?;
        let preview = publisher(keys.uav_key::<Preview>(&uav)).await?;
        let truth = publisher(keys.uav_key::<TruthPose>(&uav)).await?;
        let alive_key = keys.alive(&uav);
        let alive = session
            .liveliness()
            .declare_token(alive_key.clone())
            .await
            .map_err(|e| ShellError::zenoh(format!("declaring liveliness {alive_key}"), e))?;
        let correction_key = keys.uav_key::<IdCorrection>(&uav);
        let corrections = session
            .declare_subscriber(correction_key.clone())
            .await
            .map_err(|e| ShellError::zenoh(format!("subscribing {correction_key}"), e))?;
        Ok(Self {
            session,
            uav,
            keys,
            pose,
            tracks,
            status,
            detections,
            preview,
            truth,
            corrections,
            garbage: std::sync::Mutex::default(),
            _alive: alive,
        })
    }

    pub fn uav(&self) -> &NodeId {
        &self.uav
    }

    pub fn session(&self) -> &Session {
        &self.session
    }

    async fn put<M: Message>(
        publisher: &Publisher<'static>,
        message: &M,
    ) -> Result<(), ShellError> {
        let bytes = encode(message)?;
        publisher
            .put(bytes)
            .await
            .map_err(|e| ShellError::zenoh(format!("publishing on {}", publisher.key_expr()), e))
    }

    pub async fn publish_pose(&self, pose: &PoseEstimate) -> Result<(), ShellError> {
        let bytes = encode(pose)?;
        self.pose
            .put(bytes)
            .await
            .map_err(|e| ShellError::zenoh("publishing a pose", e))
    }

    pub async fn publish_detections(&self, report: &DetectionReport) -> Result<(), ShellError> {
        Self::put(&self.detections, report).await
    }

    pub async fn publish_preview(&self, preview: &Preview) -> Result<(), ShellError> {
        Self::put(&self.preview, preview).await
    }

    pub async fn publish_truth(&self, truth: &TruthPose) -> Result<(), ShellError> {
        Self::put(&self.truth, truth).await
    }

    pub async fn publish_tracks(&self, tracks: &TrackReport) -> Result<(), ShellError> {
        Self::put(&self.tracks, tracks).await
    }

    pub async fn publish_status(&self, status: &StatusHeartbeat) -> Result<(), ShellError> {
        Self::put(&self.status, status).await
    }

    /// Waits for the next correction for this UAV (cancel-safe: a sample is
    /// taken and read with no wait in between). A payload that does not decode
    /// is logged with its key and dropped: there is no request id to refuse it by. Pending forever once the
    /// subscription has closed.
    pub async fn next_correction(&self) -> IdCorrection {
        while let Ok(sample) = self.corrections.recv_async().await {
            if let Some(c) = self.correction_in(&sample) {
                return c;
            }
        }
        std::future::pending().await
    }

    fn correction_in(&self, sample: &Sample) -> Option<IdCorrection> {
        // Read on the key it came on: a correction naming another UAV is refused.
        match decode_on_key::<IdCorrection>(
            sample.key_expr().as_str(),
            &sample.payload().to_bytes(),
        ) {
            Ok(c) if c.uav == self.uav => Some(c),
            Ok(c) => {
                self.warn_limited(&format!("correction for UAV {} ignored", c.uav));
                None
            }
            Err(e) => {
                self.warn_limited(&e.to_string());
                None
            }
        }
    }

    /// One warning per ten seconds for refused corrections, with how many
    /// were held back: a flood of them does not flood the log.
    fn warn_limited(&self, error: &str) {
        let allowed = self
            .garbage
            .lock()
            .map(|mut l| l.allow(std::time::Instant::now()))
            .unwrap_or(Some(0));
        if let Some(held_back) = allowed {
            tracing::warn!(%error, held_back, "correction refused");
        }
    }

    /// Acknowledgements are sent reliably and never dropped under congestion.
    pub async fn acknowledge(&self, ack: &CorrectionAck) -> Result<(), ShellError> {
        let key = self.keys.uav_key::<CorrectionAck>(&self.uav);
        let bytes = encode(ack)?;
        self.session
            .put(key.clone(), bytes)
            .congestion_control(zenoh::qos::CongestionControl::Block)
            .reliability(zenoh::qos::Reliability::Reliable)
            .await
            .map_err(|e| ShellError::zenoh(format!("publishing on {key}"), e))
    }
}

/// Waits until `session` has a Zenoh link to some peer, so nothing published is lost to a slow start.
pub async fn wait_for_peer(session: &Session, timeout: Duration) -> Result<(), ShellError> {
    let deadline = tokio::time::Instant::now() + timeout;
    loop {
        let info = session.info();
        if info.peers_zid().await.next().is_some() || info.routers_zid().await.next().is_some() {
            // Let subscriptions propagate over the fresh link.
            tokio::time::sleep(Duration::from_millis(300)).await;
            return Ok(());
        }
        if tokio::time::Instant::now() >= deadline {
            return Err(ShellError::zenoh(
                "waiting for a peer",
                format!("no link within {timeout:?}"),
            ));
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}
