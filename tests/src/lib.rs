//! Helpers shared by the cross-crate tests and benches in `tests/`.

use std::sync::atomic::{AtomicU16, Ordering};

pub mod fleet;
pub mod programs;

/// Ports each process may hand out, in its own block below the kernel's
/// ephemeral range (32768 and up), so a port it hands out is never one the
/// kernel just gave a connection.
const BLOCK: u16 = 100;
const FIRST_PORT: u16 = 10_000;
const BLOCKS: u32 = 200;

/// A Zenoh endpoint on a loopback port that no other caller in this process
/// has been given, and that nothing held when it was handed out.
///
/// Binding port 0 and dropping the socket lets the kernel give the same port
/// to the next test that asks; here each call takes the next port of the
/// process's own block instead.
pub fn loopback_endpoint() -> String {
    format!("tcp/127.0.0.1:{}", loopback_port())
}

/// A loopback port free for TCP and UDP alike, from the same block (MAVLink
/// tests listen on UDP).
pub fn loopback_port() -> u16 {
    static NEXT: AtomicU16 = AtomicU16::new(0);
    let base = FIRST_PORT + (std::process::id() % BLOCKS) as u16 * BLOCK;
    for _ in 0..BLOCK {
        let port = base + NEXT.fetch_add(1, Ordering::Relaxed) % BLOCK;
        if std::net::TcpListener::bind(("127.0.0.1", port)).is_ok()
            && std::net::UdpSocket::bind(("127.0.0.1", port)).is_ok()
        {
            return port;
        }
    }
    panic!("no free loopback port in {base}..{}", base + BLOCK);
}

/// pymavlink, from the Python package index (`cargo xtask test` installs it
/// and says where in `TOWERNAV_PYTHONPATH`); `None` where it is missing and
/// nobody asked for it.
pub fn pymavlink() -> Option<std::ffi::OsString> {
    let path = std::env::var_os("TOWERNAV_PYTHONPATH");
    let found = std::process::Command::new("python3")
        .args(["-c", "import pymavlink"])
        .env("PYTHONPATH", path.clone().unwrap_or_default())
        .status()
        .is_ok_and(|s| s.success());
    match (found, path) {
        (true, path) => Some(path.unwrap_or_default()),
        (false, Some(path)) => panic!("pymavlink is not importable from {path:?}"),
        (false, None) => None,
    }
}

/// A Python module by name from `TOWERNAV_PYTHONPATH` (as [`pymavlink`]
/// finds it): that path, or `None` where it is missing and nobody asked for it.
pub fn python_module(module: &str) -> Option<std::ffi::OsString> {
    let path = std::env::var_os("TOWERNAV_PYTHONPATH");
    let found = std::process::Command::new("python3")
        .args(["-c", &format!("import {module}")])
        .env("PYTHONPATH", path.clone().unwrap_or_default())
        .status()
        .is_ok_and(|s| s.success());
    match (found, path) {
        (true, path) => Some(path.unwrap_or_default()),
        (false, Some(path)) => panic!("{module} is not importable from {path:?}"),
        (false, None) => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_two_callers_get_one_port() {
        let ports: std::collections::HashSet<String> =
            (0..50).map(|_| loopback_endpoint()).collect();
        assert_eq!(ports.len(), 50);
    }
}
