//! The Debian packages `cargo xtask deb` builds (`cargo xtask test` builds
//! amd64 and, where it can cross-build, arm64, and hands them here in
//! `TOWERNAV_DEBS`): each unpacked into a root
//! of its own (a chroot's view, where systemd cannot run), its files and
//! control data checked, its systemd unit verified with `systemd-analyze
//! verify` (which says nothing of a good unit, and names a bad directive or a
//! missing program), its `postinst` run against stand-in programs, and the amd64 package's daemon started from that root on a
//! short rendered flight with the packaged models and ONNX Runtime.

use std::path::{Path, PathBuf};
use std::process::Command;

use towernav_tests::programs::{output, run_ok as ok, short_flight};

const FILES: [&str; 8] = [
    "usr/bin/towernav-edge",
    "usr/bin/towernav-db",
    "usr/bin/towernav-fleet",
    "usr/share/towernav/models/towers-int8.onnx",
    "usr/share/towernav/models/tower-types-int8.onnx",
    "usr/lib/towernav/libonnxruntime.so",
    "etc/towernav/edge.toml",
    "lib/systemd/system/towernav-edge.service",
];

#[test]
fn the_packages_hold_the_daemon_its_models_runtime_config_and_service() {
    let Some(debs) = std::env::var_os("TOWERNAV_DEBS") else {
        eprintln!(
            "skipped: no packages given (`cargo xtask test` builds them with \
             `cargo xtask deb amd64` and `cargo xtask deb arm64` and sets TOWERNAV_DEBS)"
        );
        return;
    };
    let debs: Vec<PathBuf> = std::env::split_paths(&debs).collect();
    // amd64 always; arm64 where the machine could cross-build it (the xtask
    // says when it could not).
    assert!(
        !debs.is_empty() && debs.len() <= 2,
        "one package per architecture: {debs:?}"
    );
    for deb in &debs {
        let info = ok(Command::new("dpkg-deb").arg("--info").arg(deb));
        let arch = if info.contains("Architecture: arm64") {
            "arm64"
        } else {
            assert!(info.contains("Architecture: amd64"), "{info}");
            "amd64"
        };
        assert!(info.contains("Package: towernav-edge"), "{info}");
        let root = tempfile::tempdir().expect("tempdir");
        ok(Command::new("dpkg-deb").arg("-x").arg(deb).arg(root.path()));
        for file in FILES {
            assert!(root.path().join(file).is_file(), "{arch}: no /{file}");
        }
        let contents = ok(Command::new("dpkg-deb").arg("--contents").arg(deb));
        // Owned by root, whoever built it; the daemon is executable.
        assert!(contents.contains("-rwxr-xr-x root/root"), "{contents}");
        let control = ok(Command::new("dpkg-deb")
            .arg("--info")
            .arg(deb)
            .arg("postinst"));
        assert!(
            control.contains("adduser --system"),
            "no service user: {control}"
        );
        let machine = std::fs::read(root.path().join("usr/bin/towernav-edge")).expect("the daemon");
        let expected: &[u8] = if arch == "arm64" {
            &[0xB7, 0]
        } else {
            &[0x3E, 0]
        };
        assert_eq!(
            machine.get(18..20),
            Some(expected),
            "{arch}: wrong ELF machine"
        );

        let unit =
            std::fs::read_to_string(root.path().join("lib/systemd/system/towernav-edge.service"))
                .expect("unit");
        for line in [
            "User=towernav",
            "Restart=on-failure",
            "ExecStart=/usr/bin/towernav-edge run --config /etc/towernav/edge.toml",
            "Environment=ORT_DYLIB_PATH=/usr/lib/towernav/libonnxruntime.so",
        ] {
            assert!(
                unit.lines().any(|l| l == line),
                "{arch}: the unit lacks {line:?}"
            );
        }
        assert!(!unit.contains("StandardOutput="), "logs go to the journal");
        let config =
            std::fs::read_to_string(root.path().join("etc/towernav/edge.toml")).expect("config");
        for path in [
            "/usr/share/towernav/models/towers-int8.onnx",
            "/etc/towernav/credentials/edge-7",
        ] {
            assert!(
                config.contains(path),
                "{arch}: the config does not point at {path}"
            );
        }
        if arch == "amd64" {
            verify_unit(root.path());
            configures_a_service_user(deb);
            starts_from_the_package(root.path());
        }
    }
}

