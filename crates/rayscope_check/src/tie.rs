//! When a disagreement with the oracle is a genuine tie, either answer right: only where the
//! exact double-precision answer lies within rounding of a different one, a ray passing that
//! close to a triangle's edge, a sphere's rim or a tangent. "Within rounding" is
//! [`Tolerances::tie`](crate::Tolerances::tie) (1e-4) times the size of the coordinates
//! involved, because rounding error grows with their size: [`is_tie`]. The log checker (`judge`)
//! measures that size as [`scale`] does (at least 1), `probe` as [`magnitude`] does (its battery
//! shrinks primitives and rays by 1e-4 to catch absolute epsilons, where a floor of 1 would make
//! every ray a tie).

use glam::DVec3;

/// The largest absolute coordinate of `points` (0 for none): the size rounding error is
/// relative to.
#[must_use]
pub fn magnitude(points: &[DVec3]) -> f64 {
    points.iter().map(|p| p.abs().max_element()).fold(0.0, f64::max)
}

/// The scale the log checker's tolerances are multiplied by: [`magnitude`], at least 1 (a
/// course tracer's logged coordinates are of unit size, and its epsilons absolute).
#[must_use]
pub fn scale(points: &[DVec3]) -> f64 {
    magnitude(points).max(1.0)
}

/// True when a ray passing `margin` (scene units) from an edge, rim or tangent is a tie, at the
/// coordinates' `scale` with the relative tie tolerance `tie`.
#[must_use]
pub fn is_tie(margin: f64, tie: f64, scale: f64) -> bool {
    margin.abs() <= tie * scale
}
