use super::*;
use std::process::Command;
use towernav_protocol::security::Credentials;

/// `openssl verify` of `cert` against `ca`: `Some(passed)`, or `None` on a
/// machine without openssl.
fn openssl_verifies(ca: &std::path::Path, cert: &std::path::Path) -> Option<bool> {
    let out = openssl(&[
        "verify",
        "-CAfile",
        &ca.display().to_string(),
        &cert.display().to_string(),
    ])?;
    Some(out.contains(": OK"))
}

fn openssl(args: &[&str]) -> Option<String> {
    let out = Command::new("openssl").args(args).output().ok()?;
    Some(format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    ))
}

#[test]
fn issued_certificates_chain_to_the_fleet_ca_and_name_the_node() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let dir = tmp.path().join("fleet");
    let mut ca = Authority::init(&dir, "demo", 30).expect("init");
    let gs = ca
        .issue(
            node("gs-1", Role::GroundStation, None, &["127.0.0.1".into()]).expect("node"),
            10,
        )
        .expect("issue");
    ca.issue(
        node("edge-7", Role::Edge, Some("uav-7"), &[]).expect("node"),
        10,
    )
    .expect("issue");
    // The ground station's folder got the roster that names the edge issued after it.
    let roster = std::fs::read_to_string(gs.join(ROSTER_FILE)).expect("roster");
    assert!(
        roster.contains("edge-7") && roster.contains("uav-7"),
        "{roster}"
    );
    // An independent X.509 implementation agrees (when the machine has one).
    let (ca_pem, cert) = (dir.join(CA_FILE), gs.join(CERT_FILE));
    if let Some(verified) = openssl_verifies(&ca_pem, &cert) {
        assert!(verified, "openssl does not verify {}", cert.display());
        let text = openssl(&[
            "x509",
            "-noout",
            "-text",
            "-in",
            &cert.display().to_string(),
        ])
        .expect("openssl");
        assert!(
            text.contains("CN=gs-1") || text.contains("CN = gs-1"),
            "{text}"
        );
        assert!(text.contains("IP Address:127.0.0.1"), "{text}");
        assert!(text.contains("TLS Web Client Authentication"), "{text}");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        for key in [dir.join(CA_KEY_FILE), gs.join(KEY_FILE)] {
            let mode = std::fs::metadata(&key).expect("key").permissions().mode();
            assert_eq!(mode & 0o077, 0, "{} is readable by others", key.display());
        }
    }
}

#[test]
fn rotation_and_revocation_rewrite_every_folder() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let dir = tmp.path().join("fleet");
    let mut ca = Authority::init(&dir, "demo", 30).expect("init");
    let gs = ca
        .issue(
            node("gs-1", Role::GroundStation, None, &[]).expect("node"),
            10,
        )
        .expect("issue");
    let edge = ca
        .issue(
            node("edge-7", Role::Edge, Some("uav-7"), &[]).expect("node"),
            10,
        )
        .expect("issue");
    let old_ca = std::fs::read_to_string(gs.join(CA_FILE)).expect("ca");
    let old_cert = std::fs::read_to_string(gs.join(CERT_FILE)).expect("cert");
    let mut ca = Authority::open(&dir).expect("open");
    ca.rotate_ca(30, 10).expect("rotate");
    assert_ne!(
        std::fs::read_to_string(gs.join(CA_FILE)).expect("ca"),
        old_ca
    );
    assert_ne!(
        std::fs::read_to_string(gs.join(CERT_FILE)).expect("cert"),
        old_cert
    );
    let (ca_pem, cert) = (dir.join(CA_FILE), edge.join(CERT_FILE));
    if let Some(verified) = openssl_verifies(&ca_pem, &cert) {
        assert!(verified, "the new CA does not sign {}", cert.display());
        // Nor does the old CA sign the reissued certificate.
        let old = tmp.path().join("old-ca.pem");
        std::fs::write(&old, &old_ca).expect("old CA");
        assert_eq!(openssl_verifies(&old, &cert), Some(false));
    }
    ca.revoke("edge-7").expect("revoke");
    assert!(!edge.exists());
    let text = std::fs::read_to_string(gs.join(ROSTER_FILE)).expect("roster");
    let roster = Roster::from_toml(&text, "roster").expect("roster");
    assert!(roster.node("edge-7").is_none(), "{text}");
    // Its first certificate was superseded by the rotation, its second revoked.
    let retired: Vec<(&str, &str)> = roster
        .retired
        .iter()
        .filter(|r| r.node == "edge-7")
        .map(|r| (r.certificate.common_name.as_str(), r.why.as_str()))
        .collect();
    assert_eq!(
        retired,
        vec![("edge-7#2", "superseded"), ("edge-7#4", "revoked")],
        "{text}"
    );
}

#[test]
fn a_name_issued_again_does_not_bring_back_its_old_certificates() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let dir = tmp.path().join("fleet");
    let mut ca = Authority::init(&dir, "demo", 30).expect("init");
    let edge = || node("edge-8", Role::Edge, Some("uav-8"), &[]).expect("node");
    ca.issue(edge(), 10).expect("issue");
    ca.issue(edge(), 10).expect("reissue");
    ca.revoke("edge-8").expect("revoke");
    ca.issue(edge(), 10).expect("a replacement vehicle");
    let roster = ca.roster();
    let current = roster.node("edge-8").and_then(|n| n.certificate.clone());
    assert_eq!(current.map(|c| c.common_name), Some("edge-8#3".to_owned()));
    let acl = roster.access_control().to_string();
    assert!(acl.contains("\"edge-8#3\""), "{acl}");
    for old in ["edge-8#1", "edge-8#2"] {
        assert!(
            !acl.contains(&format!("\"{old}\"")),
            "{old} still has rights: {acl}"
        );
    }
    let listing = crate::listing(roster);
    for line in ["edge-8#1", "superseded", "edge-8#2", "revoked", "edge-8#3"] {
        assert!(listing.contains(line), "{listing}");
    }
    // The folder on disk is the current certificate's: it loads.
    Credentials::load(&ca.node_dir("edge-8"), "edge-8").expect("current folder loads");
}

#[test]
fn mistakes_are_refused_with_the_reason() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let dir = tmp.path().join("fleet");
    let mut ca = Authority::init(&dir, "demo", 30).expect("init");
    let again = Authority::init(&dir, "demo", 30)
        .err()
        .expect("a second CA refused");
    assert!(again.to_string().contains("rotate-ca"), "{again}");
    let no_uav = node("edge-1", Role::Edge, None, &[]).expect_err("no uav");
    assert!(no_uav.to_string().contains("--uav"), "{no_uav}");
    ca.issue(
        node("edge-1", Role::Edge, Some("uav-1"), &[]).expect("node"),
        10,
    )
    .expect("issue");
    let twice = ca
        .issue(
            node("edge-2", Role::Edge, Some("uav-1"), &[]).expect("node"),
            10,
        )
        .expect_err("two edges for one UAV");
    assert!(twice.to_string().contains("uav-1"), "{twice}");
    let unknown = ca.revoke("nobody").expect_err("unknown");
    assert!(unknown.to_string().contains("nobody"), "{unknown}");
    let missing = Authority::open(&tmp.path().join("nowhere"))
        .err()
        .expect("no CA there");
    assert!(missing.to_string().contains("nowhere"), "{missing}");
}
