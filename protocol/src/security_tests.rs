use super::*;

const ROSTER: &str = r#"
fleet = "demo"

[[node]]
name = "gs-1"
role = "ground-station"
hosts = ["127.0.0.1"]

[[node]]
name = "edge-7"
role = "edge"
uav = "uav-7"

[[node]]
name = "edge-8"
role = "edge"
uav = "uav-8"
"#;

fn roster() -> Roster {
    Roster::from_toml(ROSTER, "roster.toml").expect("roster")
}

/// The rule ids a node named `cn` gets, by way of its subjects.
fn rules_of(acl: &Value, cn: &str) -> Vec<String> {
    let subjects: Vec<&str> = acl["subjects"]
        .as_array()
        .expect("subjects")
        .iter()
        .filter(|s| {
            s["cert_common_names"]
                .as_array()
                .is_some_and(|n| n.iter().any(|n| n == cn))
        })
        .filter_map(|s| s["id"].as_str())
        .collect();
    acl["policies"]
        .as_array()
        .expect("policies")
        .iter()
        .filter(|p| {
            p["subjects"].as_array().is_some_and(|s| {
                s.iter()
                    .any(|s| subjects.contains(&s.as_str().unwrap_or("")))
            })
        })
        .flat_map(|p| p["rules"].as_array().cloned().unwrap_or_default())
        .filter_map(|r| r.as_str().map(str::to_owned))
        .collect()
}

fn rule<'a>(acl: &'a Value, id: &str) -> &'a Value {
    acl["rules"]
        .as_array()
        .expect("rules")
        .iter()
        .find(|r| r["id"] == id)
        .unwrap_or_else(|| panic!("no rule {id}"))
}

#[test]
fn an_edge_may_send_only_its_own_uavs_outgoing_keys() {
    let acl = roster().access_control();
    assert_eq!(acl["default_permission"], "deny");
    let rules = rules_of(&acl, "edge-7");
    assert!(!rules.contains(&"anything".to_owned()), "{rules:?}");
    let own = rule(&acl, "own-keys-edge-7");
    let keys: Vec<&str> = own["key_exprs"]
        .as_array()
        .expect("keys")
        .iter()
        .filter_map(Value::as_str)
        .collect();
    assert!(keys.contains(&"towernav/demo/uav/uav-7/pose"), "{keys:?}");
    assert!(keys.contains(&"towernav/demo/alive/uav-7"), "{keys:?}");
    assert!(!keys.iter().any(|k| k.ends_with("/correction")), "{keys:?}");
    assert!(
        !keys
            .iter()
            .any(|k| k.contains("uav-8") || k.contains("landmarks"))
    );
    assert_eq!(own["flows"], json!(["ingress"]));
    // What an edge may send on any key: interest, never data.
    let listen = rule(&acl, "edges-listen");
    for m in listen["messages"].as_array().expect("messages") {
        assert!(
            !["put", "delete", "reply", "declare_queryable"].contains(&m.as_str().unwrap_or(""))
        );
    }
}

#[test]
fn ground_stations_may_do_anything_and_strangers_nothing() {
    let acl = roster().access_control();
    assert_eq!(rules_of(&acl, "gs-1"), vec!["anything".to_owned()]);
    assert!(rules_of(&acl, "someone-else").is_empty());
}

/// A credentials folder whose certificate is self-signed with common name `cn`.
fn write_credentials(dir: &Path, cn: &str) {
    let key = rcgen::KeyPair::generate().expect("key");
    let mut params = rcgen::CertificateParams::new(Vec::<String>::new()).expect("params");
    params
        .distinguished_name
        .push(rcgen::DnType::CommonName, cn);
    let cert = params.self_signed(&key).expect("cert");
    std::fs::write(dir.join(CA_FILE), cert.pem()).expect("write");
    std::fs::write(dir.join(CERT_FILE), cert.pem()).expect("write");
    std::fs::write(dir.join(KEY_FILE), key.serialize_pem()).expect("write");
    std::fs::write(dir.join(ROSTER_FILE), ROSTER).expect("write");
}

fn session_json(credentials: &Credentials, key: &str) -> String {
    let config = crate::session::session_config(&crate::session::Endpoints {
        listen: vec!["tls/127.0.0.1:17449".into()],
        connect: vec![],
        security: Some(credentials.clone()),
    })
    .expect("config");
    config.get_json(key).expect("key")
}

