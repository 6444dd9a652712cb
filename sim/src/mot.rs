//! MOTChallenge ground truth as text, laid out as MOT17's so that the
//! community's tools (TrackEval, py-motmetrics) score it as the project does:
//! every tower is class 1 (the class those tools evaluate); a tower too small
//! or too hidden to demand is a distractor (class 8, confidence 0), so a
//! hypothesis on it is neither a hit nor a false positive. Track ids are
//! tower indices + 1; the towers' ids and types are in a side file.

use std::fmt::Write;

use crate::{FrameTruth, Scenario, World};

/// MOT17's pedestrian: the one class TrackEval and py-motmetrics score.
pub const TOWER_CLASS: u8 = 1;
/// MOT17's distractor: hypotheses matched to it are removed before scoring.
pub const DONT_CARE_CLASS: u8 = 8;

#[derive(Debug, thiserror::Error)]
#[error("truth box names tower {0}, which the world lacks")]
pub struct UnknownTower(pub String);

/// One sequence's files, relative to its folder, with their text:
/// `gt/gt.txt`, `gt/towers.csv` and `seqinfo.ini`.
pub fn sequence_files(
    name: &str,
    scenario: &Scenario,
    frames: &[FrameTruth],
) -> Result<Vec<(&'static str, String)>, UnknownTower> {
    Ok(vec![
        ("gt/gt.txt", gt_text(scenario, frames)?),
        ("gt/towers.csv", towers_csv(&scenario.world)),
        ("seqinfo.ini", seqinfo(name, scenario, frames.len())),
    ])
}

/// `gt.txt`: `frame,id,left,top,width,height,conf,class,visibility` per box.
pub fn gt_text(scenario: &Scenario, frames: &[FrameTruth]) -> Result<String, UnknownTower> {
    let world = &scenario.world;
    let mut out = String::new();
    for f in frames {
        for b in &f.boxes {
            let id = track_id(world, &b.tower_id)?;
            let (conf, class) = if scenario.demanded(b) {
                (1, TOWER_CLASS)
            } else {
                (0, DONT_CARE_CLASS)
            };
            let _ = writeln!(
                out,
                "{},{id},{:.2},{:.2},{:.2},{:.2},{conf},{class},{:.3}",
                f.seq + 1,
                b.bbox.left,
                b.bbox.top,
                b.bbox.width(),
                b.bbox.height(),
                1.0 - b.occluded
            );
        }
    }
    Ok(out)
}

/// The MOT track id of a tower: its index in the world, from 1.
pub fn track_id(world: &World, tower_id: &str) -> Result<usize, UnknownTower> {
    world
        .towers
        .iter()
        .position(|t| t.id == tower_id)
        .map(|i| i + 1)
        .ok_or_else(|| UnknownTower(tower_id.to_string()))
}

/// `seqinfo.ini`, every field MOT17's has.
pub fn seqinfo(name: &str, scenario: &Scenario, frames: usize) -> String {
    let k = &scenario.camera.intrinsics;
    format!(
        "[Sequence]\nname={name}\nimDir=img1\nframeRate={}\nseqLength={frames}\nimWidth={}\nimHeight={}\nimExt=.jpg\n",
        scenario.fps, k.width, k.height
    )
}

/// `gt/towers.csv`: each track id's tower id and type.
pub fn towers_csv(world: &World) -> String {
    let mut out = String::from("track_id,tower_id,tower_type\n");
    for (i, t) in world.towers.iter().enumerate() {
        let _ = writeln!(out, "{},{},{}", i + 1, t.id, t.tower_type);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_and_hidden_towers_are_distractors_and_the_rest_class_one() {
        let scenario = Scenario::paper(1);
        let frames: Vec<FrameTruth> = (0..300).step_by(30).map(|s| scenario.truth(s)).collect();
        let text = gt_text(&scenario, &frames).expect("every tower known");
        let (mut towers, mut dont_care) = (0, 0);
        for line in text.lines() {
            let f: Vec<&str> = line.split(',').collect();
            assert_eq!(f.len(), 9, "{line}");
            match (f[6], f[7]) {
                ("1", "1") => towers += 1,
                ("0", "8") => dont_care += 1,
                other => panic!("{other:?} in {line}"),
            }
        }
        assert!(
            towers > 0 && dont_care > 0,
            "{towers} towers, {dont_care} don't care"
        );
        let ini = seqinfo("p1", &scenario, 10);
        for key in [
            "name=p1",
            "imDir=img1",
            "frameRate=30",
            "seqLength=10",
            "imWidth=1280",
            "imHeight=720",
            "imExt=.jpg",
        ] {
            assert!(ini.contains(key), "{key} missing from {ini}");
        }
        assert!(
            towers_csv(&scenario.world)
                .lines()
                .nth(1)
                .is_some_and(|l| l.starts_with("1,"))
        );
    }
}
