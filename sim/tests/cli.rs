//! The `towernav-sim` commands write what they promise: YOLO datasets split by
//! world, MOT ground truth, flights and a rendered picture.

use std::path::Path;
use std::process::Command;

fn sim(args: &[&str]) -> std::process::Output {
    let out = Command::new(env!("CARGO_BIN_EXE_towernav-sim"))
        .args(args)
        .output()
        .expect("run towernav-sim");
    assert!(
        out.status.success(),
        "towernav-sim {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn files(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn dataset_writes_yolo_splits_by_world_and_mot_truth() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("ds");
    let out_s = out.to_str().expect("utf-8 path");
    sim(&[
        "dataset",
        "--out",
        out_s,
        "--worlds",
        "3",
        "--frames-per-world",
        "2",
        "--seed",
        "7",
    ]);
    let yaml = std::fs::read_to_string(out.join("data.yaml")).expect("data.yaml");
    for line in [
        "train: images/train",
        "val: images/val",
        "test: images/test",
        "0: A",
        "3: D",
    ] {
        assert!(yaml.contains(line), "data.yaml lacks {line:?}:\n{yaml}");
    }
    let mut worlds_seen = Vec::new();
    for split in ["train", "val", "test"] {
        let images = files(&out.join("images").join(split));
        let labels = files(&out.join("labels").join(split));
        assert_eq!(images.len(), 2, "{split}: {images:?}");
        let stems = |v: &[String]| -> Vec<String> {
            v.iter()
                .map(|n| n.rsplit_once('.').expect("ext").0.to_string())
                .collect()
        };
        assert_eq!(
            stems(&images),
            stems(&labels),
            "{split}: every image has a label file"
        );
        let world = images[0]
            .split('_')
            .next()
            .expect("world prefix")
            .to_string();
        assert!(
            images.iter().all(|n| n.starts_with(&world)),
            "one world per split here"
        );
        worlds_seen.push(world.clone());
        for label in &labels {
            let text =
                std::fs::read_to_string(out.join("labels").join(split).join(label)).expect("label");
            for line in text.lines() {
                let v: Vec<f64> = line
                    .split(' ')
                    .map(|x| x.parse().expect("number"))
                    .collect();
                assert_eq!(v.len(), 5, "{line}");
                assert!(
                    (0.0..=3.0).contains(&v[0]) && v[0].fract() == 0.0,
                    "class {line}"
                );
                assert!(
                    v[1..].iter().all(|x| (0.0..=1.0).contains(x)),
                    "normalised {line}"
                );
            }
        }
        let seq = out.join("mot").join(split).join(&world);
        let ini = std::fs::read_to_string(seq.join("seqinfo.ini")).expect("seqinfo");
        assert!(
            ini.contains("frameRate=30") && ini.contains("imWidth=1280"),
            "{ini}"
        );
        let gt = std::fs::read_to_string(seq.join("gt").join("gt.txt")).expect("gt");
        let first: Vec<&str> = gt.lines().next().expect("a box").split(',').collect();
        assert_eq!(first.len(), 9, "MOT gt has 9 columns");
    }
    worlds_seen.dedup();
    assert_eq!(
        worlds_seen.len(),
        3,
        "train, val and test hold different worlds"
    );
    let img = image::open(
        out.join("images/train")
            .join(&files(&out.join("images/train"))[0]),
    )
    .expect("a readable JPEG");
    assert_eq!((img.width(), img.height()), (1280, 720));
}

#[test]
fn flight_and_render_write_trajectory_truth_and_a_picture() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("flight");
    sim(&[
        "flight",
        "--preset",
        "straight",
        "--dataset-every",
        "300",
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    a_flight_dataset_holds_every_300th_frame_with_its_truth_boxes(&out);
    let traj = std::fs::read_to_string(out.join("trajectory.csv")).expect("trajectory");
    let rows = traj.lines().count() - 1;
    assert!(
        (2700..3000).contains(&rows),
        "{rows} frames of a ~95 s flight at 30 fps"
    );
    let gt = std::fs::read_to_string(out.join("mot/straight/gt/gt.txt")).expect("gt");
    assert!(gt.lines().count() > rows, "several towers per frame");
    let png = dir.path().join("frame.png");
    sim(&[
        "render",
        "--preset",
        "paper-path-1",
        "--time",
        "20",
        "--out",
        png.to_str().expect("utf-8"),
    ]);
    let img = image::open(&png).expect("PNG");
    assert_eq!((img.width(), img.height()), (1280, 720));
}

#[test]
fn bad_plans_and_times_are_refused_with_the_reason() {
    let dir = tempfile::tempdir().expect("tempdir");
    let plan = dir.path().join("bad.toml");
    std::fs::write(
        &plan,
        "name = \"x\"\n[[waypoint]]\neast_m = 0\nnorth_m = 0\nheight_m = 30\nspeed_mps = 10\n",
    )
    .expect("write");
    let out = Command::new(env!("CARGO_BIN_EXE_towernav-sim"))
        .args([
            "flight",
            "--plan",
            plan.to_str().expect("utf-8"),
            "--out",
            dir.path().join("o").to_str().expect("utf-8"),
        ])
        .output()
        .expect("run");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("bad.toml") && err.contains("at least two waypoints"),
        "{err}"
    );
    let out = Command::new(env!("CARGO_BIN_EXE_towernav-sim"))
        .args([
            "render",
            "--time",
            "9999",
            "--out",
            dir.path().join("x.png").to_str().expect("utf-8"),
        ])
        .output()
        .expect("run");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("--time 9999"),
        "{err}"
    );
}

