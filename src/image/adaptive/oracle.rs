//! Where an adaptive run's samples come from: an oracle of the image function (a scene, a
//! closure, either with seeded Gaussian noise), and the hash that seeds the noise.

/// A scene as seen by the refiner: the values of every channel at a point of the image
/// (pixel units).
pub trait ImageOracle: Sync {
    /// Number of channels.
    fn channels(&self) -> usize;
    /// The values at `(x, y)` into `out` (`channels()` entries).
    fn sample(&self, x: f64, y: f64, out: &mut [f64]);
}

/// A built-in scene on a plane (RGB, noise-free).
pub struct SceneOracle<'a> {
    /// The scene.
    pub scene: &'a crate::image::scene::Scene,
    /// The image plane.
    pub plane: crate::image::ImagePlane,
}

impl ImageOracle for SceneOracle<'_> {
    fn channels(&self) -> usize {
        3
    }
    fn sample(&self, x: f64, y: f64, out: &mut [f64]) {
        out.copy_from_slice(&self.scene.radiance_on(self.plane, x, y));
    }
}

/// Any `Fn(x, y) -> f64` is a one-channel oracle.
impl<F: Fn(f64, f64) -> f64 + Sync> ImageOracle for F {
    fn channels(&self) -> usize {
        1
    }
    fn sample(&self, x: f64, y: f64, out: &mut [f64]) {
        out[0] = self(x, y);
    }
}

/// 64-bit mix (SplitMix64's finaliser).
pub(crate) fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A standard normal deviate that is a function of `seed`, the position's bits and the index
/// `k` (Box–Muller on two uniforms from a 64-bit mix): the same position always gets the same
/// deviate, whatever the order or the process that asks.
pub fn position_normal(seed: u64, x: f64, y: f64, k: usize) -> f64 {
    let h = mix64(seed ^ mix64(x.to_bits() ^ mix64(y.to_bits() ^ mix64(k as u64 + 1))));
    let (a, b) = (mix64(h), mix64(h ^ 0x9E37_79B9_7F4A_7C15));
    // 53-bit uniforms, u1 in (0, 1], u2 in [0, 1)
    let u1 = ((a >> 11) + 1) as f64 / (1u64 << 53) as f64;
    let u2 = (b >> 11) as f64 / (1u64 << 53) as f64;
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// An oracle with Gaussian noise, a renderer's Monte Carlo estimate in miniature:
/// `f(x, y) + sigma n_c(x, y)` per channel `c`, `n_c` standard normal deviates seeded by the
/// seed and the position ([`position_normal`]), so the in-process loop and a renderer driving
/// the file protocol see the same values, and runs are deterministic.
pub struct NoisyOracle<'a> {
    /// The noise-free oracle.
    pub inner: &'a dyn ImageOracle,
    /// Standard deviation `sigma` of the noise.
    pub sigma: f64,
    /// Seed of the noise.
    pub seed: u64,
}

impl ImageOracle for NoisyOracle<'_> {
    fn channels(&self) -> usize {
        self.inner.channels()
    }
    fn sample(&self, x: f64, y: f64, out: &mut [f64]) {
        self.inner.sample(x, y, out);
        if self.sigma > 0.0 {
            for (c, v) in out.iter_mut().enumerate() {
                *v += self.sigma * position_normal(self.seed, x, y, c);
            }
        }
    }
}
