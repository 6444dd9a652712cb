//! The network side: a Zenoh session on its own thread, decoded messages over a
//! channel to the UI, commands (corrections, recording) back from it.
//!
//! Poses come through zenoh-ext's advanced subscriber: on joining, it fetches
//! each edge's cached poses (history), and it recovers samples it missed.

use std::path::PathBuf;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::time::{SystemTime, UNIX_EPOCH};

use tokio::sync::mpsc::{UnboundedReceiver, UnboundedSender, unbounded_channel};
use towernav_protocol::session::{Endpoints, session_config};
use towernav_protocol::{IdCorrection, Keys, NodeId, Topic, encode};
use zenoh::Session;
use zenoh::sample::{Sample, SampleKind};
use zenoh_ext::{AdvancedSubscriberBuilderExt, HistoryConfig, RecoveryConfig};

use crate::events::{NetEvent, decode_alive, decode_sample};
use crate::recording::{ALIVE_DELETE, ALIVE_PUT, Recorder};

/// What the UI asks of the network thread.
#[derive(Debug, Clone, PartialEq)]
pub enum NetCommand {
    /// Publish a correction to its UAV, reliably.
    Correct(IdCorrection),
    /// Record every sample from now on into this MCAP file (never over an
    /// existing one), the landmarks it starts with first.
    StartRecording {
        path: PathBuf,
        landmarks: Vec<towernav_protocol::LandmarkRecord>,
    },
    StopRecording,
}

/// The UI's end of the network thread.
pub struct NetLink {
    pub events: Receiver<NetEvent>,
    pub commands: UnboundedSender<NetCommand>,
}

impl NetLink {
    /// A link with no network behind it: for replay and tests. Commands are kept
    /// in the returned receiver; `Sender` stands in for the network thread.
    pub fn detached() -> (Sender<NetEvent>, UnboundedReceiver<NetCommand>, Self) {
        let (tx, events) = channel();
        let (commands, rx) = unbounded_channel();
        (tx, rx, Self { events, commands })
    }
}

/// Starts the network thread; `wake` is called after each event (egui's `request_repaint`).
/// With `landmarks`, it also serves that landmark database to the fleet's edges.
pub fn spawn(
    endpoints: Endpoints,
    fleet: NodeId,
    landmarks: Option<PathBuf>,
    wake: impl Fn() + Send + 'static,
) -> NetLink {
    let (tx, events) = channel();
    let (commands, commands_rx) = unbounded_channel();
    std::thread::Builder::new()
        .name("towernav-gs-net".into())
        .spawn(move || {
            // Zenoh needs tokio's multi-thread scheduler; one worker is plenty here.
            let result = tokio::runtime::Builder::new_multi_thread()
                .worker_threads(1)
                .enable_all()
                .build()
                .map_err(|e| format!("starting tokio: {e}"))
                .and_then(|rt| {
                    rt.block_on(listen(endpoints, fleet, landmarks, commands_rx, &tx, &wake))
                });
            if let Err(e) = result {
                tracing::error!(error = %e, "network thread stopped");
                let _ = tx.send(NetEvent::Failed(e));
                wake();
            }
        })
        .map_err(|e| tracing::error!(error = %e, "cannot start the network thread"))
        .ok();
    NetLink { events, commands }
}

fn unix_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
}

struct Listener<'a, W: Fn()> {
    tx: &'a Sender<NetEvent>,
    wake: &'a W,
    recorder: Option<Recorder>,
    /// A peer flooding bad payloads (or posing as another UAV) is logged
    /// once per ten seconds; the panel counts every one.
    rejected_log: towernav_core::log_limit::LogLimiter,
}

impl<W: Fn()> Listener<'_, W> {
    /// Hands an event to the UI; `false` once the UI has closed.
    fn send(&mut self, event: NetEvent) -> bool {
        if let NetEvent::Rejected { key, error } = &event
            && let Some(held_back) = self.rejected_log.allow(std::time::Instant::now())
        {
            tracing::warn!(%key, %error, held_back, "rejected payload");
        }
        let open = self.tx.send(event).is_ok();
        (self.wake)();
        open
    }

    fn record(&mut self, key: &str, payload: &[u8]) {
        if let Some(rec) = self.recorder.as_mut()
            && let Err(e) = rec.write(key, payload, unix_ns())
        {
            self.recorder = None;
            self.send(NetEvent::Notice(format!("recording stopped: {e}")));
            self.send(NetEvent::Recording(None));
        }
    }

    fn sample(&mut self, sample: &Sample) -> bool {
        let key = sample.key_expr().as_str();
        let payload = sample.payload().to_bytes();
        self.record(key, &payload);
        match decode_sample(key, &payload) {
            Some(event) => self.send(event),
            None => true,
        }
    }

    fn liveliness(&mut self, sample: &Sample) -> bool {
        let key = sample.key_expr().as_str();
        let alive = sample.kind() == SampleKind::Put;
        self.record(key, if alive { ALIVE_PUT } else { ALIVE_DELETE });
        self.send(decode_alive(key, alive))
    }

    fn finish_recording(&mut self) {
        if let Some(rec) = self.recorder.take() {
            let path = rec.path().display().to_string();
            let notice = match rec.finish() {
                Ok(n) => format!("recorded {n} messages to {path}"),
                Err(e) => format!("recording did not finish cleanly: {e}"),
            };
            self.send(NetEvent::Notice(notice));
            self.send(NetEvent::Recording(None));
        }
    }
}

