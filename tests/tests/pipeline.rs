//! The pipeline over a simulated flight, across a landmark swap.

use towernav_core::{FrameOutput, LandmarkMap, Pipeline, PipelineConfig};
use towernav_sim::Scenario;

#[test]
fn bindings_follow_their_towers_when_the_map_is_replaced() {
    let scenario = Scenario::paper(2);
    let records = scenario.world.landmarks();
    let map = LandmarkMap::from_records(&records, &scenario.world.datum);
    let mut pipeline = Pipeline::new(
        PipelineConfig::new(scenario.camera, scenario.start_in_world()),
        map,
    );
    let frames: Vec<_> = scenario.frames().take(200).map(|(_, f)| f).collect();
    let mut last = None;
    for f in &frames[..150] {
        last = Some(pipeline.process(f));
    }
    let ids = |out: &FrameOutput, map: &LandmarkMap| -> Vec<(u64, Option<String>)> {
        out.tracks
            .iter()
            .map(|t| (t.track_id, t.tower.map(|i| map.towers[i].id.clone())))
            .collect()
    };
    let before = ids(&last.expect("frames"), pipeline.map());
    assert!(
        before.iter().filter(|(_, id)| id.is_some()).count() >= 2,
        "{before:?}"
    );

    // The same towers in reverse order, minus one nobody is tracking.
    let tracked: Vec<&str> = before.iter().filter_map(|(_, id)| id.as_deref()).collect();
    let mut reordered: Vec<_> = records.iter().rev().cloned().collect();
    let dropped = reordered
        .iter()
        .position(|r| !tracked.contains(&r.id.as_str()))
        .expect("an untracked tower");
    reordered.remove(dropped);
    pipeline.replace_map(LandmarkMap::from_records(&reordered, &scenario.world.datum));

    let after = pipeline.process(&frames[150]);
    for (track, id) in ids(&after, pipeline.map()) {
        if let Some((_, was)) = before.iter().find(|(t, _)| *t == track) {
            assert_eq!(&id, was, "track {track} changed tower with the map");
        }
    }
}
