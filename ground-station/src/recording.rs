//! Session recording and replay as MCAP, the robotics log standard: one
//! channel per Zenoh key, the payloads exactly as they crossed the wire (JSON),
//! so Foxglove or `mcap cat` can read a towernav session too.
//!
//! Liveliness is recorded on the `alive` key with the payload `put` or `delete`.
//! The landmarks the recording started with go first, on [`LANDMARKS_CHANNEL`],
//! so a replay shows the towers it was flown with, wherever it is opened.
//!
//! A replay is a [`ReplayPlayer`]: the recording and a clock the app moves
//! each frame (paused, faster, sought), with no thread of its own.
//!
//! Messages go straight into the file, not into compressed chunks: a
//! recording cut short (the ground station killed, the disk pulled) keeps
//! every message written before the cut, and [`read`] replays up to the last
//! whole one, saying where the recording ends.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use towernav_protocol::{Keys, LandmarkRecord};

use crate::events::{NetEvent, decode_alive, decode_sample};

#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    #[error("recording {path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("recording {path}: the landmarks snapshot: {reason}")]
    Landmarks { path: PathBuf, reason: String },
    #[error("recording {path}: not an MCAP recording (it does not start with MCAP's magic bytes)")]
    NotMcap { path: PathBuf },
    #[error("recording {path}: {source}")]
    Mcap {
        path: PathBuf,
        source: mcap::McapError,
    },
}

/// Payloads of liveliness changes in a recording.
pub const ALIVE_PUT: &[u8] = b"put";
pub const ALIVE_DELETE: &[u8] = b"delete";
/// The recording's own channel (not a network key) for the landmarks it started with.
pub const LANDMARKS_CHANNEL: &str = "towernav-recording/landmarks";

pub struct Recorder {
    writer: mcap::Writer<BufWriter<File>>,
    channels: HashMap<String, u16>,
    path: PathBuf,
    sequence: u32,
}

