//! A barometer's height above the take-off point, as an autopilot reports it
//! (ALTITUDE's relative altitude): the truth's climb, off by a bias drawn once
//! per flight (the day's pressure drift, the airframe's pressure field) and
//! white noise. Seeded.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BarometerParams {
    /// One-sigma of the flight's bias, metres.
    pub bias_sigma_m: f64,
    /// One-sigma of each reading's noise, metres.
    pub noise_sigma_m: f64,
}

impl Default for BarometerParams {
    /// A multicopter's MEMS barometer over a short flight: 1 m bias, 0.3 m noise.
    fn default() -> Self {
        Self {
            bias_sigma_m: 1.0,
            noise_sigma_m: 0.3,
        }
    }
}

/// Readings of one flight.
pub struct Barometer {
    params: BarometerParams,
    rng: ChaCha8Rng,
    bias_m: f64,
    takeoff_up_m: f64,
}

impl Barometer {
    /// A barometer zeroed at `takeoff_up_m`, the take-off point's height in the world.
    pub fn new(params: BarometerParams, seed: u64, takeoff_up_m: f64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xba20_0000_0000);
        let bias_m = params.bias_sigma_m * rng.sample::<f64, _>(StandardNormal);
        Self {
            params,
            rng,
            bias_m,
            takeoff_up_m,
        }
    }

    /// The reading at a true height `up_m` in the world: metres above take-off.
    pub fn read(&mut self, up_m: f64) -> f64 {
        let noise = self.params.noise_sigma_m * self.rng.sample::<f64, _>(StandardNormal);
        up_m - self.takeoff_up_m + self.bias_m + noise
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn readings_are_the_climb_off_by_one_bias_and_small_noise() {
        let params = BarometerParams::default();
        let mut baro = Barometer::new(params, 7, 100.0);
        let readings: Vec<f64> = (0..2000).map(|_| baro.read(130.0)).collect();
        let mean = readings.iter().sum::<f64>() / readings.len() as f64;
        let spread = (readings.iter().map(|r| (r - mean).powi(2)).sum::<f64>()
            / readings.len() as f64)
            .sqrt();
        assert!((mean - 30.0).abs() < 4.0 * params.bias_sigma_m, "{mean}");
        assert!((spread - params.noise_sigma_m).abs() < 0.05, "{spread}");
        // The bias is the flight's: the same seed gives the same one, another seed another.
        let bias = |seed| Barometer::new(params, seed, 0.0).bias_m;
        assert_eq!(bias(7), bias(7));
        assert_ne!(bias(7), bias(8));
    }
}