#[test]
fn a_flight_without_images_writes_an_oracle_replay_over_the_same_world() {
    let dir = tempfile::tempdir().expect("tempdir");
    let first = dir.path().join("first");
    sim(&[
        "flight",
        "--random-world",
        "5",
        "--preset",
        "straight",
        "--out",
        first.to_str().expect("utf-8"),
    ]);
    let towers = first.join("towers.csv");
    let replay = std::fs::read_to_string(first.join("replay.toml")).expect("replay.toml");
    for line in [
        "kind = \"sim\"",
        "random_world = 5",
        "flight = \"straight\"",
        "kind = \"oracle\"",
        &format!("file = {:?}", towers.display().to_string()),
    ] {
        assert!(
            replay.contains(line),
            "replay.toml lacks {line:?}:\n{replay}"
        );
    }
    // The written towers fly again as a world of their own.
    let second = dir.path().join("second");
    sim(&[
        "flight",
        "--world",
        towers.to_str().expect("utf-8"),
        "--preset",
        "straight",
        "--out",
        second.to_str().expect("utf-8"),
    ]);
    let replay = std::fs::read_to_string(second.join("replay.toml")).expect("replay.toml");
    assert!(
        replay.contains(&format!("world = {:?}", towers.display().to_string())),
        "{replay}"
    );
    let written = std::fs::read_to_string(second.join("towers.csv")).expect("towers");
    assert_eq!(
        written.lines().count(),
        std::fs::read_to_string(&towers)
            .expect("towers")
            .lines()
            .count()
    );
}

/// Two tower-free "photos" (noise) in a folder, as a user's backgrounds.
fn photo_folder(dir: &Path) -> std::path::PathBuf {
    let photos = dir.join("photos");
    std::fs::create_dir_all(&photos).expect("mkdir");
    for (i, size) in [(640u32, 480u32), (300, 500)].into_iter().enumerate() {
        let img = image::RgbImage::from_fn(size.0, size.1, |x, y| {
            image::Rgb([(x * 7 + y) as u8, (y * 3) as u8, ((x ^ y) * 5) as u8])
        });
        img.save(photos.join(format!("p{i}.jpg"))).expect("jpeg");
    }
    photos
}

#[test]
fn a_randomized_dataset_writes_valid_labels_and_its_photos_as_negatives() {
    let dir = tempfile::tempdir().expect("tempdir");
    let photos = photo_folder(dir.path());
    let out = dir.path().join("ds");
    sim(&[
        "dataset",
        "--out",
        out.to_str().expect("utf-8"),
        "--worlds",
        "3",
        "--frames-per-world",
        "6",
        "--seed",
        "11",
        "--randomize",
        "1",
        "--backgrounds",
        photos.to_str().expect("utf-8"),
    ]);
    let mut boxes = 0;
    for split in ["train", "val", "test"] {
        let images = files(&out.join("images").join(split));
        let labels = files(&out.join("labels").join(split));
        assert_eq!(images.len(), labels.len(), "{split}: a label per image");
        for label in &labels {
            let text =
                std::fs::read_to_string(out.join("labels").join(split).join(label)).expect("label");
            if label.starts_with("photo") {
                assert!(
                    text.is_empty(),
                    "a background photo shows no tower: {label}"
                );
                continue;
            }
            for line in text.lines() {
                let v: Vec<f64> = line
                    .split(' ')
                    .map(|x| x.parse().expect("number"))
                    .collect();
                assert_eq!(v.len(), 5, "{line}");
                assert!((0.0..=3.0).contains(&v[0]) && v[0].fract() == 0.0, "{line}");
                let (cx, cy, w, h) = (v[1], v[2], v[3], v[4]);
                assert!(w > 0.0 && h > 0.0, "a box with area: {line}");
                assert!(
                    cx - w / 2.0 >= -1e-6 && cx + w / 2.0 <= 1.0 + 1e-6,
                    "inside the frame: {line}"
                );
                assert!(
                    cy - h / 2.0 >= -1e-6 && cy + h / 2.0 <= 1.0 + 1e-6,
                    "inside the frame: {line}"
                );
                boxes += 1;
            }
        }
    }
    assert!(
        boxes > 10,
        "randomized views still show towers ({boxes} boxes)"
    );
    let train = files(&out.join("images/train"));
    assert_eq!(
        train.iter().filter(|n| n.starts_with("photo")).count(),
        2,
        "each background photo is also a negative, in train only: {train:?}"
    );
    assert!(
        !files(&out.join("images/test"))
            .iter()
            .any(|n| n.starts_with("photo"))
    );

    let sheet = dir.path().join("sheet.png");
    sim(&[
        "render",
        "--randomized",
        "8",
        "--backgrounds",
        photos.to_str().expect("utf-8"),
        "--out",
        sheet.to_str().expect("utf-8"),
    ]);
    let img = image::open(&sheet).expect("PNG");
    assert_eq!(
        (img.width(), img.height()),
        (6 * 320, 2 * 180),
        "8 tiles, 6 a row"
    );
}

