//! `cargo xtask demo | gs | test | train | quantize | screenshot | bench-edge | setup-ort | zenohd`: the project's two front doors, the ground station, and the detector's training.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, bail};

mod bench_edge;
mod cross;
mod deb;
mod screenshot;
mod system_packages;
mod train;
mod train_card;
mod zenohd;
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(about = "towernav project tasks")]
struct Cli {
    #[command(subcommand)]
    task: Task,
}

#[derive(Subcommand)]
enum Task {
    /// Fly the simulated flight of the paper through the whole chain and print the report.
    Demo(DemoArgs),
    /// Open the ground station on the demo's towers, connected to the demo's edge.
    Gs,
    /// Formatting, lints and every test: what CI runs.
    Test,
    /// Train the tower detector from scratch on rendered data (background, resumable).
    Train {
        /// Wait for it instead of running it in the background.
        #[arg(long)]
        foreground: bool,
        /// Copy a finished run's model into models/.
        #[arg(long)]
        ship: bool,
        /// Wall-clock budget for the training loop, hours.
        #[arg(long, default_value_t = 1.6)]
        hours: f64,
        #[arg(long, default_value_t = 100)]
        worlds: u32,
        #[arg(long, default_value_t = 30)]
        frames_per_world: u32,
        /// Start a new stage from the finished run's own best weights (the
        /// earlier run is kept as `run-stage<N>`); no weights are downloaded.
        #[arg(long)]
        continue_run: bool,
        /// Share of the rendered dataset's frames that are domain-randomized.
        #[arg(long, default_value_t = 0.75)]
        randomize: f64,
        /// Folders of real tower-free photos: backgrounds and negatives (repeatable).
        #[arg(long)]
        backgrounds: Vec<PathBuf>,
        /// Train the detector only; keep the shipped type classifier.
        #[arg(long)]
        detector_only: bool,
        /// Train from a random start instead of fine-tuning models/towers.pt.
        #[arg(long, conflicts_with = "init")]
        from_scratch: bool,
        /// The checkpoint to start from (default: models/towers.pt): `coco`
        /// for the COCO-trained YOLOv5n in ../shared/weights/coco/, another
        /// checkpoint of the old yolov5 tree (converted: backbone and neck
        /// kept, a fresh head), or an Ultralytics checkpoint.
        #[arg(long)]
        init: Option<PathBuf>,
        /// Train first with this many leading layers frozen (10: the
        /// backbone), then all; default 10 from a COCO start, else 0.
        #[arg(long)]
        freeze: Option<u32>,
        /// Mix in the real photographs of training/data/real-sources.csv
        /// (`training/real_data.py`): its training sources as one `tower`
        /// class, their tower-free frames as the renderer's backgrounds.
        #[arg(long)]
        real: bool,
        /// Train the detector on this device: `cpu`, or a CUDA index such as
        /// `0` (larger batches and more data workers there).
        #[arg(long, default_value = "cpu")]
        device: String,
        /// Labelled images to mix with the rendered frames (repeatable): a
        /// data.yaml (`towernav-edge label`'s output) or a folder with images/
        /// and labels/ or labels_yolo/. The model takes the first data.yaml's
        /// class names; a survey flight's last fifth is held out and scored.
        #[arg(long)]
        data: Vec<PathBuf>,
        /// Class names, by id, of --data folders that have no data.yaml.
        #[arg(long)]
        data_names: Option<String>,
        /// The model's class names, comma-separated (default: see --data).
        #[arg(long)]
        names: Option<String>,
        /// SRC=DST: train a --data class as one of the model's (DST `-`
        /// leaves out the images that hold it). Repeatable.
        #[arg(long)]
        map: Vec<String>,
        /// The training folder (dataset, mixed dataset, run); default
        /// `target/train`. One per model: two runs never share one.
        #[arg(long)]
        work: Option<PathBuf>,
        /// Write the finished run's model card (run after training by itself).
        #[arg(long, hide = true)]
        card: bool,
    },
    /// INT8 versions of the finished training run's two models (ONNX Runtime's quantizer).
    Quantize,
    /// The edge daemon end to end on 1280x720 camera frames with the shipped detector: frames/s, latency, peak RSS.
    BenchEdge,
    /// A long flight through the edge daemon: peak RSS, latency p99 and lost poses per minute of flight.
    Soak {
        /// Minutes of flight (the simulator flies as fast as the daemon goes).
        #[arg(long, default_value_t = 60.0)]
        minutes: f64,
        /// `oracle` (the simulator's boxes) or `yolo` (rendered frames through the detector).
        #[arg(long, default_value = "oracle")]
        detector: String,
    },
    /// A screenshot of the ground station's real window under Xvfb, beside a demo edge (docs/ground-station.png).
    Screenshot {
        /// Seconds of flight before the picture.
        #[arg(long, default_value_t = 15.0)]
        seconds: f64,
    },
    /// Install ONNX Runtime's shared library into .ort/ (from the onnxruntime wheel on PyPI).
    SetupOrt,
    /// Build the Zenoh router matching the project's Zenoh into .zenohd/
    /// (`.zenohd/bin/zenohd -c router.json5`; see `towernav-fleet router-config`).
    Zenohd,
    /// Cross-build the onboard binaries (edge, towernav-db, towernav-fleet)
    /// for a companion computer, with ONNX Runtime's library for it.
    Cross {
        /// The architecture: aarch64.
        #[arg(default_value = "aarch64")]
        arch: String,
    },
    /// The onboard binaries, models, ONNX Runtime, config and systemd unit as
    /// a Debian package in target/deb/.
    Deb {
        /// The Debian architecture: amd64 or arm64.
        #[arg(default_value = "amd64")]
        arch: String,
    },
}

