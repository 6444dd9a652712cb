//! How long a writer waits for another's lock: the store sets it and the
//! error that reports a lock held past it names it.

/// How long a writer waits for another's lock before it gives up.
pub const BUSY_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(5);
