//! The one Zenoh session config every towernav node uses.
//!
//! Zenoh's default peer multicasts its scouting and listens on every interface;
//! towernav turns both off and talks only to the endpoints it is given.
//! With [`Credentials`], links are mutual TLS and the fleet's access rules apply.

use crate::security::Credentials;

#[derive(Debug, thiserror::Error)]
pub enum SessionConfigError {
    #[error("zenoh endpoint {endpoint:?} is not valid: {reason}")]
    Endpoint { endpoint: String, reason: String },
    #[error("zenoh config key {key}: {reason}")]
    Key { key: &'static str, reason: String },
    #[error(
        "zenoh endpoint {endpoint:?}: with fleet credentials every link is tls/<host>:<port> (plain tcp would bypass them)"
    )]
    PlainWithCredentials { endpoint: String },
}

/// Where a node listens and what it connects to, e.g. `tcp/127.0.0.1:7447`,
/// and, on a secured fleet, its credentials (then every endpoint is `tls/`).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Endpoints {
    pub listen: Vec<String>,
    pub connect: Vec<String>,
    pub security: Option<Credentials>,
}

/// A peer-mode config with multicast scouting off and only the given endpoints.
/// (Gossip stays on: it travels over links we opened, and zenoh needs it to de-duplicate.)
/// Samples carry the sender's timestamp, so receivers can tell their age.
pub fn session_config(endpoints: &Endpoints) -> Result<zenoh::Config, SessionConfigError> {
    config_for("peer", endpoints)
}

/// A client of a router: it talks only through the router it connects to
/// (the mode for edges and ground stations of a fleet behind a router).
pub fn client_config(endpoints: &Endpoints) -> Result<zenoh::Config, SessionConfigError> {
    config_for("client", endpoints)
}

/// A router for a fleet: edges and ground stations connect to its `listen`
/// endpoints; multicast scouting off, as everywhere.
pub fn router_config(endpoints: &Endpoints) -> Result<zenoh::Config, SessionConfigError> {
    config_for("router", endpoints)
}

fn config_for(mode: &str, endpoints: &Endpoints) -> Result<zenoh::Config, SessionConfigError> {
    for endpoint in endpoints.listen.iter().chain(&endpoints.connect) {
        endpoint
            .parse::<zenoh::config::EndPoint>()
            .map_err(|e| SessionConfigError::Endpoint {
                endpoint: endpoint.clone(),
                reason: e.to_string(),
            })?;
        if endpoints.security.is_some() && !endpoint.starts_with("tls/") {
            return Err(SessionConfigError::PlainWithCredentials {
                endpoint: endpoint.clone(),
            });
        }
    }
    let mut config = zenoh::Config::default();
    let json = |v: &[String]| serde_json::to_string(v).unwrap_or_else(|_| "[]".into());
    let mut settings: Vec<(&'static str, String)> = vec![
        ("mode", format!("{mode:?}")),
        ("timestamping/enabled", "true".into()),
        ("scouting/multicast/enabled", "false".into()),
        // Opening does not wait for the configured peers: a caller that needs
        // one waits for it and says so itself, rather than zenoh warning
        // ("scouting delay elapsed") whenever a loaded machine connects slowly.
        ("open/return_conditions/connect_scouted", "false".into()),
        ("listen/endpoints", json(&endpoints.listen)),
        ("connect/endpoints", json(&endpoints.connect)),
    ];
    if let Some(credentials) = &endpoints.security {
        settings.extend(credentials.settings());
    }
    for (key, value) in settings {
        config
            .insert_json5(key, &value)
            .map_err(|e| SessionConfigError::Key {
                key,
                reason: e.to_string(),
            })?;
    }
    Ok(config)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn multicast_is_off_and_endpoints_are_ours() {
        let config = session_config(&Endpoints {
            listen: vec!["tcp/127.0.0.1:17447".into()],
            connect: vec![],
            ..Default::default()
        })
        .expect("config");
        let text = format!("{config}");
        assert!(text.contains("127.0.0.1:17447"), "{text}");
        let multicast = config.get_json("scouting/multicast/enabled").expect("key");
        assert_eq!(multicast, "false");
        // No wait for peers at open, so no scouting-delay warning on a slow connect.
        let wait = config
            .get_json("open/return_conditions/connect_scouted")
            .expect("key");
        assert_eq!(wait, "false");
        let router = router_config(&Endpoints::default()).expect("config");
        assert_eq!(router.get_json("mode").expect("key"), "\"router\"");
        assert_eq!(
            router.get_json("scouting/multicast/enabled").expect("key"),
            "false"
        );
    }

    #[test]
    fn a_bad_endpoint_is_named() {
        let err = session_config(&Endpoints {
            listen: vec![],
            connect: vec!["nonsense".into()],
            ..Default::default()
        })
        .expect_err("must refuse");
        assert!(err.to_string().contains("nonsense"));
    }
}
