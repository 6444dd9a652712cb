//! A quadrotor flying a waypoint plan: point-mass dynamics with drag and gusty
//! wind, a velocity controller, and the attitude that its thrust vector needs.
//!
//! The attitude is what makes the camera realistic: thrust must tilt forward to
//! hold speed against drag (nose down), and sideways to turn (roll). The
//! airframe cannot tilt at once: roll and pitch follow the tilt the controller
//! asks for through a first-order loop with rate and acceleration limits, as a
//! small quadrotor's attitude controller does, and the thrust acts along the
//! tilt the airframe has, not the one it was asked for. Turns through a
//! waypoint start before it, so the command itself does not step either.

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
    /// Time constant of the roll and pitch loop, s.
    pub attitude_tau_s: f64,
    /// Largest roll and pitch rate, rad/s.
    pub max_tilt_rate_rad_s: f64,
    /// Largest roll and pitch angular acceleration, rad/s^2.
    pub max_tilt_accel_rad_s2: f64,
    /// Time constant of the heading loop, s.
    pub yaw_tau_s: f64,
    /// Largest yaw angular acceleration, rad/s^2.
    pub max_yaw_accel_rad_s2: f64,
    /// The turn onto the next leg starts this many seconds of flight before
    /// its waypoint (at most half the shorter leg), and blends back out as far
    /// after it.
    pub turn_lead_s: f64,
    /// Velocity loop gain, 1/s.
    pub velocity_gain: f64,
    /// Cross-track and height gains, 1/s.
    pub position_gain: f64,
    pub wind: WindParams,
    /// Integration and sampling step, s.
    pub dt_s: f64,
    /// Give up after this long (or three times the plan's nominal time,
    /// if longer) even if the last waypoint was not reached.
    pub max_duration_s: f64,
}

