//! The fleet's own certificate authority, kept in one folder:
//!
//! - `ca.pem` and `ca.key`: the CA (keep `ca.key` at the ground, never on a vehicle);
//! - `roster.toml`: every node issued a certificate, with its role (the
//!   access rules every node enforces are built from it);
//! - `nodes/<name>/`: one node's credentials (`ca.pem`, `node.pem`,
//!   `node.key`, `roster.toml`), the folder copied to that node.
//!
//! Issuing or revoking a node rewrites every `nodes/*/roster.toml`, so the
//! whole `nodes/` tree is what gets handed out again.
//!
//! Every certificate gets the next serial and the common name
//! `<node>#<serial>`; the roster names each node's current one, and the
//! access rules give rights to those names only. A revoked or superseded
//! certificate is listed as retired and never named again.

use std::path::{Path, PathBuf};

use rcgen::{
    BasicConstraints, CertificateParams, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair,
    KeyUsagePurpose,
};
use time::{Duration, OffsetDateTime};
use towernav_protocol::security::{
    CA_FILE, CERT_FILE, CertificateInfo, KEY_FILE, ROSTER_FILE, RetiredCertificate, Role, Roster,
    RosterNode, SecurityError,
};

pub mod router;

/// The CA's private key, in the authority's folder only.
pub const CA_KEY_FILE: &str = "ca.key";
/// Where the nodes' credential folders go.
pub const NODES_DIR: &str = "nodes";

#[derive(Debug, thiserror::Error)]
pub enum FleetError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{what}: {source}")]
    Cert {
        what: String,
        #[source]
        source: rcgen::Error,
    },
    #[error(transparent)]
    Roster(#[from] SecurityError),
    #[error("{0} already holds a fleet CA; rotate it with `rotate-ca` instead")]
    Exists(PathBuf),
    #[error("{0}")]
    Invalid(String),
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> FleetError + '_ {
    move |source| FleetError::Io {
        path: path.to_owned(),
        source,
    }
}

fn cert_err(what: impl Into<String>) -> impl FnOnce(rcgen::Error) -> FleetError {
    let what = what.into();
    move |source| FleetError::Cert { what, source }
}

/// Writes `text` to `path` through a temporary file, so a reader never sees
/// half of it; `secret` files are readable by their owner only.
fn write_file(path: &Path, text: &str, secret: bool) -> Result<(), FleetError> {
    use std::io::Write;
    let tmp = path.with_extension("tmp");
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create(true).truncate(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.mode(if secret { 0o600 } else { 0o644 });
    }
    #[cfg(not(unix))]
    let _ = secret;
    let mut file = options.open(&tmp).map_err(io(&tmp))?;
    file.write_all(text.as_bytes()).map_err(io(&tmp))?;
    file.sync_all().map_err(io(&tmp))?;
    std::fs::rename(&tmp, path).map_err(io(path))
}

fn read(path: &Path) -> Result<String, FleetError> {
    std::fs::read_to_string(path).map_err(io(path))
}

/// The CA's subject: rebuilt from the fleet's name whenever a node is signed.
fn ca_params(fleet: &str, days: i64) -> Result<CertificateParams, FleetError> {
    let mut params = CertificateParams::new(Vec::<String>::new()).map_err(cert_err("CA"))?;
    params.distinguished_name = rcgen::DistinguishedName::new();
    params
        .distinguished_name
        .push(DnType::CommonName, format!("towernav fleet {fleet} CA"));
    params.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
    params.key_usages = vec![
        KeyUsagePurpose::KeyCertSign,
        KeyUsagePurpose::CrlSign,
        KeyUsagePurpose::DigitalSignature,
    ];
    validity(&mut params, days);
    Ok(params)
}

fn validity(params: &mut CertificateParams, days: i64) {
    let now = OffsetDateTime::now_utc();
    // An hour back, for clocks a little behind the CA's.
    params.not_before = now - Duration::hours(1);
    params.not_after = now + Duration::days(days);
}

/// The fleet CA's folder, opened.
pub struct Authority {
    dir: PathBuf,
    roster: Roster,
    key: KeyPair,
    ca_pem: String,
}

impl Authority {
    /// Creates a CA for `fleet` in `dir`, valid `days`, with an empty roster.
    pub fn init(dir: &Path, fleet: &str, days: i64) -> Result<Self, FleetError> {
        let key_path = dir.join(CA_KEY_FILE);
        if key_path.exists() {
            return Err(FleetError::Exists(dir.to_owned()));
        }
        let roster = Roster {
            fleet: fleet.to_owned(),
            next_serial: 1,
            nodes: Vec::new(),
            retired: Vec::new(),
        };
        roster.check().map_err(FleetError::Invalid)?;
        std::fs::create_dir_all(dir).map_err(io(dir))?;
        let mut authority = Self {
            dir: dir.to_owned(),
            roster,
            key: KeyPair::generate().map_err(cert_err("CA key"))?,
            ca_pem: String::new(),
        };
        authority.new_ca(days)?;
        authority.save_roster()?;
        Ok(authority)
    }