#[derive(clap::Args)]
struct DemoArgs {
    /// Playback speed relative to real time (0: as fast as possible, every
    /// frame processed; 1 to watch live). Faster than the detector can go
    /// drops frames, and the estimate drifts from the truth it is scored on.
    #[arg(long, default_value_t = 0.0)]
    speed: f64,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// A preset flight or a waypoint plan file (see `towernav-edge demo --help`).
    #[arg(long)]
    flight: Option<String>,
    /// Fly over a random world drawn from this seed.
    #[arg(long, conflicts_with = "world")]
    random_world: Option<u64>,
    /// Fly over the towers of this landmark CSV or database.
    #[arg(long)]
    world: Option<PathBuf>,
    /// `yolo` (the shipped models on rendered frames) or `oracle` (no model).
    #[arg(long, default_value = "yolo", value_parser = ["yolo", "oracle"])]
    detector: String,
}

/// What a task needs on the machine beyond the Rust toolchain, installed
/// before it builds anything so a fresh machine fails early or not at all.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Prerequisite {
    /// ONNX Runtime's shared library in `.ort/lib/`, for the YOLO detector.
    OnnxRuntime,
    /// ffmpeg, for the video source's tests.
    Ffmpeg,
    /// Xvfb, for the ground station's real window.
    Xvfb,
    /// rustfmt and clippy.
    LintComponents,
    /// pymavlink, the independent MAVLink decoder the autopilot-link test listens with.
    Pymavlink,
}

impl Task {
    fn prerequisites(&self) -> Vec<Prerequisite> {
        use Prerequisite::*;
        match self {
            Self::Demo(args) if args.detector == "oracle" => vec![],
            Self::Demo(_) | Self::BenchEdge => vec![OnnxRuntime],
            Self::Soak { detector, .. } if detector != "oracle" => vec![OnnxRuntime],
            Self::Test => vec![LintComponents, OnnxRuntime, Ffmpeg, Pymavlink],
            Self::Screenshot { .. } => vec![Xvfb],
            // The model card scores the finished run with the edge's detector.
            Self::Train { card: true, .. } => vec![OnnxRuntime],
            Self::Gs
            | Self::Train { .. }
            | Self::Quantize
            | Self::SetupOrt
            | Self::Zenohd
            | Self::Soak { .. }
            | Self::Cross { .. }
            | Self::Deb { .. } => {
                vec![]
            }
        }
    }
}

/// Installs what `task` needs; returns the ONNX Runtime library when it is one.
fn install(root: &Path, task: &Task) -> anyhow::Result<Option<PathBuf>> {
    let mut ort = None;
    for need in task.prerequisites() {
        match need {
            Prerequisite::OnnxRuntime => ort = Some(ensure_onnxruntime(root)?),
            Prerequisite::Ffmpeg => system_packages::ensure_program("ffmpeg", "ffmpeg")?,
            Prerequisite::Xvfb => system_packages::ensure_program("xvfb-run", "xvfb")?,
            Prerequisite::LintComponents => ensure_components()?,
            Prerequisite::Pymavlink => ensure_pymavlink(root)?,
        }
    }
    Ok(ort)
}

