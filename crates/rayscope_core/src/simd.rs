//! The SIMD vocabulary every lane kernel shares: the lane count, lane masks, lane access, the
//! number type that lets a rule be written once for one lane or four (`Lanes`), the run-time
//! choice of instruction set and the cache prefetch hint.
//!
//! The kernels are plain loops over `[f32; LANES]` arrays that the compiler vectorises. A module
//! with a kernel defines its entry point with `dispatched!`, which also compiles the kernel with
//! AVX-512 and with AVX2 enabled and runs the best build the CPU has. FMA is not enabled and Rust
//! never fuses a multiply and an add on its own, so every build computes identical results (the
//! tests in `simd/kernel_builds.rs` compare them). This file is the one place the core's product
//! code writes `unsafe`: a function compiled for an instruction set may only be called on a CPU
//! that has it, which the macro checks immediately before each call (the check is a cached load),
//! and the prefetch intrinsic is `unsafe` to call as well. On an AVX-512 CPU the AVX-512 builds
//! render course scene 2 1.35× and the bunny scene 1.42× as fast as the baseline builds
//! (`rayscope bench render -f SCENE -x 4 --stage 2`); the prefetch makes scattered rays in a
//! 1 M-triangle tree 25 % faster (`rayscope bench rays --rays-file FILE`).
#![allow(unsafe_code)]

#[cfg(test)]
mod kernel_builds;

/// Rays in a packet.
pub const LANES: usize = 16;

/// Per-lane flags.
pub type Mask = [bool; LANES];

/// Lane `i` of a vector stored per axis.
#[inline(always)]
pub(crate) fn lane(v: &[[f32; LANES]; 3], i: usize) -> glam::Vec3A {
    glam::Vec3A::new(v[0][i], v[1][i], v[2][i])
}

/// Stores `v` as lane `i` of the per-axis vector `dst`.
#[inline(always)]
pub(crate) fn put(dst: &mut [[f32; LANES]; 3], i: usize, v: [f32; 3]) {
    for (ax, x) in v.into_iter().enumerate() {
        dst[ax][i] = x;
    }
}

/// `a` when `c`, else `b`.
#[inline(always)]
pub(crate) fn sel(c: bool, a: f32, b: f32) -> f32 {
    if c {
        a
    } else {
        b
    }
}

