//! χ² goodness-of-fit tests of every sampling routine the stage-3 integrator uses, against the
//! density functions the integrator uses for MIS (integrated numerically over each bin).

use glam::Vec3A;
use rayscope_core::bsdf::{glossy_alpha, Bsdf};
use rayscope_core::geometry::{Primitive, Sphere, Triangle};
use rayscope_core::lights::{sample_sphere, sample_triangle, sphere_pdf, triangle_pdf};
use rayscope_core::math::{basis, Ray};
use rayscope_core::rng::Rng;
use rayscope_core::sampling::{
    cosine_hemisphere, cosine_hemisphere_pdf, ggx_reflect_pdf, ggx_sample_vndf, reflect_about, to_local, to_world,
};

/// p-value below which a test fails.
const P_MIN: f64 = 1e-3;

fn ln_gamma(x: f64) -> f64 {
    // Lanczos approximation (g = 7, n = 9).
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + 7.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised upper incomplete gamma Q(a, x) (Numerical Recipes' gammq).
fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let gln = ln_gamma(a);
    if x < a + 1.0 {
        let (mut ap, mut sum) = (a, 1.0 / a);
        let mut del = sum;
        for _ in 0..1000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        1.0 - sum * (-x + a * x.ln() - gln).exp()
    } else {
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / 1e-300;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..1000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < 1e-300 {
                d = 1e-300;
            }
            c = b + an / c;
            if c.abs() < 1e-300 {
                c = 1e-300;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        (-x + a * x.ln() - gln).exp() * h
    }
}

/// A χ² test of directions, binned by (cosθ, φ) about the frame's +z over cosθ ∈ [c0, c1].
struct Chi2 {
    c0: f32,
    c1: f32,
    n_theta: usize,
    n_phi: usize,
    samples: usize,
}

impl Chi2 {
    fn bin(&self, d: Vec3A) -> Option<usize> {
        if d.z < self.c0 || d.z > self.c1 {
            return None;
        }
        let i = (((d.z - self.c0) / (self.c1 - self.c0)) * self.n_theta as f32) as usize;
        let phi = d.y.atan2(d.x).rem_euclid(2.0 * std::f32::consts::PI);
        let j = (phi / (2.0 * std::f32::consts::PI) * self.n_phi as f32) as usize;
        Some(i.min(self.n_theta - 1) * self.n_phi + j.min(self.n_phi - 1))
    }

    /// Runs the test; `sample` returns a local direction or `None` (a failed sample), `pdf` the
    /// density of a local direction. Returns the p-value.
    fn run(&self, name: &str, mut sample: impl FnMut(&mut Rng) -> Option<Vec3A>, pdf: impl Fn(Vec3A) -> f32) -> f64 {
        let bins = self.n_theta * self.n_phi;
        let mut observed = vec![0f64; bins + 1];
        let mut rng = Rng::for_sample(0x5eed, 0, 0);
        for _ in 0..self.samples {
            match sample(&mut rng).and_then(|d| self.bin(d.normalize())) {
                Some(b) => observed[b] += 1.0,
                None => observed[bins] += 1.0,
            }
        }
        // Expected counts: midpoint rule on a 32×32 grid inside each bin (dω = dcosθ dφ).
        let k = 32;
        let mut expected = vec![0f64; bins + 1];
        let dc = (self.c1 - self.c0) as f64 / self.n_theta as f64;
        let dp = 2.0 * std::f64::consts::PI / self.n_phi as f64;
        for i in 0..self.n_theta {
            for j in 0..self.n_phi {
                let mut sum = 0.0;
                for a in 0..k {
                    for b in 0..k {
                        let c = self.c0 as f64 + dc * (i as f64 + (a as f64 + 0.5) / k as f64);
                        let p = dp * (j as f64 + (b as f64 + 0.5) / k as f64);
                        let s = (1.0 - c * c).max(0.0).sqrt();
                        let d = Vec3A::new((s * p.cos()) as f32, (s * p.sin()) as f32, c as f32);
                        sum += pdf(d) as f64;
                    }
                }
                expected[i * self.n_phi + j] = sum * dc * dp / (k * k) as f64 * self.samples as f64;
            }
        }
        let inside: f64 = expected[..bins].iter().sum();
        expected[bins] = (self.samples as f64 - inside).max(0.0);
        // Samples where the density is zero fail at once; small bins are pooled (pbrt's rule).
        let mut pairs: Vec<(f64, f64)> = expected.iter().copied().zip(observed.iter().copied()).collect();
        for (i, &(e, o)) in pairs.iter().enumerate() {
            assert!(
                !(e < 1e-9 * self.samples as f64 && o > self.samples as f64 * 1e-4 + 2.0),
                "{name}: {o} samples in bin {i} where the density is 0"
            );
        }
        pairs.sort_by(|a, b| a.0.partial_cmp(&b.0).unwrap());
        let (mut chi2, mut dof) = (0.0, 0usize);
        let (mut pool_e, mut pool_o) = (0.0, 0.0);
        for (e, o) in pairs {
            if e < 5.0 {
                pool_e += e;
                pool_o += o;
                continue;
            }
            chi2 += (o - e) * (o - e) / e;
            dof += 1;
        }
        if pool_e > 5.0 {
            chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
            dof += 1;
        }
        let p = gamma_q((dof as f64 - 1.0) / 2.0, chi2 / 2.0);
        eprintln!("{name}: chi2 = {chi2:.1}, dof = {}, p = {p:.4}", dof - 1);
        p
    }
}

#[test]
fn chi2_helper_rejects_a_wrong_density() {
    // Cosine samples judged against a uniform-hemisphere density must fail.
    let t = Chi2 {
        c0: 0.0,
        c1: 1.0,
        n_theta: 10,
        n_phi: 16,
        samples: 100_000,
    };
    let p = t.run(
        "cosine vs uniform",
        |r| Some(cosine_hemisphere(r.next_f32(), r.next_f32())),
        |_| 0.5 / std::f32::consts::PI,
    );
    assert!(p < 1e-6, "p = {p}");
    assert!((gamma_q(2.5, 0.0) - 1.0).abs() < 1e-12);
    // Q(1, x) = e^{−x}.
    assert!((gamma_q(1.0, 3.0) - (-3.0f64).exp()).abs() < 1e-10);
}

#[test]
fn chi2_cosine_hemisphere() {
    let t = Chi2 {
        c0: 0.0,
        c1: 1.0,
        n_theta: 10,
        n_phi: 20,
        samples: 200_000,
    };
    let p = t.run(
        "cosine",
        |r| Some(cosine_hemisphere(r.next_f32(), r.next_f32())),
        |d| cosine_hemisphere_pdf(d.z),
    );
    assert!(p > P_MIN, "p = {p}");
}

/// Frame about the direction from `p` to `target`.
fn frame(p: Vec3A, target: Vec3A) -> (Vec3A, Vec3A, Vec3A) {
    let n = (target - p).normalize();
    let (t, b) = basis(n);
    (t, b, n)
}

fn sphere_test(name: &str, s: Sphere, p: Vec3A, c0: f32) {
    let (t, b, n) = frame(p, s.center);
    let test = Chi2 {
        c0,
        c1: 1.0,
        n_theta: 12,
        n_phi: 16,
        samples: 200_000,
    };
    let pv = test.run(
        name,
        |r| {
            let (d, dist, pdf) = sample_sphere(&s, p, r.next_f32(), r.next_f32())?;
            // The reported point must lie on the sphere and agree with the density function.
            let y = p + d * dist;
            assert!(((y - s.center).length() - s.radius).abs() < 1e-3 * s.radius.max(1.0));
            let q = sphere_pdf(&s, p, y);
            assert!((q - pdf).abs() <= 1e-3 * pdf, "{q} vs {pdf}");
            Some(to_local(d, t, b, n))
        },
        |d| {
            let w = to_world(d, t, b, n);
            match s.intersect(&Ray::new(p, w), 0.0, f32::INFINITY) {
                Some(h) => sphere_pdf(&s, p, p + w * h.t),
                None => 0.0,
            }
        },
    );
    assert!(pv > P_MIN, "{name}: p = {pv}");
}

#[test]
fn chi2_sphere_emitter_cone_from_outside() {
    let s = Sphere {
        center: Vec3A::new(0.3, 1.0, 3.0),
        radius: 0.8,
    };
    let p = Vec3A::new(0.0, -0.5, 0.5);
    let d = (s.center - p).length();
    let cos_max = (1.0 - (s.radius / d).powi(2)).sqrt();
    sphere_test("sphere cone", s, p, cos_max - 0.02);
}

#[test]
fn chi2_sphere_emitter_area_from_inside() {
    let s = Sphere {
        center: Vec3A::new(0.0, 0.0, 0.0),
        radius: 2.0,
    };
    // Directions from an interior point cover the whole sphere; the frame's +z points at the centre.
    sphere_test("sphere inside", s, Vec3A::new(0.7, -0.4, 0.9), -1.0);
}

#[test]
fn chi2_triangle_emitter_area() {
    let tri = Triangle::new(
        Vec3A::new(-1.0, 1.5, 2.0),
        Vec3A::new(1.2, 1.7, 2.5),
        Vec3A::new(0.1, 1.4, 4.0),
    );
    let p = Vec3A::new(0.2, 0.0, 1.0);
    let centroid = (tri.vertices()[0] + tri.vertices()[1] + tri.vertices()[2]) / 3.0;
    let (t, b, n) = frame(p, centroid);
    let c0 = tri
        .vertices()
        .iter()
        .map(|v| (*v - p).normalize().dot(n))
        .fold(1.0f32, f32::min)
        - 0.02;
    let test = Chi2 {
        c0,
        c1: 1.0,
        n_theta: 12,
        n_phi: 16,
        samples: 200_000,
    };
    let pv = test.run(
        "triangle",
        |r| {
            let (d, _, _) = sample_triangle(&tri, p, r.next_f32(), r.next_f32())?;
            Some(to_local(d, t, b, n))
        },
        |d| {
            let w = to_world(d, t, b, n);
            match tri.intersect(&Ray::new(p, w), 0.0, f32::INFINITY) {
                Some(h) => triangle_pdf(&tri, p, p + w * h.t),
                None => 0.0,
            }
        },
    );
    assert!(pv > P_MIN, "p = {pv}");
}

#[test]
fn chi2_ggx_vndf() {
    for (alpha, theta) in [(0.3f32, 0.4f32), (0.8, 1.2), (0.15, 1.0)] {
        let wo = Vec3A::new(theta.sin() * 0.8, theta.sin() * 0.6, theta.cos());
        let test = Chi2 {
            c0: -1.0,
            c1: 1.0,
            n_theta: 20,
            n_phi: 24,
            samples: 300_000,
        };
        let p = test.run(
            &format!("ggx vndf α={alpha} θ={theta}"),
            |r| {
                Some(reflect_about(
                    wo,
                    ggx_sample_vndf(wo, alpha, r.next_f32(), r.next_f32()),
                ))
            },
            |wi| ggx_reflect_pdf(wo, wi, alpha),
        );
        assert!(p > P_MIN, "α {alpha} θ {theta}: p = {p}");
    }
}

#[test]
fn chi2_glossy_bsdf_mixture() {
    for n in [1.0f32, 3.0] {
        let b = Bsdf::Coated {
            base: Vec3A::new(0.6, 0.3, 0.1),
            alpha: glossy_alpha(n),
            coat_only: false,
        };
        let wo = Vec3A::new(0.5, 0.1, 0.8).normalize();
        let test = Chi2 {
            c0: 0.0,
            c1: 1.0,
            n_theta: 16,
            n_phi: 24,
            samples: 300_000,
        };
        let p = test.run(
            &format!("glossy n={n}"),
            |r| b.sample(wo, r.next_f32(), r.next_f32(), r.next_f32()).map(|s| s.wi),
            |wi| b.pdf(wo, wi),
        );
        assert!(p > P_MIN, "n {n}: p = {p}");
    }
}
