//! The renderer's random numbers: a padded, Owen-scrambled Sobol (0,2)-sequence (Burley 2020,
//! "Practical Hash-based Owen Scrambling"), keyed by (seed, pixel, sample) and stateless, so
//! any sample can be computed alone and images do not depend on the thread count, the
//! scheduling or the engine.
//!
//! Every draw names its dimension ([`Draw`]): a 1-D draw at dimension `d` is the first Sobol
//! coordinate, a 2-D draw both first coordinates, of the pixel's sample index shuffled by a
//! nested uniform scramble keyed by (pixel, `d`), each coordinate then Owen-scrambled by a
//! hash keyed by (pixel, `d`, axis). A pixel's first 2^m samples are therefore a (0, m, 2)-net
//! in every 2-D draw (stratified at every power of two), and different dimensions are
//! independent of one another. Dimensions are fixed per decision and per path vertex, so a
//! draw one path takes and another does not shifts nothing else.
//!
//! The lens point is not a dimension of its own: it is Sobol coordinates 2 and 3 of the pixel
//! point's scrambled index ([`Sampler::lens_in_stratum`]), so that a pixel's pixel and lens
//! points together are a 4-D net (Sobol's first four coordinates, t = 2 at 16 and 64 points)
//! and out-of-focus edges, an integral over both, are stratified in both at once.

use crate::simd::LANES;

/// What a number is drawn for; with the path vertex it fixes the dimension ([`Draw::dim`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Draw {
    /// The sample's point in its pixel (or `-x` grid cell), 2-D, and with it the point on the
    /// lens ([`Sampler::lens_in_stratum`]).
    Pixel,
    /// Which emitter a vertex samples, 1-D.
    LightChoice,
    /// The point on that emitter, 2-D.
    LightPoint,
    /// Which BSDF lobe a vertex samples, 1-D.
    Lobe,
    /// The BSDF sample's direction, 2-D.
    BsdfDirection,
    /// Russian roulette at a vertex, 1-D.
    Roulette,
    /// Glass's reflected-or-refracted choice, 1-D.
    GlassChoice,
}

/// Dimensions the camera takes (pixel point and lens point, one 4-D draw) before the first
/// vertex's.
const CAMERA_DIMS: u32 = 4;
/// Dimensions each path vertex takes.
const VERTEX_DIMS: u32 = 8;

impl Draw {
    /// The dimension of this draw at path vertex `vertex` (0 at the camera ray's hit; the
    /// camera's draws ignore it).
    #[must_use]
    #[inline(always)]
    pub fn dim(self, vertex: u32) -> u32 {
        let base = CAMERA_DIMS + VERTEX_DIMS * vertex;
        match self {
            Draw::Pixel => 0,
            Draw::LightPoint => base,
            Draw::BsdfDirection => base + 2,
            Draw::LightChoice => base + 4,
            Draw::Lobe => base + 5,
            Draw::Roulette => base + 6,
            Draw::GlassChoice => base + 7,
        }
    }
}

/// SplitMix64's finaliser: turns structured keys into well-spread bits.
#[inline(always)]
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A random permutation of 32-bit numbers in which each output bit depends on the input bit
/// in the same place and the bits below it only (additions, multiplications by odd numbers,
/// and xors with multiples by even numbers carry upwards only): the building block of a
/// hash-based nested uniform scramble.
#[inline(always)]
fn upward_hash(mut x: u32, seed: u32) -> u32 {
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x3c6e_f372);
    x = x.wrapping_mul((seed >> 15) | 1);
    x ^= x.wrapping_mul(0xa54f_f53a);
    x = x.wrapping_add(seed.rotate_left(11));
    x ^= x.wrapping_mul(0x510e_527e);
    x
}

