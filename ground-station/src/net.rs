//! The network side: a Zenoh session on its own thread, decoded messages over a channel.

use std::sync::mpsc::{Receiver, Sender, channel};

use towernav_protocol::session::{Endpoints, session_config};
use towernav_protocol::{Keys, NodeId, Topic, decode};

use crate::fleet::NetEvent;

/// Starts the network thread; `wake` is called after each event (egui's `request_repaint`).
/// With `landmarks`, it also serves that landmark database to the fleet's edges.
pub fn spawn(
    endpoints: Endpoints,
    fleet: NodeId,
    landmarks: Option<std::path::PathBuf>,
    wake: impl Fn() + Send + 'static,
) -> Receiver<NetEvent> {
    let (tx, rx) = channel();
    std::thread::Builder::new()
        .name("towernav-gs-net".into())
        .spawn(move || {
            // Zenoh needs tokio's multi-thread scheduler; one worker is plenty here.
            let result = tokio::runtime::Builder::new_multi_thread()
                .worker_threads(1)
                .enable_all()
                .build()
                .map_err(|e| format!("starting tokio: {e}"))
                .and_then(|rt| rt.block_on(listen(endpoints, fleet, landmarks, &tx, &wake)));
            if let Err(e) = result {
                tracing::error!(error = %e, "network thread stopped");
                let _ = tx.send(NetEvent::Failed(e));
                wake();
            }
        })
        .map_err(|e| tracing::error!(error = %e, "cannot start the network thread"))
        .ok();
    rx
}

async fn listen(
    endpoints: Endpoints,
    fleet: NodeId,
    landmarks: Option<std::path::PathBuf>,
    tx: &Sender<NetEvent>,
    wake: &impl Fn(),
) -> Result<(), String> {
    let config = session_config(&endpoints).map_err(|e| e.to_string())?;
    let session = zenoh::open(config)
        .await
        .map_err(|e| format!("opening zenoh session: {e}"))?;
    if let Some(db) = landmarks {
        let (session, fleet, tx) = (session.clone(), fleet.clone(), tx.clone());
        tokio::spawn(async move {
            if let Err(e) = crate::landmark_service::serve(session, fleet, db).await {
                tracing::error!(error = %e, "landmark service stopped");
                let _ = tx.send(NetEvent::Failed(format!("landmark service: {e}")));
            }
        });
    }
    // One subscription for every per-UAV topic of the fleet.
    let key = Keys::new(fleet).all_uavs_any_topic();
    let subscriber = session
        .declare_subscriber(key.clone())
        .await
        .map_err(|e| format!("subscribing {key}: {e}"))?;
    tracing::info!(%key, ?endpoints, "listening");
    while let Ok(sample) = subscriber.recv_async().await {
        let key = sample.key_expr().as_str().to_owned();
        let bytes = sample.payload().to_bytes();
        let event = match Keys::parse_uav(&key) {
            Ok(parsed) => match parsed.topic {
                Topic::Pose => decode(&bytes).map(NetEvent::Pose),
                Topic::Tracks => decode(&bytes).map(NetEvent::Tracks),
                Topic::Status => decode(&bytes).map(NetEvent::Status),
                // Corrections and their acks are the ground station's own traffic.
                Topic::Correction | Topic::CorrectionAck => continue,
                // The camera view is not drawn yet: raw boxes and previews are skipped.
                Topic::Detections | Topic::Preview => continue,
            }
            .unwrap_or_else(|e| NetEvent::Rejected {
                key: key.clone(),
                error: e.to_string(),
            }),
            Err(e) => NetEvent::Rejected {
                key: key.clone(),
                error: e.to_string(),
            },
        };
        if let NetEvent::Rejected { key, error } = &event {
            tracing::warn!(%key, %error, "rejected payload");
        }
        if tx.send(event).is_err() {
            return Ok(()); // The UI has closed.
        }
        wake();
    }
    Ok(())
}
