//! `cargo xtask train --card`: the model card of a run fine-tuned on a user's
//! labels, the last step of `cargo xtask train --data`.
//!
//! Their held-out frames (`training/mix.py` keeps the last stretch of each
//! survey flight out of training) are scored with `towernav-edge
//! eval-detector --images` for the new model and for the shipped one, so the
//! card shows what the fine-tuning bought on frames it never saw.

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;

use anyhow::{Context, bail};

use crate::build_release;

pub fn write(root: &Path, work: &Path, ort: &Path) -> anyhow::Result<()> {
    let run_dir = work.join("run");
    let mixed = work.join("mixed");
    let model = ["towers-int8.onnx", "towers.onnx"]
        .iter()
        .map(|name| run_dir.join(name))
        .find(|p| p.is_file())
        .with_context(|| format!("no finished run in {} (no towers.onnx)", run_dir.display()))?;
    let read = |name: &str| {
        let path = mixed.join(name);
        std::fs::read_to_string(&path).with_context(|| format!("reading {}", path.display()))
    };
    let names = read("names.txt")?.trim().to_string();
    let heldout: Vec<String> = read("heldout.txt")?
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(str::to_string)
        .collect();
    let bin = build_release(root, &["towernav-edge"])?;
    let edge = bin.join("towernav-edge");
    let shipped = root.join("models").join("towers-int8.onnx");
    let classifier = classifier_classes(root);
    // The shipped type classifier reads each box's crop better than a small
    // detector types it: keep it whenever it knows the model's classes.
    let keeps_classifier =
        !classifier.is_empty() && names.split(',').eq(classifier.iter().map(String::as_str));

    let mut card = String::new();
    writeln!(card, "# Model card: {}\n", model.display())?;
    writeln!(
        card,
        "Fine-tuned by `cargo xtask train --data` on the rendered frames mixed with \
         the labelled images below; classes: `{names}`.\n"
    )?;
    writeln!(card, "## Data\n\n```\n{}```\n", read("mix.json")?)?;
    if let Ok(summary) = std::fs::read_to_string(run_dir.join("summary.json")) {
        writeln!(card, "## Training (Ultralytics)\n\n```\n{summary}```\n")?;
    }
    if heldout.is_empty() {
        writeln!(
            card,
            "## Held-out frames\n\nNone: every labelled source was a folder without its own \
             validation split, so all of it trained. Score real frames with \
             `towernav-edge eval-detector --images DIR --model {}`.\n",
            model.display()
        )?;
    }
    for folder in &heldout {
        writeln!(card, "## Held out: {folder}\n")?;
        let own = if keeps_classifier {
            "this model, with the shipped type classifier"
        } else {
            "this model, its own classes"
        };
        for (what, onnx, own_types) in [
            (own, model.as_path(), keeps_classifier),
            ("the shipped model", shipped.as_path(), true),
        ] {
            let mut args = vec!["--images", folder.as_str(), "--names", names.as_str()];
            if !own_types {
                args.push("--no-type-model");
            }
            let score = eval_detector(&edge, &args, onnx, &run_dir, ort, root)?;
            writeln!(card, "### {what}\n\n```\n{score}```\n")?;
        }
    }
    real_photos(&mut card, &edge, &model, &shipped, work, ort, root)?;
    let flag = if keeps_classifier {
        ""
    } else {
        " --no-type-model"
    };
    writeln!(
        card,
        "## Flying it\n\n    towernav-edge run --model {}{flag} ...\n\n\
         Every tower type in the landmark database must be one of `{names}` \
         (a one-class `tower` model takes any).{}",
        model.display(),
        if keeps_classifier {
            " Its classes are the shipped type classifier's, which stays on: \
             without it the boxes' types are the detector's own, and wrong types \
             bind towers wrongly."
        } else {
            " The shipped type classifier does not know these classes: it is off."
        }
    )?;
    let path = run_dir.join("MODEL_CARD.md");
    std::fs::write(&path, card).with_context(|| format!("writing {}", path.display()))?;
    eprintln!(
        "xtask: wrote {}; fly the model with `--model {}{flag}`",
        path.display(),
        model.display()
    );
    Ok(())
}

