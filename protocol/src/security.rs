//! Who may say what on a fleet's link.
//!
//! Every node holds a certificate signed by the fleet's own CA and links are
//! mutual TLS, so a peer without one is refused at connect. Zenoh's access
//! control then names, by certificate, what each node may send: ground
//! stations and routers anything; an edge only its own UAV's outgoing topics
//! and liveliness token. The rules are built here, beside the keys they name.
//!
//! A node's credentials are one folder (`towernav-fleet issue` writes it):
//! `ca.pem`, `node.pem`, `node.key` and `roster.toml`, the fleet's nodes.
//!
//! The rules name certificates, not nodes: each certificate's common name is
//! `<node>#<serial>`, the serial counted up by the CA for every certificate it
//! signs. Re-issuing or revoking a node leaves its earlier certificates out of
//! every rule for good, since no later roster can name their serials again,
//! and the access control denies whatever no rule allows.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

use crate::ids::NodeId;
use crate::keys::{Keys, Topic};

/// The fleet CA's certificate in a node's credentials folder.
pub const CA_FILE: &str = "ca.pem";
/// The node's own certificate.
pub const CERT_FILE: &str = "node.pem";
/// The node's private key.
pub const KEY_FILE: &str = "node.key";
/// The fleet's nodes and their roles.
pub const ROSTER_FILE: &str = "roster.toml";

#[derive(Debug, thiserror::Error)]
pub enum SecurityError {
    #[error("reading {path}: {source}")]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {reason}")]
    Roster { path: String, reason: String },
    #[error("{path}: no node named {name:?} in the roster")]
    NotInRoster { path: PathBuf, name: String },
    #[error("{path}: {reason}")]
    Certificate { path: PathBuf, reason: String },
}

/// What a node is allowed to do.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Role {
    /// Owns the landmarks; sends corrections and landmark changes.
    GroundStation,
    /// Relays for everyone; trusted as a ground station is.
    Router,
    /// One UAV: publishes its own poses, tracks, status and previews.
    Edge,
}

/// One node of the fleet, by its certificate's common name.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RosterNode {
    pub name: String,
    pub role: Role,
    /// An edge's UAV id (its keys are `towernav/<fleet>/uav/<uav>/...`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uav: Option<String>,
    /// Names and addresses its certificate is valid for (peers check them on connect).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub hosts: Vec<String>,
    /// Its current certificate; `None` in a roster from before certificates
    /// were named by serial (the rules then name the node itself).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub certificate: Option<CertificateInfo>,
}

/// One certificate the fleet CA signed.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CertificateInfo {
    /// `<node>#<serial>`: what the access rules name.
    pub common_name: String,
    pub serial: u64,
    /// SHA-256 of the DER certificate, hex.
    pub sha256: String,
    /// Last valid day, UTC, `YYYY-MM-DD`.
    pub expires: String,
}

impl CertificateInfo {
    /// The common name of `node`'s certificate with `serial`.
    pub fn common_name_of(node: &str, serial: u64) -> String {
        format!("{node}#{serial}")
    }
}

/// A certificate that no longer has any right: revoked, or superseded by a
/// newer one of the same node.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RetiredCertificate {
    pub node: String,
    #[serde(flatten)]
    pub certificate: CertificateInfo,
    /// `revoked` or `superseded`.
    pub why: String,
    /// The day it was retired, UTC, `YYYY-MM-DD`.
    pub on: String,
}

/// The fleet's nodes: every node enforces the rules built from it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Roster {
    pub fleet: String,
    /// The serial the CA signs its next certificate with.
    #[serde(default = "first_serial")]
    pub next_serial: u64,
    #[serde(default, rename = "node")]
    pub nodes: Vec<RosterNode>,
    /// Certificates that lost their rights, kept so that `list` shows them
    /// and no serial is used twice.
    #[serde(default, rename = "retired", skip_serializing_if = "Vec::is_empty")]
    pub retired: Vec<RetiredCertificate>,
}

fn first_serial() -> u64 {
    1
}

const ALL_MESSAGES: [&str; 9] = [
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "declare_queryable",
    "reply",
    "liveliness_token",
    "declare_liveliness_subscriber",
    "liveliness_query",
];

