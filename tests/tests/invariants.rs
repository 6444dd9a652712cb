//! Architecture invariants that are cheap to check: ARCHITECTURE.md states them as absences.

use std::path::Path;

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir)
        .expect("readable source dir")
        .flatten()
    {
        let path = entry.path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Whether `path` occurs as a whole path (so `sort::` is not `ort::`).
fn uses(text: &str, path: &str) -> bool {
    text.match_indices(path).any(|(i, _)| {
        !text[..i]
            .chars()
            .next_back()
            .is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':')
    })
}

#[test]
fn path_matching_respects_word_boundaries() {
    assert!(uses("use ort::Session;", "ort::"));
    assert!(!uses("use crate::tracker::sort::Sort;", "ort::"));
    assert!(uses("x = tokio::spawn(f)", "tokio::"));
}

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("workspace root")
}

#[test]
fn the_pipeline_core_imports_no_tokio_zenoh_or_ort() {
    let edge = root().join("edge/src");
    let mut files = Vec::new();
    rust_files(&edge, &mut files);
    for crate_dir in ["sim/src", "geometry/src"] {
        rust_files(&root().join(crate_dir), &mut files);
    }
    let core: Vec<_> = files
        .into_iter()
        .filter(|f| !f.starts_with(edge.join("shell")) && !f.ends_with("main.rs"))
        .collect();
    assert!(core.len() > 10, "found only {} core files", core.len());
    for file in core {
        let text = std::fs::read_to_string(&file).expect("readable");
        for banned in [
            "tokio::",
            "zenoh::",
            "ort::",
            "std::time::Instant",
            "std::net",
        ] {
            assert!(!uses(&text, banned), "{} uses {banned}", file.display());
        }
    }
}

#[test]
fn only_protocol_formats_zenoh_keys() {
    let mut files = Vec::new();
    for crate_dir in [
        "edge/src",
        "ground-station/src",
        "landmark-db/src",
        "sim/src",
        "geometry/src",
    ] {
        rust_files(&root().join(crate_dir), &mut files);
    }
    for file in files {
        let text = std::fs::read_to_string(&file).expect("readable");
        assert!(
            !text.contains("\"towernav/"),
            "{} spells a key by hand",
            file.display()
        );
    }
}

#[test]
fn the_simulator_library_touches_no_files() {
    let sim = root().join("sim/src");
    let mut files = Vec::new();
    rust_files(&sim, &mut files);
    let library: Vec<_> = files
        .into_iter()
        .filter(|f| !f.starts_with(sim.join("cli")) && !f.ends_with("main.rs"))
        .collect();
    assert!(
        library.len() > 8,
        "found only {} library files",
        library.len()
    );
    for file in library {
        let text = std::fs::read_to_string(&file).expect("readable");
        for banned in ["std::fs", "File::", "std::env"] {
            assert!(!uses(&text, banned), "{} uses {banned}", file.display());
        }
    }
}