    /// Opens the CA folder `init` wrote.
    pub fn open(dir: &Path) -> Result<Self, FleetError> {
        let roster_path = dir.join(ROSTER_FILE);
        let roster = Roster::from_toml(&read(&roster_path)?, &roster_path.display().to_string())?;
        let key_path = dir.join(CA_KEY_FILE);
        let key = KeyPair::from_pem(&read(&key_path)?)
            .map_err(cert_err(key_path.display().to_string()))?;
        Ok(Self {
            dir: dir.to_owned(),
            roster,
            key,
            ca_pem: read(&dir.join(CA_FILE))?,
        })
    }

    pub fn roster(&self) -> &Roster {
        &self.roster
    }

    pub fn ca_pem(&self) -> &str {
        &self.ca_pem
    }

    /// A node's credentials folder.
    pub fn node_dir(&self, name: &str) -> PathBuf {
        self.dir.join(NODES_DIR).join(name)
    }

    fn new_ca(&mut self, days: i64) -> Result<(), FleetError> {
        let params = ca_params(&self.roster.fleet, days)?;
        let cert = params.self_signed(&self.key).map_err(cert_err("CA"))?;
        self.ca_pem = cert.pem();
        write_file(&self.dir.join(CA_KEY_FILE), &self.key.serialize_pem(), true)?;
        write_file(&self.dir.join(CA_FILE), &self.ca_pem, false)
    }

    /// Signs a certificate for `node`, valid `days`, and writes its
    /// credentials folder. An earlier certificate of that name is superseded:
    /// it is retired and loses every right.
    pub fn issue(&mut self, node: RosterNode, days: i64) -> Result<PathBuf, FleetError> {
        let mut roster = self.roster.clone();
        let today = today();
        if let Some(old) = roster.nodes.iter().position(|n| n.name == node.name) {
            let old = roster.nodes.remove(old);
            retire(&mut roster, old, "superseded", &today);
        }
        let mut node = RosterNode {
            certificate: None,
            ..node
        };
        roster.nodes.push(node.clone());
        roster.check().map_err(FleetError::Invalid)?;
        let (dir, certificate) = self.sign(&node, roster.next_serial, days)?;
        roster.next_serial += 1;
        node.certificate = Some(certificate.clone());
        if let Some(entry) = roster.nodes.iter_mut().find(|n| n.name == node.name) {
            entry.certificate = Some(certificate);
        }
        roster.check().map_err(FleetError::Invalid)?;
        self.roster = roster;
        self.save_roster()?;
        Ok(dir)
    }

    fn sign(
        &self,
        node: &RosterNode,
        serial: u64,
        days: i64,
    ) -> Result<(PathBuf, CertificateInfo), FleetError> {
        let what = format!("certificate for {}", node.name);
        let common_name = CertificateInfo::common_name_of(&node.name, serial);
        let mut params = CertificateParams::new(node.hosts.clone()).map_err(cert_err(&what))?;
        params.distinguished_name = rcgen::DistinguishedName::new();
        params
            .distinguished_name
            .push(DnType::CommonName, common_name.clone());
        params.serial_number = Some(rcgen::SerialNumber::from(serial));
        // Peers both listen and connect: one certificate for both ends.
        params.extended_key_usages = vec![
            ExtendedKeyUsagePurpose::ServerAuth,
            ExtendedKeyUsagePurpose::ClientAuth,
        ];
        params.key_usages = vec![
            KeyUsagePurpose::DigitalSignature,
            KeyUsagePurpose::KeyEncipherment,
        ];
        params.use_authority_key_identifier_extension = true;
        validity(&mut params, days);
        let expires = day(params.not_after);
        let key = KeyPair::generate().map_err(cert_err(&what))?;
        let issuer = Issuer::new(ca_params(&self.roster.fleet, days)?, &self.key);
        let cert = params.signed_by(&key, &issuer).map_err(cert_err(&what))?;
        let sha256 = ring::digest::digest(&ring::digest::SHA256, cert.der())
            .as_ref()
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect();
        let dir = self.node_dir(&node.name);
        std::fs::create_dir_all(&dir).map_err(io(&dir))?;
        write_file(&dir.join(KEY_FILE), &key.serialize_pem(), true)?;
        write_file(&dir.join(CERT_FILE), &cert.pem(), false)?;
        write_file(&dir.join(CA_FILE), &self.ca_pem, false)?;
        Ok((
            dir,
            CertificateInfo {
                common_name,
                serial,
                sha256,
                expires,
            },
        ))
    }

