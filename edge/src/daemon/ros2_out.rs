//! The onboard Zenoh: the core's `RosOutput`s published as rmw_zenoh does
//! (CDR payloads on `<domain>/<topic>/<type>/<hash>`, an attachment on each
//! sample, liveliness tokens for the node and each endpoint, so that ROS 2's
//! graph sees them), PX4's auxiliary global position on the key PX4's Zenoh
//! module subscribes to, and PX4's `vehicle_attitude` read back as an
//! attitude source and as PX4's clock.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use towernav_core::ros_link::RosOutput;
use towernav_geometry::Attitude;
use towernav_protocol::ros2::cdr::CdrVersion;
use towernav_protocol::ros2::msgs::{self, Px4AuxMessage, RosMessage, VehicleAttitude};
use towernav_protocol::ros2::rmw_zenoh::{Endpoint, Qos, RosNode, attachment, gid_of};
use towernav_protocol::ros2::type_hash::MsgType;
use towernav_protocol::session::{Endpoints, session_config};
use zenoh::Session;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::{Publisher, Subscriber};

use super::config::EdgeConfig;
use crate::ShellError;

/// Depth announced in the tokens: what a late subscriber may expect queued.
const DEPTH: u32 = 10;

/// One ROS publisher: its Zenoh publisher, token, GID and sequence.
struct RosPublisher {
    publisher: Publisher<'static>,
    gid: [u8; 16],
    sequence: i64,
    _token: LivelinessToken,
}

impl RosPublisher {
    async fn declare(
        session: &Session,
        node: &RosNode,
        entity_id: u32,
        topic: &str,
        t: &MsgType,
        reliable: bool,
    ) -> Result<Self, ShellError> {
        let key = node.topic_key(topic, t);
        let zid = session.zid().to_string();
        let token_key = node.endpoint_token(
            &zid,
            0,
            entity_id,
            Endpoint::Publisher,
            topic,
            t,
            Qos {
                reliable,
                depth: DEPTH,
            },
        );
        let publisher = session
            .declare_publisher(key.clone())
            .reliability(if reliable {
                zenoh::qos::Reliability::Reliable
            } else {
                zenoh::qos::Reliability::BestEffort
            })
            .await
            .map_err(|e| ShellError::zenoh(format!("declaring publisher {key}"), e))?;
        let token = session
            .liveliness()
            .declare_token(token_key.clone())
            .await
            .map_err(|e| ShellError::zenoh(format!("declaring liveliness {token_key}"), e))?;
        tracing::info!(%key, "ROS 2 publisher");
        Ok(Self {
            publisher,
            gid: gid_of(&token_key),
            sequence: 0,
            _token: token,
        })
    }

    async fn put(&mut self, payload: Vec<u8>, unix_ns: i64) -> Result<(), ShellError> {
        self.sequence += 1;
        self.publisher
            .put(payload)
            .attachment(attachment(self.sequence, unix_ns, &self.gid))
            .await
            .map_err(|e| ShellError::zenoh("publishing on the onboard Zenoh", e))
    }
}

/// The ROS 2 topics' publishers.
struct Ros2Topics {
    fix: RosPublisher,
    pose: RosPublisher,
    odometry: RosPublisher,
}

/// What goes to PX4, and how it is written.
struct Px4Out {
    publisher: RosPublisher,
    message: Px4AuxMessage,
    cdr: CdrVersion,
}

/// PX4's attitude as its `vehicle_attitude` last said, and its clock.
#[derive(Clone)]
pub struct Px4Attitude {
    latest: Arc<Mutex<Option<(Instant, Attitude)>>>,
}

impl Px4Attitude {
    /// The latest attitude if it is younger than `max_age`.
    pub fn latest(&self, max_age: Duration) -> Option<Attitude> {
        let latest = *self.latest.lock().unwrap_or_else(|p| p.into_inner());
        latest.and_then(|(at, a)| (at.elapsed() <= max_age).then_some(a))
    }
}

