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

/// Names of the crates `package` links (normal edges, transitively), as `cargo tree` sees them.
fn linked_crates(package: &str, features: &[&str]) -> std::collections::BTreeSet<String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut command = std::process::Command::new(cargo);
    command.current_dir(root()).args([
        "tree",
        "--offline",
        "-e",
        "normal",
        "--prefix",
        "none",
        "-p",
        package,
    ]);
    if !features.is_empty() {
        command.args(["--features", &features.join(",")]);
    }
    let out = command.output().expect("cargo tree runs");
    assert!(
        out.status.success(),
        "cargo tree -p {package}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .map(str::to_string)
        .collect()
}

#[test]
fn the_core_links_no_runtime_network_model_simulator_database_or_plots() {
    let linked = linked_crates("towernav-core", &[]);
    assert!(linked.contains("nalgebra"), "{linked:?}");
    for banned in [
        "tokio",
        "zenoh",
        "ort",
        "towernav-sim",
        "tiny-skia",
        "rusqlite",
        "plotters",
    ] {
        assert!(!linked.contains(banned), "towernav-core links {banned}");
    }
}

#[test]
fn the_onboard_daemon_links_no_simulator_renderer_plots_or_evaluations() {
    let onboard = linked_crates("towernav-edge", &[]);
    assert!(
        onboard.contains("zenoh") && onboard.contains("ort"),
        "{onboard:?}"
    );
    let banned = [
        "towernav-sim",
        "tiny-skia",
        "plotters",
        "towernav-eval",
        "comfy-table",
        "indicatif",
    ];
    for crate_name in banned {
        assert!(
            !onboard.contains(crate_name),
            "the onboard towernav-edge links {crate_name}"
        );
    }
    // The demo build is where they went: the check above is not vacuous.
    let demo = linked_crates("towernav-edge", &["demo"]);
    for crate_name in ["towernav-sim", "tiny-skia", "plotters", "towernav-eval"] {
        assert!(
            demo.contains(crate_name),
            "the demo build lacks {crate_name}"
        );
    }
}

#[test]
fn the_pure_crates_read_no_clock_and_open_no_socket_or_file() {
    let mut files = Vec::new();
    for crate_dir in ["core/src", "geometry/src"] {
        rust_files(&root().join(crate_dir), &mut files);
    }
    // Unit-test files may take one `Instant::now()` as virtual time's origin.
    files.retain(|f| !f.to_string_lossy().ends_with("_tests.rs"));
    assert!(files.len() > 30, "found only {} files", files.len());
    for file in files {
        let text = std::fs::read_to_string(&file).expect("readable");
        for banned in [
            "Instant::now",
            "SystemTime::now",
            "std::net",
            "std::fs",
            "std::thread",
        ] {
            assert!(!uses(&text, banned), "{} uses {banned}", file.display());
        }
    }
}

#[test]
fn only_protocol_formats_zenoh_keys() {
    let mut files = Vec::new();
    for crate_dir in [
        "core/src",
        "onnx/src",
        "eval/src",
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

/// Each third-party package of a `cargo tree` with a feature set it is built
/// with (one entry per set: a package built for the host and for the target
/// may have two).
fn dependency_features(args: &[&str]) -> std::collections::BTreeSet<String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = std::process::Command::new(cargo)
        .current_dir(root())
        .args(["tree", "--offline", "--prefix", "none", "-f", "{p}|{f}"])
        .args(args)
        .output()
        .expect("cargo tree runs");
    assert!(
        out.status.success(),
        "cargo tree {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter_map(|line| line.split_once('|'))
        // Path packages print their directory; only registry crates are shared artifacts.
        .filter(|(package, _)| !package.contains('('))
        .map(|(package, list)| {
            let mut features: Vec<&str> = list
                .trim_end_matches(" (*)")
                .split(',')
                .filter(|f| !f.is_empty())
                .collect();
            features.sort_unstable();
            format!("{package} [{}]", features.join(","))
        })
        .collect()
}

/// `cargo xtask test` lints the onboard daemon after the workspace: with equal
/// dependency features it reuses the workspace's checked crates instead of
/// checking a third of them again (`build-unify/` asks for the features).
#[test]
fn the_onboard_build_shares_the_workspace_s_dependency_features() {
    let onboard = dependency_features(&["-p", "towernav-edge", "-e", "normal,build"]);
    let workspace = dependency_features(&["--workspace", "-e", "normal,build,dev"]);
    assert!(onboard.len() > 100, "{} packages", onboard.len());
    let differing: Vec<&String> = onboard.difference(&workspace).collect();
    assert!(
        differing.is_empty(),
        "built with features the workspace build does not use (add them to build-unify/Cargo.toml):\n{differing:#?}"
    );
}
