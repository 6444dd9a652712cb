//! `training/mix.py`, which mixes a user's labels with the rendered frames
//! for `cargo xtask train --data`, on a tiny fixture with known answers.

use std::path::Path;
use std::process::Command;

/// Writes `n` one-pixel JPEG stand-ins and their labels under `dir`.
fn frames(dir: &Path, names: &[&str], label: &str) {
    std::fs::create_dir_all(dir.join("images")).expect("images");
    for (i, name) in names.iter().enumerate() {
        std::fs::write(dir.join("images").join(format!("{name}.jpg")), b"jpg").expect("image");
        let labels = dir.join(if label == "yolo" {
            "labels_yolo"
        } else {
            "labels"
        });
        std::fs::create_dir_all(&labels).expect("labels");
        // Class i % 3: 0, 1, 2, 0...
        std::fs::write(
            labels.join(format!("{name}.txt")),
            format!("{} 0.5 0.5 0.1 0.4\n", i % 3),
        )
        .expect("label");
    }
}

fn lines(path: &Path) -> Vec<String> {
    std::fs::read_to_string(path)
        .expect("list")
        .lines()
        .map(str::to_owned)
        .collect()
}

#[test]
fn a_survey_and_a_real_folder_mix_with_rendered_frames_renamed_and_held_out() {
    let Some(pythonpath) = towernav_tests::python_module("yaml") else {
        eprintln!("skipped: no PyYAML (cargo xtask test installs it)");
        return;
    };
    let dir = tempfile::tempdir().expect("tempdir");
    let root = dir.path();
    // The rendered set: types A-D, its own splits.
    let rendered = root.join("rendered");
    frames(
        &rendered.join("train"),
        &["r0", "r1", "r2", "r3", "r4", "r5"],
        "",
    );
    frames(&rendered.join("val"), &["v0"], "");
    std::fs::write(
        rendered.join("data.yaml"),
        format!(
            "path: {}\ntrain: train/images\nval: val/images\nnames:\n  0: A\n  1: B\n  2: C\n  3: D\n",
            rendered.display()
        ),
    )
    .expect("yaml");
    // A survey flight's labels: one class, train and val the same folder.
    let survey = root.join("survey");
    frames(&survey, &["f00", "f01", "f02", "f03", "f04"], "");
    std::fs::write(
        survey.join("data.yaml"),
        format!(
            "path: {}\ntrain: images\nval: images\nnames:\n  0: tower\n",
            survey.display()
        ),
    )
    .expect("yaml");
    // Class 0 everywhere in the survey: rewrite its labels so.
    for f in ["f00", "f01", "f02", "f03", "f04"] {
        std::fs::write(
            survey.join("labels").join(format!("{f}.txt")),
            "0 0.5 0.5 0.1 0.4\n",
        )
        .expect("label");
    }
    // A real folder without data.yaml, its labels in labels_yolo/.
    let real = root.join("real");
    frames(&real, &["p0", "p1", "p2"], "yolo");
    let out = root.join("mixed");
    let status = Command::new("python3")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("../training/mix.py"))
        .arg("--out")
        .arg(&out)
        .arg("--source")
        .arg(rendered.join("data.yaml"))
        .arg("--source")
        .arg(survey.join("data.yaml"))
        .arg("--source")
        .arg(&real)
        .args(["--source-names", "lattice,tubular,wooden"])
        .args(["--map", "wooden=-", "--repeat", "2"])
        .env("PYTHONPATH", pythonpath)
        .status()
        .expect("python3 runs");
    assert!(status.success());

    // The survey's names win: a one-class model, every rendered and real
    // tower renamed to it, but wooden poles' images left out.
    let yaml = std::fs::read_to_string(out.join("data.yaml")).expect("data.yaml");
    assert!(yaml.contains("0: tower") && !yaml.contains("1:"), "{yaml}");
    let train = lines(&out.join("train.txt"));
    // 6 rendered, 4 survey frames twice, 2 real photos (p2 is wooden) twice.
    assert_eq!(train.len(), 6 + 4 * 2 + 2 * 2, "{train:?}");
    assert!(
        !train.iter().any(|p| p.ends_with("p2.jpg")),
        "wooden left out"
    );
    // The survey's last frame is held out, in val and as a folder to score.
    let val = lines(&out.join("val.txt"));
    assert!(val.iter().any(|p| p.ends_with("f04.jpg")), "{val:?}");
    assert!(
        !train.iter().any(|p| p.ends_with("f04.jpg")),
        "never trained on"
    );
    let heldout = lines(&out.join("heldout.txt"));
    assert_eq!(heldout.len(), 1, "{heldout:?}");
    assert!(Path::new(&heldout[0]).join("images").is_dir());
    // Every label was renamed to class 0, next to its linked image.
    for image in &train {
        let label = image
            .replace("/images/", "/labels/")
            .replace(".jpg", ".txt");
        let text = std::fs::read_to_string(&label).expect("a label per image");
        assert!(text.lines().all(|l| l.starts_with("0 ")), "{label}: {text}");
    }
}
