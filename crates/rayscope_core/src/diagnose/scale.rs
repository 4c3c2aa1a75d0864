//! One factor every colour of a picture was multiplied by, fitted to its pixels.
//!
//! A picture that is rayscope's render darker or brighter by the same factor everywhere comes
//! from one multiplication too many or too few: the diffuse sum divided by the number of
//! lights, the `-x` grid's samples divided by N instead of N², a light's colour halved. The
//! fit reads the factor from the bytes themselves (the median ratio of the student's byte to
//! rayscope's where neither is near black or clipped), offers round values first, and leaves
//! the confirmation at full size to the caller.

/// Fewest channel values the ratio is read from: fewer, and the picture says too little.
const MIN_VALUES: usize = 64;

/// Rayscope's bytes the ratio is read at: far enough from 0 that a byte's truncation moves the
/// ratio by at most about 3 %, below the clipped top.
const OURS: std::ops::RangeInclusive<u8> = 32..=240;

/// How far from 1 a factor must be to be one (a picture within this is not scaled).
const NOT_ONE: f64 = 0.02;

/// How far from the measured factor a round value may lie and still be offered.
const NEAR: f64 = 0.03;

/// The factor by which `theirs` is `ours` (both RGB8) scaled, read from the channel values
/// where rayscope's byte is in [`OURS`] and the student's is neither 0 nor 255: their median
/// ratio, each byte taken at the middle of its truncation range. `None` where too few values
/// tell, where the factor is within [`NOT_ONE`] of 1, or where the ratios do not agree (the
/// middle half of them spread over more than a fifth of the factor: not one factor).
pub(crate) fn estimate(ours: &[u8], theirs: &[u8]) -> Option<f64> {
    let mut ratios: Vec<f64> = ours
        .iter()
        .zip(theirs)
        .filter(|&(o, t)| OURS.contains(o) && *t != 0 && *t != 255)
        .map(|(&o, &t)| (f64::from(t) + 0.5) / (f64::from(o) + 0.5))
        .collect();
    if ratios.len() < MIN_VALUES {
        return None;
    }
    ratios.sort_by(f64::total_cmp);
    let n = ratios.len();
    let k = ratios[n / 2];
    let spread = ratios[3 * n / 4] - ratios[n / 4];
    ((k - 1.0).abs() > NOT_ONE && spread <= 0.2 * k).then_some(k)
}

/// The factors worth rendering for a measured factor `k`, best first: those a known way gives
/// (one over the number of `lights`, the `-x` level `aa` or one over its square), then simple
/// fractions p/q (q up to 16) within [`NEAR`] of `k`, smallest denominator first, then `k` to
/// three significant figures; at most four.
pub(crate) fn candidates(k: f64, lights: usize, aa: u32) -> Vec<f32> {
    let near = |v: f64| (v / k - 1.0).abs() <= NEAR;
    let mut out: Vec<f64> = Vec::new();
    let mut known = Vec::new();
    if lights >= 2 {
        known.push(1.0 / lights as f64);
    }
    if aa >= 2 {
        let n = f64::from(aa);
        known.extend([n, n * n, 1.0 / (n * n)]);
    }
    out.extend(known.into_iter().filter(|&v| near(v)));
    for q in 1..=16u32 {
        let p = (k * f64::from(q)).round();
        if p >= 1.0 && near(p / f64::from(q)) {
            out.push(p / f64::from(q));
        }
    }
    let digits = 10f64.powi(2 - k.log10().floor() as i32);
    out.push((k * digits).round() / digits);
    let mut factors: Vec<f32> = Vec::new();
    for v in out {
        let f = v as f32;
        if (f64::from(f) - 1.0).abs() > NOT_ONE && !factors.contains(&f) {
            factors.push(f);
        }
    }
    factors.truncate(4);
    factors
}

