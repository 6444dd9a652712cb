//! A JSON-lines log the daemon records into (poses, the autopilot's
//! positions): each line flushed as it is written, so a kill loses none and
//! a full disk is told at once, naming the file; the flight goes on without
//! the log.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::ShellError;

pub struct JsonlLog {
    what: &'static str,
    path: PathBuf,
    out: std::io::BufWriter<std::fs::File>,
}

impl JsonlLog {
    /// Creates (or empties) `path`; `what` names the log in messages.
    pub fn create(path: &Path, what: &'static str) -> Result<Self, ShellError> {
        let file = std::fs::File::create(path).map_err(|e| {
            ShellError::Daemon(format!("creating the {what} {}: {e}", path.display()))
        })?;
        Ok(Self {
            what,
            path: path.to_owned(),
            out: std::io::BufWriter::new(file),
        })
    }

    /// Writes one line. `false` when the file refused it: the error is in
    /// the log, and the caller stops writing to it.
    pub fn line(&mut self, value: &impl serde::Serialize) -> bool {
        let written = serde_json::to_writer(&mut self.out, value)
            .map_err(std::io::Error::other)
            .and_then(|()| self.out.write_all(b"\n"))
            .and_then(|()| self.out.flush());
        match written {
            Ok(()) => true,
            Err(e) => {
                tracing::error!(
                    file = %self.path.display(),
                    error = %e,
                    "the {} could not be written (disk full?); the flight goes on without it",
                    self.what
                );
                false
            }
        }
    }
}
