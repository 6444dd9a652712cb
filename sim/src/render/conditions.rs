//! Weather, light and sensor settings for one rendered frame.

use rand::Rng;

/// Everything about a frame's look that is not geometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Conditions {
    /// Sun direction: ENU azimuth (counter-clockwise from east) and elevation, radians.
    pub sun_azimuth: f64,
    pub sun_elevation: f64,
    /// Multiplies every linear colour before the sensor clips it.
    pub exposure: f64,
    /// Distance at which haze hides 63 % of a surface's own colour, metres.
    pub visibility_m: f64,
    /// Share of the sky covered by cloud, 0..1.
    pub cloud_cover: f64,
    /// Standard deviation of per-pixel sensor noise, in 8-bit levels.
    pub noise_sigma: f64,
    /// Shutter time for motion blur, seconds; 0 turns blur off.
    pub shutter_s: f64,
    /// Draw trees, buildings and poles.
    pub distractors: bool,
    /// How the towers' steel looks.
    pub tower_paint: TowerPaint,
}

/// Finishes seen on real lattice towers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TowerPaint {
    /// Bare galvanised steel, light grey.
    #[default]
    Galvanised,
    /// Dark grey or green paint; near black against a bright sky.
    Dark,
    /// Aviation marking: red and white bands.
    RedWhite,
    /// Dull, rust-brown weathered steel.
    Weathered,
}

impl TowerPaint {
    pub const ALL: [Self; 4] = [
        Self::Galvanised,
        Self::Dark,
        Self::RedWhite,
        Self::Weathered,
    ];

    /// The colour of a member of base colour `galvanised` in band `band`
    /// (counted up the tower in sevenths).
    pub fn colour(self, galvanised: [f32; 3], band: u32) -> [f32; 3] {
        match self {
            Self::Galvanised => galvanised,
            Self::Dark => galvanised.map(|c| c * 0.3),
            Self::RedWhite if band.is_multiple_of(2) => [0.78, 0.16, 0.12],
            Self::RedWhite => [0.90, 0.90, 0.88],
            Self::Weathered => [
                galvanised[0] * 0.85,
                galvanised[1] * 0.68,
                galvanised[2] * 0.55,
            ],
        }
    }
}

impl Default for Conditions {
    /// Clear midday, light haze, a little noise, a 1/250 s shutter.
    fn default() -> Self {
        Self {
            sun_azimuth: 2.0,
            sun_elevation: 0.9,
            exposure: 1.0,
            visibility_m: 2500.0,
            cloud_cover: 0.3,
            noise_sigma: 2.0,
            shutter_s: 0.004,
            distractors: true,
            tower_paint: TowerPaint::Galvanised,
        }
    }
}

impl Conditions {
    /// Varied weather and light for datasets: low to high sun, hazy to clear,
    /// under- to over-exposed, clear to overcast.
    pub fn random(rng: &mut impl Rng) -> Self {
        Self {
            sun_azimuth: rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
            sun_elevation: rng.random_range(0.15..1.3),
            exposure: rng.random_range(0.7..1.3),
            visibility_m: rng.random_range(800.0..5000.0),
            cloud_cover: rng.random_range(0.0..0.9),
            noise_sigma: rng.random_range(0.5..5.0),
            shutter_s: rng.random_range(0.0..0.012),
            distractors: true,
            tower_paint: TowerPaint::Galvanised,
        }
    }

    /// Wider variety for domain randomization, facing `view_yaw` (ENU): one
    /// of midday, dawn or dusk, backlit (the sun low ahead: dark towers on a
    /// bright sky), overcast, or hazy; exposure from under to over; any paint.
    pub fn randomized(rng: &mut impl Rng, view_yaw: f64) -> Self {
        let mut c = Self::random(rng);
        c.exposure = rng.random_range(0.45..1.8);
        c.tower_paint = TowerPaint::ALL[rng.random_range(0..TowerPaint::ALL.len())];
        match rng.random_range(0..5) {
            0 => {}
            1 => c.sun_elevation = rng.random_range(0.02..0.18),
            2 => {
                c.sun_azimuth = view_yaw + rng.random_range(-0.5..0.5);
                c.sun_elevation = rng.random_range(0.05..0.5);
                c.exposure = rng.random_range(0.9..1.8);
                if c.tower_paint == TowerPaint::Galvanised {
                    c.tower_paint = TowerPaint::Dark;
                }
            }
            3 => {
                c.cloud_cover = rng.random_range(0.85..1.0);
                c.sun_elevation = rng.random_range(0.1..0.6);
            }
            _ => c.visibility_m = rng.random_range(250.0..900.0),
        }
        c
    }

    /// No haze, noise, clouds or blur, no distractors: for checking geometry.
    pub fn plain() -> Self {
        Self {
            visibility_m: f64::INFINITY,
            cloud_cover: 0.0,
            noise_sigma: 0.0,
            shutter_s: 0.0,
            distractors: false,
            ..Self::default()
        }
    }

    /// Sun direction as a unit ENU vector.
    pub fn sun_in_world(&self) -> [f32; 3] {
        let (ce, se) = (self.sun_elevation.cos(), self.sun_elevation.sin());
        [
            (ce * self.sun_azimuth.cos()) as f32,
            (ce * self.sun_azimuth.sin()) as f32,
            se as f32,
        ]
    }

    /// Fraction of a surface's colour left after haze over `distance_m`.
    pub fn transmittance(&self, distance_m: f64) -> f32 {
        if self.visibility_m.is_finite() && self.visibility_m > 0.0 {
            (-distance_m / self.visibility_m).exp() as f32
        } else {
            1.0
        }
    }

    /// The haze's colour: the sky near the horizon, dimmer with a low sun.
    pub fn haze_colour(&self) -> [f32; 3] {
        let light = self.daylight();
        [0.78 * light, 0.82 * light, 0.88 * light]
    }

    /// Overall daylight level from the sun's height.
    pub fn daylight(&self) -> f32 {
        (0.55 + 0.45 * self.sun_elevation.sin().max(0.0)) as f32
    }
}