/// The attitude in a PX4 quaternion (w, x, y, z; FRD body to NED).
pub fn attitude_of(q: [f32; 4]) -> Option<Attitude> {
    let [w, x, y, z] = q.map(f64::from);
    let q = nalgebra::Quaternion::new(w, x, y, z);
    if !(q.norm() > 0.5 && q.norm() < 1.5) {
        return None;
    }
    let (roll, pitch, yaw) = nalgebra::UnitQuaternion::from_quaternion(q).euler_angles();
    Some(Attitude::from_ned(roll, pitch, yaw))
}

pub struct OnboardBus {
    /// Kept open for the publishers and tokens below.
    _session: Session,
    ros2: Option<Ros2Topics>,
    px4: Option<Px4Out>,
    _node_token: LivelinessToken,
    _attitude: (Subscriber<()>, LivelinessToken),
    px4_times: tokio::sync::mpsc::Receiver<u64>,
    failures: u64,
}

impl OnboardBus {
    /// Opens the onboard Zenoh and declares what the config asks for; `None`
    /// where nothing onboard is on. With a PX4 attitude subscription, the
    /// attitude it keeps comes back too.
    pub async fn open(config: &EdgeConfig) -> Result<Option<(Self, Px4Attitude)>, ShellError> {
        if !config.onboard_zenoh() {
            return Ok(None);
        }
        let ros2 = &config.ros2;
        let session = zenoh::open(session_config(&Endpoints {
            listen: ros2.listen.clone(),
            connect: ros2.connect.clone(),
            security: None,
        })?)
        .await
        .map_err(|e| {
            ShellError::zenoh(format!("opening the onboard Zenoh {:?}", ros2.connect), e)
        })?;
        let node = ros2.node();
        let zid = session.zid().to_string();
        let node_token_key = node.node_token(&zid, 0);
        let node_token = session
            .liveliness()
            .declare_token(node_token_key.clone())
            .await
            .map_err(|e| ShellError::zenoh(format!("declaring liveliness {node_token_key}"), e))?;
        let topics = match ros2.enabled {
            true => Some(Ros2Topics {
                fix: RosPublisher::declare(
                    &session,
                    &node,
                    10,
                    &ros2.fix_topic,
                    &msgs::NAV_SAT_FIX,
                    true,
                )
                .await?,
                pose: RosPublisher::declare(
                    &session,
                    &node,
                    11,
                    &ros2.pose_topic,
                    &msgs::POSE_WITH_COVARIANCE_STAMPED,
                    true,
                )
                .await?,
                odometry: RosPublisher::declare(
                    &session,
                    &node,
                    12,
                    &ros2.odometry_topic,
                    &msgs::ODOMETRY,
                    true,
                )
                .await?,
            }),
            false => None,
        };
        let px4_config = &config.px4;
        let px4 = match px4_config.enabled {
            true => {
                let message = px4_config.aux_message();
                // Best effort: a late fix is worth nothing to the EKF.
                let publisher = RosPublisher::declare(
                    &session,
                    &node,
                    13,
                    &px4_config.topic_in_namespace(&px4_config.topic),
                    message.msg_type(),
                    false,
                )
                .await?;
                Some(Px4Out {
                    publisher,
                    message,
                    cdr: px4_config.cdr_version(),
                })
            }
            false => None,
        };
        let latest = Arc::new(Mutex::new(None));
        let (times_tx, times_rx) = tokio::sync::mpsc::channel(64);
        // PX4's attitude: its clock for PX4's stamps, and an attitude source.
        let attitude_topic = px4_config.topic_in_namespace(&px4_config.attitude_topic);
        // Any type hash: PX4 releases differ; the payload's layout is the same.
        let attitude_key = node.topic_key_any_hash(&attitude_topic, &msgs::VEHICLE_ATTITUDE);
        let sink = latest.clone();
        let garbage = Arc::new(Mutex::new(towernav_core::log_limit::LogLimiter::default()));
        let subscriber = session
            .declare_subscriber(attitude_key.clone())
            .callback(move |sample| {
                let payload = sample.payload().to_bytes();
                match VehicleAttitude::from_cdr(&payload) {
                    Ok(a) => {
                        if let Some(attitude) = attitude_of(a.q) {
                            *sink.lock().unwrap_or_else(|p| p.into_inner()) =
                                Some((Instant::now(), attitude));
                        }
                        let _ = times_tx.try_send(a.timestamp_us);
                    }
                    Err(e) => {
                        let mut limit = garbage.lock().unwrap_or_else(|p| p.into_inner());
                        if limit.allow(Instant::now()).is_some() {
                            tracing::warn!(key = %sample.key_expr(), error = %e, "PX4 vehicle_attitude not understood");
                        }
                    }
                }
            })
            .await
            .map_err(|e| ShellError::zenoh(format!("subscribing {attitude_key}"), e))?;
        let subscription_token_key = node.endpoint_token(
            &zid,
            0,
            14,
            Endpoint::Subscription,
            &attitude_topic,
            &msgs::VEHICLE_ATTITUDE,
            Qos {
                reliable: false,
                depth: DEPTH,
            },
        );
        let subscription_token = session
            .liveliness()
            .declare_token(subscription_token_key.clone())
            .await
            .map_err(|e| {
                ShellError::zenoh(format!("declaring liveliness {subscription_token_key}"), e)
            })?;
        tracing::info!(connect = ?ros2.connect, ros2 = ros2.enabled, px4 = px4_config.enabled, %attitude_key, "onboard Zenoh open");
        Ok(Some((
            Self {
                _session: session,
                ros2: topics,
                px4,
                _node_token: node_token,
                _attitude: (subscriber, subscription_token),
                px4_times: times_rx,
                failures: 0,
            },
            Px4Attitude { latest },
        )))
    }

