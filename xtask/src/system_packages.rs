//! Programs the project runs that come from Debian's packages (ffmpeg for video
//! sources, Xvfb for screenshots): installed with apt-get when missing and root.

use std::process::{Command, Stdio};

use anyhow::bail;

use crate::run;

fn have(program: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {program}")])
        .stdout(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// Installs a Debian package when its program is missing (root only).
pub fn ensure_program(program: &str, package: &str) -> anyhow::Result<()> {
    if have(program) {
        return Ok(());
    }
    install(program, package)
}

/// Installs a Debian package when a file it holds is missing (root only).
pub fn ensure_file(path: &str, package: &str) -> anyhow::Result<()> {
    if std::path::Path::new(path).exists() {
        return Ok(());
    }
    install(path, package)
}

fn install(program: &str, package: &str) -> anyhow::Result<()> {
    if !have("apt-get") {
        bail!("`{program}` is missing; install the `{package}` package");
    }
    let root = Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| o.stdout.starts_with(b"0"));
    if !root {
        bail!("`{program}` is missing; install it with `sudo apt-get install {package}`");
    }
    run(Command::new("apt-get").args(["update", "-qq"]))?;
    run(Command::new("apt-get")
        .args(["install", "-y", "-qq", "--no-install-recommends", package])
        .env("DEBIAN_FRONTEND", "noninteractive"))
}
