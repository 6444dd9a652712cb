//! Recorded inputs replay through the pure pipeline with no sockets: frames go through
//! the wire codec to JSON and back, and the run is the same as the live one.

use towernav_core::{LandmarkMap, Pipeline, PipelineConfig};
use towernav_protocol::{DetectionFrame, decode, encode};
use towernav_sim::Scenario;

#[test]
fn a_recorded_flight_replays_to_the_same_fixes() -> anyhow::Result<()> {
    let scenario = Scenario::paper(5);
    let map = LandmarkMap::from_records(&scenario.world.landmarks(), &scenario.world.datum);
    let config = PipelineConfig::new(scenario.camera, scenario.start_in_world());

    let recording: Vec<Vec<u8>> = scenario
        .frames()
        .take(600)
        .map(|(_, f)| encode(&f))
        .collect::<Result<_, _>>()?;
    let mut live = Pipeline::new(config.clone(), map.clone());
    let live_out: Vec<_> = scenario
        .frames()
        .take(600)
        .map(|(_, f)| live.process(&f))
        .collect();

    let mut replay = Pipeline::new(config, map);
    let mut fixes = 0;
    for (bytes, expected) in recording.iter().zip(&live_out) {
        let frame: DetectionFrame = decode(bytes)?;
        let out = replay.process(&frame);
        assert_eq!(&out, expected, "frame {}", frame.seq);
        fixes += usize::from(out.fix.is_some());
    }
    assert!(fixes > 450, "{fixes} fixes in 600 frames");
    Ok(())
}