    /// PX4's clock readings, as its `vehicle_attitude` arrives.
    pub fn px4_times(&mut self) -> &mut tokio::sync::mpsc::Receiver<u64> {
        &mut self.px4_times
    }

    /// Publishes one output; a failure is counted and told once in a while.
    pub async fn publish(&mut self, output: RosOutput) {
        let unix_ns = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as i64);
        let result = match (output, self.ros2.as_mut(), self.px4.as_mut()) {
            (RosOutput::NavSatFix(m), Some(t), _) => {
                t.fix.put(m.to_cdr(CdrVersion::Xcdr1), unix_ns).await
            }
            (RosOutput::Pose(m), Some(t), _) => {
                t.pose.put(m.to_cdr(CdrVersion::Xcdr1), unix_ns).await
            }
            (RosOutput::Odometry(m), Some(t), _) => {
                t.odometry.put(m.to_cdr(CdrVersion::Xcdr1), unix_ns).await
            }
            (RosOutput::Px4(m), _, Some(px4)) => {
                let payload = m.to_cdr(px4.message, px4.cdr);
                px4.publisher.put(payload, unix_ns).await
            }
            _ => Ok(()),
        };
        if let Err(e) = result {
            self.failures += 1;
            if self.failures % 100 == 1 {
                tracing::warn!(error = %e, failures = self.failures, "onboard Zenoh publish failed");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn px4_s_quaternion_is_read_as_ned_euler_angles() {
        // Heading east (yaw 90 degrees from north), level.
        let h = std::f64::consts::FRAC_PI_4;
        let a = attitude_of([h.cos() as f32, 0.0, 0.0, h.sin() as f32]).expect("valid");
        assert!((a.yaw_from_north() - std::f64::consts::FRAC_PI_2).abs() < 1e-6);
        assert!(a.roll.abs() < 1e-6 && a.pitch.abs() < 1e-6);
        // ENU yaw of east is 0.
        assert!(a.yaw.abs() < 1e-6);
        assert!(
            attitude_of([0.0; 4]).is_none(),
            "PX4's zero quaternion before alignment"
        );
    }
}