async fn listen(
    endpoints: Endpoints,
    fleet: NodeId,
    landmarks: Option<PathBuf>,
    mut commands: UnboundedReceiver<NetCommand>,
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
    let keys = Keys::new(fleet);
    let pose_key = keys.all_uavs_of::<towernav_protocol::PoseEstimate>();
    let poses = session
        .declare_subscriber(pose_key.clone())
        .advanced()
        .history(HistoryConfig::default().detect_late_publishers())
        .recovery(RecoveryConfig::default().heartbeat())
        .subscriber_detection()
        .await
        .map_err(|e| format!("subscribing {pose_key}: {e}"))?;
    // Every other per-UAV topic through one wildcard; poses are filtered out
    // of it (they come through the advanced subscriber above).
    let any_key = keys.all_uavs_any_topic();
    let others = session
        .declare_subscriber(any_key.clone())
        .await
        .map_err(|e| format!("subscribing {any_key}: {e}"))?;
    let alive_key = keys.all_alive();
    let alive = session
        .liveliness()
        .declare_subscriber(alive_key.clone())
        .history(true)
        .await
        .map_err(|e| format!("subscribing liveliness {alive_key}: {e}"))?;
    tracing::info!(%any_key, ?endpoints, "listening");
    let mut listener = Listener {
        tx,
        wake,
        recorder: None,
        rejected_log: towernav_core::log_limit::LogLimiter::default(),
    };
    loop {
        let open = tokio::select! {
            sample = poses.recv_async() => match sample {
                Ok(s) => listener.sample(&s),
                Err(_) => false,
            },
            sample = others.recv_async() => match sample {
                Ok(s) if Keys::parse_uav(s.key_expr().as_str()).is_ok_and(|k| k.topic == Topic::Pose) => true,
                Ok(s) => listener.sample(&s),
                Err(_) => false,
            },
            sample = alive.recv_async() => match sample {
                Ok(s) => listener.liveliness(&s),
                Err(_) => false,
            },
            command = commands.recv() => match command {
                Some(c) => command_done(&session, &keys, &mut listener, c).await,
                None => false,
            },
        };
        if !open {
            listener.finish_recording();
            return Ok(());
        }
    }
}

async fn command_done<W: Fn()>(
    session: &Session,
    keys: &Keys,
    listener: &mut Listener<'_, W>,
    command: NetCommand,
) -> bool {
    match command {
        NetCommand::Correct(correction) => {
            let key = keys.uav_key::<IdCorrection>(&correction.uav);
            let sent = match encode(&correction) {
                Ok(bytes) => {
                    listener.record(&key, &bytes);
                    session
                        .put(key.clone(), bytes)
                        .congestion_control(zenoh::qos::CongestionControl::Block)
                        .reliability(zenoh::qos::Reliability::Reliable)
                        .await
                        .map_err(|e| e.to_string())
                }
                Err(e) => Err(e.to_string()),
            };
            match sent {
                Ok(()) => true,
                Err(e) => listener.send(NetEvent::Notice(format!(
                    "correction {} not sent on {key}: {e}",
                    correction.request_id
                ))),
            }
        }
        NetCommand::StartRecording { path, landmarks } => {
            listener.finish_recording();
            match Recorder::create(&path)
                .and_then(|mut rec| rec.write_landmarks(&landmarks, unix_ns()).map(|()| rec))
            {
                Ok(rec) => {
                    listener.recorder = Some(rec);
                    listener.send(NetEvent::Recording(Some(path)))
                }
                Err(e) => {
                    listener.send(NetEvent::Notice(format!("cannot record: {e}")));
                    listener.send(NetEvent::Recording(None))
                }
            }
        }
        NetCommand::StopRecording => {
            listener.finish_recording();
            true
        }
    }
}