/// The pymavlink release the tests decode with (its dialects know
/// GLOBAL_POSITION_SENSOR and ODOMETRY's quality).
const PYMAVLINK_VERSION: &str = "2.4.50";
/// PyYAML, for the training data mixer's test.
const PYYAML_VERSION: &str = "6.0.3";
/// eclipse-zenoh for Python, an independent client of a secured fleet.
const ECLIPSE_ZENOH_VERSION: &str = "1.10.2";
/// GoPro's own GPMF parser (its C library, bound for Python), to check ours.
const PY_GPMF_PARSER_VERSION: &str = "0.1.1";
/// rosbags: ROS 2's CDR and type hashes in pure Python, to check the ROS 2 topics.
const ROSBAGS_VERSION: &str = "0.11.9";
/// pycdr2: Cyclone DDS's XCDR2 in pure Python, as PX4's Zenoh module reads it.
const PYCDR2_VERSION: &str = "1.0.0";

/// `.pydeps/` under the workspace, holding pymavlink from the Python package
/// index; the tests find it through `TOWERNAV_PYTHONPATH`.
fn ensure_pymavlink(root: &Path) -> anyhow::Result<()> {
    let dir = root.join(".pydeps");
    // PyYAML beside it: the training data mixer's test reads data.yaml files;
    // eclipse-zenoh, a client of a secured fleet that is not ours; GoPro's
    // GPMF parser; rosbags and pycdr2, ROS 2's and PX4's CDR.
    let installed = |name: &str, version: &str| {
        let want = format!("{name}-{version}.dist-info").to_lowercase();
        std::fs::read_dir(&dir).is_ok_and(|entries| {
            entries
                .flatten()
                .any(|e| e.file_name().to_string_lossy().to_lowercase() == want)
        })
    };
    if installed("pymavlink", PYMAVLINK_VERSION)
        && installed("pyyaml", PYYAML_VERSION)
        && installed("eclipse_zenoh", ECLIPSE_ZENOH_VERSION)
        && installed("py_gpmf_parser", PY_GPMF_PARSER_VERSION)
        && installed("rosbags", ROSBAGS_VERSION)
        && installed("pycdr2", PYCDR2_VERSION)
    {
        return Ok(());
    }
    run(Command::new("python3")
        .args([
            "-m",
            "pip",
            "install",
            "--quiet",
            "--disable-pip-version-check",
            "--upgrade",
            "--target",
        ])
        .arg(&dir)
        .arg(format!("pymavlink=={PYMAVLINK_VERSION}"))
        .arg(format!("pyyaml=={PYYAML_VERSION}"))
        .arg(format!("eclipse-zenoh=={ECLIPSE_ZENOH_VERSION}"))
        .arg(format!("py-gpmf-parser=={PY_GPMF_PARSER_VERSION}"))
        .arg(format!("rosbags=={ROSBAGS_VERSION}"))
        .arg(format!("pycdr2=={PYCDR2_VERSION}")))?;
    eprintln!(
        "xtask: pymavlink {PYMAVLINK_VERSION}, PyYAML {PYYAML_VERSION}, eclipse-zenoh {ECLIPSE_ZENOH_VERSION}, py-gpmf-parser {PY_GPMF_PARSER_VERSION}, rosbags {ROSBAGS_VERSION} and pycdr2 {PYCDR2_VERSION} in {}",
        dir.display()
    );
    Ok(())
}

/// The ONNX Runtime release whose C API the `ort` crate's `api-31` feature speaks.
const ONNXRUNTIME_VERSION: &str = "1.31.1";

