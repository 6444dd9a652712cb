//! A GNSS receiver's error, as a survey or replay flight's log holds it:
//! first-order Gauss-Markov in each axis (a receiver's error wanders over
//! tens of seconds; it does not jump from fix to fix), seeded. Its velocity,
//! from the carrier's Doppler shift, is far better: off by centimetres a
//! second, forgotten within [`VELOCITY_CORRELATION_S`], apart from the
//! position's error.

use nalgebra::{Point3, Vector2, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnssParams {
    /// One-sigma horizontal error per axis, metres.
    pub horizontal_sigma_m: f64,
    /// One-sigma vertical error, metres.
    pub vertical_sigma_m: f64,
    /// How long the error takes to forget itself, seconds.
    pub correlation_s: f64,
    /// One-sigma error of each horizontal axis of the velocity, m/s.
    pub velocity_sigma_mps: f64,
}

/// How long the velocity's error takes to forget itself, seconds.
pub const VELOCITY_CORRELATION_S: f64 = 1.0;

impl Default for GnssParams {
    /// A consumer receiver with a clear sky: 1.5 m, 3 m vertical, 10 s;
    /// its velocity to 0.1 m/s (u-blox M8 and M9 state 0.05 m/s).
    fn default() -> Self {
        Self {
            horizontal_sigma_m: 1.5,
            vertical_sigma_m: 3.0,
            correlation_s: 10.0,
            velocity_sigma_mps: 0.1,
        }
    }
}

/// Noisy fixes of a true track, in the world's ENU metres.
pub struct GnssNoise {
    params: GnssParams,
    rng: ChaCha8Rng,
    error: Vector3<f64>,
    last_s: Option<f64>,
    /// The velocity's error draws from its own stream: the positions'
    /// errors are the same with or without it.
    velocity_rng: ChaCha8Rng,
    velocity_error: Vector2<f64>,
    velocity_last_s: Option<f64>,
}

impl GnssNoise {
    pub fn new(params: GnssParams, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x6e55);
        let error = Self::draw(&params, &mut rng);
        let mut velocity_rng = ChaCha8Rng::seed_from_u64(seed ^ 0x7e10);
        let velocity_error = Self::draw_velocity(&params, &mut velocity_rng);
        Self {
            params,
            rng,
            error,
            last_s: None,
            velocity_rng,
            velocity_error,
            velocity_last_s: None,
        }
    }

    fn draw_velocity(params: &GnssParams, rng: &mut ChaCha8Rng) -> Vector2<f64> {
        let mut n = || rng.sample::<f64, _>(StandardNormal);
        Vector2::new(n(), n()) * params.velocity_sigma_mps
    }

    /// The velocity the receiver gives at `time_s` (increasing), east and
    /// north, moving truly at `truth`.
    pub fn velocity(&mut self, time_s: f64, truth: Vector2<f64>) -> Vector2<f64> {
        let dt = self
            .velocity_last_s
            .map_or(0.0, |last| (time_s - last).max(0.0));
        self.velocity_last_s = Some(time_s);
        if dt > 0.0 {
            let keep = (-dt / VELOCITY_CORRELATION_S).exp();
            let fresh = Self::draw_velocity(&self.params, &mut self.velocity_rng);
            self.velocity_error = self.velocity_error * keep + fresh * (1.0 - keep * keep).sqrt();
        }
        truth + self.velocity_error
    }

    fn draw(params: &GnssParams, rng: &mut ChaCha8Rng) -> Vector3<f64> {
        let mut n = || rng.sample::<f64, _>(StandardNormal);
        Vector3::new(
            params.horizontal_sigma_m * n(),
            params.horizontal_sigma_m * n(),
            params.vertical_sigma_m * n(),
        )
    }

    /// The fix at `time_s` (increasing) of a receiver truly at `truth`.
    pub fn fix(&mut self, time_s: f64, truth: &Point3<f64>) -> Point3<f64> {
        let dt = self.last_s.map_or(0.0, |last| (time_s - last).max(0.0));
        self.last_s = Some(time_s);
        if dt > 0.0 {
            let keep = if self.params.correlation_s > 0.0 {
                (-dt / self.params.correlation_s).exp()
            } else {
                0.0
            };
            let fresh = Self::draw(&self.params, &mut self.rng);
            // Stationary: the variance stays sigma^2 whatever the step.
            self.error = self.error * keep + fresh * (1.0 - keep * keep).sqrt();
        }
        truth + self.error
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_error_has_its_sigma_and_wanders_slowly() {
        let mut gnss = GnssNoise::new(GnssParams::default(), 3);
        let truth = Point3::new(10.0, 20.0, 30.0);
        let errors: Vec<Vector3<f64>> = (0..20_000)
            .map(|i| gnss.fix(f64::from(i) * 0.2, &truth) - truth)
            .collect();
        let rms_east = (errors.iter().map(|e| e.x * e.x).sum::<f64>() / errors.len() as f64).sqrt();
        assert!((rms_east - 1.5).abs() < 0.2, "east RMS {rms_east:.2} m");
        let step = errors
            .windows(2)
            .map(|w| (w[1] - w[0]).x.abs())
            .sum::<f64>()
            / (errors.len() - 1) as f64;
        assert!(step < 0.4, "mean step between fixes {step:.2} m");
    }

    #[test]
    fn the_velocity_is_off_by_its_sigma_and_leaves_the_positions_as_they_were() {
        let truth = Point3::new(10.0, 20.0, 30.0);
        let mut plain = GnssNoise::new(GnssParams::default(), 3);
        let mut with_velocity = GnssNoise::new(GnssParams::default(), 3);
        let mut errors = Vec::new();
        for i in 0..20_000 {
            let t = f64::from(i) * 0.1;
            errors
                .push(with_velocity.velocity(t, Vector2::new(5.0, -2.0)) - Vector2::new(5.0, -2.0));
            assert_eq!(plain.fix(t, &truth), with_velocity.fix(t, &truth));
        }
        let rms = (errors.iter().map(|e| e.norm_squared()).sum::<f64>()
            / (2.0 * errors.len() as f64))
            .sqrt();
        assert!((rms - 0.1).abs() < 0.02, "velocity RMS {rms:.3} m/s");
    }
}
