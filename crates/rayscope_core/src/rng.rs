//! Deterministic random streams keyed by (seed, pixel, sample), so images do not depend on the
//! thread count or scheduling and any sample can be replayed.

use crate::simd::LANES;

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
    /// The stream for one sample of one pixel.
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

/// Sixteen [`Rng`] streams in structure-of-arrays form, stepped together, so a wave of paths
/// draws its lanes' numbers in one vectorised pass.
#[derive(Debug, Clone, Default)]
pub(crate) struct RngLanes {
    state: [u64; LANES],
    inc: [u64; LANES],
}

impl RngLanes {
    /// Puts stream `r` in lane `i`.
    #[inline]
    pub(crate) fn set(&mut self, i: usize, r: &Rng) {
        (self.state[i], self.inc[i]) = (r.state, r.inc);
    }

    /// Lane `i`'s stream, where it stands now.
    #[inline]
    pub(crate) fn get(&self, i: usize) -> Rng {
        Rng {
            state: self.state[i],
            inc: self.inc[i],
        }
    }

    /// [`Rng::next_f32`] in every lane of `on`; the other lanes' streams do not move (and
    /// get 0).
    /// [`Rng::for_sample`] of (`seed`, `pixel[i]`, `sample[i]`) in every lane, computed for all
    /// lanes at once.
    #[inline]
    pub(crate) fn for_samples(seed: u64, pixel: &[u64; LANES], sample: &[u64; LANES]) -> Self {
        let mut out = Self::default();
        for i in 0..LANES {
            let s = mix(seed ^ mix(pixel[i].wrapping_add(0x9e37_79b9_7f4a_7c15)));
            let inc = (mix(s ^ sample[i].wrapping_mul(0xd1b5_4a32_d192_ed03)) << 1) | 1;
            // Rng::for_sample's two steps: from state 0, then from its state plus `s`.
            let state = inc.wrapping_add(s);
            out.state[i] = state.wrapping_mul(PCG_MUL).wrapping_add(inc);
            out.inc[i] = inc;
        }
        out
    }

    #[inline]
    pub(crate) fn next_f32(&mut self, on: &[bool; LANES]) -> [f32; LANES] {
        let mut out = [0.0; LANES];
        for i in 0..LANES {
            let old = self.state[i];
            let next = old.wrapping_mul(PCG_MUL).wrapping_add(self.inc[i]);
            self.state[i] = if on[i] { next } else { old };
            let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
            let bits = xorshifted.rotate_right((old >> 59) as u32);
            out[i] = if on[i] {
                (bits >> 8) as f32 * (1.0 / 16_777_216.0)
            } else {
                0.0
            };
        }
        out
    }
}

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
    fn lanes_draw_what_each_stream_draws() {
        // A lane switched off keeps its place in its stream, as a path that draws nothing.
        let streams: Vec<Rng> = (0..LANES as u64).map(|i| Rng::for_sample(5, i, 3 * i)).collect();
        let mut lanes = RngLanes::default();
        for (i, r) in streams.iter().enumerate() {
            lanes.set(i, r);
        }
        let mut want = streams.clone();
        for round in 0..7 {
            let on: [bool; LANES] = std::array::from_fn(|i| (i + round) % 3 != 0);
            let got = lanes.next_f32(&on);
            for (i, stream) in want.iter_mut().enumerate() {
                let expect = if on[i] { stream.next_f32() } else { 0.0 };
                assert_eq!(got[i].to_bits(), expect.to_bits(), "round {round}, lane {i}");
            }
        }
        for (i, stream) in want.iter_mut().enumerate() {
            assert_eq!(lanes.get(i).next_u32(), stream.next_u32(), "lane {i} after the rounds");
        }
    }

    #[test]
    fn lanes_start_where_each_sample_starts() {
        for seed in [0, 7, u64::MAX] {
            let pixel: [u64; LANES] = std::array::from_fn(|i| (i as u64 * 7919) ^ (u64::MAX >> (i % 5)));
            let sample: [u64; LANES] = std::array::from_fn(|i| i as u64 * 31 + seed % 3);
            let lanes = RngLanes::for_samples(seed, &pixel, &sample);
            for i in 0..LANES {
                let (mut got, mut want) = (lanes.get(i), Rng::for_sample(seed, pixel[i], sample[i]));
                for _ in 0..3 {
                    assert_eq!(got.next_u32(), want.next_u32(), "seed {seed}, lane {i}");
                }
            }
        }
    }

    #[test]
    fn uniform_mean() {
        let mut r = Rng::for_sample(0, 0, 0);
        let n = 100_000;
        let mean: f64 = (0..n).map(|_| r.next_f32() as f64).sum::<f64>() / n as f64;
        assert!((mean - 0.5).abs() < 0.005);
    }
}
