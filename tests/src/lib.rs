//! Helpers shared by the cross-crate tests and benches in `tests/`.

pub mod fleet;

/// A Zenoh endpoint on a loopback port that was free a moment ago.
pub fn loopback_endpoint() -> String {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free loopback port");
    format!("tcp/127.0.0.1:{port}")
}
