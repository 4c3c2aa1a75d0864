//! The SIMD vocabulary every sixteen-lane kernel shares: the lane count, lane masks, lane access,
//! the run-time choice of instruction set and the cache prefetch hint.
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
/// more instructions under callgrind).
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
