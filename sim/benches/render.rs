//! Rendering speed: one 1280x720 frame of the paper's field, default conditions, one thread.

use criterion::{Criterion, criterion_group, criterion_main};
use towernav_sim::{Conditions, Renderer, Scenario};

fn render(c: &mut Criterion) {
    let scenario =
        Scenario::preset(towernav_sim::World::paper_field(), "paper-path-1", 1).expect("preset");
    let renderer = Renderer::new(&scenario.world, scenario.camera, 1);
    let mut buffers = renderer.buffers();
    let conditions = Conditions::default();
    // Mid-flight, with the A and B lines close on either side.
    let t = 30.0;
    let pose = scenario.flight.pose_at(t);
    let rates = scenario.flight.attitude_rates(t);
    c.bench_function("render_1280x720_seed_field", |b| {
        b.iter(|| renderer.render_into(&mut buffers, &pose, &conditions, rates, 7))
    });
    let turn = scenario.flight.duration_s() / 2.0;
    let (pose, rates) = (
        scenario.flight.pose_at(turn),
        scenario.flight.attitude_rates(turn),
    );
    c.bench_function("render_1280x720_in_the_turn", |b| {
        b.iter(|| renderer.render_into(&mut buffers, &pose, &conditions, rates, 7))
    });
}

criterion_group!(benches, render);
criterion_main!(benches);