fn main() -> anyhow::Result<()> {
    // `cargo run` names the checkout it runs from; the path compiled in may be
    // another checkout's when two share a target directory and its build.
    let manifest_dir = std::env::var_os("CARGO_MANIFEST_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| env!("CARGO_MANIFEST_DIR").into());
    let root = manifest_dir
        .parent()
        .context("xtask lives one level below the workspace root")?
        .to_path_buf();
    let task = Cli::parse().task;
    let ort = install(&root, &task)?;
    match task {
        Task::Demo(args) => demo(&root, &args, ort.as_deref()),
        Task::Gs => ground_station(&root),
        Task::Test => test(&root, ort.as_deref()),
        Task::BenchEdge => bench_edge::bench_edge(&root, ort.as_deref()),
        Task::Soak { minutes, detector } => soak(&root, minutes, &detector, ort.as_deref()),
        Task::Screenshot { seconds } => screenshot::screenshot(&root, seconds),
        Task::Quantize => train::quantize(&root),
        Task::SetupOrt => ensure_onnxruntime(&root).map(|_| ()),
        Task::Zenohd => zenohd::ensure_zenohd(&root).map(|bin| println!("{}", bin.display())),
        Task::Cross { arch } => cross::cross(&root, &arch).map(|_| ()),
        Task::Deb { arch } => deb::deb(&root, &arch).map(|_| ()),
        Task::Train {
            foreground,
            ship,
            hours,
            worlds,
            frames_per_world,
            continue_run,
            randomize,
            backgrounds,
            detector_only,
            from_scratch,
            init,
            freeze,
            real,
            device,
            data,
            data_names,
            names,
            map,
            work,
            card,
        } => train::train(
            &root,
            &train::TrainOptions {
                foreground,
                ship,
                hours,
                worlds,
                frames_per_world,
                continue_run,
                randomize,
                backgrounds,
                detector_only,
                from_scratch,
                init,
                freeze,
                real,
                device,
                mix: train::MixOptions {
                    data,
                    data_names,
                    names,
                    map,
                },
                card,
                work,
            },
            ort.as_deref(),
        ),
    }
}

/// `.ort/lib/libonnxruntime.so` under the workspace, fetched once from the
/// `onnxruntime` wheel on the Python package index (pip, no other network).
fn ensure_onnxruntime(root: &Path) -> anyhow::Result<PathBuf> {
    onnxruntime_from_wheel(&root.join(".ort"), &[])
}

/// `dir/lib/libonnxruntime.so` from the `onnxruntime` wheel pip picks with
/// `pip_args` (a `--platform` for another architecture's), fetched once.
fn onnxruntime_from_wheel(dir: &Path, pip_args: &[&str]) -> anyhow::Result<PathBuf> {
    let lib = dir.join("lib").join("libonnxruntime.so");
    if lib.exists() {
        return Ok(lib);
    }
    let wheels = dir.join("wheel");
    std::fs::create_dir_all(lib.parent().context("lib has a parent")?)?;
    run(Command::new("python3")
        .args([
            "-m",
            "pip",
            "download",
            "--quiet",
            "--no-deps",
            "--only-binary=:all:",
        ])
        .args(pip_args)
        .arg(format!("onnxruntime=={ONNXRUNTIME_VERSION}"))
        .arg("-d")
        .arg(&wheels))?;
    // Unpack only the shared library from the wheel (a zip).
    let script = "import sys, zipfile, glob, shutil\n\
        wheel = glob.glob(sys.argv[1] + '/onnxruntime-*.whl')[0]\n\
        z = zipfile.ZipFile(wheel)\n\
        name = [n for n in z.namelist() if '/capi/libonnxruntime.so' in n][0]\n\
        with z.open(name) as src, open(sys.argv[2], 'wb') as dst: shutil.copyfileobj(src, dst)\n";
    run(Command::new("python3")
        .args(["-c", script])
        .arg(&wheels)
        .arg(&lib))?;
    eprintln!(
        "xtask: ONNX Runtime {ONNXRUNTIME_VERSION} at {}",
        lib.display()
    );
    Ok(lib)
}

fn target_dir(root: &Path) -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| root.join("target"), PathBuf::from)
}

/// `cargo xtask soak`: the daemon built for release, then the soak bench against it.
fn soak(root: &Path, minutes: f64, detector: &str, ort: Option<&Path>) -> anyhow::Result<()> {
    let bin = build_release(root, &["towernav-edge"])?;
    let edge = bin.join("towernav-edge");
    let out = target_dir(root).join("soak");
    let mut env = vec![];
    let ort = ort.map(|p| p.display().to_string());
    if let Some(ort) = &ort {
        env.push(("ORT_DYLIB_PATH", ort.as_str()));
    }
    cargo_with(
        root,
        &[
            "bench",
            "-p",
            "towernav-tests",
            "--bench",
            "soak",
            "--",
            "--edge",
            &edge.display().to_string(),
            "--minutes",
            &minutes.to_string(),
            "--detector",
            detector,
            "--out",
            &out.display().to_string(),
        ],
        &env,
    )
}

