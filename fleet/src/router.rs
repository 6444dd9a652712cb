//! A `zenohd` config for a fleet's router: the same mutual TLS and access
//! rules as every node's session (`towernav_protocol::session`), as a file.

use serde_json::{Map, Value, json};
use towernav_protocol::security::Credentials;

/// `zenohd -c <file>`'s config: router mode, multicast scouting off, listening
/// on `listen` (all `tls/`), with `credentials`' TLS files and access rules.
pub fn router_config(credentials: &Credentials, listen: &[String]) -> Value {
    let mut config = json!({
        "mode": "router",
        "listen": { "endpoints": listen },
        "scouting": { "multicast": { "enabled": false } },
        "timestamping": { "enabled": { "router": true, "peer": true, "client": true } },
    });
    for (path, value) in credentials.settings() {
        let value = serde_json::from_str(&value).unwrap_or(Value::String(value));
        insert(&mut config, path, value);
    }
    config
}

/// Sets `a/b/c` in nested objects.
fn insert(config: &mut Value, path: &str, value: Value) {
    let mut node = config;
    let mut parts = path.split('/').peekable();
    while let Some(part) = parts.next() {
        let Value::Object(map) = node else { return };
        if parts.peek().is_none() {
            map.insert(part.to_owned(), value);
            return;
        }
        node = map
            .entry(part.to_owned())
            .or_insert_with(|| Value::Object(Map::new()));
    }
}
