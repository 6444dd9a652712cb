use towernav_protocol::session::SessionConfigError;

#[derive(Debug, thiserror::Error)]
pub enum ShellError {
    #[error(transparent)]
    Config(#[from] SessionConfigError),
    #[error("zenoh: {what}: {reason}")]
    Zenoh { what: String, reason: String },
    #[error(transparent)]
    Encode(#[from] towernav_protocol::EncodeError),
    #[error("landmarks: {0}")]
    Landmarks(String),
    #[error("edge daemon: {0}")]
    Daemon(String),
    #[error(transparent)]
    Detector(#[from] towernav_onnx::OnnxError),
}

impl ShellError {
    pub fn zenoh(what: impl Into<String>, reason: impl std::fmt::Display) -> Self {
        Self::Zenoh {
            what: what.into(),
            reason: reason.to_string(),
        }
    }
}