/// Builds these packages' release binaries; returns the folder they are in.
/// The edge is built with its demo feature: every xtask that runs it flies the simulator.
fn build_release(root: &Path, packages: &[&str]) -> anyhow::Result<PathBuf> {
    let mut args = vec!["build", "--release"];
    for p in packages {
        args.extend(["-p", p]);
    }
    if packages.contains(&"towernav-edge") {
        args.extend(["--features", "towernav-edge/demo"]);
    }
    cargo(root, &args)?;
    Ok(target_dir(root).join("release"))
}

fn cargo(root: &Path, args: &[&str]) -> anyhow::Result<()> {
    cargo_with(root, args, &[])
}

fn cargo_with(root: &Path, args: &[&str], env: &[(&str, &str)]) -> anyhow::Result<()> {
    run(
        Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
            .args(args)
            .envs(env.iter().copied())
            .current_dir(root),
    )
}

fn run(cmd: &mut Command) -> anyhow::Result<()> {
    eprintln!("xtask: {cmd:?}");
    let status = cmd.status().with_context(|| format!("starting {cmd:?}"))?;
    if !status.success() {
        bail!("{cmd:?} failed with {status}");
    }
    Ok(())
}

/// Makes sure rustfmt and clippy are there; a fresh rustup toolchain may lack them.
fn ensure_components() -> anyhow::Result<()> {
    let installed = Command::new("rustup")
        .args(["component", "list", "--installed"])
        .output();
    let Ok(out) = installed else {
        return Ok(()); // No rustup: trust the toolchain as it is.
    };
    let list = String::from_utf8_lossy(&out.stdout);
    for component in ["rustfmt", "clippy"] {
        if !list.lines().any(|l| l.starts_with(component)) {
            run(Command::new("rustup").args(["component", "add", component]))?;
        }
    }
    Ok(())
}

fn demo(root: &Path, args: &DemoArgs, ort: Option<&Path>) -> anyhow::Result<()> {
    let bin = build_release(root, &["towernav-edge", "towernav-sim"])?;
    let demo_dir = target_dir(root).join("demo");
    std::fs::create_dir_all(&demo_dir)
        .with_context(|| format!("creating {}", demo_dir.display()))?;
    // The world's towers, for the edge and for `cargo xtask gs`.
    let towers = demo_dir.join("towers.csv");
    let mut world = Vec::new();
    if let Some(seed) = args.random_world {
        world.extend(["--random-world".into(), seed.to_string()]);
    }
    if let Some(path) = &args.world {
        world.extend(["--world".into(), path.display().to_string()]);
    }
    run(Command::new(bin.join("towernav-sim"))
        .arg("world")
        .args(&world)
        .arg("--out")
        .arg(&towers))?;
    let mut edge = Command::new(bin.join("towernav-edge"));
    edge.args([
        "demo",
        "--speed",
        &args.speed.to_string(),
        "--seed",
        &args.seed.to_string(),
        "--detector",
        &args.detector,
    ])
    .args(&world)
    .arg("--landmarks")
    .arg(&towers);
    if let Some(flight) = &args.flight {
        edge.args(["--flight", flight]);
    }
    if let Some(ort) = ort {
        edge.env("ORT_DYLIB_PATH", ort);
    }
    run(&mut edge)
}

fn ground_station(root: &Path) -> anyhow::Result<()> {
    let demo_dir = target_dir(root).join("demo");
    let towers = demo_dir.join("towers.csv");
    if !towers.exists() {
        bail!(
            "{} is missing: run `cargo xtask demo` once first",
            towers.display()
        );
    }
    let bin = build_release(root, &["towernav-ground-station"])?;
    let db = demo_dir.join("towers.sqlite");
    let mut cmd = Command::new(bin.join("towernav-gs"));
    cmd.arg("--db")
        .arg(&db)
        .args(["--connect", "tcp/127.0.0.1:7447"]);
    if !db.exists() {
        cmd.arg("--import").arg(&towers);
    }
    run(&mut cmd)
}