/// What an edge publishes under its own UAV's keys (not `correction`, which
/// only a ground station sends).
const EDGE_TOPICS: [Topic; 7] = [
    Topic::Pose,
    Topic::Tracks,
    Topic::Status,
    Topic::CorrectionAck,
    Topic::Detections,
    Topic::Preview,
    Topic::Truth,
];

impl Roster {
    /// Parses and checks a roster; `origin` names it in errors.
    pub fn from_toml(text: &str, origin: &str) -> Result<Self, SecurityError> {
        let bad = |reason: String| SecurityError::Roster {
            path: origin.to_owned(),
            reason,
        };
        let roster: Roster = toml::from_str(text).map_err(|e| bad(e.to_string()))?;
        roster.check().map_err(bad)?;
        Ok(roster)
    }

    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_default()
    }

    /// Names unique and usable as ids; every edge has a UAV, and only edges.
    pub fn check(&self) -> Result<(), String> {
        NodeId::new(self.fleet.clone()).map_err(|e| format!("fleet: {e}"))?;
        let mut names = BTreeSet::new();
        let mut uavs = BTreeSet::new();
        for node in &self.nodes {
            NodeId::new(node.name.clone()).map_err(|e| format!("node name: {e}"))?;
            if !names.insert(node.name.as_str()) {
                return Err(format!("node {:?} is listed twice", node.name));
            }
            match (node.role, &node.uav) {
                (Role::Edge, Some(uav)) => {
                    NodeId::new(uav.clone())
                        .map_err(|e| format!("node {:?}: uav: {e}", node.name))?;
                    if !uavs.insert(uav.as_str()) {
                        return Err(format!("uav {uav:?} has two edges"));
                    }
                }
                (Role::Edge, None) => {
                    return Err(format!("edge {:?} has no uav", node.name));
                }
                (_, Some(_)) => {
                    return Err(format!("node {:?}: only an edge has a uav", node.name));
                }
                (_, None) => {}
            }
        }
        let mut common_names = BTreeSet::new();
        for node in &self.nodes {
            if let Some(cert) = &node.certificate {
                if cert.common_name != CertificateInfo::common_name_of(&node.name, cert.serial) {
                    return Err(format!(
                        "node {:?}: certificate {:?} is not named <node>#<serial>",
                        node.name, cert.common_name
                    ));
                }
                if cert.serial >= self.next_serial {
                    return Err(format!(
                        "node {:?}: serial {} is not below next_serial {}",
                        node.name, cert.serial, self.next_serial
                    ));
                }
            }
            common_names.insert(Self::common_name(node));
        }
        for retired in &self.retired {
            if common_names.contains(retired.certificate.common_name.as_str()) {
                return Err(format!(
                    "certificate {:?} is both current and retired",
                    retired.certificate.common_name
                ));
            }
        }
        Ok(())
    }

    pub fn node(&self, name: &str) -> Option<&RosterNode> {
        self.nodes.iter().find(|n| n.name == name)
    }

    /// The common name the rules give rights to for `node`: its current
    /// certificate's, or its name in a roster without certificates.
    pub fn common_name(node: &RosterNode) -> &str {
        node.certificate
            .as_ref()
            .map_or(node.name.as_str(), |c| c.common_name.as_str())
    }

    /// Zenoh's `access_control` section: denied unless allowed. Ground
    /// stations and routers may do anything. An edge may send only on its own
    /// UAV's outgoing keys and liveliness token, and is sent only the
    /// landmarks and its own UAV's keys (its corrections, the queries on its
    /// pose cache): nothing of another UAV. What it may hear besides is
    /// interest (others' subscriptions and queries), never data, so that its
    /// publications find their subscribers.
    pub fn access_control(&self) -> Value {
        let fleet = &self.fleet;
        let whole_fleet = [
            format!("towernav/{fleet}/**"),
            format!("towernav/{fleet}/**/@adv/**"),
        ];
        let names = |roles: &[Role]| -> Vec<&str> {
            self.nodes
                .iter()
                .filter(|n| roles.contains(&n.role))
                .map(Self::common_name)
                .collect()
        };
        let trusted = names(&[Role::GroundStation, Role::Router]);
        let edges = names(&[Role::Edge]);
        let interest = [
            "declare_subscriber",
            "declare_liveliness_subscriber",
            "query",
            "liveliness_query",
        ];
        let mut rules = vec![
            json!({
                "id": "anything",
                "permission": "allow",
                "flows": ["ingress", "egress"],
                "messages": ALL_MESSAGES,
                "key_exprs": whole_fleet,
            }),
            json!({
                "id": "edges-hear-interest",
                "permission": "allow",
                "flows": ["egress"],
                "messages": interest,
                "key_exprs": whole_fleet,
            }),
            json!({
                "id": "landmarks-to-edges",
                "permission": "allow",
                "flows": ["egress"],
                "messages": ["put", "delete", "reply", "declare_queryable"],
                "key_exprs": [format!("towernav/{fleet}/landmarks/**")],
            }),
            json!({
                "id": "edges-listen",
                "permission": "allow",
                "flows": ["ingress"],
                "messages": interest,
                "key_exprs": whole_fleet,
            }),
        ];
        let mut subjects = Vec::new();
        let mut policies = Vec::new();
        if !trusted.is_empty() {
            subjects.push(json!({"id": "trusted", "cert_common_names": trusted}));
            policies.push(json!({"rules": ["anything"], "subjects": ["trusted"]}));
        }
        if !edges.is_empty() {
            subjects.push(json!({"id": "edges", "cert_common_names": edges}));
            policies.push(json!({
                "rules": ["edges-hear-interest", "landmarks-to-edges", "edges-listen"],
                "subjects": ["edges"],
            }));
        }
        let keys = NodeId::new(fleet.clone()).ok().map(Keys::new);
        for node in self.nodes.iter().filter(|n| n.role == Role::Edge) {
            let (Some(keys), Some(uav)) =
                (&keys, node.uav.clone().and_then(|u| NodeId::new(u).ok()))
            else {
                continue;
            };
            let mut own: Vec<String> = EDGE_TOPICS.iter().map(|t| keys.uav(&uav, *t)).collect();
            // zenoh-ext's advanced publisher: its cache, heartbeat and presence.
            own.push(format!("{}/@adv/**", keys.uav(&uav, Topic::Pose)));
            own.push(keys.alive(&uav));
            let id = format!("own-keys-{}", node.name);
            rules.push(json!({
                "id": id,
                "permission": "allow",
                "flows": ["ingress"],
                "messages": ["put", "delete", "declare_queryable", "reply", "liveliness_token"],
                "key_exprs": own,
            }));
            let uav_root = format!("towernav/{fleet}/uav/{uav}");
            let to = format!("to-{}", node.name);
            rules.push(json!({
                "id": to,
                "permission": "allow",
                "flows": ["egress"],
                "messages": ALL_MESSAGES,
                "key_exprs": [
                    format!("{uav_root}/**"),
                    format!("{uav_root}/*/@adv/**"),
                    keys.alive(&uav),
                ],
            }));
            subjects.push(json!({"id": id, "cert_common_names": [Self::common_name(node)]}));
            policies.push(json!({"rules": [id, to], "subjects": [id]}));
        }
        json!({
            "enabled": true,
            "default_permission": "deny",
            "rules": rules,
            "subjects": subjects,
            "policies": policies,
        })
    }
}

