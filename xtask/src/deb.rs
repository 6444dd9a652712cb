//! `cargo xtask deb [amd64|arm64]`: the onboard side as a Debian package,
//! `target/deb/towernav-edge_<version>_<arch>.deb`, built with `dpkg-deb`:
//!
//! - `/usr/bin/towernav-edge`, `towernav-db`, `towernav-fleet` (the edge's
//!   onboard build: no simulator, no evaluation tools);
//! - `/usr/share/towernav/models/`: the INT8 detector and type classifier;
//! - `/usr/lib/towernav/libonnxruntime.so`: ONNX Runtime for that architecture;
//! - `/etc/towernav/edge.toml` (a conffile) from `deploy/edge.toml`, and
//!   `/etc/towernav/credentials/`, where `towernav-fleet`'s node folder goes;
//! - `/lib/systemd/system/towernav-edge.service` from `deploy/`: the daemon
//!   as the unprivileged `towernav` user, restarted on failure, logging to
//!   the journal. Installing creates the user and does not start the service:
//!   the config is the integrator's to fill in first.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, bail};

use crate::{cargo, cross, ensure_onnxruntime, run, target_dir};

pub const PACKAGE: &str = "towernav-edge";

const POSTINST: &str = r#"#!/bin/sh
set -e
if [ "$1" = configure ]; then
    if ! getent passwd towernav >/dev/null; then
        adduser --system --group --home /var/lib/towernav --no-create-home \
            --gecos "towernav edge daemon" towernav
    fi
    for group in video dialout; do
        if getent group "$group" >/dev/null; then adduser towernav "$group" >/dev/null; fi
    done
    install -d -o towernav -g towernav -m 0750 /var/lib/towernav
    install -d -o root -g towernav -m 0750 /etc/towernav/credentials
    if [ -d /run/systemd/system ]; then systemctl daemon-reload || true; fi
    echo "towernav-edge: edit /etc/towernav/edge.toml, copy the fleet's node folder into"
    echo "  /etc/towernav/credentials/, then: systemctl enable --now towernav-edge"
fi
"#;

const PRERM: &str = r#"#!/bin/sh
set -e
if [ -d /run/systemd/system ] && [ "$1" = remove ]; then
    systemctl stop towernav-edge.service || true
    systemctl disable towernav-edge.service || true
fi
"#;

const POSTRM: &str = r#"#!/bin/sh
set -e
if [ -d /run/systemd/system ]; then systemctl daemon-reload || true; fi
"#;

pub fn deb(root: &Path, arch: &str) -> anyhow::Result<PathBuf> {
    let (bin, ort) = match arch {
        "amd64" => {
            cargo(
                root,
                &[&["build", "--release"][..], &cross::ONBOARD[..]].concat(),
            )?;
            (target_dir(root).join("release"), ensure_onnxruntime(root)?)
        }
        "arm64" => {
            let build = cross::cross(root, "aarch64")?;
            (build.bin, build.ort)
        }
        other => bail!("a package for amd64 or arm64 (asked for {other:?})"),
    };
    let version = env!("CARGO_PKG_VERSION");
    let out_dir = target_dir(root).join("deb");
    let stage = out_dir.join(format!("{PACKAGE}_{arch}"));
    if stage.exists() {
        std::fs::remove_dir_all(&stage).with_context(|| format!("clearing {}", stage.display()))?;
    }
    let put = |from: &Path, to: &str, mode: u32| -> anyhow::Result<()> {
        let dest = stage.join(to);
        std::fs::create_dir_all(dest.parent().context("a parent")?)?;
        std::fs::copy(from, &dest)
            .with_context(|| format!("copying {} to {}", from.display(), dest.display()))?;
        set_mode(&dest, mode)
    };
    let write = |to: &str, text: &str, mode: u32| -> anyhow::Result<()> {
        let dest = stage.join(to);
        std::fs::create_dir_all(dest.parent().context("a parent")?)?;
        std::fs::write(&dest, text).with_context(|| format!("writing {}", dest.display()))?;
        set_mode(&dest, mode)
    };
    // Stripped: the release profile keeps debug info, a board needs none of it.
    let strip = if arch == "arm64" {
        "aarch64-linux-gnu-strip"
    } else {
        "strip"
    };
    for name in ["towernav-edge", "towernav-db", "towernav-fleet"] {
        let to = format!("usr/bin/{name}");
        put(&bin.join(name), &to, 0o755)?;
        run(Command::new(strip)
            .arg("--strip-debug")
            .arg(stage.join(&to)))?;
    }
    for model in ["towers-int8.onnx", "tower-types-int8.onnx"] {
        put(
            &root.join("models").join(model),
            &format!("usr/share/towernav/models/{model}"),
            0o644,
        )?;
    }
    put(&ort, "usr/lib/towernav/libonnxruntime.so", 0o644)?;
    put(
        &root.join("deploy/edge.toml"),
        "etc/towernav/edge.toml",
        0o644,
    )?;
    put(
        &root.join("deploy/towernav-edge.service"),
        "lib/systemd/system/towernav-edge.service",
        0o644,
    )?;
    put(
        &root.join("README.md"),
        &format!("usr/share/doc/{PACKAGE}/README.md"),
        0o644,
    )?;
    for licence in ["LICENSE-MIT", "LICENSE-APACHE"] {
        put(
            &root.join(licence),
            &format!("usr/share/doc/{PACKAGE}/{licence}"),
            0o644,
        )?;
    }
    write(
        &format!("usr/share/doc/{PACKAGE}/MODELS"),
        "The detector in /usr/share/towernav/models was fine-tuned from a GPL-3.0\n\
         COCO checkpoint with Ultralytics (AGPL-3.0); see models/README.md in the\n\
         source. ONNX Runtime (/usr/lib/towernav) is MIT-licensed.\n",
        0o644,
    )?;
    write(
        "DEBIAN/control",
        &format!(
            "Package: {PACKAGE}\nVersion: {version}\nArchitecture: {arch}\n\
             Maintainer: towernav developers <towernav@localhost>\n\
             Depends: libc6 (>= 2.31), libstdc++6, libgcc-s1, adduser\n\
             Section: misc\nPriority: optional\n\
             Description: position for a small UAV from transmission towers in its camera\n \
             The onboard daemon: camera frames, a tower detector (ONNX Runtime),\n \
             tracking, tower identity and localization against a surveyed database;\n \
             the pose over Zenoh and to the autopilot over MAVLink. Runs as a\n \
             systemd service (towernav-edge.service).\n"
        ),
        0o644,
    )?;
    write("DEBIAN/conffiles", "/etc/towernav/edge.toml\n", 0o644)?;
    write("DEBIAN/postinst", POSTINST, 0o755)?;
    write("DEBIAN/prerm", PRERM, 0o755)?;
    write("DEBIAN/postrm", POSTRM, 0o755)?;
    let deb = out_dir.join(format!("{PACKAGE}_{version}_{arch}.deb"));
    run(Command::new("dpkg-deb")
        .args(["--build", "--root-owner-group"])
        .arg(&stage)
        .arg(&deb))?;
    eprintln!("xtask: {}", deb.display());
    Ok(deb)
}

fn set_mode(path: &Path, mode: u32) -> anyhow::Result<()> {
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode))
        .with_context(|| format!("setting the mode of {}", path.display()))
}
