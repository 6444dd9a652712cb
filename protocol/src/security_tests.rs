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

#[test]
fn zenoh_takes_the_rules_and_the_tls_files() {
    let dir = tempfile::tempdir().expect("tempdir");
    for f in [CA_FILE, CERT_FILE, KEY_FILE] {
        std::fs::write(dir.path().join(f), "pem").expect("write");
    }
    std::fs::write(dir.path().join(ROSTER_FILE), ROSTER).expect("write");
    let credentials = Credentials::load(dir.path(), "gs-1").expect("credentials");
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
