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

/// A χ² test of [`sample_triangle`] against [`triangle_pdf`] for triangle `tri` seen from `p`.
fn triangle_test(name: &str, tri: Triangle, p: Vec3A) {
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
        name,
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

/// A triangle of moderate solid angle (0.3 sr), drawn by solid angle.
#[test]
fn chi2_triangle_emitter_solid_angle() {
    let tri = Triangle::new(
        Vec3A::new(-1.0, 1.5, 2.0),
        Vec3A::new(1.2, 1.7, 2.5),
        Vec3A::new(0.1, 1.4, 4.0),
    );
    triangle_test("triangle", tri, Vec3A::new(0.2, 0.0, 1.0));
    triangle_cells_test("triangle", tri, Vec3A::new(0.2, 0.0, 1.0), true);
}

type D3 = [f64; 3];

fn d3(v: Vec3A) -> D3 {
    [f64::from(v.x), f64::from(v.y), f64::from(v.z)]
}

fn dot_d(a: D3, b: D3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross_d(a: D3, b: D3) -> D3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The solid angle of the triangle (a, b, c) seen from `p`, in f64.
fn solid_angle_d(p: D3, [a, b, c]: [D3; 3]) -> f64 {
    let unit = |v: D3| {
        let w = [v[0] - p[0], v[1] - p[1], v[2] - p[2]];
        let l = dot_d(w, w).sqrt();
        [w[0] / l, w[1] / l, w[2] / l]
    };
    let (a, b, c) = (unit(a), unit(b), unit(c));
    let num = dot_d(a, cross_d(b, c)).abs();
    let den = 1.0 + dot_d(a, b) + dot_d(b, c) + dot_d(c, a);
    2.0 * num.atan2(den)
}

/// A χ² test of where [`sample_triangle`]'s points land on `tri`, seen from `p`, by the n² cells
/// of its subdivision into n × n: each cell's expected share is its share of the triangle's solid
/// angle (`by_solid_angle`) or of its area. Unlike the test by directions, no cell is thinner
/// than the directions' grid, however close `p` is to the triangle's plane.
fn triangle_cells_test(name: &str, tri: Triangle, p: Vec3A, by_solid_angle: bool) {
    let pv = triangle_cells_p(name, tri, p, by_solid_angle);
    assert!(pv > P_MIN, "{name}: p = {pv}");
}

/// The p-value of [`triangle_cells_test`].
fn triangle_cells_p(name: &str, tri: Triangle, p: Vec3A, by_solid_angle: bool) -> f64 {
    const N: usize = 8;
    const SAMPLES: usize = 400_000;
    let [v0, v1, v2] = tri.vertices().map(d3);
    let (e1, e2) = (
        [v1[0] - v0[0], v1[1] - v0[1], v1[2] - v0[2]],
        [v2[0] - v0[0], v2[1] - v0[1], v2[2] - v0[2]],
    );
    let at = |b1: f64, b2: f64| -> D3 { std::array::from_fn(|a| v0[a] + e1[a] * b1 + e2[a] * b2) };
    let pd = d3(p);
    // Cells: (i, j, up) with corners at barycentrics on the 1/N grid.
    let mut cells = Vec::new();
    for i in 0..N {
        for j in 0..N - i {
            let (x, y, k) = (i as f64, j as f64, N as f64);
            cells.push([at(x / k, y / k), at((x + 1.0) / k, y / k), at(x / k, (y + 1.0) / k)]);
            if i + j + 1 < N {
                cells.push([
                    at((x + 1.0) / k, y / k),
                    at((x + 1.0) / k, (y + 1.0) / k),
                    at(x / k, (y + 1.0) / k),
                ]);
            }
        }
    }
    let index = |b1: f64, b2: f64| -> Option<usize> {
        let (x, y) = (b1 * N as f64, b2 * N as f64);
        let (i, j) = (x.floor().max(0.0) as usize, y.floor().max(0.0) as usize);
        if i + j >= N {
            return None;
        }
        // The last cell of a row has no lower neighbour: a point on the hypotenuse is in it.
        let up = (x - i as f64) + (y - j as f64) < 1.0 || i + j + 1 == N;
        // Cells are pushed row by row of i: before row i come Σ_{r<i} (2(N − r) − 1) cells.
        let before: usize = (0..i).map(|r| 2 * (N - r) - 1).sum();
        Some(before + 2 * j + usize::from(!up))
    };
    let omega = solid_angle_d(pd, [v0, v1, v2]);
    let expected: Vec<f64> = cells
        .iter()
        .map(|&c| {
            if by_solid_angle {
                solid_angle_d(pd, c) / omega
            } else {
                1.0 / cells.len() as f64
            }
        })
        .collect();
    let total: f64 = expected.iter().sum();
    assert!((total - 1.0).abs() < 1e-9, "{name}: the cells' shares sum to {total}");
    let n = cross_d(e1, e2);
    let nn = dot_d(n, n);
    let mut observed = vec![0f64; cells.len()];
    let mut rng = Rng::for_sample(0x5eed, 1, 0);
    let mut failed = 0usize;
    for _ in 0..SAMPLES {
        let Some((dir, dist, pdf)) = sample_triangle(&tri, p, rng.next_f32(), rng.next_f32()) else {
            failed += 1;
            continue;
        };
        let y: D3 = std::array::from_fn(|a| pd[a] + f64::from(dir[a]) * f64::from(dist));
        let w = [y[0] - v0[0], y[1] - v0[1], y[2] - v0[2]];
        let b1 = dot_d(cross_d(w, e2), n) / nn;
        let b2 = dot_d(cross_d(e1, w), n) / nn;
        let want = triangle_pdf(&tri, p, p + dir * dist);
        assert!(
            (pdf - want).abs() <= 1e-4 * want,
            "{name}: drawn with density {pdf}, triangle_pdf says {want}"
        );
        if by_solid_angle && omega > 3e-4 {
            assert!(
                (f64::from(pdf) * omega - 1.0).abs() < 1e-4,
                "{name}: density {pdf} is not 1/Ω, Ω = {omega}"
            );
        }
        // Points that rounding puts a hair outside go to the nearest cell.
        let (b1, b2) = (b1.clamp(0.0, 1.0), b2.clamp(0.0, 1.0));
        let s = b1 + b2;
        let (b1, b2) = if s > 1.0 { (b1 / s, b2 / s) } else { (b1, b2) };
        let k = index(b1.min(1.0 - 1e-12), b2.min(1.0 - 1e-12)).unwrap_or(cells.len() - 1);
        observed[k] += 1.0;
    }
    assert!(failed * 10_000 <= SAMPLES, "{name}: {failed} of {SAMPLES} draws failed");
    let drawn = (SAMPLES - failed) as f64;
    let chi2: f64 = expected
        .iter()
        .zip(&observed)
        .map(|(e, o)| (o - e * drawn).powi(2) / (e * drawn))
        .sum();
    let dof = cells.len() - 1;
    let pv = gamma_q(dof as f64 / 2.0, chi2 / 2.0);
    eprintln!("{name} by cells: chi2 = {chi2:.1}, dof = {dof}, p = {pv:.4}");
    pv
}

/// Points 0.005–0.01 from a triangle's plane, above it and beside it (the ceiling around a lamp
/// hung just below it): the solid angle is large and most directions graze the triangle; drawn
/// by solid angle.
#[test]
fn chi2_triangle_emitter_seen_from_close_by() {
    let tri = Triangle::new(
        Vec3A::new(-0.35, 0.995, 1.9),
        Vec3A::new(0.35, 0.995, 1.9),
        Vec3A::new(0.35, 0.995, 2.6),
    );
    triangle_cells_test("above the triangle", tri, Vec3A::new(0.1, 1.0, 2.3), true);
    triangle_cells_test("beside the triangle", tri, Vec3A::new(0.4, 1.005, 2.0), true);
    triangle_cells_test("at a corner", tri, Vec3A::new(-0.36, 1.0, 1.89), true);
    // The same draws judged as if they were uniform by area must fail: the test can tell.
    let pv = triangle_cells_p("above, judged by area", tri, Vec3A::new(0.1, 1.0, 2.3), false);
    assert!(pv < 1e-9, "draws by solid angle passed as draws by area: p = {pv}");
}

/// A small, far triangle (solid angle below 3e-4 sr), drawn by area.
#[test]
fn chi2_triangle_emitter_area_far_away() {
    let tri = Triangle::new(
        Vec3A::new(-0.1, 1.5, 20.0),
        Vec3A::new(0.12, 1.7, 20.5),
        Vec3A::new(0.01, 1.4, 20.3),
    );
    triangle_cells_test("small far triangle", tri, Vec3A::new(0.2, 0.0, 1.0), false);
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
