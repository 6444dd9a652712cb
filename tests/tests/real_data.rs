//! `training/real_data.py`, which rebuilds the real-photograph part of the
//! detector's data from the manifest of its sources, on tiny fixtures.

use std::path::Path;
use std::process::{Command, Output};

const HEADER: &str = "source,folder,repository,commit,path,licence,images,steel_towers,role,note\n";

/// A folder of `n` stand-in JPEGs, the first `with_towers` of them labelled.
fn folder(dir: &Path, n: usize, with_towers: usize) {
    std::fs::create_dir_all(dir.join("images")).expect("images");
    std::fs::create_dir_all(dir.join("labels_yolo")).expect("labels");
    for i in 0..n {
        std::fs::write(dir.join("images").join(format!("{i}.jpg")), b"jpg").expect("image");
        let label = if i < with_towers {
            "0 0.5 0.5 0.1 0.4\n"
        } else {
            ""
        };
        std::fs::write(dir.join("labels_yolo").join(format!("{i}.txt")), label).expect("label");
    }
}

fn rebuild(manifest: &str, real: &Path, out: &Path) -> Output {
    let path = real.join("manifest.csv");
    std::fs::write(&path, format!("{HEADER}{manifest}")).expect("manifest");
    Command::new("python3")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("../training/real_data.py"))
        .arg("--manifest")
        .arg(&path)
        .arg("--real")
        .arg(real)
        .arg("--out")
        .arg(out)
        .output()
        .expect("python3 runs")
}

#[test]
fn training_sources_and_their_tower_free_frames_are_staged_and_the_rest_kept_out() {
    let dir = tempfile::tempdir().expect("tempdir");
    let real = dir.path().join("real");
    folder(&real.join("mine"), 5, 2);
    folder(&real.join("theirs"), 3, 1);
    folder(&real.join("unlicensed"), 4, 0);
    let out = dir.path().join("out");
    let result = rebuild(
        "mine,mine,me/mine,abc,images,MIT,5,2,train,\n\
         theirs,theirs,them/theirs,def,images,Apache-2.0,3,1,held-out,\n\
         unlicensed,unlicensed,x/y,,images,none stated,4,0,eval-only,\n",
        &real,
        &out,
    );
    assert!(result.status.success(), "{result:?}");
    let read = |name: &str| std::fs::read_to_string(out.join(name)).expect(name);
    assert_eq!(
        read("sources.txt").trim(),
        real.join("mine")
            .canonicalize()
            .expect("path")
            .display()
            .to_string()
    );
    assert!(read("held-out.txt").contains("theirs"));
    assert!(read("negatives.txt").contains("unlicensed"));
    // Only the training source's three tower-free frames become backgrounds.
    let backgrounds: Vec<String> = std::fs::read_dir(out.join("backgrounds"))
        .expect("backgrounds")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(backgrounds.len(), 3, "{backgrounds:?}");
    assert!(backgrounds.iter().all(|b| b.starts_with("mine-")));
    let summary: serde_json::Value = serde_json::from_str(&read("real-data.json")).expect("json");
    assert_eq!(summary["sources"][0]["licence"], "MIT");
    assert_eq!(summary["sources"][0]["tower_free"], 3);
}

#[test]
fn a_source_without_a_training_licence_is_refused_for_training() {
    let dir = tempfile::tempdir().expect("tempdir");
    let real = dir.path().join("real");
    folder(&real.join("scraped"), 2, 1);
    let result = rebuild(
        "scraped,scraped,x/y,,images,none stated,2,1,train,\n",
        &real,
        &dir.path().join("out"),
    );
    assert_eq!(result.status.code(), Some(2));
    let err = String::from_utf8_lossy(&result.stderr);
    assert!(
        err.contains("scraped") && err.contains("does not allow training"),
        "{err}"
    );
}

#[test]
fn a_copy_that_differs_from_the_manifest_is_an_error_naming_both_counts() {
    let dir = tempfile::tempdir().expect("tempdir");
    let real = dir.path().join("real");
    folder(&real.join("mine"), 4, 1);
    let result = rebuild(
        "mine,mine,me/mine,abc,images,MIT,5,1,train,\n",
        &real,
        &dir.path().join("out"),
    );
    assert_eq!(result.status.code(), Some(2));
    let err = String::from_utf8_lossy(&result.stderr);
    assert!(err.contains("4 images") && err.contains("says 5"), "{err}");
}
