//! A plain deterministic random generator keyed by three numbers, for tests, benchmarks and
//! tools that need a reproducible random source. The renderer's own numbers come from
//! [`crate::sobol::Sampler`].

/// A PCG32 generator (O'Neill 2014): small state, good statistics, cheap to seed per sample.
#[derive(Debug, Clone)]
pub struct Rng {
    state: u64,
    inc: u64,
}

fn mix(mut z: u64) -> u64 {
    // SplitMix64 finaliser: turns structured keys into well-spread seeds.
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

impl Rng {
    /// The stream keyed by (`seed`, `pixel`, `sample`).
    #[must_use]
    pub fn for_sample(seed: u64, pixel: u64, sample: u64) -> Self {
        let s = mix(seed ^ mix(pixel.wrapping_add(0x9e37_79b9_7f4a_7c15)));
        let inc = (mix(s ^ sample.wrapping_mul(0xd1b5_4a32_d192_ed03)) << 1) | 1;
        let mut r = Rng { state: 0, inc };
        r.next_u32();
        r.state = r.state.wrapping_add(s);
        r.next_u32();
        r
    }

    /// The next 32 random bits.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(PCG_MUL).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// A uniform float in [0, 1).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }
}

/// The PCG32 multiplier.
const PCG_MUL: u64 = 6_364_136_223_846_793_005;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let a: Vec<u32> = (0..4)
            .map({
                let mut r = Rng::for_sample(1, 2, 3);
                move |_| r.next_u32()
            })
            .collect();
        let b: Vec<u32> = (0..4)
            .map({
                let mut r = Rng::for_sample(1, 2, 3);
                move |_| r.next_u32()
            })
            .collect();
        let c: Vec<u32> = (0..4)
            .map({
                let mut r = Rng::for_sample(1, 2, 4);
                move |_| r.next_u32()
            })
            .collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn uniform_mean() {
        let mut r = Rng::for_sample(0, 0, 0);
        let n = 100_000;
        let mean: f64 = (0..n).map(|_| r.next_f32() as f64).sum::<f64>() / n as f64;
        assert!((mean - 0.5).abs() < 0.005);
    }
}