/// The second Sobol coordinate of point `i`, bit-reversed. Its generator matrix is Pascal's
/// triangle mod 2 (direction number `j` is `v[j] = v[j-1] ^ (v[j-1] >> 1)` from `1 << 31`), so
/// bit `k` of the reversed coordinate is the xor of the bits `j` of `i` whose position has every
/// set bit of `k`'s (Lucas's theorem: C(j, k) is odd exactly then). That sum over supersets
/// takes one shift, mask and xor per bit of a position, five in all, with no table, so a loop
/// over lanes vectorises. Every value is the direction numbers' (the map is linear, and
/// `sobol1_matches_its_direction_numbers` checks every basis vector).
#[inline(always)]
fn sobol1_reversed(i: u32) -> u32 {
    let mut x = i;
    x ^= (x >> 1) & 0x5555_5555;
    x ^= (x >> 2) & 0x3333_3333;
    x ^= (x >> 4) & 0x0f0f_0f0f;
    x ^= (x >> 8) & 0x00ff_00ff;
    x ^= (x >> 16) & 0x0000_ffff;
    x
}

/// Two 32-bit values bit-reversed with one 64-bit reversal: `(a.reverse_bits(),
/// b.reverse_bits())`.
#[inline(always)]
fn reverse_pair(a: u32, b: u32) -> (u32, u32) {
    let r = ((u64::from(b) << 32) | u64::from(a)).reverse_bits();
    ((r >> 32) as u32, r as u32)
}

/// Direction numbers (32-bit fractions) of a Sobol coordinate from its primitive polynomial of
/// degree `s` with inner coefficients `a` (bit `s - 1 - k` is the coefficient of x^(s-k)) and
/// its first `s` odd integers `m` (Joe and Kuo's table).
const fn directions(s: usize, a: u32, m: [u32; 3]) -> [u32; 32] {
    let mut mm = [0u32; 33];
    let mut k = 1;
    while k <= 32 {
        if k <= s {
            mm[k] = m[k - 1];
        } else {
            let mut v = mm[k - s] ^ (mm[k - s] << s);
            let mut j = 1;
            while j < s {
                if (a >> (s - 1 - j)) & 1 == 1 {
                    v ^= mm[k - j] << j;
                }
                j += 1;
            }
            mm[k] = v;
        }
        k += 1;
    }
    let mut out = [0u32; 32];
    let mut k = 1;
    while k <= 32 {
        out[k - 1] = mm[k] << (32 - k);
        k += 1;
    }
    out
}

/// The third Sobol coordinate's direction numbers (x^2 + x + 1; m = 1, 3).
const SOBOL2: [u32; 32] = directions(2, 1, [1, 3, 0]);
/// The fourth Sobol coordinate's direction numbers (x^3 + x + 1; m = 1, 3, 1).
const SOBOL3: [u32; 32] = directions(3, 1, [1, 3, 1]);

/// Coordinate `dirs` (a 32-bit fraction) of the Sobol point whose index is the low 16 bits of
/// `i`. A shuffled index's higher bits are the same for a pixel's first 2^16 samples (bit `b`
/// of the shuffle depends on the index's bits `b` and above): leaving them out is a digital
/// shift of every point, which the coordinate's own scramble randomises anyway. Each later
/// block of 2^16 samples covers the same strata again.
#[inline(always)]
fn sobol_low(i: u32, dirs: &[u32; 32]) -> u32 {
    let mut x = 0;
    for (b, v) in dirs.iter().enumerate().take(16) {
        x ^= v & 0u32.wrapping_sub((i >> b) & 1);
    }
    x
}

/// Sobol coordinates 2 and 3 of the shuffled index `i` ([`sobol_low`]), each Owen-scrambled:
/// the first by `seed`, the second by a hash of it.
#[inline(always)]
fn lens_bits(i: u32, seed: u32) -> (u32, u32) {
    let other = (seed ^ 0x68e3_1da4).wrapping_mul(0x2c1b_3c6d) ^ (seed >> 15);
    reverse_pair(
        upward_hash(sobol_low(i, &SOBOL2).reverse_bits(), seed),
        upward_hash(sobol_low(i, &SOBOL3).reverse_bits(), other),
    )
}

