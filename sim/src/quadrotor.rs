//! A quadrotor flying a waypoint plan: point-mass dynamics with drag and gusty
//! wind, a velocity controller, and the attitude that its thrust vector needs.
//!
//! The attitude is what makes the camera realistic: thrust must tilt forward to
//! hold speed against drag (nose down), and sideways to turn (roll).

use nalgebra::{Point3, Vector2, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use towernav_geometry::{Attitude, Pose, wrap_angle};

use crate::waypoints::FlightPlan;

const GRAVITY: f64 = 9.81;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindParams {
    /// Steady wind, east and north, m/s.
    pub mean_mps: (f64, f64),
    /// Standard deviation of the gusts per horizontal axis, m/s.
    pub gust_sigma_mps: f64,
    /// Correlation time of the gusts (first-order Gauss-Markov), s.
    pub gust_tau_s: f64,
}

impl Default for WindParams {
    fn default() -> Self {
        Self {
            mean_mps: (2.0, -1.0),
            gust_sigma_mps: 1.0,
            gust_tau_s: 2.0,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuadParams {
    /// Linear drag per unit mass, 1/s: sets the nose-down pitch at cruise.
    pub drag_per_s: f64,
    /// Horizontal acceleration the controller may ask for, m/s^2.
    pub max_accel_mps2: f64,
    /// Largest tilt of the thrust vector.
    pub max_tilt_rad: f64,
    pub max_yaw_rate_rad_s: f64,
    /// Velocity loop gain, 1/s.
    pub velocity_gain: f64,
    /// Cross-track and height gains, 1/s.
    pub position_gain: f64,
    pub wind: WindParams,
    /// Integration and sampling step, s.
    pub dt_s: f64,
    /// Give up after this long even if the last waypoint was not reached.
    pub max_duration_s: f64,
}

impl Default for QuadParams {
    fn default() -> Self {
        Self {
            drag_per_s: 0.1,
            max_accel_mps2: 3.0,
            max_tilt_rad: 25f64.to_radians(),
            max_yaw_rate_rad_s: 45f64.to_radians(),
            velocity_gain: 1.5,
            position_gain: 0.4,
            wind: WindParams::default(),
            dt_s: 0.01,
            max_duration_s: 900.0,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    pub position_in_world: Point3<f64>,
    pub velocity_in_world: Vector3<f64>,
    pub attitude: Attitude,
}

/// Samples every `dt_s` from t = 0; poses between samples are interpolated.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    pub dt_s: f64,
    pub samples: Vec<Sample>,
}

impl Trajectory {
    pub fn duration_s(&self) -> f64 {
        self.samples.len().saturating_sub(1) as f64 * self.dt_s
    }

    pub fn sample_at(&self, t: f64) -> Sample {
        let last = self.samples.len().saturating_sub(1);
        let x = (t / self.dt_s).clamp(0.0, last as f64);
        let i = (x.floor() as usize).min(last.saturating_sub(1));
        let s = x - i as f64;
        let (a, b) = (self.samples[i], self.samples[(i + 1).min(last)]);
        let mix = |p: f64, q: f64| p + (q - p) * s;
        Sample {
            position_in_world: a.position_in_world
                + (b.position_in_world - a.position_in_world) * s,
            velocity_in_world: a.velocity_in_world.lerp(&b.velocity_in_world, s),
            attitude: Attitude {
                roll: mix(a.attitude.roll, b.attitude.roll),
                pitch: mix(a.attitude.pitch, b.attitude.pitch),
                yaw: wrap_angle(a.attitude.yaw + wrap_angle(b.attitude.yaw - a.attitude.yaw) * s),
            },
        }
    }

    pub fn pose_at(&self, t: f64) -> Pose {
        let s = self.sample_at(t);
        Pose {
            position_in_world: s.position_in_world,
            attitude: s.attitude,
        }
    }
}

/// Fly `plan` from its first waypoint, heading along the first leg at the first leg's speed.
/// Deterministic in `seed` (the gusts).
pub fn fly(plan: &FlightPlan, params: &QuadParams, seed: u64) -> Trajectory {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x9a0d_5eed);
    let wps = &plan.waypoints;
    let at = |i: usize| Point3::new(wps[i].east_m, wps[i].north_m, wps[i].height_m);
    let dt = params.dt_s.max(1e-3);
    let first_dir = leg_direction(&at(0), &at(1));
    let mut position = at(0);
    let mut velocity = Vector3::new(first_dir.x, first_dir.y, 0.0) * wps[0].speed_mps;
    let mut yaw = first_dir.y.atan2(first_dir.x);
    let wind_mean = Vector2::new(params.wind.mean_mps.0, params.wind.mean_mps.1);
    let mut gust = Vector2::zeros();
    let mut leg = 0;
    let mut samples = Vec::new();
    let max_steps = (params.max_duration_s / dt) as usize;
    let max_horizontal = GRAVITY * params.max_tilt_rad.tan();
    for _ in 0..max_steps {
        let (a, b) = (at(leg), at(leg + 1));
        let dir = leg_direction(&a, &b);
        let leg_len = (b - a).xy().norm().max(1e-6);
        let along = (position - a).xy().dot(&dir).clamp(0.0, leg_len);
        let to_go = leg_len - along;
        let cross = (position - a).xy() - dir * along;
        // Slow down before a turn so the corner stays tight: v^2 = v_turn^2 + 2 a d.
        let turn_speed = match wps.get(leg + 2) {
            Some(_) => {
                let next = leg_direction(&b, &at(leg + 2));
                wps[leg].speed_mps * (0.5 * (1.0 + dir.dot(&next))).sqrt().max(0.2)
            }
            None => 0.0,
        };
        let speed = wps[leg]
            .speed_mps
            .min((turn_speed.powi(2) + 2.0 * 0.6 * params.max_accel_mps2 * to_go).sqrt());
        let height_target = a.z + (b.z - a.z) * (along / leg_len);
        let v_des_h = dir * speed - cross * params.position_gain;
        let vz_des = ((height_target - position.z) * params.position_gain).clamp(-3.0, 3.0);
        // The controller knows the steady wind's drag, not the gusts'.
        let air_known = velocity.xy() - wind_mean;
        let mut accel_cmd = (v_des_h - velocity.xy()) * params.velocity_gain;
        if accel_cmd.norm() > params.max_accel_mps2 {
            accel_cmd *= params.max_accel_mps2 / accel_cmd.norm();
        }
        let mut thrust_h = accel_cmd + air_known * params.drag_per_s;
        if thrust_h.norm() > max_horizontal {
            thrust_h *= max_horizontal / thrust_h.norm();
        }
        let accel_z = (vz_des - velocity.z) * params.velocity_gain;
        let air_true = velocity.xy() - wind_mean - gust;
        let accel_h = thrust_h - air_true * params.drag_per_s;

        samples.push(Sample {
            position_in_world: position,
            velocity_in_world: velocity,
            attitude: attitude_from_thrust(&thrust_h, GRAVITY + accel_z, yaw),
        });

        velocity += Vector3::new(accel_h.x, accel_h.y, accel_z) * dt;
        position += velocity * dt;
        let ground_speed = velocity.xy().norm();
        if ground_speed > 1.0 {
            let want = velocity.y.atan2(velocity.x);
            let step = params.max_yaw_rate_rad_s * dt;
            yaw = wrap_angle(yaw + wrap_angle(want - yaw).clamp(-step, step));
        }
        let tau = params.wind.gust_tau_s.max(dt);
        let decay = (-dt / tau).exp();
        let drive = params.wind.gust_sigma_mps.max(0.0) * (1.0 - decay * decay).sqrt();
        gust = gust * decay
            + Vector2::new(
                rng.sample::<f64, _>(StandardNormal),
                rng.sample::<f64, _>(StandardNormal),
            ) * drive;

        // Next leg once abeam of its end (or close to it).
        if to_go < 2.0 || along >= leg_len - 1e-9 {
            if leg + 2 < wps.len() {
                leg += 1;
            } else if (position - b).xy().norm() < 3.0 || ground_speed < 0.3 {
                break;
            }
        }
    }
    Trajectory { dt_s: dt, samples }
}

fn leg_direction(a: &Point3<f64>, b: &Point3<f64>) -> Vector2<f64> {
    let d = (b - a).xy();
    if d.norm() < 1e-9 {
        Vector2::new(1.0, 0.0)
    } else {
        d.normalize()
    }
}

/// Roll and pitch that point the thrust along (horizontal thrust, vertical thrust) at this yaw.
fn attitude_from_thrust(thrust_h: &Vector2<f64>, thrust_z: f64, yaw: f64) -> Attitude {
    let forward = thrust_h.x * yaw.cos() + thrust_h.y * yaw.sin();
    let right = thrust_h.x * yaw.sin() - thrust_h.y * yaw.cos();
    let thrust_z = thrust_z.max(1.0);
    Attitude {
        // Forward thrust needs the nose down: negative pitch.
        pitch: -forward.atan2(thrust_z),
        // Thrust to the right needs the right wing down: positive roll.
        roll: right.atan2((forward * forward + thrust_z * thrust_z).sqrt()),
        yaw,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flown(name: &str) -> Trajectory {
        fly(
            &FlightPlan::preset(name).expect("preset"),
            &QuadParams::default(),
            1,
        )
    }

    #[test]
    fn cruise_is_nose_down_and_level_across() {
        let tr = flown("straight");
        let mid = tr.sample_at(tr.duration_s() / 2.0);
        let pitch = mid.attitude.pitch.to_degrees();
        assert!((-12.0..=-2.0).contains(&pitch), "pitch {pitch}");
        assert!(mid.attitude.roll.abs().to_degrees() < 6.0);
        assert!((mid.velocity_in_world.xy().norm() - 10.0).abs() < 1.5);
        let end = tr.samples.last().expect("samples").position_in_world;
        assert!((end.x - 950.0).abs() < 5.0 && (end.y - 250.0).abs() < 5.0);
    }

    #[test]
    fn the_turn_rolls_and_reverses_heading() {
        let tr = flown("seed-path-1");
        let max_roll = tr
            .samples
            .iter()
            .map(|s| s.attitude.roll.abs())
            .fold(0.0, f64::max);
        assert!(
            max_roll.to_degrees() > 5.0,
            "roll {}",
            max_roll.to_degrees()
        );
        let last = tr.samples.last().expect("samples");
        assert!(
            wrap_angle(last.attitude.yaw - std::f64::consts::PI).abs() < 0.2,
            "yaw {}",
            last.attitude.yaw
        );
        assert!(last.position_in_world.x < 20.0);
    }

    #[test]
    fn the_flight_follows_its_legs_and_heights() {
        let tr = flown("lawnmower");
        for s in tr.samples.iter().step_by(50) {
            assert!((s.position_in_world.z - 60.0).abs() < 3.0);
        }
        let steady = tr.sample_at(20.0).position_in_world;
        assert!((steady.y - 150.0).abs() < 5.0, "cross-track {}", steady.y);
    }

    #[test]
    fn gusts_are_seeded() {
        let plan = FlightPlan::preset("straight").expect("preset");
        let p = QuadParams::default();
        assert_eq!(fly(&plan, &p, 5), fly(&plan, &p, 5));
        assert_ne!(fly(&plan, &p, 5), fly(&plan, &p, 6));
    }
}
