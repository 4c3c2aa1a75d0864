//! The field of view a picture was rendered with, fitted to its pixels.
//!
//! A student who takes the wrong angle — not halved before its tangent, halved twice, the image
//! plane two units away, degrees given to a tangent that takes radians, another number — makes a
//! picture that is rayscope's render at another field of view. The fit scans the command line's
//! range on a sparse grid of pixels (above 180° the image plane's half-width is negative: the
//! picture turned half a turn, as tan(30) of a 60° angle taken in radians gives), refines the
//! best angle by golden-section search; the caller confirms it at full size, the known ways to
//! get it and round values first.

use rayon::prelude::*;

/// Pixels of the sparse grid the fit compares.
const FIT_PIXELS: f64 = 2_000.0;

/// Step of the coarse scan over the field of view, in degrees.
const SCAN_STEP: f32 = 2.5;

/// Golden-section steps after the scan: the bracket of two scan steps shrinks to 2e-4°.
const REFINE_STEPS: usize = 20;

/// How many times closer than the course's angle the fitted one must be on the sparse grid.
const GAIN: f64 = 4.0;

/// Relative tolerance within which a fitted half-width is named as a known way to get it.
const NAMED: f64 = 2e-3;

/// The bytes of some pixels rendered at a field of view (degrees).
pub(crate) type RenderAt<'a> = dyn Fn(f32, &[(u32, u32)]) -> Vec<u8> + Sync + 'a;