impl Default for QuadParams {
    fn default() -> Self {
        Self {
            drag_per_s: 0.1,
            max_accel_mps2: 3.0,
            max_tilt_rad: 25f64.to_radians(),
            max_yaw_rate_rad_s: 45f64.to_radians(),
            attitude_tau_s: 0.15,
            max_tilt_rate_rad_s: 150f64.to_radians(),
            max_tilt_accel_rad_s2: 800f64.to_radians(),
            yaw_tau_s: 0.3,
            max_yaw_accel_rad_s2: 180f64.to_radians(),
            turn_lead_s: 1.5,
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
    let mut yaw_rate = 0.0;
    // Roll and pitch with their rates; `None` until the first command, which
    // the flight starts trimmed at.
    let mut tilt: Option<[AxisState; 2]> = None;
    let wind_mean = Vector2::new(params.wind.mean_mps.0, params.wind.mean_mps.1);
    let mut gust = Vector2::zeros();
    let mut leg = 0;
    let mut samples = Vec::new();
    // A long plan (laps for a soak) is given three times its nominal time.
    let nominal_s: f64 = wps
        .windows(2)
        .map(|w| {
            let leg = Point3::new(w[1].east_m, w[1].north_m, w[1].height_m)
                - Point3::new(w[0].east_m, w[0].north_m, w[0].height_m);
            leg.norm() / w[1].speed_mps.max(0.1)
        })
        .sum();
    let max_steps = (params.max_duration_s.max(3.0 * nominal_s) / dt) as usize;
    let max_horizontal = GRAVITY * params.max_tilt_rad.tan();
    let loop_limits = AxisLimits {
        tau_s: params.attitude_tau_s,
        max_rate: params.max_tilt_rate_rad_s,
        max_accel: params.max_tilt_accel_rad_s2,
    };
    let yaw_limits = AxisLimits {
        tau_s: params.yaw_tau_s,
        max_rate: params.max_yaw_rate_rad_s,
        max_accel: params.max_yaw_accel_rad_s2,
    };
    for _ in 0..max_steps {
        let b = at(leg + 1);
        let Guidance {
            along,
            leg_len,
            to_go,
            v_des_h,
            vz_des,
        } = guidance(wps, leg, &position, params);
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
        let thrust_z = GRAVITY + accel_z;
        let wanted = attitude_from_thrust(&thrust_h, thrust_z, yaw);
        let [roll, pitch] =
            tilt.get_or_insert([AxisState::at(wanted.roll), AxisState::at(wanted.pitch)]);
        let attitude = Attitude {
            roll: roll.angle,
            pitch: pitch.angle,
            yaw,
        };
        // The thrust acts along the tilt the airframe has.
        let thrust_applied = thrust_from_attitude(&attitude, thrust_z);
        let air_true = velocity.xy() - wind_mean - gust;
        let accel_h = thrust_applied - air_true * params.drag_per_s;

        samples.push(Sample {
            position_in_world: position,
            velocity_in_world: velocity,
            attitude,
        });

        roll.step(wanted.roll - roll.angle, &loop_limits, dt);
        pitch.step(wanted.pitch - pitch.angle, &loop_limits, dt);
        velocity += Vector3::new(accel_h.x, accel_h.y, accel_z) * dt;
        position += velocity * dt;
        let ground_speed = velocity.xy().norm();
        let yaw_error = if ground_speed > 1.0 {
            wrap_angle(velocity.y.atan2(velocity.x) - yaw)
        } else {
            0.0
        };
        let mut yaw_axis = AxisState {
            angle: yaw,
            rate: yaw_rate,
        };
        yaw_axis.step(yaw_error, &yaw_limits, dt);
        (yaw, yaw_rate) = (wrap_angle(yaw_axis.angle), yaw_axis.rate);
        gust = next_gust(gust, params, dt, &mut rng);

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

/// Where the plan steers the vehicle at `position` on leg `leg`.
struct Guidance {
    /// Distance flown along the leg, its length and what is left, m.
    along: f64,
    leg_len: f64,
    to_go: f64,
    /// Horizontal velocity wanted (along the leg, back onto it), m/s.
    v_des_h: Vector2<f64>,
    /// Climb rate wanted towards the leg's height profile, m/s.
    vz_des: f64,
}

fn guidance(
    wps: &[crate::waypoints::Waypoint],
    leg: usize,
    position: &Point3<f64>,
    params: &QuadParams,
) -> Guidance {
    let at = |i: usize| Point3::new(wps[i].east_m, wps[i].north_m, wps[i].height_m);
    let (a, b) = (at(leg), at(leg + 1));
    let dir = leg_direction(&a, &b);
    let leg_len = (b - a).xy().norm().max(1e-6);
    let along = (position - a).xy().dot(&dir).clamp(0.0, leg_len);
    let to_go = leg_len - along;
    let cross = (position - a).xy() - dir * along;
    let next_dir = (leg + 2 < wps.len()).then(|| leg_direction(&b, &at(leg + 2)));
    // Slow down before a turn so the corner stays tight: v^2 = v_turn^2 + 2 a d,
    // and slow enough that the bend through the waypoint (radius about
    // lead / tan(angle / 2)) asks for no more than the braking share of
    // the acceleration.
    let turn_speed = match next_dir {
        Some(next) => {
            let cos = dir.dot(&next).clamp(-1.0, 1.0);
            let half_tan = ((1.0 - cos) / (1.0 + cos).max(1e-9)).sqrt();
            let radius = turn_lead_m(wps, leg, params.turn_lead_s) / half_tan.max(1e-9);
            (wps[leg].speed_mps * (0.5 * (1.0 + cos)).sqrt())
                .min((0.6 * params.max_accel_mps2 * radius).sqrt())
                .max(0.2 * wps[leg].speed_mps)
        }
        None => 0.0,
    };
    let speed = wps[leg]
        .speed_mps
        .min((turn_speed.powi(2) + 2.0 * 0.6 * params.max_accel_mps2 * to_go).sqrt());
    let heading = turn_heading(wps, leg, along, to_go, params.turn_lead_s);
    let height_target = a.z + (b.z - a.z) * (along / leg_len);
    Guidance {
        along,
        leg_len,
        to_go,
        v_des_h: heading * speed - cross * params.position_gain,
        vz_des: ((height_target - position.z) * params.position_gain).clamp(-3.0, 3.0),
    }
}

/// The gust one step on: a first-order Gauss-Markov process with the wind's
/// time constant and standard deviation.
fn next_gust(
    gust: Vector2<f64>,
    params: &QuadParams,
    dt: f64,
    rng: &mut ChaCha8Rng,
) -> Vector2<f64> {
    let tau = params.wind.gust_tau_s.max(dt);
    let decay = (-dt / tau).exp();
    let drive = params.wind.gust_sigma_mps.max(0.0) * (1.0 - decay * decay).sqrt();
    gust * decay
        + Vector2::new(
            rng.sample::<f64, _>(StandardNormal),
            rng.sample::<f64, _>(StandardNormal),
        ) * drive
}

/// One attitude axis: its angle and rate, rad and rad/s.
#[derive(Debug, Clone, Copy)]
struct AxisState {
    angle: f64,
    rate: f64,
}

#[derive(Debug, Clone, Copy)]
struct AxisLimits {
    tau_s: f64,
    max_rate: f64,
    max_accel: f64,
}

impl AxisState {
    fn at(angle: f64) -> Self {
        Self { angle, rate: 0.0 }
    }

    /// Close `error` with time constant `tau_s`, the rate and its change limited.
    fn step(&mut self, error: f64, limits: &AxisLimits, dt: f64) {
        let wanted_rate = (error / limits.tau_s.max(dt)).clamp(-limits.max_rate, limits.max_rate);
        let max_change = limits.max_accel * dt;
        self.rate += (wanted_rate - self.rate).clamp(-max_change, max_change);
        self.angle += self.rate * dt;
    }
}

/// How far before the end of `leg` (and after the start of the next) the
/// turn between them blends: `lead_s` of flight, at most half of either leg.
fn turn_lead_m(wps: &[crate::waypoints::Waypoint], leg: usize, lead_s: f64) -> f64 {
    let at = |i: usize| Point3::new(wps[i].east_m, wps[i].north_m, wps[i].height_m);
    let leg_len = |i: usize| (at(i + 1) - at(i)).xy().norm();
    let mut lead = (wps[leg].speed_mps * lead_s).min(0.5 * leg_len(leg));
    if leg + 2 < wps.len() {
        lead = lead.min(0.5 * leg_len(leg + 1));
    }
    lead.max(1e-6)
}

/// The direction to fly on `leg`: the leg's own, turning onto the next leg in
/// the last stretch before its waypoint and out of the previous one in the
/// first stretch after, so the heading bends through a waypoint instead of
/// stepping there. The stretch is `lead_s` of flight, at most half a leg.
fn turn_heading(
    wps: &[crate::waypoints::Waypoint],
    leg: usize,
    along: f64,
    to_go: f64,
    lead_s: f64,
) -> Vector2<f64> {
    let at = |i: usize| Point3::new(wps[i].east_m, wps[i].north_m, wps[i].height_m);
    let dir = leg_direction(&at(leg), &at(leg + 1));
    let mut heading = dir;
    if leg + 2 < wps.len() {
        let d = turn_lead_m(wps, leg, lead_s);
        if to_go < d {
            let w = 0.5 * (1.0 - to_go / d);
            heading = heading * (1.0 - w) + leg_direction(&at(leg + 1), &at(leg + 2)) * w;
        }
    }
    if leg > 0 {
        let d = turn_lead_m(wps, leg - 1, lead_s);
        if along < d {
            let w = 0.5 * (1.0 - along / d);
            heading = heading * (1.0 - w) + leg_direction(&at(leg - 1), &at(leg)) * w;
        }
    }
    // A reversal blends through zero: keep the leg's own direction there.
    if heading.norm() < 1e-3 {
        dir
    } else {
        heading.normalize()
    }
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

/// The horizontal thrust per unit mass that roll and pitch give with vertical
/// thrust `thrust_z`: the inverse of `attitude_from_thrust`.
fn thrust_from_attitude(attitude: &Attitude, thrust_z: f64) -> Vector2<f64> {
    let thrust_z = thrust_z.max(1.0);
    let forward = -attitude.pitch.tan() * thrust_z;
    let right = attitude.roll.tan() * forward.hypot(thrust_z);
    let (sin, cos) = attitude.yaw.sin_cos();
    Vector2::new(forward * cos + right * sin, forward * sin - right * cos)
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
        let tr = flown("paper-path-1");
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

    /// Largest roll or pitch rate, yaw rate and roll or pitch acceleration, per second.
    fn peak_rates(tr: &Trajectory) -> (f64, f64, f64) {
        let rate = |a: &Sample, b: &Sample| {
            (
                (b.attitude.roll - a.attitude.roll) / tr.dt_s,
                (b.attitude.pitch - a.attitude.pitch) / tr.dt_s,
                wrap_angle(b.attitude.yaw - a.attitude.yaw) / tr.dt_s,
            )
        };
        let rates: Vec<_> = tr.samples.windows(2).map(|w| rate(&w[0], &w[1])).collect();
        let tilt = rates
            .iter()
            .map(|r| r.0.abs().max(r.1.abs()))
            .fold(0.0, f64::max);
        let yaw = rates.iter().map(|r| r.2.abs()).fold(0.0, f64::max);
        let accel = rates
            .windows(2)
            .map(|w| ((w[1].0 - w[0].0).abs().max((w[1].1 - w[0].1).abs())) / tr.dt_s)
            .fold(0.0, f64::max);
        (tilt, yaw, accel)
    }

    #[test]
    fn every_preset_turns_at_a_small_quadrotors_rates() {
        let p = QuadParams::default();
        for (name, _) in crate::waypoints::PRESETS {
            let tr = flown(name);
            let (tilt, yaw, accel) = peak_rates(&tr);
            assert!(
                tilt.to_degrees() <= 200.0,
                "{name}: tilt rate {:.0} deg/s",
                tilt.to_degrees()
            );
            assert!(
                tilt <= p.max_tilt_rate_rad_s + 1e-9,
                "{name}: tilt rate {tilt}"
            );
            assert!(yaw <= p.max_yaw_rate_rad_s + 1e-9, "{name}: yaw rate {yaw}");
            assert!(
                accel <= p.max_tilt_accel_rad_s2 * 1.001,
                "{name}: tilt acceleration {:.0} deg/s^2",
                accel.to_degrees()
            );
            // At 30 frames/s no frame sees the roll step, as trackers need.
            let per_frame = tr
                .samples
                .iter()
                .step_by(3)
                .collect::<Vec<_>>()
                .windows(2)
                .map(|w| (w[1].attitude.roll - w[0].attitude.roll).abs())
                .fold(0.0, f64::max);
            assert!(
                per_frame.to_degrees() < 5.0,
                "{name}: {:.1} deg in a frame",
                per_frame.to_degrees()
            );
        }
    }

    #[test]
    fn the_airframe_lags_the_command_it_is_given() {
        // A lazier loop reaches the same turn with a smaller rate.
        let plan = FlightPlan::preset("paper-path-1").expect("preset");
        let quick = fly(&plan, &QuadParams::default(), 1);
        let lazy = fly(
            &plan,
            &QuadParams {
                attitude_tau_s: 0.6,
                ..QuadParams::default()
            },
            1,
        );
        assert!(peak_rates(&lazy).0 < peak_rates(&quick).0 * 0.8);
    }

    proptest::proptest! {
        #[test]
        fn thrust_and_attitude_invert_each_other(
            east in -8.0..8.0f64, north in -8.0..8.0f64, up in 5.0..15.0f64, yaw in -3.1..3.1f64
        ) {
            let thrust = Vector2::new(east, north);
            let attitude = attitude_from_thrust(&thrust, up, yaw);
            let back = thrust_from_attitude(&attitude, up);
            proptest::prop_assert!((back - thrust).norm() < 1e-9, "{back} vs {thrust}");
        }
    }

    #[test]
    fn gusts_are_seeded() {
        let plan = FlightPlan::preset("straight").expect("preset");
        let p = QuadParams::default();
        assert_eq!(fly(&plan, &p, 5), fly(&plan, &p, 5));
        assert_ne!(fly(&plan, &p, 5), fly(&plan, &p, 6));
    }
}