/// The subject common name of the PEM certificate at `path`.
fn certificate_common_name(path: &Path) -> Result<String, SecurityError> {
    let bad = |reason: String| SecurityError::Certificate {
        path: path.to_owned(),
        reason,
    };
    let bytes = std::fs::read(path).map_err(|source| SecurityError::Read {
        path: path.to_owned(),
        source,
    })?;
    let (_, pem) = x509_parser::pem::parse_x509_pem(&bytes)
        .map_err(|e| bad(format!("not a PEM certificate: {e}")))?;
    let cert = pem
        .parse_x509()
        .map_err(|e| bad(format!("not an X.509 certificate: {e}")))?;
    let common_name = cert
        .subject()
        .iter_common_name()
        .next()
        .and_then(|cn| cn.as_str().ok())
        .ok_or_else(|| bad("the certificate has no common name".into()))?;
    Ok(common_name.to_owned())
}

fn read_roster(dir: &Path) -> Result<(PathBuf, Roster), SecurityError> {
    let path = dir.join(ROSTER_FILE);
    let text = std::fs::read_to_string(&path).map_err(|source| SecurityError::Read {
        path: path.clone(),
        source,
    })?;
    let roster = Roster::from_toml(&text, &path.display().to_string())?;
    Ok((path, roster))
}

