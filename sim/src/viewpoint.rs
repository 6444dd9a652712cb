//! Random places to look at a world's towers from, for training sets: from
//! just above the ground to 120 m, looking level or down (to nearly straight
//! down, as survey photos look), near and far, upright or banked as in a
//! turn, with the tower sometimes cut by the frame's edge.

use nalgebra::Point3;
use rand::Rng;
use towernav_geometry::{Attitude, Pose};

use crate::world::World;

/// Highest and lowest eye heights, metres above the ground.
pub const EYE_HEIGHT_M: (f64, f64) = (1.5, 120.0);

/// Share of viewpoints rolled as in a banked turn, up to `BANKED_ROLL_RAD`
/// either way (the quadrotor banks to 25 degrees): a detector that has
/// seen only upright towers fragments leaning ones. The rest roll a few
/// degrees at most.
pub const BANKED_SHARE: f64 = 0.3;
pub const BANKED_ROLL_RAD: f64 = 0.52;

/// A pose looking roughly at one of `world`'s towers, for a camera of
/// horizontal field of view `hfov` (radians) tilted `mount_pitch` on its body.
/// `None` for a world without towers.
pub fn random_viewpoint(
    world: &World,
    hfov: f64,
    mount_pitch: f64,
    rng: &mut impl Rng,
) -> Option<Pose> {
    if world.towers.is_empty() {
        return None;
    }
    let tower = &world.towers[rng.random_range(0..world.towers.len())];
    // Log-uniform range: as many close views as far ones.
    let range = rng.random_range(15f64.ln()..450f64.ln()).exp();
    // A fifth are from above, as a survey flight photographs a tower.
    let above = rng.random_bool(0.2);
    let bearing = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
    let eye = if above {
        (tower.height_m + rng.random_range(10.0..60.0)).min(EYE_HEIGHT_M.1)
    } else if rng.random_bool(0.2) {
        rng.random_range(EYE_HEIGHT_M.0..10.0)
    } else {
        rng.random_range(10.0..EYE_HEIGHT_M.1)
    };
    let foot = tower.foot_in_world;
    let range = if above { range.min(40.0) } else { range };
    let position_in_world = Point3::new(
        foot.x + range * bearing.cos(),
        foot.y + range * bearing.sin(),
        eye,
    );
    let toward = (foot.y - position_in_world.y).atan2(foot.x - position_in_world.x);
    let yaw = toward + rng.random_range(-0.6..0.6) * hfov;
    let aim = rng.random_range(0.0..tower.height_m);
    let look = ((aim - eye) / range).atan() + rng.random_range(-0.15..0.15);
    // Lowest look: a little short of straight down (where yaw is undefined).
    const STEEPEST: f64 = -1.5;
    Some(Pose {
        position_in_world,
        attitude: Attitude {
            roll: if rng.random_bool(BANKED_SHARE) {
                rng.random_range(-BANKED_ROLL_RAD..BANKED_ROLL_RAD)
            } else {
                rng.random_range(-0.1..0.1)
            },
            pitch: look.clamp(STEEPEST, 0.15) - mount_pitch,
            yaw,
        },
    })
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::world::WorldParams;

    #[test]
    fn viewpoints_stay_in_the_eye_heights_and_look_level_or_down() {
        let world = World::random(3, &WorldParams::default());
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for _ in 0..500 {
            let pose = random_viewpoint(&world, 1.2, 0.0, &mut rng).expect("towers");
            let z = pose.position_in_world.z;
            assert!((EYE_HEIGHT_M.0..=EYE_HEIGHT_M.1).contains(&z), "{z}");
            assert!((-1.5..=0.15).contains(&pose.attitude.pitch));
            assert!(pose.attitude.roll.abs() <= BANKED_ROLL_RAD);
        }
        // A fifth rolled past 10 degrees: two thirds of the banked share.
        let banked = (0..1000)
            .filter_map(|_| random_viewpoint(&world, 1.2, 0.0, &mut rng))
            .filter(|p| p.attitude.roll.abs() > 10f64.to_radians())
            .count();
        assert!((150..350).contains(&banked), "{banked} of 1000 banked");
        let empty = World {
            towers: Vec::new(),
            lines: Vec::new(),
            ..world
        };
        assert!(random_viewpoint(&empty, 1.2, 0.0, &mut rng).is_none());
    }
}
