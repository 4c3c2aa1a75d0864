//! Optics at an interface: mirror reflection, Snell refraction and the Fresnel reflectance
//! (exact, and Schlick's approximation a tracer with that mistake uses).
//!
//! The BSDFs (`bsdf`), the integrators and the packet kernels all take these rules from here.

use glam::Vec3A;

/// Mirror reflection of `d` about the unit normal `n`.
#[must_use]
#[inline]
pub fn reflect(d: Vec3A, n: Vec3A) -> Vec3A {
    d - n * (2.0 * d.dot(n))
}

/// Exact unpolarised Fresnel reflectance for a ray meeting an interface with `cos_i` = cos of
/// the incidence angle (≥ 0), going from index `n1` to `n2`; 1 under total internal reflection.
#[must_use]
#[inline]
pub fn fresnel(cos_i: f32, n1: f32, n2: f32) -> f32 {
    let eta = n1 / n2;
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
    let rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// Refracted direction of unit `d` through unit normal `n` (facing `d`'s origin side) with
/// `eta = n1 / n2`; `None` under total internal reflection.
#[must_use]
#[inline]
pub fn refract(d: Vec3A, n: Vec3A, eta: f32) -> Option<Vec3A> {
    let cos_i = -d.dot(n);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((d * eta + n * (eta * cos_i - cos_t)).normalize())
}

/// Schlick's approximation of the Fresnel reflectance, from `n1` into `n2` at `cos_i`; 1 under
/// total internal reflection.
#[must_use]
pub fn schlick(cos_i: f32, n1: f32, n2: f32) -> f32 {
    let r0 = ((n1 - n2) / (n1 + n2)).powi(2);
    let eta = n1 / n2;
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    // Going into the denser medium the incident angle is the larger one; leaving it, the
    // transmitted one is.
    let c = if n1 <= n2 { cos_i } else { (1.0 - sin2_t).sqrt() };
    r0 + (1.0 - r0) * (1.0 - c).powi(5)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_limits() {
        // Normal incidence air→glass 1.5: ((1−1.5)/(1+1.5))² = 0.04.
        assert!((fresnel(1.0, 1.0, 1.5) - 0.04).abs() < 1e-6);
        // Grazing: total reflection.
        assert!((fresnel(0.0, 1.0, 1.5) - 1.0).abs() < 1e-6);
        // Inside glass past the critical angle (41.8° for 1.5): TIR.
        assert_eq!(fresnel(50f32.to_radians().cos(), 1.5, 1.0), 1.0);
        assert!(fresnel(30f32.to_radians().cos(), 1.5, 1.0) < 1.0);
    }

    #[test]
    fn refraction_obeys_snell() {
        let d = Vec3A::new(1.0, -1.0, 0.0).normalize();
        let n = Vec3A::Y;
        let t = refract(d, n, 1.0 / 1.4).unwrap();
        let sin_i = d.x;
        let sin_t = t.x;
        assert!((sin_i - 1.4 * sin_t).abs() < 1e-6);
        assert!(
            refract(Vec3A::new(0.9, -0.1, 0.0).normalize(), n, 1.4).is_none(),
            "TIR from inside"
        );
    }

    #[test]
    fn schlick_is_close_to_fresnel_but_not_equal() {
        for k in 0..=20 {
            let c = k as f32 / 20.0;
            let (s, f) = (schlick(c, 1.0, 1.5), fresnel(c, 1.0, 1.5));
            assert!((s - f).abs() < 0.06, "{c}: {s} vs {f}");
        }
        assert!((schlick(0.5, 1.0, 1.5) - fresnel(0.5, 1.0, 1.5)).abs() > 1e-4);
        assert_eq!(schlick(0.1, 1.5, 1.0), 1.0, "TIR");
    }
}
