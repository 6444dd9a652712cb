//! `cargo xtask zenohd`: the Zenoh router, built from the crate published
//! for the Zenoh release the project links, into the git-ignored `.zenohd/`.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::Context;

/// The `zenoh` version Cargo.lock pins: the router must speak its protocol.
fn locked_zenoh(root: &Path) -> anyhow::Result<String> {
    let lock = root.join("Cargo.lock");
    let text =
        std::fs::read_to_string(&lock).with_context(|| format!("reading {}", lock.display()))?;
    let mut lines = text.lines();
    while let Some(line) = lines.next() {
        if line == "name = \"zenoh\""
            && let Some(version) = lines
                .next()
                .and_then(|l| l.strip_prefix("version = \""))
                .and_then(|v| v.strip_suffix('"'))
        {
            return Ok(version.to_owned());
        }
    }
    anyhow::bail!("no zenoh package in {}", lock.display())
}

/// `.zenohd/bin/zenohd`, installed with `cargo install` if missing or of
/// another version (a few minutes of building, once).
pub fn ensure_zenohd(root: &Path) -> anyhow::Result<PathBuf> {
    install(root, &root.join(".zenohd"), None)
}

/// The same, installed under `base/<version>/`; its build's own target
/// folder is `base/build`, so a rebuild reuses what it compiled.
pub fn ensure_zenohd_in(root: &Path, base: &Path) -> anyhow::Result<PathBuf> {
    let version = locked_zenoh(root)?;
    install(root, &base.join(&version), Some(&base.join("build")))
}

fn install(root: &Path, dir: &Path, target: Option<&Path>) -> anyhow::Result<PathBuf> {
    let version = locked_zenoh(root)?;
    let dir = dir.to_path_buf();
    let bin = dir.join("bin").join("zenohd");
    let stamp = dir.join("version");
    if bin.exists() && std::fs::read_to_string(&stamp).ok().as_deref() == Some(version.as_str()) {
        return Ok(bin);
    }
    eprintln!("xtask: building zenohd {version} into {}", dir.display());
    let status = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
        .args(["install", "zenohd", "--locked", "--force", "--version"])
        .arg(format!("={version}"))
        .arg("--root")
        .arg(&dir)
        .args(
            target
                .map(|t| ["--target-dir".as_ref(), t.as_os_str()])
                .into_iter()
                .flatten(),
        )
        .status()
        .context("running cargo install zenohd")?;
    anyhow::ensure!(status.success(), "cargo install zenohd {version} failed");
    std::fs::write(&stamp, &version)?;
    Ok(bin)
}