/// A 32-bit fraction as a float in [0, 1).
#[inline(always)]
fn unit(bits: u32) -> f32 {
    (bits >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// The random numbers of one sample of one pixel: stateless, any draw computed on its own.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Sampler {
    /// Hash of the seed and the pixel.
    key: u64,
    /// The sample's index in its pixel.
    index: u32,
}

impl Sampler {
    /// The numbers of sample `sample` of pixel `pixel` in the render with seed `seed`.
    #[must_use]
    #[inline]
    pub fn new(seed: u64, pixel: u64, sample: u32) -> Self {
        Sampler {
            key: mix(seed ^ mix(pixel.wrapping_add(0x9e37_79b9_7f4a_7c15))),
            index: sample,
        }
    }

    /// The numbers of sample `sample` of the same pixel in the same render: what
    /// [`Self::new`] returns for it, without hashing the pixel again.
    #[must_use]
    #[inline]
    pub fn with_sample(&self, sample: u32) -> Self {
        Sampler {
            key: self.key,
            index: sample,
        }
    }

    /// Dimension `dim`'s scramble seeds: the index shuffle's and the first coordinate's.
    #[inline(always)]
    fn seeds(&self, dim: u32) -> u64 {
        mix(self.seed_key(dim))
    }

    /// What [`Self::seeds`] mixes: the key moved by the dimension.
    #[inline(always)]
    fn seed_key(&self, dim: u32) -> u64 {
        self.key ^ u64::from(dim + 1).wrapping_mul(0xd1b5_4a32_d192_ed03)
    }

    /// The number at dimension `dim`, uniform in [0, 1).
    #[must_use]
    #[inline]
    pub fn get1d(&self, dim: u32) -> f32 {
        self.point_1d(self.seeds(dim))
    }

    /// [`Self::get1d`] with the dimension's seeds `h` ([`Self::seeds`]).
    #[inline(always)]
    fn point_1d(&self, h: u64) -> f32 {
        // The index's Owen scramble i = rev(U(rev(index))), then the first coordinate rev(i)
        // scrambled: rev(U(rev(rev(i)))) = rev(U(i)), U being `upward_hash`.
        let i = upward_hash(self.index.reverse_bits(), h as u32).reverse_bits();
        unit(upward_hash(i, (h >> 32) as u32).reverse_bits())
    }

    /// The pair at dimensions `dim` and `dim + 1`, uniform in [0, 1)².
    #[must_use]
    #[inline]
    pub fn get2d(&self, dim: u32) -> [f32; 2] {
        self.point_2d(self.index, dim, 0)
    }

    /// The point in stratum `stratum` (of any number of strata) at dimensions `dim` and
    /// `dim + 1`, for the sample that is the `index`-th in its stratum: each stratum's samples
    /// have their own scrambled sequence, so the first 2^m of every stratum are a (0, m, 2)-net.
    #[must_use]
    #[inline]
    pub fn get2d_in_stratum(&self, dim: u32, stratum: u32, index: u32) -> [f32; 2] {
        self.point_2d(index, dim, u64::from(stratum) << 32)
    }

    /// The lens point of the `index`-th sample of stratum `stratum`: Sobol coordinates 2 and 3
    /// of the same scrambled index as that sample's pixel point ([`Self::get2d_in_stratum`] at
    /// `dim`), so that the pixel and lens points of a stratum's samples are one 4-D net.
    #[must_use]
    #[inline]
    pub fn lens_in_stratum(&self, dim: u32, stratum: u32, index: u32) -> [f32; 2] {
        let (i, _, g) = self.shuffled(index, dim, u64::from(stratum) << 32);
        let (x, y) = lens_bits(i, (g >> 32) as u32);
        [unit(x), unit(y)]
    }

    /// Point `index`'s shuffled index at dimension `dim` with the key moved by `salt`, and the
    /// two seeds it and its coordinates' scrambles take (the first draws the shuffle's and the
    /// first coordinate's, the second the other coordinates').
    #[inline(always)]
    fn shuffled(&self, index: u32, dim: u32, salt: u64) -> (u32, u64, u64) {
        let h = mix(self.seed_key(dim) ^ salt);
        // The index's Owen scramble i = rev(U(rev(index))), U being `upward_hash`.
        (upward_hash(index.reverse_bits(), h as u32).reverse_bits(), h, mix(h))
    }

    /// Point `index` of the 2-D sequence at dimension `dim`, scrambled by the key moved by
    /// `salt`.
    #[inline(always)]
    fn point_2d(&self, index: u32, dim: u32, salt: u64) -> [f32; 2] {
        // Each coordinate c of the shuffled index i is scrambled as rev(U(rev(c))): for the
        // first, c = rev(i), so rev(c) = i; for the second, rev(c) is `sobol1_reversed(i)`. The
        // two final reversals share one 64-bit reversal.
        let (i, h, g) = self.shuffled(index, dim, salt);
        let (x, y) = reverse_pair(
            upward_hash(i, (h >> 32) as u32),
            upward_hash(sobol1_reversed(i), g as u32),
        );
        [unit(x), unit(y)]
    }
}

/// [`mix`] of every lane's `z`. Where every lane holds the same value (a wave's lanes, or a
/// camera batch, drawing one pixel's samples at one dimension) it is mixed once: the 64-bit
/// multiplications of a mix cost several vector instructions a lane where the CPU has no 64-bit
/// vector multiply (AVX2).
#[inline(always)]
fn mixed_lanes(z: &[u64; LANES]) -> [u64; LANES] {
    if z.iter().fold(true, |same, &v| same & (v == z[0])) {
        [mix(z[0]); LANES]
    } else {
        z.map(mix)
    }
}

/// Sixteen lanes' [`Sampler`]s, drawn lane by lane where a mask is on (0 elsewhere).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct SamplerLanes(pub(crate) [Sampler; LANES]);

impl SamplerLanes {
    /// [`Sampler::get1d`] at dimension `dim[i]` in every lane `i` of `on`: every lane drawn in
    /// a loop without branches, which the compiler vectorises, and the lanes not on set to 0.
    #[inline]
    pub(crate) fn get1d(&self, on: &[bool; LANES], dim: &[u32; LANES]) -> [f32; LANES] {
        // `point_1d` from arrays: the indices gathered and the seeds split first, so that the
        // loop vectorises (read from the samplers inside it, they keep it lane by lane).
        let index: [u32; LANES] = std::array::from_fn(|i| self.0[i].index);
        let h = mixed_lanes(&std::array::from_fn(|i| self.0[i].seed_key(dim[i])));
        let (lo, hi): ([u32; LANES], [u32; LANES]) = (
            std::array::from_fn(|i| h[i] as u32),
            std::array::from_fn(|i| (h[i] >> 32) as u32),
        );
        let mut out = [0.0; LANES];
        for k in 0..LANES {
            let i = upward_hash(index[k].reverse_bits(), lo[k]).reverse_bits();
            let u = unit(upward_hash(i, hi[k]).reverse_bits());
            out[k] = if on[k] { u } else { 0.0 };
        }
        out
    }

    /// [`Sampler::get2d`] at dimension `dim[i]` in every lane `i` of `on`, by axis.
    #[inline]
    pub(crate) fn get2d(&self, on: &[bool; LANES], dim: &[u32; LANES]) -> [[f32; LANES]; 2] {
        let index = std::array::from_fn(|i| self.0[i].index);
        let mut out = self.points_2d(&index, dim, &[0; LANES]);
        for i in 0..LANES {
            for axis in &mut out {
                axis[i] = if on[i] { axis[i] } else { 0.0 };
            }
        }
        out
    }

    /// [`Sampler::get2d_in_stratum`] at dimension `dim` and [`Sampler::lens_in_stratum`] of the
    /// same samples, in every lane, by axis: the pixel points, then the lens points.
    #[inline]
    pub(crate) fn camera_points(
        &self,
        dim: u32,
        stratum: &[u32; LANES],
        index: &[u32; LANES],
    ) -> [[[f32; LANES]; 2]; 2] {
        // `points_2d`'s arithmetic again, the lens coordinates of the same shuffled index in
        // the same loop: the shuffle shared through a function of its own and the coordinates
        // in loops of their own took 2 % more instructions on a lens render (callgrind).
        let keys = std::array::from_fn(|k| self.0[k].seed_key(dim) ^ (u64::from(stratum[k]) << 32));
        let h = mixed_lanes(&keys);
        let g = mixed_lanes(&h);
        let mut out = [[[0.0; LANES]; 2]; 2];
        for k in 0..LANES {
            let i = upward_hash(index[k].reverse_bits(), h[k] as u32).reverse_bits();
            out[0][0][k] = unit(upward_hash(i, (h[k] >> 32) as u32).reverse_bits());
            out[0][1][k] = unit(upward_hash(sobol1_reversed(i), g[k] as u32).reverse_bits());
            let (x, y) = lens_bits(i, (g[k] >> 32) as u32);
            (out[1][0][k], out[1][1][k]) = (unit(x), unit(y));
        }
        out
    }

    /// [`Sampler::point_2d`] in every lane, by axis: the same integer arithmetic in loops over
    /// the lanes without branches, which the compiler vectorises (the bit reversals become
    /// byte shuffles).
    #[inline(always)]
    fn points_2d(&self, index: &[u32; LANES], dim: &[u32; LANES], salt: &[u64; LANES]) -> [[f32; LANES]; 2] {
        let keys = std::array::from_fn(|k| self.0[k].seed_key(dim[k]) ^ salt[k]);
        let h = mixed_lanes(&keys);
        let g = mixed_lanes(&h);
        let (mut i, mut hx, mut gy) = ([0u32; LANES], [0u32; LANES], [0u32; LANES]);
        for k in 0..LANES {
            i[k] = upward_hash(index[k].reverse_bits(), h[k] as u32).reverse_bits();
            (hx[k], gy[k]) = ((h[k] >> 32) as u32, g[k] as u32);
        }
        let mut out = [[0.0; LANES]; 2];
        for k in 0..LANES {
            out[0][k] = unit(upward_hash(i[k], hx[k]).reverse_bits());
            out[1][k] = unit(upward_hash(sobol1_reversed(i[k]), gy[k]).reverse_bits());
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Nested uniform (Owen) scramble of `v` read as a binary fraction (bit 31 first): each bit
    /// is flipped or not by a function of `seed` and the bits before it.
    fn owen_scramble(v: u32, seed: u32) -> u32 {
        upward_hash(v.reverse_bits(), seed).reverse_bits()
    }

    /// The first Sobol coordinate of point `i` (a 32-bit fraction): the van der Corput sequence.
    fn sobol0(i: u32) -> u32 {
        i.reverse_bits()
    }

    /// The second Sobol coordinate of point `i` (a 32-bit fraction), from its direction numbers
    /// one bit at a time.
    fn sobol1(i: u32) -> u32 {
        let (mut v, mut x) = (1u32 << 31, 0);
        for bit in 0..32 {
            if i & (1 << bit) != 0 {
                x ^= v;
            }
            v ^= v >> 1;
        }
        x
    }

    #[test]
    fn another_sample_of_the_pixel_is_that_samples_sampler() {
        let s = Sampler::new(7, 1234, 5);
        for k in [0, 1, 6, 63, 1 << 20] {
            assert_eq!(s.with_sample(k), Sampler::new(7, 1234, k));
        }
    }

    #[test]
    fn sobol1_matches_its_direction_numbers() {
        // Both sides are linear over GF(2), so agreeing on every basis vector is agreeing on all.
        for bit in 0..32 {
            let i = 1u32 << bit;
            assert_eq!(sobol1_reversed(i), sobol1(i).reverse_bits(), "bit {bit}");
        }
        let mut z = 0x0123_4567u32;
        for _ in 0..10_000 {
            z = z.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
            assert_eq!(sobol1_reversed(z), sobol1(z).reverse_bits());
        }
    }

    /// [`Sampler::point_2d`] as the module documentation defines it: the index Owen-scrambled,
    /// its two Sobol coordinates each Owen-scrambled.
    fn point_2d_by_definition(s: &Sampler, index: u32, dim: u32, salt: u64) -> [f32; 2] {
        let h = mix(s.key ^ salt ^ u64::from(dim + 1).wrapping_mul(0xd1b5_4a32_d192_ed03));
        let g = mix(h);
        let i = owen_scramble(index, h as u32);
        [
            unit(owen_scramble(sobol0(i), (h >> 32) as u32)),
            unit(owen_scramble(sobol1(i), g as u32)),
        ]
    }

    #[test]
    fn draws_are_the_scrambled_sobol_points_of_the_definition() {
        let mut z = 0x1234_5678_9abc_def0u64;
        for n in 0..200_000u32 {
            z = mix(z.wrapping_add(0x9e37_79b9_7f4a_7c15));
            let s = Sampler::new(z, z >> 17, (z >> 40) as u32);
            // Small indices (the common case) and arbitrary ones.
            let index = if n % 2 == 0 { n % 4096 } else { (z >> 7) as u32 };
            let (dim, stratum) = ((z % 101) as u32, (z >> 50) as u32);
            let salt = u64::from(stratum) << 32;
            assert_eq!(
                s.point_2d(index, dim, salt),
                point_2d_by_definition(&s, index, dim, salt)
            );
            let h = s.seeds(dim);
            let one = unit(owen_scramble(
                sobol0(owen_scramble(s.index, h as u32)),
                (h >> 32) as u32,
            ));
            assert_eq!(s.get1d(dim), one);
        }
    }

    /// True when `pts` (2^m of them) put one point in every elementary interval of area 2^-m.
    /// True when the 2^m points `pts` are a (t, m, s)-net in base 2: every box of sides 2^-d_k
    /// with Σ d_k = m − t holds exactly 2^t of them.
    fn is_tms_net<const S: usize>(pts: &[[f32; S]], m: u32, t: u32) -> bool {
        fn boxes<const S: usize>(pts: &[[f32; S]], d: &mut [u32; S], k: usize, left: u32, t: u32) -> bool {
            if k == S - 1 {
                d[k] = left;
                let mut count = std::collections::HashMap::new();
                for p in pts {
                    let key: [u32; S] = std::array::from_fn(|j| (p[j] * (1u64 << d[j]) as f32) as u32);
                    *count.entry(key).or_insert(0u32) += 1;
                }
                return count.values().all(|&c| c == 1 << t);
            }
            (0..=left).all(|a| {
                d[k] = a;
                boxes(pts, d, k + 1, left - a, t)
            })
        }
        boxes(pts, &mut [0; S], 0, m - t, t)
    }

    #[test]
    fn pixel_and_lens_points_are_one_4d_net() {
        // The t of Sobol's first four coordinates at 2^m points, and of the lens's two alone.
        // Scrambling keeps every t.
        for pixel in 0..12 {
            for stratum in [0, 3] {
                let s = Sampler::new(4, pixel, 0);
                for (m, t, lens_t) in [(2, 1, 1), (4, 2, 0), (6, 2, 1), (8, 3, 1)] {
                    let pts: Vec<[f32; 4]> = (0..1u32 << m)
                        .map(|j| {
                            let [a, b] = s.get2d_in_stratum(0, stratum, j);
                            let [c, d] = s.lens_in_stratum(0, stratum, j);
                            [a, b, c, d]
                        })
                        .collect();
                    assert!(is_tms_net(&pts, m, t), "pixel {pixel}, stratum {stratum}, 2^{m}");
                    let lens: Vec<[f32; 2]> = pts.iter().map(|p| [p[2], p[3]]).collect();
                    assert!(is_tms_net(&lens, m, lens_t), "lens, pixel {pixel}, 2^{m}");
                }
            }
        }
    }

    fn is_net(pts: &[[f32; 2]], m: u32) -> bool {
        (0..=m).all(|a| {
            let (nx, ny) = (1u32 << a, 1u32 << (m - a));
            let mut seen = vec![false; 1 << m];
            pts.iter().all(|p| {
                let (cx, cy) = ((p[0] * nx as f32) as u32, (p[1] * ny as f32) as u32);
                !std::mem::replace(&mut seen[(cy * nx + cx) as usize], true)
            })
        })
    }

    #[test]
    fn unscrambled_sobol_is_a_0_2_sequence() {
        // Every aligned block of 2^m points is a (0, m, 2)-net.
        for m in 0..=8 {
            for block in [0u32, 1, 5, 1000] {
                let pts: Vec<[f32; 2]> = (0..1u32 << m)
                    .map(|k| {
                        let i = (block << m) + k;
                        [unit(sobol0(i)), unit(sobol1(i))]
                    })
                    .collect();
                assert!(is_net(&pts, m), "m = {m}, block {block}");
            }
        }
        // Its known first points.
        let first: Vec<[f32; 2]> = (0..4).map(|i| [unit(sobol0(i)), unit(sobol1(i))]).collect();
        assert_eq!(first, [[0.0, 0.0], [0.5, 0.5], [0.25, 0.75], [0.75, 0.25]]);
    }

    #[test]
    fn every_pixels_first_samples_are_nets_in_every_draw() {
        for pixel in 0..20 {
            for dim in [Draw::Pixel.dim(0), 2, Draw::BsdfDirection.dim(3), 1001] {
                for m in 0..=7 {
                    let pts: Vec<[f32; 2]> = (0..1u32 << m).map(|s| Sampler::new(9, pixel, s).get2d(dim)).collect();
                    assert!(is_net(&pts, m), "pixel {pixel}, dimension {dim}, 2^{m} samples");
                    let cell: Vec<[f32; 2]> = (0..1u32 << m)
                        .map(|j| Sampler::new(9, pixel, 0).get2d_in_stratum(dim, 3, j))
                        .collect();
                    assert!(is_net(&cell, m), "pixel {pixel}, a stratum, 2^{m} samples");
                }
                let mut bins: Vec<u32> = (0..64)
                    .map(|s| (Sampler::new(9, pixel, s).get1d(dim) * 64.0) as u32)
                    .collect();
                bins.sort_unstable();
                assert_eq!(bins, (0..64).collect::<Vec<u32>>(), "1-D draws, pixel {pixel}");
            }
        }
    }

    #[test]
    fn scrambled_draws_are_uniform_and_independent_across_dimensions_and_pixels() {
        // Sample 0 of many pixels: each draw is uniform, and two dimensions, and the two
        // coordinates of a 2-D draw, are uncorrelated.
        let n = 200_000u64;
        let (mut mean, mut sq, mut cross, mut cross2, mut low) = (0.0, 0.0, 0.0, 0.0, 0u32);
        for p in 0..n {
            let s = Sampler::new(4, p, 0);
            let (a, b) = (f64::from(s.get1d(9)), f64::from(s.get1d(10)));
            let [x, y] = s.get2d(12);
            mean += a;
            sq += a * a;
            cross += (a - 0.5) * (b - 0.5);
            cross2 += (f64::from(x) - 0.5) * (f64::from(y) - 0.5);
            low += u32::from(a < 0.01);
        }
        let n = n as f64;
        // Standard errors: mean 0.00065, second moment 0.00067, covariances 0.00019.
        assert!((mean / n - 0.5).abs() < 0.003, "mean {}", mean / n);
        assert!((sq / n - 1.0 / 3.0).abs() < 0.003, "second moment {}", sq / n);
        assert!((cross / n).abs() < 0.001, "covariance of two dimensions {}", cross / n);
        assert!((cross2 / n).abs() < 0.001, "covariance of a pair {}", cross2 / n);
        assert!((f64::from(low) / n - 0.01).abs() < 0.001, "share under 0.01");
    }

    #[test]
    fn samples_are_keyed_by_seed_pixel_and_index() {
        let d = Draw::LightPoint.dim(2);
        let a = Sampler::new(1, 2, 3).get2d(d);
        assert_eq!(a, Sampler::new(1, 2, 3).get2d(d));
        assert_ne!(a, Sampler::new(0, 2, 3).get2d(d));
        assert_ne!(a, Sampler::new(1, 1, 3).get2d(d));
        assert_ne!(a, Sampler::new(1, 2, 4).get2d(d));
        assert_ne!(a, Sampler::new(1, 2, 3).get2d(d + 8));
    }

    #[test]
    fn dimensions_are_distinct_per_decision_and_vertex() {
        let all = [
            Draw::LightPoint,
            Draw::BsdfDirection,
            Draw::LightChoice,
            Draw::Lobe,
            Draw::Roulette,
            Draw::GlassChoice,
        ];
        let mut used = vec![0, 1, 2, 3];
        for v in 0..10 {
            for d in all {
                let dim = d.dim(v);
                let width = if matches!(d, Draw::LightPoint | Draw::BsdfDirection) {
                    2
                } else {
                    1
                };
                for k in dim..dim + width {
                    assert!(!used.contains(&k), "{d:?} at vertex {v} reuses dimension {k}");
                    used.push(k);
                }
            }
        }
    }

    #[test]
    fn lanes_draw_what_each_sampler_draws() {
        let lanes = SamplerLanes(std::array::from_fn(|i| Sampler::new(5, i as u64 * 7, i as u32)));
        let on: [bool; LANES] = std::array::from_fn(|i| i % 3 != 0);
        let dim: [u32; LANES] = std::array::from_fn(|i| 4 + i as u32);
        let (one, two) = (lanes.get1d(&on, &dim), lanes.get2d(&on, &dim));
        for i in 0..LANES {
            let s = &lanes.0[i];
            let (w1, w2) = if on[i] {
                (s.get1d(dim[i]), s.get2d(dim[i]))
            } else {
                (0.0, [0.0; 2])
            };
            assert_eq!(one[i], w1, "lane {i}");
            assert_eq!([two[0][i], two[1][i]], w2, "lane {i}");
        }
        // Every lane at one dimension, and in strata; indices with bits in every byte.
        let lanes = SamplerLanes(std::array::from_fn(|i| {
            Sampler::new(3, i as u64, (i as u32).wrapping_mul(0x9e37_79b9))
        }));
        let stratum: [u32; LANES] = std::array::from_fn(|i| i as u32 % 4);
        let index: [u32; LANES] = std::array::from_fn(|i| (i as u32).wrapping_mul(0x0101_0107));
        let [at, lens] = lanes.camera_points(6, &stratum, &index);
        for i in 0..LANES {
            let s = &lanes.0[i];
            assert_eq!(
                [at[0][i], at[1][i]],
                s.get2d_in_stratum(6, stratum[i], index[i]),
                "lane {i}"
            );
            assert_eq!(
                [lens[0][i], lens[1][i]],
                s.lens_in_stratum(6, stratum[i], index[i]),
                "lane {i}"
            );
        }
    }
}