/// A node's credentials folder, read and checked.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Credentials {
    dir: PathBuf,
    name: String,
    roster: Roster,
}

impl Credentials {
    /// Reads `dir`'s roster and checks the certificate, key and CA are there.
    /// `name` is the node's certificate name (the roster entry it must match).
    pub fn load(dir: &Path, name: &str) -> Result<Self, SecurityError> {
        for file in [CA_FILE, CERT_FILE, KEY_FILE] {
            let path = dir.join(file);
            std::fs::metadata(&path).map_err(|source| SecurityError::Read { path, source })?;
        }
        let (path, roster) = read_roster(dir)?;
        let Some(node) = roster.node(name) else {
            return Err(SecurityError::NotInRoster {
                path,
                name: name.to_owned(),
            });
        };
        let cert_path = dir.join(CERT_FILE);
        let common_name = certificate_common_name(&cert_path)?;
        let expected = Roster::common_name(node);
        if common_name != expected {
            return Err(SecurityError::Certificate {
                path: cert_path,
                reason: format!(
                    "this is certificate {common_name:?}, but the roster gives {name}'s rights to \
                     {expected:?}: the folder is out of date (copy nodes/{name}/ from the CA again)"
                ),
            });
        }
        Ok(Self {
            dir: dir.to_owned(),
            name: name.to_owned(),
            roster,
        })
    }

    /// An edge's credentials, its name being the roster's edge for `uav`.
    pub fn load_edge(dir: &Path, uav: &str) -> Result<Self, SecurityError> {
        let (path, roster) = read_roster(dir)?;
        match roster
            .nodes
            .iter()
            .find(|n| n.role == Role::Edge && n.uav.as_deref() == Some(uav))
        {
            Some(node) => Self::load(dir, &node.name.clone()),
            None => Err(SecurityError::Roster {
                path: path.display().to_string(),
                reason: format!(
                    "no edge for uav {uav:?} (towernav-fleet issue --role edge --uav {uav})"
                ),
            }),
        }
    }

    /// A ground station's credentials: the node named `name`, or else the
    /// roster's only ground station.
    pub fn load_ground_station(dir: &Path, name: Option<&str>) -> Result<Self, SecurityError> {
        if let Some(name) = name {
            return Self::load(dir, name);
        }
        let (path, roster) = read_roster(dir)?;
        let mut stations = roster
            .nodes
            .iter()
            .filter(|n| n.role == Role::GroundStation);
        match (stations.next(), stations.next()) {
            (Some(node), None) => Self::load(dir, &node.name.clone()),
            _ => Err(SecurityError::Roster {
                path: path.display().to_string(),
                reason: "the roster has several ground stations (or none): name this one".into(),
            }),
        }
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    pub fn roster(&self) -> &Roster {
        &self.roster
    }

    /// Zenoh config settings: mutual TLS with this folder's files, links
    /// closed when a certificate expires, and the roster's access control.
    pub fn settings(&self) -> Vec<(&'static str, String)> {
        let file = |f: &str| {
            serde_json::to_string(&self.dir.join(f).display().to_string()).unwrap_or_default()
        };
        vec![
            ("transport/link/tls/root_ca_certificate", file(CA_FILE)),
            ("transport/link/tls/listen_certificate", file(CERT_FILE)),
            ("transport/link/tls/listen_private_key", file(KEY_FILE)),
            ("transport/link/tls/connect_certificate", file(CERT_FILE)),
            ("transport/link/tls/connect_private_key", file(KEY_FILE)),
            ("transport/link/tls/enable_mtls", "true".into()),
            ("transport/link/tls/close_link_on_expiration", "true".into()),
            // Nothing but TLS is opened or accepted, whatever gossip offers.
            ("transport/link/protocols", r#"["tls"]"#.into()),
            ("access_control", self.roster.access_control().to_string()),
        ]
    }
}

#[cfg(test)]
#[path = "security_tests.rs"]
mod tests;