/// `systemd-analyze verify` on the unit as installed, its `ExecStart`
/// pointed into the unpacked root (verify checks that the program exists).
fn verify_unit(root: &Path) {
    let unit = std::fs::read_to_string(root.join("lib/systemd/system/towernav-edge.service"))
        .expect("unit");
    let daemon = root.join("usr/bin/towernav-edge");
    let here = tempfile::tempdir().expect("tempdir");
    let copy = here.path().join("towernav-edge.service");
    std::fs::write(
        &copy,
        unit.replace("/usr/bin/towernav-edge", &daemon.display().to_string()),
    )
    .expect("write");
    let (success, text) = output(Command::new("systemd-analyze").arg("verify").arg(&copy));
    assert!(
        success && text.trim().is_empty(),
        "systemd-analyze verify:\n{text}"
    );
}

/// The package's `postinst configure`, run with every program it calls
/// stood in for by one that writes down its arguments (the test must not
/// add users to the machine it runs on): it adds the system user, puts it in
/// the camera's and the serial port's groups, makes the state and
/// credentials folders, and does not start the service.
fn configures_a_service_user(deb: &Path) {
    let dir = tempfile::tempdir().expect("tempdir");
    let control = dir.path().join("DEBIAN");
    ok(Command::new("dpkg-deb").arg("-e").arg(deb).arg(&control));
    let bin = dir.path().join("bin");
    std::fs::create_dir_all(&bin).expect("bin");
    let calls = dir.path().join("calls.txt");
    for program in ["adduser", "getent", "install", "systemctl"] {
        // getent finds nothing: the user and groups are new.
        let status = if program == "getent" { 2 } else { 0 };
        let stub = bin.join(program);
        std::fs::write(
            &stub,
            format!(
                "#!/bin/sh\necho \"{program} $*\" >> '{}'\nexit {status}\n",
                calls.display()
            ),
        )
        .expect("stub");
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&stub, std::fs::Permissions::from_mode(0o755)).expect("mode");
    }
    let path = format!("{}:/usr/bin:/bin", bin.display());
    ok(Command::new("sh")
        .arg(control.join("postinst"))
        .arg("configure")
        .env("PATH", path));
    let calls = std::fs::read_to_string(&calls).expect("calls");
    for call in [
        "adduser --system --group --home /var/lib/towernav --no-create-home",
        "install -d -o towernav -g towernav -m 0750 /var/lib/towernav",
        "install -d -o root -g towernav -m 0750 /etc/towernav/credentials",
    ] {
        assert!(
            calls.contains(call),
            "postinst did not run {call:?}:\n{calls}"
        );
    }
    assert!(
        !calls.contains("systemctl enable") && !calls.contains("systemctl start"),
        "installing must not start the service before its config is filled in:\n{calls}"
    );
}

/// The packaged daemon, runtime and models on a short rendered flight.
fn starts_from_the_package(root: &Path) {
    let dir = tempfile::tempdir().expect("tempdir");
    let jsonl = dir.path().join("poses.jsonl");
    let models = root.join("usr/share/towernav/models");
    let log = ok(Command::new(root.join("usr/bin/towernav-edge"))
        .arg("run")
        .arg("--config")
        .arg(short_flight().join("replay.toml"))
        .arg("--model")
        .arg(models.join("towers-int8.onnx"))
        .arg("--type-model")
        .arg(models.join("tower-types-int8.onnx"))
        .args(["--speed", "0", "--max-frames", "30"])
        .args(["--listen", &towernav_tests::loopback_endpoint()])
        .arg("--jsonl")
        .arg(&jsonl)
        .env(
            "ORT_DYLIB_PATH",
            root.join("usr/lib/towernav/libonnxruntime.so"),
        )
        .env_remove("RUST_LOG"));
    let poses = std::fs::read_to_string(&jsonl).expect("poses");
    assert!(poses.lines().count() >= 10, "few poses:\n{log}");
    // Not a terminal: plain text for the journal, no colour codes.
    assert!(!log.contains('\u{1b}'), "colour codes in the log:\n{log}");
    // The packaged config itself is refused with a clear reason here (no
    // camera, no credentials), never a panic.
    let (success, text) = output(
        Command::new(root.join("usr/bin/towernav-edge"))
            .arg("run")
            .arg("--config")
            .arg(root.join("etc/towernav/edge.toml"))
            .env(
                "ORT_DYLIB_PATH",
                root.join("usr/lib/towernav/libonnxruntime.so"),
            ),
    );
    assert!(
        !success,
        "it ran without its camera and credentials:\n{text}"
    );
    assert!(!text.contains("panicked"), "{text}");
    assert!(
        text.contains("/etc/towernav"),
        "the error names no path:\n{text}"
    );
}