/// How a report says the factor `k`, with the known ways to get it where `k` is one of them
/// (`lights` point lights, the `-x` level `aa`, the one `grey` level every light has).
pub(crate) fn words(k: f32, lights: usize, aa: u32, grey: Option<f32>) -> String {
    let what = if k < 1.0 { "darker" } else { "brighter" };
    let mut s = format!(
        "every colour multiplied by {k} before it is written as bytes (the whole picture {what} by that one factor)"
    );
    let is = |v: f64| (f64::from(k) - v).abs() <= 1e-6 * v;
    let mut ways = Vec::new();
    if lights >= 2 && is(1.0 / lights as f64) {
        ways.push(format!(
            "the sum over the {lights} lights divided by their number (the course adds each light's contribution)"
        ));
    }
    if let Some(g) = grey.filter(|&g| is(1.0 / f64::from(g))) {
        ways.push(format!(
            "each light's colour ({g}, {g}, {g}) left out of the diffuse term (albedo × N·L, as if every light were white)"
        ));
    }
    if let Some(g) = grey.filter(|&g| g < 1.0 && is(f64::from(g))) {
        ways.push(format!(
            "each light's colour ({g}, {g}, {g}) multiplied in twice (albedo × light × light × N·L)"
        ));
    }
    if aa >= 2 && is(f64::from(aa)) {
        ways.push(format!(
            "the -x {aa} grid's {} samples divided by {aa} instead of {}",
            aa * aa,
            aa * aa
        ));
    }
    if aa >= 2 && is(f64::from(aa * aa)) {
        ways.push(format!(
            "the -x {aa} grid's {} samples added up and never divided by {}",
            aa * aa,
            aa * aa
        ));
    }
    if aa >= 2 && is(1.0 / f64::from(aa * aa)) {
        ways.push(format!(
            "the -x {aa} grid's {} samples divided by {} twice",
            aa * aa,
            aa * aa
        ));
    }
    if !ways.is_empty() {
        s.push_str(" — ");
        s.push_str(&ways.join(", or "));
        s.push_str(&format!(
            " gives exactly this, as does any other mistake that multiplies every colour by {k}"
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scaled_picture_gives_its_factor_and_round_values_first() {
        // A gradient, halved as a truncating tracer would write it.
        let ours: Vec<u8> = (0..=255u8).cycle().take(3 * 400).collect();
        let half: Vec<u8> = ours.iter().map(|&b| ((f64::from(b) + 0.5) * 0.5) as u8).collect();
        let k = estimate(&ours, &half).expect("halved");
        assert!((k - 0.5).abs() < 0.01, "{k}");
        assert_eq!(candidates(k, 2, 4)[0], 0.5);
        assert!(words(0.5, 2, 4, None).contains("divided by their number"));
        assert!(!words(0.5, 3, 4, None).contains("divided by their number"));
        // Two lights of grey 0.5: averaged, or each colour multiplied in twice.
        let both = words(0.5, 2, 1, Some(0.5));
        assert!(
            both.contains("divided by their number") && both.contains("multiplied in twice"),
            "{both}"
        );
        assert!(both.contains("any other mistake"), "{both}");
        assert!(words(2.0, 2, 1, Some(0.5)).contains("each light's colour (0.5, 0.5, 0.5) left out"));
        assert!(!words(2.0, 2, 1, Some(0.25)).contains("left out"));
        // Four times brighter where it is not clipped: the -x 4 grid divided by 4.
        let bright: Vec<u8> = ours
            .iter()
            .map(|&b| ((f64::from(b) + 0.5) * 4.0).min(255.0) as u8)
            .collect();
        let k = estimate(&ours, &bright).expect("brighter");
        assert_eq!(candidates(k, 1, 4)[0], 4.0);
        assert!(
            words(4.0, 1, 4, None).contains("divided by 4 instead of 16"),
            "{}",
            words(4.0, 1, 4, None)
        );
        assert!(words(4.0, 1, 2, None).contains("the -x 2 grid's 4 samples added up and never divided by 4"));
        assert!(!words(4.0, 1, 4, None).contains("never divided"));
        // The same picture, and one that differs by no one factor, give none.
        assert_eq!(estimate(&ours, &ours), None);
        let mixed: Vec<u8> = ours
            .iter()
            .enumerate()
            .map(|(i, &b)| if i % 2 == 0 { b / 2 } else { b.saturating_add(b / 2) })
            .collect();
        assert_eq!(estimate(&ours, &mixed), None, "half darker, half brighter");
    }
}
