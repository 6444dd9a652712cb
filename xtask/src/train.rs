//! `cargo xtask train`: the detector's whole training pipeline in one command.
//!
//! 1. installs the pinned training environment (`training/requirements.txt`,
//!    Ultralytics on the CPU, from the Python package index) into `.venv-train/`;
//! 2. renders the simulator's YOLO dataset (`towernav-sim dataset`) into
//!    `target/train/dataset` unless it is there;
//!    (with `--randomize` of its frames domain-randomized, over the real
//!    tower-free photos of `--backgrounds`);
//! 3. runs `training/train.py`, detached, logging to `target/train/train.log`:
//!    it fine-tunes the shipped detector (`models/towers.pt`; `--from-scratch`
//!    starts over) within a wall-clock budget, on the CPU or `--device 0`,
//!    resumes from its last checkpoint when run again after an interruption,
//!    exports ONNX and evaluates;
//! 4. then `training/train_types.py`: the tower-type classifier the edge runs
//!    on each box's full-resolution crop (about 35 minutes), into `target/train/types`;
//! 5. then `training/quantize.py`: INT8 versions of both (`cargo xtask quantize`
//!    alone redoes this step).
//!
//! With `--data` (a survey flight's labels, real labelled photos), step 2
//! ends with `training/mix.py`: their frames and the rendered ones in one
//! dataset (`target/train/mixed`), the model taking their class names; the
//! classifier step is skipped (the detector's own classes type the boxes); and
//! a last step writes the run's model card (`MODEL_CARD.md`: their held-out
//! frames scored for the new model and the one it started from).
//!
//! `--foreground` waits for it; `--ship` copies the exported models and the
//! detector's checkpoint into `models/` once a run has finished, so the next
//! stage starts from it on any machine. `--detector-only` skips the classifier.

use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use anyhow::{Context, bail};

use crate::{build_release, run, target_dir};

#[derive(Clone)]
pub struct TrainOptions {
    pub foreground: bool,
    pub ship: bool,
    pub hours: f64,
    pub worlds: u32,
    pub frames_per_world: u32,
    pub continue_run: bool,
    pub randomize: f64,
    pub backgrounds: Vec<PathBuf>,
    pub detector_only: bool,
    pub from_scratch: bool,
    pub init: Option<PathBuf>,
    pub freeze: Option<u32>,
    pub real: bool,
    pub device: String,
    pub mix: MixOptions,
    pub card: bool,
    pub work: Option<PathBuf>,
}

/// Labelled images mixed with the rendered frames (`training/mix.py`).
#[derive(Clone)]
pub struct MixOptions {
    pub data: Vec<PathBuf>,
    pub data_names: Option<String>,
    pub names: Option<String>,
    pub map: Vec<String>,
}