/// `--real`: the manifest's held-out sources and tower-free frames
/// (`work/real/held-out.txt`, `negatives.txt`, from `training/real_data.py`),
/// scored at the daemon's threshold for this model and the shipped one.
/// Boxes match whatever their class; wooden poles are neither hits nor misses.
fn real_photos(
    card: &mut String,
    edge: &Path,
    model: &Path,
    shipped: &Path,
    work: &Path,
    ort: &Path,
    root: &Path,
) -> anyhow::Result<()> {
    let list = |name: &str| -> Vec<String> {
        std::fs::read_to_string(work.join("real").join(name))
            .map(|t| {
                t.lines()
                    .filter(|l| !l.trim().is_empty())
                    .map(str::to_owned)
                    .collect()
            })
            .unwrap_or_default()
    };
    let (held_out, negatives) = (list("held-out.txt"), list("negatives.txt"));
    if held_out.is_empty() && negatives.is_empty() {
        return Ok(());
    }
    writeln!(
        card,
        "## Real photographs kept out of training (training/data/real-sources.csv)\n"
    )?;
    let cases = held_out
        .iter()
        .map(|f| (f, "--images"))
        .chain(negatives.iter().map(|f| (f, "--negatives")));
    for (folder, flag) in cases {
        writeln!(card, "### {folder}\n")?;
        for (what, onnx) in [("this model", model), ("the shipped model", shipped)] {
            let args = [
                flag,
                folder.as_str(),
                "--names",
                "tower_lattice,tower_tucohy,tower_wooden",
                "--dont-care",
                "tower_wooden",
            ];
            let score = eval_detector(edge, &args, onnx, &work.join("run"), ort, root)?;
            writeln!(card, "#### {what}\n\n```\n{score}```\n")?;
        }
    }
    Ok(())
}

/// `towernav-edge eval-detector ARGS --model MODEL`, its report as printed.
fn eval_detector(
    edge: &Path,
    args: &[&str],
    model: &Path,
    run_dir: &Path,
    ort: &Path,
    root: &Path,
) -> anyhow::Result<String> {
    let score = Command::new(edge)
        .arg("eval-detector")
        .args(args)
        .arg("--model")
        .arg(model)
        .arg("--out")
        .arg(run_dir.join("card-eval"))
        .env("ORT_DYLIB_PATH", ort)
        .current_dir(root)
        .output()
        .with_context(|| format!("running {}", edge.display()))?;
    if !score.status.success() {
        bail!(
            "eval-detector {} with {} failed:\n{}",
            args.join(" "),
            model.display(),
            String::from_utf8_lossy(&score.stderr)
        );
    }
    Ok(String::from_utf8_lossy(&score.stdout).into_owned())
}

/// The shipped type classifier's classes, by id (empty when unreadable).
fn classifier_classes(root: &Path) -> Vec<String> {
    let path = root.join("models").join("tower-types.training.json");
    let Some(classes) = std::fs::read_to_string(path)
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .and_then(|v| v.get("classes").and_then(|c| c.as_object().cloned()))
    else {
        return Vec::new();
    };
    let mut by_id: Vec<(usize, String)> = classes
        .iter()
        .filter_map(|(id, name)| Some((id.parse().ok()?, name.as_str()?.to_owned())))
        .collect();
    by_id.sort();
    by_id.into_iter().map(|(_, name)| name).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_classifier_lists_its_classes_in_id_order() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"))
            .parent()
            .expect("the workspace");
        let classes = classifier_classes(root);
        assert!(
            !classes.is_empty(),
            "models/tower-types.training.json unread"
        );
        let mut sorted = classes.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), classes.len(), "{classes:?}");
        assert!(classifier_classes(Path::new("/nonexistent")).is_empty());
    }
}