fn test(root: &Path, ort: Option<&Path>) -> anyhow::Result<()> {
    let ort = ort.context("the tests need ONNX Runtime")?;
    cargo(root, &["fmt", "--all", "--", "--check"])?;
    // Clippy lints while the tests build: clippy-driver compiles the
    // workspace's own crates (as `cargo clippy` has it do), so every
    // dependency is compiled once, for the tests, instead of checked for the
    // lints and then built again. Warnings are errors.
    let clippy = Clippy::find()?;
    run(clippy
        .cargo(root)
        .args(["test", "--workspace", "--all-targets", "--no-run"]))?;
    // The workspace build turns the edge's demo feature on (the tests use it):
    // lint the onboard build, which has none of it, on its own. Its
    // dependencies are the workspace's (build-unify/), so only it compiles.
    run(clippy.cargo(root).args(["build", "-p", "towernav-edge"]))?;
    // The onboard binaries for aarch64, which a test runs under qemu-user,
    // and both architectures' Debian packages, which a test unpacks.
    let mut debs = vec![deb::deb(root, "amd64")?];
    // The aarch64 toolchain comes from Debian and rustup: where the machine
    // cannot get it, its tests say they were skipped, and the rest run.
    let aarch64 = cross::cross(root, "aarch64")
        .and_then(|build| {
            system_packages::ensure_program("qemu-aarch64", "qemu-user")?;
            debs.push(deb::deb(root, "arm64")?);
            Ok(build)
        })
        .map_err(|e| eprintln!("xtask: no aarch64 build here ({e:#}): its tests are skipped"))
        .ok();
    // A real router for the fault suite's restart, built once beside the
    // target cache (outside the clone, so CI keeps it between runs).
    let zenohd = zenohd::ensure_zenohd_in(root, &target_dir(root).with_file_name("zenohd"))
        .map_err(|e| eprintln!("xtask: no zenohd here ({e:#}): its restart test is skipped"))
        .ok();
    let mut tests = clippy.cargo(root);
    if let Some(zenohd) = &zenohd {
        tests.env("TOWERNAV_ZENOHD", zenohd);
    }
    tests
        .args(["test", "--workspace", "--no-fail-fast"])
        .env("ORT_DYLIB_PATH", ort)
        .env("TOWERNAV_PYTHONPATH", root.join(".pydeps"))
        .env("TOWERNAV_DEBS", std::env::join_paths(&debs)?);
    if let Some(build) = &aarch64 {
        tests
            .env("TOWERNAV_AARCH64_BIN", &build.bin)
            .env("TOWERNAV_AARCH64_ORT", &build.ort)
            .env("TOWERNAV_AARCH64_SYSROOT", &build.qemu_sysroot);
    }
    run(&mut tests)
}

/// clippy-driver as the compiler of the workspace's own crates, with
/// warnings denied: what `cargo clippy` sets up, around any cargo command.
struct Clippy {
    driver: PathBuf,
}

impl Clippy {
    /// The driver beside the cargo running this task (the same toolchain), else on PATH.
    fn find() -> anyhow::Result<Self> {
        let cargo = PathBuf::from(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
        let beside = cargo.with_file_name("clippy-driver");
        let driver = if beside.is_file() {
            beside
        } else {
            PathBuf::from("clippy-driver")
        };
        let works = Command::new(&driver)
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success());
        anyhow::ensure!(
            works,
            "clippy-driver not found beside {} nor on PATH: `rustup component add clippy`",
            cargo.display()
        );
        Ok(Self { driver })
    }

    fn cargo(&self, root: &Path) -> Command {
        let mut cmd = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
        cmd.current_dir(root)
            .env("RUSTC_WORKSPACE_WRAPPER", &self.driver)
            // cargo-clippy's own way of handing lint flags to the driver.
            .env(
                "CLIPPY_ARGS",
                "-D__CLIPPY_HACKERY__warnings__CLIPPY_HACKERY__",
            );
        cmd
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn task(args: &[&str]) -> Task {
        Cli::parse_from(std::iter::once("xtask").chain(args.iter().copied())).task
    }

    #[test]
    fn the_demo_installs_onnx_runtime_before_it_builds() {
        assert!(
            task(&["demo"])
                .prerequisites()
                .contains(&Prerequisite::OnnxRuntime)
        );
        assert!(
            task(&["demo", "--random-world", "3", "--flight", "plan.toml"])
                .prerequisites()
                .contains(&Prerequisite::OnnxRuntime)
        );
        assert_eq!(
            task(&["demo", "--detector", "oracle"]).prerequisites(),
            vec![],
            "the oracle runs no model"
        );
        let test = task(&["test"]).prerequisites();
        for need in [
            Prerequisite::OnnxRuntime,
            Prerequisite::Ffmpeg,
            Prerequisite::LintComponents,
            Prerequisite::Pymavlink,
        ] {
            assert!(test.contains(&need), "{need:?}");
        }
        assert!(
            task(&["bench-edge"])
                .prerequisites()
                .contains(&Prerequisite::OnnxRuntime)
        );
    }
}