impl Recorder {
    /// A new recording at `path`; an existing file is refused, never overwritten.
    pub fn create(path: &Path) -> Result<Self, RecordingError> {
        let file = File::create_new(path).map_err(|source| RecordingError::Io {
            path: path.into(),
            source,
        })?;
        let writer = mcap::WriteOptions::new()
            .use_chunks(false)
            .create(BufWriter::new(file))
            .map_err(|source| RecordingError::Mcap {
                path: path.into(),
                source,
            })?;
        Ok(Self {
            writer,
            channels: HashMap::new(),
            path: path.into(),
            sequence: 0,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn messages(&self) -> u32 {
        self.sequence
    }

    fn err(&self) -> impl Fn(mcap::McapError) -> RecordingError + '_ {
        |source| RecordingError::Mcap {
            path: self.path.clone(),
            source,
        }
    }

    /// One sample, stamped with the ground station's receive time.
    pub fn write(
        &mut self,
        key: &str,
        payload: &[u8],
        log_time_ns: u64,
    ) -> Result<(), RecordingError> {
        let channel_id = match self.channels.get(key) {
            Some(&id) => id,
            None => {
                let id = self
                    .writer
                    .add_channel(0, key, "json", &BTreeMap::new())
                    .map_err(|source| RecordingError::Mcap {
                        path: self.path.clone(),
                        source,
                    })?;
                self.channels.insert(key.to_owned(), id);
                id
            }
        };
        self.sequence += 1;
        let header = mcap::records::MessageHeader {
            channel_id,
            sequence: self.sequence,
            log_time: log_time_ns,
            publish_time: log_time_ns,
        };
        self.writer
            .write_to_known_channel(&header, payload)
            .map_err(self.err())
    }

    /// The landmarks in force, as JSON on [`LANDMARKS_CHANNEL`].
    pub fn write_landmarks(
        &mut self,
        landmarks: &[LandmarkRecord],
        log_time_ns: u64,
    ) -> Result<(), RecordingError> {
        let json = serde_json::to_vec(landmarks).map_err(|e| RecordingError::Landmarks {
            path: self.path.clone(),
            reason: e.to_string(),
        })?;
        self.write(LANDMARKS_CHANNEL, &json, log_time_ns)
    }

    /// Writes the summary and index; a recording not finished is still readable up to its last chunk.
    pub fn finish(mut self) -> Result<u32, RecordingError> {
        self.writer.finish().map_err(self.err())?;
        Ok(self.sequence)
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct RecordedSample {
    pub log_time_ns: u64,
    pub key: String,
    pub payload: Vec<u8>,
}

impl RecordedSample {
    /// The event this sample stood for when it was live.
    pub fn event(&self) -> Option<NetEvent> {
        if self.key == LANDMARKS_CHANNEL {
            return None;
        }
        if Keys::parse_alive(&self.key).is_ok() {
            return Some(decode_alive(&self.key, self.payload != ALIVE_DELETE));
        }
        decode_sample(&self.key, &self.payload)
    }
}

/// A recording as read: its messages, and where it ends early if it does.
#[derive(Debug, Clone, Default)]
pub struct Recording {
    pub samples: Vec<RecordedSample>,
    /// Why the file stops before its end (a recording cut short): every
    /// whole message before the cut is in `samples`.
    pub cut_short: Option<String>,
}

/// MCAP's magic, at the start of every recording.
const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// Every whole message of a recording, in log-time order. A file that is
/// not MCAP is refused; one cut short gives what it holds before the cut.
pub fn read(path: &Path) -> Result<Recording, RecordingError> {
    let bytes = std::fs::read(path).map_err(|source| RecordingError::Io {
        path: path.into(),
        source,
    })?;
    // Cut inside the magic itself: a recording that never got a message.
    if bytes.len() < MCAP_MAGIC.len() && MCAP_MAGIC.starts_with(&bytes) {
        return Ok(Recording {
            samples: Vec::new(),
            cut_short: Some(format!(
                "{} ends after {} bytes, before any message",
                path.display(),
                bytes.len()
            )),
        });
    }
    if !bytes.starts_with(MCAP_MAGIC) {
        return Err(RecordingError::NotMcap { path: path.into() });
    }
    let stream = mcap::MessageStream::new(&bytes).map_err(|source| RecordingError::Mcap {
        path: path.into(),
        source,
    })?;
    let mut samples: Vec<RecordedSample> = Vec::new();
    let mut cut_short = None;
    for message in stream {
        match message {
            Ok(message) => samples.push(RecordedSample {
                log_time_ns: message.log_time,
                key: message.channel.topic.clone(),
                payload: message.data.into_owned(),
            }),
            Err(e) => {
                let last = samples.iter().map(|s| s.log_time_ns).max();
                let first = samples.iter().map(|s| s.log_time_ns).min();
                let span = match (first, last) {
                    (Some(a), Some(b)) => format!(", {:.1} s of it", (b - a) as f64 * 1e-9),
                    _ => String::new(),
                };
                cut_short = Some(format!(
                    "{} ends early ({e}): replaying its first {} messages{span}",
                    path.display(),
                    samples.len()
                ));
                break;
            }
        }
    }
    samples.sort_by_key(|s| s.log_time_ns);
    Ok(Recording { samples, cut_short })
}

/// The landmarks a recording started with, if it carries them.
pub fn landmarks(
    path: &Path,
    samples: &[RecordedSample],
) -> Result<Option<Vec<LandmarkRecord>>, RecordingError> {
    samples
        .iter()
        .find(|s| s.key == LANDMARKS_CHANNEL)
        .map(|s| {
            serde_json::from_slice(&s.payload).map_err(|e| RecordingError::Landmarks {
                path: path.into(),
                reason: e.to_string(),
            })
        })
        .transpose()
}

/// A recording played back on a clock the app moves (pure: wall time is
/// passed in). Seeking back starts the events over: the app clears what it
/// knew and the next [`ReplayPlayer::advance`] replays up to the new position.
pub struct ReplayPlayer {
    samples: Vec<RecordedSample>,
    /// The next sample to hand out.
    cursor: usize,
    t0_ns: u64,
    /// Recording time since its first message.
    position_s: f64,
    duration_s: f64,
    /// 1 = as recorded; 0 = everything at once.
    pub speed: f64,
    pub paused: bool,
    last_wall_s: Option<f64>,
    /// Said once, with the first events: where a recording cut short ends.
    notice: Option<String>,
}

impl ReplayPlayer {
    /// The player of a recording as read, its cut (if any) told to the operator.
    pub fn of(recording: Recording, speed: f64) -> Self {
        Self {
            notice: recording.cut_short,
            ..Self::new(recording.samples, speed)
        }
    }

    pub fn new(samples: Vec<RecordedSample>, speed: f64) -> Self {
        let t0_ns = samples.first().map_or(0, |s| s.log_time_ns);
        let duration_s = samples
            .last()
            .map_or(0.0, |s| (s.log_time_ns - t0_ns) as f64 * 1e-9);
        Self {
            samples,
            cursor: 0,
            t0_ns,
            position_s: 0.0,
            duration_s,
            speed,
            paused: false,
            last_wall_s: None,
            notice: None,
        }
    }

    /// Where the replay is, seconds into the recording: the app's clock while it replays.
    pub fn position_s(&self) -> f64 {
        self.position_s
    }

    pub fn duration_s(&self) -> f64 {
        self.duration_s
    }

    pub fn finished(&self) -> bool {
        self.cursor == self.samples.len()
    }

    /// Moves the clock by the wall time since the last call (times the speed,
    /// unless paused) and returns the events now due, in order.
    pub fn advance(&mut self, wall_s: f64) -> Vec<NetEvent> {
        let dt = self
            .last_wall_s
            .map_or(0.0, |last| (wall_s - last).max(0.0));
        self.last_wall_s = Some(wall_s);
        if !self.paused {
            self.position_s = if self.speed > 0.0 {
                (self.position_s + dt * self.speed).min(self.duration_s)
            } else {
                self.duration_s
            };
        }
        let mut due: Vec<NetEvent> = self
            .notice
            .take()
            .map(NetEvent::Notice)
            .into_iter()
            .collect();
        while let Some(s) = self.samples.get(self.cursor) {
            if (s.log_time_ns - self.t0_ns) as f64 * 1e-9 > self.position_s {
                break;
            }
            due.extend(s.event());
            self.cursor += 1;
        }
        due
    }

    /// Jumps to `t_s` into the recording; true when that is backwards, and
    /// the app must forget what it was shown before the next advance.
    pub fn seek(&mut self, t_s: f64) -> bool {
        let t_s = t_s.clamp(0.0, self.duration_s);
        let back = t_s < self.position_s;
        if back {
            self.cursor = 0;
        }
        self.position_s = t_s;
        back
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::pose;
    use towernav_protocol::{NodeId, PoseEstimate, encode};

    #[test]
    fn a_recording_replays_the_same_events_in_order() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("session.mcap");
        let keys = Keys::new(NodeId::new("demo").expect("valid"));
        let uav = NodeId::new("uav1").expect("valid");
        let mut rec = Recorder::create(&path).expect("create");
        rec.write(&keys.alive(&uav), ALIVE_PUT, 5).expect("write");
        for seq in 0..3 {
            let p = pose("uav1", 30.52, 114.36, seq);
            rec.write(
                &keys.uav_key::<PoseEstimate>(&uav),
                &encode(&p).expect("encode"),
                10 + seq,
            )
            .expect("write");
        }
        rec.write(&keys.alive(&uav), ALIVE_DELETE, 20)
            .expect("write");
        assert_eq!(rec.finish().expect("finish"), 5);

        let samples = read(&path).expect("read").samples;
        let events: Vec<NetEvent> = samples.iter().filter_map(RecordedSample::event).collect();
        assert_eq!(events.len(), 5);
        assert!(matches!(&events[0], NetEvent::Alive { alive: true, .. }));
        assert!(matches!(&events[2], NetEvent::Pose(p) if p.seq == 1));
        assert!(matches!(&events[4], NetEvent::Alive { alive: false, .. }));
    }

    #[test]
    fn a_recording_cut_at_any_byte_replays_up_to_its_last_whole_message() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("whole.mcap");
        let keys = Keys::new(NodeId::new("demo").expect("valid"));
        let uav = NodeId::new("uav1").expect("valid");
        let mut rec = Recorder::create(&path).expect("create");
        for seq in 0..6 {
            let p = pose("uav1", 30.52, 114.36, seq);
            rec.write(
                &keys.uav_key::<PoseEstimate>(&uav),
                &encode(&p).expect("encode"),
                1_000_000_000 * (10 + seq),
            )
            .expect("write");
        }
        rec.finish().expect("finish");
        let whole = std::fs::read(&path).expect("bytes");
        let all = read(&path).expect("whole").samples;
        assert_eq!(all.len(), 6);
        let cut = dir.path().join("cut.mcap");
        let mut seen = std::collections::BTreeSet::new();
        for at in 0..whole.len() {
            std::fs::write(&cut, &whole[..at]).expect("cut");
            let got = read(&cut).unwrap_or_else(|e| panic!("cut at byte {at}: {e}"));
            // A prefix of the whole, in order, and the cut is said.
            assert_eq!(got.samples, all[..got.samples.len()], "cut at byte {at}");
            assert!(got.cut_short.is_some(), "cut at byte {at} not reported");
            seen.insert(got.samples.len());
        }
        // Every whole message before a cut is kept: each count appears.
        assert_eq!(seen, (0..=6).collect(), "message counts seen over all cuts");
        // The player says where it ends with its first events.
        let mut player = ReplayPlayer::of(read(&cut).expect("cut"), 0.0);
        let events = player.advance(0.0);
        assert!(
            matches!(&events[0], NetEvent::Notice(n) if n.contains("ends early")),
            "{events:?}"
        );
        assert_eq!(events.len(), 7);
    }

    #[test]
    fn a_recording_carries_its_landmarks_and_never_overwrites_a_file() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("session.mcap");
        let mut rec = Recorder::create(&path).expect("create");
        rec.write_landmarks(&crate::test_support::towers(), 1)
            .expect("landmarks");
        rec.finish().expect("finish");
        let samples = read(&path).expect("read").samples;
        let towers = landmarks(&path, &samples)
            .expect("decodes")
            .expect("carried");
        assert_eq!(towers, crate::test_support::towers());
        assert!(samples[0].event().is_none(), "not a network event");
        let err = Recorder::create(&path).err().expect("exists");
        assert!(err.to_string().contains("session.mcap"), "{err}");
        assert_eq!(
            read(&path).expect("intact").samples.len(),
            1,
            "left as it was"
        );
    }

    #[test]
    fn the_player_pauses_speeds_up_and_seeks_back_to_replay_from_the_start() {
        let samples: Vec<RecordedSample> = (0..10u64)
            .map(|i| RecordedSample {
                log_time_ns: 1_000_000_000 * (100 + i),
                key: Keys::new(NodeId::new("demo").expect("valid"))
                    .uav_key::<PoseEstimate>(&NodeId::new("uav1").expect("valid")),
                payload: encode(&pose("uav1", 30.52, 114.36, i)).expect("encode"),
            })
            .collect();
        let mut player = ReplayPlayer::new(samples, 1.0);
        assert_eq!(player.duration_s(), 9.0);
        let seqs = |events: Vec<NetEvent>| -> Vec<u64> {
            events
                .into_iter()
                .filter_map(|e| match e {
                    NetEvent::Pose(p) => Some(p.seq),
                    _ => None,
                })
                .collect()
        };
        assert_eq!(seqs(player.advance(50.0)), [0]);
        assert_eq!(seqs(player.advance(52.5)), [1, 2]);
        player.paused = true;
        assert!(seqs(player.advance(60.0)).is_empty(), "paused");
        player.paused = false;
        player.speed = 2.0;
        assert_eq!(
            seqs(player.advance(61.0)),
            [3, 4],
            "2 s of recording in 1 s"
        );
        assert!(player.seek(1.0), "backwards");
        assert_eq!(seqs(player.advance(61.0)), [0, 1], "from the start again");
        assert!(!player.seek(8.0));
        assert_eq!(seqs(player.advance(61.0)), [2, 3, 4, 5, 6, 7, 8]);
        assert_eq!(seqs(player.advance(100.0)), [9]);
        assert!(player.finished());
        assert_eq!(player.position_s(), 9.0, "stops at the end");
    }

    #[test]
    fn a_file_that_is_not_mcap_is_refused_with_its_path() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("notes.mcap");
        std::fs::write(&path, b"hello").expect("write");
        let err = read(&path).expect_err("not mcap");
        assert!(err.to_string().contains("notes.mcap"), "{err}");
    }
}