pub fn train(root: &Path, options: &TrainOptions, ort: Option<&Path>) -> anyhow::Result<()> {
    let work = options
        .work
        .clone()
        .unwrap_or_else(|| target_dir(root).join("train"));
    let work = std::path::absolute(&work)
        .with_context(|| format!("the training folder {}", work.display()))?;
    let run_dir = work.join("run");
    if options.ship {
        return ship(root, &run_dir, &work.join("types"));
    }
    if options.card {
        let ort = ort.context("the model card needs ONNX Runtime")?;
        return crate::train_card::write(root, &work, ort);
    }
    let pid_file = work.join("train.pid");
    if let Some(pid) = running(&pid_file) {
        bail!(
            "training is already running (pid {pid}); follow it with `tail -f {}`",
            work.join("train.log").display()
        );
    }
    let python = ensure_venv(root)?;
    let (options, mix_options) = &with_real_data(root, &python, &work, options)?;
    let rendered = work.join("dataset");
    if !rendered.join("data.yaml").exists() {
        render_dataset(root, &rendered, options)?;
    }
    let mixing = !mix_options.data.is_empty();
    let dataset = if mixing {
        mix(root, &python, &work, &rendered, mix_options)?
    } else {
        rendered.clone()
    };
    let shipped = root.join("models").join("towers.pt");
    let init = if options.continue_run {
        Some(archive_finished_run(&work, &run_dir)?)
    } else if let Some(init) = &options.init {
        let init = &resolve_init(root, init);
        if !init.is_file() {
            bail!("--init {}: no such checkpoint", init.display());
        }
        Some(init.clone())
    } else if !options.from_scratch && shipped.exists() {
        Some(shipped)
    } else {
        None
    };
    // A COCO start freezes its backbone first.
    let freeze = options
        .freeze
        .unwrap_or(if options.init.as_deref() == Some(Path::new(COCO)) {
            10
        } else {
            0
        });
    // Their own classes type the boxes: no classifier trained on rendered A-D crops.
    let detector_only = options.detector_only || mixing;
    // The detector, then the tower-type classifier on its dataset's crops (a
    // finished classifier only re-exports). Lowest CPU priority, and OpenMP
    // threads that sleep instead of spinning: the run soaks up idle cores
    // without slowing a build beside it.
    let types_dir = work.join("types");
    // With --detector-only the classifier step is `true` and the quantizer gets the detector alone.
    let classifier_step = if detector_only {
        r#"true"#
    } else {
        r#""$1" "$7" --data "$3" --out "$8""#
    };
    let mut cmd = Command::new("nice");
    // After a mixed run, the model card: this same xtask binary, `train --card`.
    let card_step = if mixing {
        r#" && "$TOWERNAV_XTASK" train --card --work "$TOWERNAV_TRAIN_WORK""#
    } else {
        ""
    };
    cmd.args(["-n", "19", "sh", "-c"])
        .arg(format!(r#""$1" "$2" --data "$3" --out "$4" --hours "$5" ${{6:+--init "$6"}} && {classifier_step} && py="$1" q="$9" && shift 9 && "$py" "$q" "$@"{card_step}"#))
        .arg("sh")
        .arg(&python)
        .arg(root.join("training").join("train.py"))
        .arg(&dataset)
        .arg(&run_dir)
        .arg(options.hours.to_string())
        .arg(init.as_deref().unwrap_or(Path::new("")))
        .env("TOWERNAV_TRAIN_FREEZE", freeze.to_string())
        .arg(root.join("training").join("train_types.py"))
        .arg(&types_dir)
        .arg(root.join("training").join("quantize.py"))
        // The quantizer's own arguments, "$@" after `shift 9`.
        .args(quantize_args(&work, &dataset, !detector_only, options.real))
        .env("OMP_WAIT_POLICY", "PASSIVE")
        .env("TOWERNAV_TRAIN_DEVICE", &options.device)
        .env("TOWERNAV_XTASK", std::env::current_exe()?)
        .env("TOWERNAV_TRAIN_WORK", &work)
        .current_dir(root);
    if options.foreground {
        return run(&mut cmd);
    }
    spawn_in_background(cmd, &work, &pid_file, options.hours, mixing)
}

/// `--init coco`: the COCO-trained YOLOv5n beside the project.
const COCO: &str = "coco";

fn resolve_init(root: &Path, init: &Path) -> PathBuf {
    if init == Path::new(COCO) {
        root.join("..")
            .join("shared")
            .join("weights")
            .join("coco")
            .join("yolov5n.pt")
    } else {
        init.to_path_buf()
    }
}

/// `--real`: `training/real_data.py` stages the manifest's real photographs in
/// `work/real`; its training folders join `--data` as one `tower` class (wooden
/// poles, not the detector's, leave with their frames) and their tower-free
/// frames join the renderer's backgrounds.
fn with_real_data(
    root: &Path,
    python: &Path,
    work: &Path,
    options: &TrainOptions,
) -> anyhow::Result<(TrainOptions, MixOptions)> {
    let mut mix = options.mix.clone();
    let mut backgrounds = options.backgrounds.clone();
    if options.real {
        let real = work.join("real");
        run(Command::new(python)
            .arg(root.join("training").join("real_data.py"))
            .arg("--real")
            .arg(root.join("..").join("shared").join("real"))
            .arg("--out")
            .arg(&real)
            .current_dir(root))?;
        let sources = std::fs::read_to_string(real.join("sources.txt"))
            .with_context(|| format!("reading {}", real.join("sources.txt").display()))?;
        mix.data.extend(sources.lines().map(PathBuf::from));
        mix.data_names
            .get_or_insert_with(|| "tower_lattice,tower_tucohy,tower_wooden".into());
        mix.names.get_or_insert_with(|| "tower".into());
        if mix.map.is_empty() {
            mix.map = vec![
                "tower_lattice=tower".into(),
                "tower_tucohy=tower".into(),
                "tower_wooden=-".into(),
            ];
        }
        backgrounds.push(real.join("backgrounds"));
    }
    let options = TrainOptions {
        backgrounds,
        mix: mix.clone(),
        ..options.clone()
    };
    Ok((options, mix))
}

/// The simulator's training set: `options.worlds` random worlds, randomized as asked.
fn render_dataset(root: &Path, dataset: &Path, options: &TrainOptions) -> anyhow::Result<()> {
    let bin = build_release(root, &["towernav-sim"])?;
    run(Command::new(bin.join("towernav-sim"))
        .arg("dataset")
        .arg("--out")
        .arg(dataset)
        .args([
            "--worlds",
            &options.worlds.to_string(),
            "--frames-per-world",
            &options.frames_per_world.to_string(),
            "--seed",
            "0",
            "--randomize",
            &options.randomize.to_string(),
        ])
        .args(
            options
                .backgrounds
                .iter()
                .flat_map(|b| [Path::new("--backgrounds"), b.as_path()]),
        ))?;
    Ok(())
}

/// `training/mix.py`: the rendered frames and `mix.data` in `work/mixed`.
fn mix(
    root: &Path,
    python: &Path,
    work: &Path,
    rendered: &Path,
    mix: &MixOptions,
) -> anyhow::Result<PathBuf> {
    let mixed = work.join("mixed");
    let mut cmd = Command::new(python);
    cmd.arg(root.join("training").join("mix.py"))
        .arg("--out")
        .arg(&mixed)
        .arg("--source")
        .arg(rendered.join("data.yaml"));
    for data in &mix.data {
        // A folder holding a data.yaml is that dataset.
        let source = if data.join("data.yaml").is_file() {
            data.join("data.yaml")
        } else {
            data.clone()
        };
        cmd.arg("--source").arg(source);
    }
    if let Some(names) = &mix.data_names {
        cmd.args(["--source-names", names]);
    }
    if let Some(names) = &mix.names {
        cmd.args(["--names", names]);
    }
    for rule in &mix.map {
        cmd.args(["--map", rule]);
    }
    run(cmd.current_dir(root))?;
    Ok(mixed)
}

/// Starts `cmd` detached, logging to `work/train.log`, its pid in `pid_file`.
fn spawn_in_background(
    mut cmd: Command,
    work: &Path,
    pid_file: &Path,
    hours: f64,
    mixed: bool,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(work)?;
    let log_path = work.join("train.log");
    let log = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&log_path)
        .with_context(|| format!("opening {}", log_path.display()))?;
    // Its own process group: the run outlives this command and the terminal.
    let child = cmd
        .stdin(Stdio::null())
        .stdout(log.try_clone()?)
        .stderr(log)
        .process_group(0)
        .spawn()
        .with_context(|| format!("starting {cmd:?}"))?;
    std::fs::write(pid_file, child.id().to_string())?;
    let done = if mixed {
        format!(
            "When it has finished, {} holds the model and MODEL_CARD.md (its score on your held-out frames).",
            work.join("run").display()
        )
    } else {
        "Run `cargo xtask train --ship` when it has finished to copy the model into models/.".into()
    };
    eprintln!(
        "xtask: training in the background (pid {}), budget {} h; follow with `tail -f {}`.\n\
         Run the same command again after an interruption to resume from the last checkpoint.\n{done}",
        child.id(),
        hours,
        log_path.display()
    );
    Ok(())
}

/// `training/quantize.py`'s arguments for the run in `work`: the detector's
/// export and, `with_types`, the classifier's, each calibrated on its own
/// training inputs (a mixed dataset's: the first of a survey's own frames; the
/// rendered ones when the mix is of real photographs, a few dozen seen from
/// above, which would set the ranges for a camera the UAV does not fly).
fn quantize_args(work: &Path, dataset: &Path, with_types: bool, real: bool) -> Vec<PathBuf> {
    let theirs = dataset.join("stage").join("1-train").join("images");
    let frames = if real {
        work.join("dataset").join("images").join("train")
    } else if theirs.is_dir() {
        theirs
    } else {
        dataset.join("images").join("train")
    };
    let mut args: Vec<PathBuf> = vec![
        "--detector".into(),
        work.join("run").join("towers.onnx"),
        "--frames".into(),
        frames,
    ];
    if with_types {
        let types = work.join("types");
        args.extend([
            "--types".into(),
            types.join("tower-types.onnx"),
            "--crops".into(),
            types.join("crops").join("train"),
        ]);
    }
    args
}

/// `cargo xtask quantize`: INT8 versions of the finished run's two models,
/// beside them (`towers-int8.onnx`, `tower-types-int8.onnx`).
pub fn quantize(root: &Path) -> anyhow::Result<()> {
    let python = ensure_venv(root)?;
    let work = target_dir(root).join("train");
    run(Command::new(python)
        .arg(root.join("training").join("quantize.py"))
        .args(quantize_args(&work, &work.join("dataset"), true, false))
        .current_dir(root))
}

/// Move a finished run to `run-stage<N>` and return its best weights, the
/// starting point of the next stage.
fn archive_finished_run(work: &Path, run_dir: &Path) -> anyhow::Result<PathBuf> {
    let best = run_dir.join("train").join("weights").join("best.pt");
    if !run_dir.join("summary.json").exists() || !best.exists() {
        bail!(
            "--continue-run needs a finished run in {} (with summary.json and train/weights/best.pt)",
            run_dir.display()
        );
    }
    let stage = (1..)
        .map(|n| work.join(format!("run-stage{n}")))
        .find(|p| !p.exists())
        .context("no free stage folder name")?;
    std::fs::rename(run_dir, &stage)
        .with_context(|| format!("moving {} to {}", run_dir.display(), stage.display()))?;
    Ok(stage.join("train").join("weights").join("best.pt"))
}

/// The pid in `pid_file` if that process is still alive.
fn running(pid_file: &Path) -> Option<u32> {
    let pid: u32 = std::fs::read_to_string(pid_file)
        .ok()?
        .trim()
        .parse()
        .ok()?;
    Path::new(&format!("/proc/{pid}")).exists().then_some(pid)
}

/// `.venv-train/bin/python` with the pinned requirements installed (once per
/// version of the requirements file).
fn ensure_venv(root: &Path) -> anyhow::Result<PathBuf> {
    let venv = root.join(".venv-train");
    let python = venv.join("bin").join("python");
    let requirements = root.join("training").join("requirements.txt");
    let wanted = std::fs::read_to_string(&requirements)
        .with_context(|| format!("reading {}", requirements.display()))?;
    let stamp = venv.join("installed-requirements.txt");
    if python.exists() && std::fs::read_to_string(&stamp).ok().as_deref() == Some(&wanted) {
        return Ok(python);
    }
    if !python.exists() {
        run(Command::new("python3").args(["-m", "venv"]).arg(&venv))?;
    }
    run(Command::new(&python)
        .args(["-m", "pip", "install", "--quiet", "-r"])
        .arg(&requirements))?;
    std::fs::write(&stamp, wanted)?;
    Ok(python)
}

/// Copy the finished run's models and numbers into `models/`.
fn ship(root: &Path, run_dir: &Path, types_dir: &Path) -> anyhow::Result<()> {
    let onnx = run_dir.join("towers.onnx");
    let summary = run_dir.join("summary.json");
    if !summary.exists() || !onnx.exists() {
        bail!(
            "no finished run in {} (it writes towers.onnx and summary.json when done)",
            run_dir.display()
        );
    }
    let models = root.join("models");
    std::fs::create_dir_all(&models)?;
    let files = [
        (onnx, "towers.onnx"),
        (summary, "towers.training.json"),
        (run_dir.join("towers-int8.onnx"), "towers-int8.onnx"),
        (
            run_dir.join("train").join("weights").join("best.pt"),
            "towers.pt",
        ),
        (types_dir.join("tower-types.onnx"), "tower-types.onnx"),
        (types_dir.join("summary.json"), "tower-types.training.json"),
        (
            types_dir.join("tower-types-int8.onnx"),
            "tower-types-int8.onnx",
        ),
    ];
    for (src, name) in files {
        if !src.exists() {
            eprintln!(
                "xtask: no {} (models/{name} left as it is; `cargo xtask quantize` makes the INT8 ones)",
                src.display()
            );
            continue;
        }
        let size = std::fs::metadata(&src)?.len();
        if size > 15 * 1024 * 1024 {
            bail!(
                "{} is {size} bytes; a shipped model must be 15 MB at most",
                src.display()
            );
        }
        std::fs::copy(&src, models.join(name))
            .with_context(|| format!("copying {} into {}", src.display(), models.display()))?;
        eprintln!(
            "xtask: shipped {} ({size} bytes) as models/{name}",
            src.display()
        );
    }
    eprintln!("xtask: update models/README.md with `towernav-edge eval-detector`'s numbers");
    Ok(())
}