#[test]
fn randomizing_refuses_a_share_outside_0_to_1_and_an_empty_photo_folder() {
    let dir = tempfile::tempdir().expect("tempdir");
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_towernav-sim"))
            .args(args)
            .output()
            .expect("run");
        assert!(!out.status.success(), "{args:?} should fail");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let out = dir.path().join("ds");
    let out = out.to_str().expect("utf-8");
    let err = run(&["dataset", "--out", out, "--randomize", "1.5"]);
    assert!(err.contains("--randomize") && err.contains("1.5"), "{err}");
    let empty = dir.path().join("empty");
    std::fs::create_dir_all(&empty).expect("mkdir");
    let err = run(&[
        "dataset",
        "--out",
        out,
        "--randomize",
        "0.5",
        "--backgrounds",
        empty.to_str().expect("utf-8"),
    ]);
    assert!(err.contains("empty") && err.contains("no .jpg"), "{err}");
}

/// `--dataset-every 300`'s dataset beside a flight rendered into `out`.
fn a_flight_dataset_holds_every_300th_frame_with_its_truth_boxes(out: &Path) {
    let frames = std::fs::read_to_string(out.join("trajectory.csv"))
        .expect("trajectory")
        .lines()
        .count()
        - 1;
    let images = files(&out.join("dataset/images"));
    assert_eq!(images.len(), frames.div_ceil(300), "{images:?}");
    assert_eq!(
        images[0], "000001.jpg",
        "frame 0, numbered as MOT numbers it"
    );
    let yaml = std::fs::read_to_string(out.join("dataset/data.yaml")).expect("data.yaml");
    assert!(
        yaml.contains("test: images") && yaml.contains("  3: D"),
        "{yaml}"
    );
    // Each label is one of truth.csv's boxes for that frame.
    let truth = std::fs::read_to_string(out.join("truth.csv")).expect("truth");
    let mut labels = 0;
    for image in &images {
        let stem = image.trim_end_matches(".jpg");
        let seq = stem.parse::<u64>().expect("numbered") - 1;
        let img = image::open(out.join("dataset/images").join(image)).expect("JPEG");
        let (w, h) = (f64::from(img.width()), f64::from(img.height()));
        let rows: Vec<Vec<f64>> = truth
            .lines()
            .skip(1)
            .map(|l| l.split(',').collect::<Vec<_>>())
            .filter(|f| f[0] == seq.to_string())
            .map(|f| f[3..7].iter().map(|v| v.parse().expect("number")).collect())
            .collect();
        let text = std::fs::read_to_string(out.join("dataset/labels").join(format!("{stem}.txt")))
            .expect("label file");
        for line in text.lines() {
            let v: Vec<f64> = line
                .split(' ')
                .map(|x| x.parse().expect("number"))
                .collect();
            let (cx, cy, bw, bh) = (v[1] * w, v[2] * h, v[3] * w, v[4] * h);
            let found = rows.iter().any(|r| {
                let (l, t, r, b) = (r[0].max(0.0), r[1].max(0.0), r[2].min(w), r[3].min(h));
                (cx - (l + r) / 2.0).abs() < 0.5
                    && (cy - (t + b) / 2.0).abs() < 0.5
                    && (bw - (r - l)).abs() < 0.5
                    && (bh - (b - t)).abs() < 0.5
            });
            assert!(found, "frame {seq}: {line} is none of {rows:?}");
            labels += 1;
        }
    }
    assert!(
        labels >= images.len(),
        "towers along the line: {labels} labels"
    );
}

#[test]
fn a_flight_dataset_of_every_0th_frame_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let refused = Command::new(env!("CARGO_BIN_EXE_towernav-sim"))
        .args([
            "flight",
            "--preset",
            "straight",
            "--dataset-every",
            "0",
            "--out",
        ])
        .arg(dir.path().join("zero"))
        .output()
        .expect("run towernav-sim");
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("--dataset-every"));
}