/// The field of view in degrees whose render of a sparse grid of pixels is closest to `image`
/// (RGB8, `w`×`h`), when it is at least [`GAIN`] times closer than `course` degrees and more
/// than 0.01° from it; `render(fov, pixels)` gives the bytes of those pixels at that angle.
pub(crate) fn fit(w: u32, h: u32, image: &[u8], course: f32, render: &RenderAt<'_>) -> Option<f32> {
    let step = ((f64::from(w) * f64::from(h) / FIT_PIXELS).sqrt() as u32).max(1);
    let pixels: Vec<(u32, u32)> = (step / 2..h)
        .step_by(step as usize)
        .flat_map(|y| (step / 2..w).step_by(step as usize).map(move |x| (x, y)))
        .collect();
    let theirs: Vec<u8> = pixels
        .iter()
        .flat_map(|&(x, y)| {
            let p = ((y * w + x) * 3) as usize;
            image[p..p + 3].iter().copied()
        })
        .collect();
    let error = |fov: f32| -> f64 {
        render(fov, &pixels)
            .iter()
            .zip(&theirs)
            .map(|(&a, &b)| (f64::from(a) - f64::from(b)).powi(2))
            .sum()
    };
    // Both sides of 180°, where the half-width tan(fov/2) is infinite.
    let scan: Vec<f32> = (1..144).filter(|&k| k != 72).map(|k| k as f32 * SCAN_STEP).collect();
    let errors: Vec<f64> = scan.par_iter().map(|&f| error(f)).collect();
    let k = (0..scan.len()).min_by(|&a, &b| errors[a].total_cmp(&errors[b]))?;
    let (mut a, mut b) = (scan[k] - SCAN_STEP, scan[k] + SCAN_STEP);
    let ratio = (5f32.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (b - ratio * (b - a), a + ratio * (b - a));
    let (mut ec, mut ed) = (error(c), error(d));
    for _ in 0..REFINE_STEPS {
        if ec <= ed {
            (b, d, ed) = (d, c, ec);
            c = b - ratio * (b - a);
            ec = error(c);
        } else {
            (a, c, ec) = (c, d, ed);
            d = a + ratio * (b - a);
            ed = error(d);
        }
    }
    let (best, e_best) = if ec <= ed { (c, ec) } else { (d, ed) };
    (e_best * GAIN < error(course) && (best - course).abs() > 0.01).then_some(best)
}

/// The fields of view that the known ways of taking the wrong angle give for the course's
/// `course` degrees, each with its half-width's words: tan(c), tan(c/4), half of tan(c/2),
/// and the tangents of c/2 and c taken as radians.
fn known(course: f32) -> [(f64, String); 5] {
    let c = f64::from(course);
    let radians = "given to a tangent that takes radians (C#'s Math.Tan, Python's math.tan, C's tan)";
    [
        (
            c.to_radians().tan(),
            format!("tan({c}°) where the course takes tan({c}°/2) — the angle not halved before its tangent"),
        ),
        (
            (c / 4.0).to_radians().tan(),
            format!("tan({c}°/4) — the angle halved twice"),
        ),
        (
            (c / 2.0).to_radians().tan() / 2.0,
            "half the course's, as an image plane two units in front of the camera with the course's size gives"
                .to_string(),
        ),
        (
            (c / 2.0).tan(),
            format!("tan({}) — the half angle in degrees {radians}", c / 2.0),
        ),
        (
            c.tan(),
            format!("tan({c}) — the angle in degrees, not halved, {radians}"),
        ),
    ]
}

/// The field of view in degrees whose image plane has the half-width `t` (negative above 180°).
fn angle_of(t: f64) -> f64 {
    let half = t.atan().to_degrees();
    2.0 * if half < 0.0 { 180.0 + half } else { half }
}

/// The angles of the known ways ([`known`]) within a degree of a fitted `fov`, for the course's
/// `course` degrees: confirmed before the fitted value, since a student's angle is one of them
/// more often than a round number.
pub(crate) fn known_near(fov: f32, course: f32) -> Vec<f32> {
    known(course)
        .iter()
        .map(|(t, _)| angle_of(*t) as f32)
        .filter(|a| (a - fov).abs() <= 1.0 && *a != 180.0)
        .collect()
}

/// The angles to confirm for a fitted `fov`, roundest first: a student writes 120°, not
/// 119.99987°, and rounding on the sparse grid cannot tell them apart.
pub(crate) fn round_first(fov: f32) -> Vec<f32> {
    let mut out: Vec<f32> = Vec::new();
    for v in [(fov * 10.0).round() / 10.0, (fov * 100.0).round() / 100.0, fov] {
        if !out.contains(&v) {
            out.push(v);
        }
    }
    out
}

/// Words for a field of view of `fitted` degrees where the course's is `course` on the `axis`
/// ("horizontal" or "vertical"): the image plane's half-width against the course's and, where
/// it is one, the known way to get it.
pub(crate) fn words(fitted: f32, course: f32, axis: &str) -> String {
    let (f, c) = (f64::from(fitted), f64::from(course));
    let (tf, tc) = ((f / 2.0).to_radians().tan(), (c / 2.0).to_radians().tan());
    let r = tf / tc;
    let near = |x: f64, y: f64| (x - y).abs() <= NAMED * y.abs();
    let known = known(course)
        .into_iter()
        .find(|(t, _)| near(tf, *t))
        .map_or_else(String::new, |(_, w)| format!(": {w}"));
    let (sign, turned) = if tf < 0.0 {
        (
            " and negative",
            ", so your picture is upside down and mirrored (turned half a turn)",
        )
    } else {
        ("", "")
    };
    format!(
        "a field of view of {fitted}° ({axis}) instead of {course}°: your image plane's half-width is {tf:.4} where the course's is tan({c}°/2) = {tc:.4}, {:.3}× as wide{sign}{turned}{known}",
        r.abs()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_ways_are_named_by_their_half_width() {
        assert!(words(120.0, 60.0, "horizontal").ends_with("the angle not halved before its tangent"));
        let quarter = 2.0 * (15f64.to_radians().tan()).atan().to_degrees();
        assert!(words(quarter as f32, 60.0, "horizontal").ends_with("the angle halved twice"));
        let two_units = 2.0 * (30f64.to_radians().tan() / 2.0).atan().to_degrees();
        assert!(words(two_units as f32, 60.0, "horizontal").contains("two units in front"));
        let other = words(47.0, 60.0, "vertical");
        assert!(
            other.starts_with("a field of view of 47° (vertical) instead of 60°"),
            "{other}"
        );
        assert!(other.ends_with("as wide"), "{other}");
        // tan(30) of a 60° angle in radians: a negative half-width, the picture turned.
        let turned = angle_of(30f64.tan()) as f32;
        assert!((turned - 197.75).abs() < 0.01, "{turned}");
        let w = words(turned, 60.0, "horizontal");
        assert!(
            w.contains(
                "11.094× as wide and negative, so your picture is upside down and mirrored (turned half a turn)"
            ),
            "{w}"
        );
        assert!(w.ends_with("tan(30) — the half angle in degrees given to a tangent that takes radians (C#'s Math.Tan, Python's math.tan, C's tan)"), "{w}");
        assert!(words(angle_of(60f64.tan()) as f32, 60.0, "horizontal")
            .contains("tan(60) — the angle in degrees, not halved"));
        assert_eq!(known_near(197.5, 60.0), vec![turned]);
    }
}