#[test]
fn a_folder_whose_certificate_the_roster_does_not_name_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    // A superseded certificate beside a roster that names its successor.
    write_credentials(dir.path(), "edge-7#1");
    let roster = ROSTER.replace(
        "uav = \"uav-7\"\n",
        "uav = \"uav-7\"\n[node.certificate]\ncommon_name = \"edge-7#2\"\nserial = 2\nsha256 = \"00\"\nexpires = \"2030-01-01\"\n",
    );
    let roster = format!("next_serial = 3\n{roster}");
    std::fs::write(dir.path().join(ROSTER_FILE), roster).expect("write");
    let err = Credentials::load(dir.path(), "edge-7").expect_err("stale folder");
    assert!(
        err.to_string().contains("edge-7#1") && err.to_string().contains("edge-7#2"),
        "{err}"
    );
}

#[test]
fn an_edge_is_sent_only_the_landmarks_and_its_own_uavs_keys() {
    let acl = roster().access_control();
    let rules = rules_of(&acl, "edge-7");
    for id in &rules {
        let rule = rule(&acl, id);
        let egress = rule["flows"]
            .as_array()
            .is_some_and(|f| f.iter().any(|f| f == "egress"));
        let data = rule["messages"].as_array().is_some_and(|m| {
            m.iter()
                .any(|m| ["put", "reply", "liveliness_token"].contains(&m.as_str().unwrap_or("")))
        });
        if !(egress && data) {
            continue;
        }
        for key in rule["key_exprs"].as_array().expect("keys") {
            let key = key.as_str().unwrap_or("");
            assert!(
                key.starts_with("towernav/demo/uav/uav-7/")
                    || key == "towernav/demo/alive/uav-7"
                    || key.starts_with("towernav/demo/landmarks/"),
                "rule {id} sends edge-7 data on {key}"
            );
        }
    }
}

#[test]
fn zenoh_takes_the_rules_and_the_tls_files() {
    let dir = tempfile::tempdir().expect("tempdir");
    write_credentials(dir.path(), "gs-1");
    let credentials = Credentials::load(dir.path(), "gs-1").expect("credentials");
    assert_eq!(
        session_json(&credentials, "transport/link/protocols"),
        r#"["tls"]"#,
        "links other than TLS must be refused, gossiped ones too"
    );
    let endpoints = crate::session::Endpoints {
        listen: vec!["tls/127.0.0.1:17448".into()],
        connect: vec![],
        security: Some(credentials),
    };
    let config = crate::session::session_config(&endpoints).expect("config");
    assert_eq!(
        config
            .get_json("transport/link/tls/enable_mtls")
            .expect("key"),
        "true"
    );
    assert_eq!(
        config
            .get_json("access_control/default_permission")
            .expect("key"),
        "\"deny\""
    );
    // Plain tcp beside credentials would be a way around them.
    let plain = crate::session::Endpoints {
        listen: vec!["tcp/127.0.0.1:17448".into()],
        ..endpoints
    };
    let err = crate::session::session_config(&plain).expect_err("plain tcp refused");
    assert!(err.to_string().contains("tcp/127.0.0.1:17448"), "{err}");
}

#[test]
fn a_bad_roster_is_refused_with_the_reason() {
    for (text, reason) in [
        (
            "fleet = \"demo\"\n[[node]]\nname = \"e\"\nrole = \"edge\"\n",
            "has no uav",
        ),
        (
            "fleet = \"demo\"\n[[node]]\nname = \"g\"\nrole = \"ground-station\"\nuav = \"u\"\n",
            "only an edge",
        ),
        (
            "fleet = \"demo\"\n[[node]]\nname = \"g\"\nrole = \"ground-station\"\n[[node]]\nname = \"g\"\nrole = \"router\"\n",
            "twice",
        ),
        (
            "fleet = \"demo\"\n[[node]]\nname = \"g\"\nrole = \"pilot\"\n",
            "pilot",
        ),
    ] {
        let err = Roster::from_toml(text, "fleet/roster.toml").expect_err(reason);
        let err = err.to_string();
        assert!(
            err.contains("fleet/roster.toml") && err.contains(reason),
            "{err}"
        );
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let err = Credentials::load(dir.path(), "gs-1").expect_err("no files");
    assert!(err.to_string().contains(CA_FILE), "{err}");
}

#[test]
fn a_roster_survives_its_own_file() {
    let roster = roster();
    assert_eq!(
        Roster::from_toml(&roster.to_toml(), "again").expect("again"),
        roster
    );
}
