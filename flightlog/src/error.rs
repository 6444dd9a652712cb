use std::path::{Path, PathBuf};

/// What is wrong with a log, and in which file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("flight log {}: {reason}", path.as_ref().map_or_else(|| "(bytes)".into(), |p| p.display().to_string()))]
pub struct LogError {
    pub path: Option<PathBuf>,
    pub reason: String,
}

impl LogError {
    pub fn new(path: &Path, reason: String) -> Self {
        Self {
            path: Some(path.to_path_buf()),
            reason,
        }
    }

    pub(crate) fn bare(reason: String) -> Self {
        Self { path: None, reason }
    }

    /// The same error, said of the file at `path`.
    pub fn in_file(self, path: &Path) -> Self {
        Self {
            path: Some(path.to_path_buf()),
            ..self
        }
    }
}