    /// Takes `name` off the roster, retires its certificate and deletes its
    /// folder: every node that gets the new roster denies that certificate
    /// everything, and issuing the name again later does not bring it back.
    pub fn revoke(&mut self, name: &str) -> Result<(), FleetError> {
        let Some(index) = self.roster.nodes.iter().position(|n| n.name == name) else {
            return Err(FleetError::Invalid(format!("no node named {name:?}")));
        };
        let node = self.roster.nodes.remove(index);
        retire(&mut self.roster, node, "revoked", &today());
        let dir = self.node_dir(name);
        if dir.exists() {
            std::fs::remove_dir_all(&dir).map_err(io(&dir))?;
        }
        self.save_roster()
    }

    /// A new CA key and certificate, and every node on the roster issued again
    /// under it: every node's folder must then be handed out again.
    pub fn rotate_ca(&mut self, ca_days: i64, node_days: i64) -> Result<(), FleetError> {
        self.key = KeyPair::generate().map_err(cert_err("CA key"))?;
        self.new_ca(ca_days)?;
        let today = today();
        for node in std::mem::take(&mut self.roster.nodes) {
            let (_, certificate) = self.sign(&node, self.roster.next_serial, node_days)?;
            self.roster.next_serial += 1;
            retire(&mut self.roster, node.clone(), "superseded", &today);
            self.roster.nodes.push(RosterNode {
                certificate: Some(certificate),
                ..node
            });
        }
        self.save_roster()
    }

    /// The roster, in the CA folder and in every node's folder.
    fn save_roster(&self) -> Result<(), FleetError> {
        let text = self.roster.to_toml();
        write_file(&self.dir.join(ROSTER_FILE), &text, false)?;
        for node in &self.roster.nodes {
            let dir = self.node_dir(&node.name);
            if dir.is_dir() {
                write_file(&dir.join(ROSTER_FILE), &text, false)?;
            }
        }
        Ok(())
    }
}

/// Lists `node`'s certificate among the retired ones.
fn retire(roster: &mut Roster, node: RosterNode, why: &str, on: &str) {
    if let Some(certificate) = node.certificate {
        roster.retired.push(RetiredCertificate {
            node: node.name,
            certificate,
            why: why.to_owned(),
            on: on.to_owned(),
        });
    }
}

fn day(at: OffsetDateTime) -> String {
    format!(
        "{:04}-{:02}-{:02}",
        at.year(),
        u8::from(at.month()),
        at.day()
    )
}

fn today() -> String {
    day(OffsetDateTime::now_utc())
}

/// The roster as a table: each node's current certificate, then the retired ones.
pub fn listing(roster: &Roster) -> String {
    let mut out = format!("fleet {}\n\nnodes (current certificates):\n", roster.fleet);
    out += &format!(
        "  {:<16} {:<15} {:<10} {:<22} {:<17} {}\n",
        "name", "role", "uav", "certificate", "sha256", "expires"
    );
    for node in &roster.nodes {
        let (cn, sha, expires) = match &node.certificate {
            Some(c) => (
                c.common_name.as_str(),
                &c.sha256[..16.min(c.sha256.len())],
                c.expires.as_str(),
            ),
            None => (node.name.as_str(), "-", "-"),
        };
        out += &format!(
            "  {:<16} {:<15} {:<10} {:<22} {:<17} {}\n",
            node.name,
            role_name(node.role),
            node.uav.as_deref().unwrap_or("-"),
            cn,
            sha,
            expires
        );
    }
    out += "\nretired certificates (no rights, whatever is issued later):\n";
    if roster.retired.is_empty() {
        out += "  none\n";
    }
    for r in &roster.retired {
        let c = &r.certificate;
        out += &format!(
            "  {:<22} {:<10} on {}  sha256 {}\n",
            c.common_name,
            r.why,
            r.on,
            &c.sha256[..16.min(c.sha256.len())]
        );
    }
    out
}

fn role_name(role: Role) -> &'static str {
    match role {
        Role::GroundStation => "ground-station",
        Role::Router => "router",
        Role::Edge => "edge",
    }
}

/// A roster entry from the command line's words.
pub fn node(
    name: &str,
    role: Role,
    uav: Option<&str>,
    hosts: &[String],
) -> Result<RosterNode, FleetError> {
    if role == Role::Edge && uav.is_none() {
        return Err(FleetError::Invalid(format!(
            "edge {name:?}: give its UAV id (--uav)"
        )));
    }
    Ok(RosterNode {
        name: name.to_owned(),
        role,
        uav: uav.map(str::to_owned),
        hosts: hosts.to_vec(),
        certificate: None,
    })
}

#[cfg(test)]
#[path = "lib_tests.rs"]
mod tests;
