//! `cargo xtask cross aarch64`: the onboard binaries for a 64-bit ARM
//! companion computer (Raspberry Pi 5, Jetson Orin, ...), built here with
//! Debian's cross toolchain, and ONNX Runtime's aarch64 library from the same
//! `onnxruntime` version's aarch64 wheel on the Python package index.
//!
//! Writes `target/aarch64-unknown-linux-gnu/release/{towernav-edge,
//! towernav-db, towernav-fleet}` and `.ort/aarch64/lib/libonnxruntime.so`.
//! Debian's `qemu-user` runs them here (`qemu-aarch64 -L
//! target/aarch64-qemu-sysroot`), as `tests/tests/aarch64.rs` does.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, bail};

use crate::system_packages::{ensure_file, ensure_program};
use crate::{cargo_with, onnxruntime_from_wheel, run, target_dir};

pub const AARCH64: &str = "aarch64-unknown-linux-gnu";
/// The onboard programs, as cargo arguments: the edge without its demo
/// feature, `towernav-db` with its command line, `towernav-fleet`.
pub const ONBOARD: [&str; 8] = [
    "-p",
    "towernav-edge",
    "-p",
    "towernav-landmark-db",
    "--features",
    "towernav-landmark-db/cli",
    "-p",
    "towernav-fleet",
];
/// Where Debian's cross packages put the aarch64 C library and loader.
pub const AARCH64_SYSROOT: &str = "/usr/aarch64-linux-gnu";

/// What the cross build made.
pub struct CrossBuild {
    /// The folder of the aarch64 binaries.
    pub bin: PathBuf,
    /// ONNX Runtime's aarch64 shared library.
    pub ort: PathBuf,
    /// The prefix for `qemu-aarch64 -L`: the aarch64 C library, and a
    /// `/proc/cpuinfo` and `/sys/devices/system/cpu` of a 2-core Cortex-A76.
    pub qemu_sysroot: PathBuf,
}

/// Two Cortex-A76 cores (a Raspberry Pi 5's), as the kernel lists them.
const CPUINFO: &str = "BogoMIPS\t: 108.00\n\
    Features\t: fp asimd evtstrm aes pmull sha1 sha2 crc32 atomics fphp asimdhp cpuid asimdrdm lrcpc dcpop asimddp\n\
    CPU implementer\t: 0x41\nCPU architecture: 8\nCPU variant\t: 0x4\nCPU part\t: 0xd0b\nCPU revision\t: 1\n";

/// qemu-user looks up every path under its `-L` prefix first. ONNX
/// Runtime's CPU probe (cpuinfo) reads `/proc/cpuinfo` and
/// `/sys/devices/system/cpu`, which under qemu-user are the x86 host's, and
/// crashes on them; this prefix gives it an ARM board's. A real board has its own.
fn qemu_sysroot(root: &Path) -> anyhow::Result<PathBuf> {
    let dir = target_dir(root).join("aarch64-qemu-sysroot");
    let cpu = dir.join("sys/devices/system/cpu");
    std::fs::create_dir_all(&cpu).with_context(|| format!("creating {}", cpu.display()))?;
    std::fs::create_dir_all(dir.join("proc"))?;
    let cpuinfo: String = (0..2)
        .map(|i| format!("processor\t: {i}\n{CPUINFO}\n"))
        .collect();
    std::fs::write(dir.join("proc/cpuinfo"), cpuinfo)?;
    for list in ["possible", "present", "online"] {
        std::fs::write(cpu.join(list), "0-1\n")?;
    }
    let lib = dir.join("lib");
    if std::fs::symlink_metadata(&lib).is_err() {
        std::os::unix::fs::symlink(format!("{AARCH64_SYSROOT}/lib"), &lib)
            .with_context(|| format!("linking {}", lib.display()))?;
    }
    Ok(dir)
}

pub fn cross(root: &Path, arch: &str) -> anyhow::Result<CrossBuild> {
    if arch != "aarch64" {
        bail!("cross builds for aarch64 only (asked for {arch:?})");
    }
    ensure_program("aarch64-linux-gnu-gcc", "gcc-aarch64-linux-gnu")?;
    // The C library's headers for the target (ring and SQLite compile C).
    ensure_file(
        &format!("{AARCH64_SYSROOT}/include/stdio.h"),
        "libc6-dev-arm64-cross",
    )?;
    // ONNX Runtime's library is C++: its runtime, for qemu here (a board has it).
    ensure_file(
        &format!("{AARCH64_SYSROOT}/lib/libstdc++.so.6"),
        "libstdc++6-arm64-cross",
    )?;
    ensure_rust_target(AARCH64)?;
    cargo_with(
        root,
        &[
            &["build", "--release", "--target", AARCH64][..],
            &ONBOARD[..],
        ]
        .concat(),
        &[
            (
                "CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER",
                "aarch64-linux-gnu-gcc",
            ),
            ("CC_aarch64_unknown_linux_gnu", "aarch64-linux-gnu-gcc"),
            ("AR_aarch64_unknown_linux_gnu", "aarch64-linux-gnu-ar"),
        ],
    )?;
    let ort = onnxruntime_from_wheel(
        &root.join(".ort").join("aarch64"),
        &[
            "--platform",
            "manylinux_2_28_aarch64",
            "--platform",
            "manylinux_2_27_aarch64",
            "--platform",
            "manylinux2014_aarch64",
            "--python-version",
            "3.11",
            "--implementation",
            "cp",
        ],
    )?;
    let bin = target_dir(root).join(AARCH64).join("release");
    for name in ["towernav-edge", "towernav-db", "towernav-fleet"] {
        let path = bin.join(name);
        anyhow::ensure!(path.is_file(), "{} was not built", path.display());
        eprintln!("xtask: {}", path.display());
    }
    Ok(CrossBuild {
        bin,
        ort,
        qemu_sysroot: qemu_sysroot(root)?,
    })
}

/// `rustup target add` when the standard library for `target` is missing.
fn ensure_rust_target(target: &str) -> anyhow::Result<()> {
    let installed = Command::new("rustup")
        .args(["target", "list", "--installed"])
        .output()
        .context("running rustup (the cross build needs the target's standard library)")?;
    if String::from_utf8_lossy(&installed.stdout)
        .lines()
        .any(|l| l.trim() == target)
    {
        return Ok(());
    }
    run(Command::new("rustup").args(["target", "add", target]))
}