/// glam's `max` of one lane (`maxps`: the second operand when either is NaN).
#[inline(always)]
pub(crate) fn maxps(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// glam's `max_element` of one lane's (x, y, z), in glam's order.
#[inline(always)]
pub(crate) fn max_element(c: [f32; 3]) -> f32 {
    maxps(maxps(c[0], c[2]), maxps(c[1], c[2]))
}

/// A number the ray–primitive tests compute with: one `f32`, or four in a `Vec4` (one ray
/// against four primitives). Both carry out each operation with the same rounding, so a test
/// written once over `Lanes` gives every lane the bits the one-value form gives.
pub(crate) trait Lanes:
    Copy
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
    + std::ops::Neg<Output = Self>
{
    /// Per-lane flags.
    type Mask: Copy + std::ops::BitAnd<Output = Self::Mask> + std::ops::BitOr<Output = Self::Mask>;
    /// `x` in every lane.
    fn splat(x: f32) -> Self;
    /// The magnitude of `self` with the sign of `sign`.
    fn copysign(self, sign: Self) -> Self;
    /// Absolute value.
    fn abs(self) -> Self;
    /// Square root.
    fn sqrt(self) -> Self;
    /// `self < o`.
    fn cmplt(self, o: Self) -> Self::Mask;
    /// `self <= o`.
    fn cmple(self, o: Self) -> Self::Mask;
    /// `self > o`.
    fn cmpgt(self, o: Self) -> Self::Mask;
    /// `self >= o`.
    fn cmpge(self, o: Self) -> Self::Mask;
    /// `self != o`.
    fn cmpne(self, o: Self) -> Self::Mask;
    /// `a` where `m`, else `b`.
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
    /// `minps`: `self` when `self < o`, else `o` (so `o` when either is NaN).
    fn minps(self, o: Self) -> Self;
    /// `maxps`: `self` when `self > o`, else `o` (so `o` when either is NaN).
    fn maxps(self, o: Self) -> Self;
}

impl Lanes for f32 {
    type Mask = bool;
    #[inline(always)]
    fn splat(x: f32) -> Self {
        x
    }
    #[inline(always)]
    fn copysign(self, sign: Self) -> Self {
        f32::copysign(self, sign)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32::abs(self)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn cmplt(self, o: Self) -> bool {
        self < o
    }
    #[inline(always)]
    fn cmple(self, o: Self) -> bool {
        self <= o
    }
    #[inline(always)]
    fn cmpgt(self, o: Self) -> bool {
        self > o
    }
    #[inline(always)]
    fn cmpge(self, o: Self) -> bool {
        self >= o
    }
    #[inline(always)]
    fn cmpne(self, o: Self) -> bool {
        self != o
    }
    #[inline(always)]
    fn select(m: bool, a: Self, b: Self) -> Self {
        sel(m, a, b)
    }
    #[inline(always)]
    fn minps(self, o: Self) -> Self {
        sel(self < o, self, o)
    }
    #[inline(always)]
    fn maxps(self, o: Self) -> Self {
        maxps(self, o)
    }
}

impl Lanes for glam::Vec4 {
    type Mask = glam::BVec4A;
    #[inline(always)]
    fn splat(x: f32) -> Self {
        glam::Vec4::splat(x)
    }
    #[inline(always)]
    fn copysign(self, sign: Self) -> Self {
        glam::Vec4::copysign(self, sign)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        glam::Vec4::abs(self)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        glam::Vec4::from_array(self.to_array().map(f32::sqrt))
    }
    #[inline(always)]
    fn cmplt(self, o: Self) -> Self::Mask {
        glam::Vec4::cmplt(self, o)
    }
    #[inline(always)]
    fn cmple(self, o: Self) -> Self::Mask {
        glam::Vec4::cmple(self, o)
    }
    #[inline(always)]
    fn cmpgt(self, o: Self) -> Self::Mask {
        glam::Vec4::cmpgt(self, o)
    }
    #[inline(always)]
    fn cmpge(self, o: Self) -> Self::Mask {
        glam::Vec4::cmpge(self, o)
    }
    #[inline(always)]
    fn cmpne(self, o: Self) -> Self::Mask {
        glam::Vec4::cmpne(self, o)
    }
    #[inline(always)]
    fn select(m: Self::Mask, a: Self, b: Self) -> Self {
        glam::Vec4::select(m, a, b)
    }
    #[inline(always)]
    fn minps(self, o: Self) -> Self {
        // glam's `min` and `max` are `minps` and `maxps`.
        glam::Vec4::min(self, o)
    }
    #[inline(always)]
    fn maxps(self, o: Self) -> Self {
        glam::Vec4::max(self, o)
    }
}

/// Asks the CPU to start loading the cache line at `p` (a hint: it never faults, whatever `p`).
#[inline(always)]
pub(crate) fn prefetch<T>(p: *const T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE is part of the x86_64 baseline, and a prefetch of any address has no effect
    // beyond the cache.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p.cast::<i8>());
    }
}

/// Defines `$name` (with visibility `$vis`), which runs `$body` (an expression over the
/// arguments) with the best instruction set the CPU has, and its AVX-512 and AVX2 builds
/// `$avx512`, `$avx2` (visible to the crate, for the tests that compare the builds). An
/// optional `<T: Trait>` after the names makes all three generic over one type.
///
/// A kernel returning a large struct keeps a public entry point that calls `$name` rather than
/// making `$name` the entry point: made the entry point, the dispatcher was inlined into the
/// packet code and its result copied with `memcpy` (course scene 2 at `-x 4 --stage 2`: 2.7 %
/// more instructions under callgrind). For the same reason the entry points stay `pub` and
/// reachable from outside the crate: made crate-private, they were inlined and copied the same way
/// (course scene 2: 2.0 % more instructions).
macro_rules! dispatched {
    ($(#[$doc:meta])* $vis:vis $name:ident, $avx512:ident, $avx2:ident, $(<$g:ident: $bound:path>)? $(#[$build:meta])* ($($arg:ident: $ty:ty),*) -> $ret:ty, $body:expr) => {
        $(#[$doc])*
        #[inline]
        #[allow(unsafe_code)]
        $vis fn $name$(<$g: $bound>)?($($arg: $ty),*) -> $ret {
            #[cfg(target_arch = "x86_64")]
            {
                if std::arch::is_x86_feature_detected!("avx512f") {
                    // SAFETY: the CPU supports AVX-512F, checked on the line above.
                    return unsafe { $avx512$(::<$g>)?($($arg),*) };
                }
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU supports AVX2, checked on the line above.
                    return unsafe { $avx2$(::<$g>)?($($arg),*) };
                }
            }
            $body
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx512f")]
        $(#[$build])*
        pub(crate) fn $avx512$(<$g: $bound>)?($($arg: $ty),*) -> $ret {
            $body
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2")]
        $(#[$build])*
        pub(crate) fn $avx2$(<$g: $bound>)?($($arg: $ty),*) -> $ret {
            $body
        }
    };
}
pub(crate) use dispatched;
