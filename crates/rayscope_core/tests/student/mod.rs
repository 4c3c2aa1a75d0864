//! A student's stage-2 ray tracer, written the way the course's template invites (f64, one
//! recursive `Trace`, brute-force intersection), with the course's common mistakes as switches.
//! `diagnose` is tested on its pictures: it shares no code with rayscope's renderer, so its
//! images match rayscope's only as closely as two correct tracers do.

use std::collections::HashSet;
use std::path::Path;

use glam::DVec3;
use rayscope_scene::{MaterialKind, SceneFile, Shape};

/// The image and what the student's command line said.
#[derive(Debug, Clone, Copy)]
pub struct Options {
    pub width: u32,
    pub height: u32,
    pub aa: u32,
    pub max_depth: u32,
    /// `--cam-axis` and `--cam-angle` (degrees).
    pub cam_axis: DVec3,
    pub cam_angle: f64,
    /// Where in its pixel the picture's sample grid sits, moved by this many pixels (x, y):
    /// a camera off by a fraction of a pixel.
    pub shift: [f64; 2],
    /// A glass that reflects this share at every angle (total internal reflection aside).
    pub fresnel_constant: Option<f64>,
    /// Where the `aa`×`aa` samples sit in their pixel: sample k of each axis at
    /// (k + grid[0])/(aa + grid[1]); the course's cell centres are [0.5, 0].
    pub grid: [f64; 2],
    /// Samples at random positions from a generator with this seed instead of the grid's:
    /// anywhere in the pixel, or with `jitter_in_cells` one anywhere in each cell of the grid.
    pub jitter: Option<u64>,
    pub jitter_in_cells: bool,
    /// Stage 1: the closest hit's material colour, black where nothing is hit.
    pub stage1: bool,
    /// The horizontal field of view in degrees (the course's is 60).
    pub fov: f64,
    /// Shadow rays started this far off the surface instead of the course's 1e-5.
    pub shadow_offset: Option<f64>,
    /// Every ray leaving a surface (shadow, mirror, glass) started this far off it instead of
    /// the course's 1e-5: one epsilon of the student's own used everywhere.
    pub ray_offset: Option<f64>,
}

impl Options {
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            aa: 1,
            max_depth: 8,
            cam_axis: DVec3::Z,
            cam_angle: 0.0,
            shift: [0.0; 2],
            fresnel_constant: None,
            grid: [0.5, 0.0],
            jitter: None,
            jitter_in_cells: false,
            stage1: false,
            fov: 60.0,
            shadow_offset: None,
            ray_offset: None,
        }
    }
}

#[derive(Clone, Copy)]
struct Ray {
    o: DVec3,
    d: DVec3,
}

#[derive(Clone, Copy)]
struct Tri {
    v: [DVec3; 3],
    n: Option<[DVec3; 3]>,
}

enum Geo {
    Plane { p: DVec3, n: DVec3 },
    Sphere { c: DVec3, r: f64 },
    Tri(Tri),
    Mesh { tris: Vec<Tri>, centre: DVec3, radius: f64 },
}

struct Obj {
    geo: Geo,
    kind: MaterialKind,
    color: DVec3,
    ior: f64,
    is_triangle: bool,
}

struct Hit {
    t: f64,
    p: DVec3,
    /// The normal as the student's code computes it (not yet turned towards the ray).
    n: DVec3,
    /// The interpolated normal of a smooth mesh, on the same side as `n`.
    shading: DVec3,
    /// The direction of the ray that hit.
    dir: DVec3,
    obj: usize,
}

/// The student's program.
pub struct Student {
    objs: Vec<Obj>,
    lights: Vec<(DVec3, DVec3)>,
    bugs: HashSet<&'static str>,
    opts: Options,
}

const EPS: f64 = 1e-5;

impl Student {
    /// The student's tracer for `file`, with the mistakes named in `bugs` (catalogue names).
    pub fn new(file: &SceneFile, bugs: &[&'static str], opts: Options) -> Student {
        let bugs: HashSet<&'static str> = bugs.iter().copied().collect();
        let mut objs = Vec::new();
        // Uncatalogued, `last-entity-skipped`: the loader's loop stops one line short.
        let read = file.entities.len() - usize::from(bugs.contains("last-entity-skipped"));
        for e in &file.entities[..read] {
            let m = &file.materials[e.material];
            let geo = match &e.shape {
                Shape::Plane { point, normal } => Geo::Plane {
                    p: *point,
                    n: normal.normalize(),
                },
                // Uncatalogued, `radius-halved`: the radius read as a diameter.
                Shape::Sphere { center, radius } => Geo::Sphere {
                    c: *center,
                    r: if bugs.contains("radius-halved") {
                        radius / 2.0
                    } else {
                        *radius
                    },
                },
                Shape::Triangle { vertices } => Geo::Tri(Tri { v: *vertices, n: None }),
                Shape::Mesh {
                    source, offset, scale, ..
                } => {
                    let tris = read_obj(source, *offset, *scale, &bugs);
                    let centre =
                        tris.iter().flat_map(|t| t.v).fold(DVec3::ZERO, |a, v| a + v) / (3 * tris.len()).max(1) as f64;
                    let radius = tris
                        .iter()
                        .flat_map(|t| t.v)
                        .map(|v| (v - centre).length())
                        .fold(0.0, f64::max);
                    Geo::Mesh {
                        tris,
                        centre,
                        radius: radius * 1.001,
                    }
                }
            };
            objs.push(Obj {
                geo,
                kind: m.kind,
                color: m.color,
                ior: m.value,
                is_triangle: matches!(e.shape, Shape::Triangle { .. }),
            });
        }
        Student {
            objs,
            // Uncatalogued, `light-y-negated`: each light's y read with the wrong sign.
            lights: file
                .lights
                .iter()
                .map(|l| {
                    let y = if bugs.contains("light-y-negated") { -1.0 } else { 1.0 };
                    (l.position * DVec3::new(1.0, y, 1.0), l.color)
                })
                .collect(),
            bugs,
            opts,
        }
    }

    fn bug(&self, name: &str) -> bool {
        self.bugs.contains(name)
    }

    /// The picture, RGB8 from the top-left.
    pub fn render(&self) -> Vec<u8> {
        let (w, h, n) = (self.opts.width, self.opts.height, self.opts.aa);
        let mut out = Vec::with_capacity((w * h * 3) as usize);
        // Uncatalogued: the angle's tangent taken whole, not of its half.
        let tan = if self.bug("fov-not-halved") {
            self.opts.fov.to_radians().tan()
        } else if self.bug("fov-in-radians") {
            // Uncatalogued: the half angle in degrees given to a tangent that takes radians.
            (self.opts.fov / 2.0).tan()
        } else {
            (self.opts.fov.to_radians() / 2.0).tan()
        };
        let aspect = w as f64 / h as f64;
        let (sx, sy) = if self.bug("fov-vertical") {
            (tan * aspect, tan)
        } else if self.bug("aspect-ignored") {
            (tan, tan)
        } else {
            (tan, tan / aspect)
        };
        // Uncatalogued: System.Numerics' CreateFromAxisAngle takes radians.
        let angle = if self.bug("cam-angle-radians") {
            self.opts.cam_angle
        } else {
            self.opts.cam_angle.to_radians()
        };
        let k = self.opts.cam_axis.normalize();
        let turn = |v: DVec3| v * angle.cos() + k.cross(v) * angle.sin() + k * k.dot(v) * (1.0 - angle.cos());
        // The sum the student forgot to reset per pixel lives outside the loops.
        let mut total = DVec3::ZERO;
        for row in 0..h {
            let y = if self.bug("image-flipped") { h - 1 - row } else { row };
            for x in 0..w {
                let mut sum = if self.bug("accumulator-not-reset") {
                    total
                } else {
                    DVec3::ZERO
                };
                let mut rng = Rng(u64::from(y * w + x));
                for j in 0..n {
                    for i in 0..n {
                        // Uncatalogued, `aa-one-counter`: the inner loop's position taken from
                        // the outer loop's counter, so every sample lies on the diagonal.
                        let j = if self.bug("aa-one-counter") { i } else { j };
                        let (ox, oy) = self.offset(i, j, &mut rng);
                        let u = (x as f64 + ox + self.opts.shift[0]) / w as f64;
                        let v = (y as f64 + oy + self.opts.shift[1]) / h as f64;
                        let d = DVec3::new((2.0 * u - 1.0) * sx, (1.0 - 2.0 * v) * sy, 1.0).normalize();
                        sum += self.trace(
                            Ray {
                                o: DVec3::ZERO,
                                d: turn(d),
                            },
                            0,
                        );
                    }
                }
                total = sum;
                // Uncatalogued: the samples' sum divided by n, not by the n² samples.
                let count = if self.bug("samples-divided-by-n") { n } else { n * n };
                let mut c = sum / count as f64;
                // Uncatalogued: the colour made grey before it is written, as its luminance
                // (Rec. 709 weights) or as its red value in every channel (`new Color(c.r, c.r, c.r)`).
                if self.bug("luminance-written") {
                    c = DVec3::splat(c.dot(DVec3::new(0.2126, 0.7152, 0.0722)));
                }
                if self.bug("red-in-every-channel") {
                    c = DVec3::splat(c.x);
                }
                for v in [c.x, c.y, c.z] {
                    out.push(self.byte(v));
                }
            }
        }
        out
    }

    /// Where sample (`i`, `j`) sits in its pixel.
    fn offset(&self, i: u32, j: u32, rng: &mut Rng) -> (f64, f64) {
        let n = f64::from(self.opts.aa);
        let [c, e] = if self.bug("pixel-corners") {
            [0.0; 2]
        } else {
            self.opts.grid
        };
        let at = |k: u32| (f64::from(k) + c) / (n + e);
        match self.opts.jitter {
            None => (at(i), at(j)),
            Some(seed) if self.opts.jitter_in_cells => {
                ((f64::from(i) + rng.next(seed)) / n, (f64::from(j) + rng.next(seed)) / n)
            }
            Some(seed) => (rng.next(seed), rng.next(seed)),
        }
    }

    fn byte(&self, v: f64) -> u8 {
        let mut v = v.clamp(0.0, 1.0);
        if self.bug("gamma") {
            v = v.powf(1.0 / 2.2);
        }
        if self.bug("rounded-colours") {
            (v * 255.0).round() as u8
        } else {
            (v * 255.0) as u8
        }
    }

    fn trace(&self, ray: Ray, depth: u32) -> DVec3 {
        let Some(hit) = self.closest(ray, f64::INFINITY) else {
            return DVec3::ZERO;
        };
        let obj = &self.objs[hit.obj];
        if self.opts.stage1 {
            return obj.color;
        }
        let reversed = obj.is_triangle && self.bug("reversed-normals");
        let outside = hit.n.dot(ray.d) < 0.0;
        // Turn the normal towards the ray, unless the student trusts the winding.
        let n = if outside || reversed { hit.n } else { -hit.n };
        let ns = if outside || reversed { hit.shading } else { -hit.shading };
        // Uncatalogued: mirrors and glass not written yet, black.
        if self.bug("mirrors-and-glass-unwritten")
            && matches!(obj.kind, MaterialKind::Reflective | MaterialKind::Refractive)
        {
            return DVec3::ZERO;
        }
        match obj.kind {
            MaterialKind::Reflective => {
                if depth >= self.max_depth() {
                    return DVec3::ZERO;
                }
                // Uncatalogued: the reflection formula with its sign wrong, d + 2 (d · n) n.
                let r = if self.bug("reflect-sign") {
                    (ray.d + n * 2.0 * ray.d.dot(n)).normalize()
                } else {
                    self.reflect(ray.d, n)
                };
                // Uncatalogued: the reflected ray starts on the mirror (acne of the mirror's own
                // rays, not of shadows).
                let o = if self.bug("no-mirror-offset") {
                    hit.p
                } else {
                    hit.p + n * self.eps()
                };
                self.trace(Ray { o, d: r }, depth + 1)
            }
            MaterialKind::Refractive => {
                if depth >= self.max_depth() {
                    return DVec3::ZERO;
                }
                self.glass(ray, &hit, n, outside, obj.ior, depth)
            }
            _ => self.diffuse(&hit, n, ns, obj.color),
        }
    }

    /// How far rays leaving a surface start off it.
    fn eps(&self) -> f64 {
        self.opts.ray_offset.unwrap_or(EPS)
    }

    /// The student's one reflection function, for mirrors and glass.
    fn reflect(&self, d: DVec3, n: DVec3) -> DVec3 {
        if self.bug("reflect-no-2") {
            (d - n * d.dot(n)).normalize()
        } else {
            reflect(d, n)
        }
    }

    fn max_depth(&self) -> u32 {
        if self.bug("recursion-limit-3") {
            3
        } else {
            self.opts.max_depth
        }
    }

    /// Offsets along the surface's normal `n`, shades with the interpolated one `ns`.
    fn diffuse(&self, hit: &Hit, n: DVec3, ns: DVec3, color: DVec3) -> DVec3 {
        let origin = if self.bug("no-shadow-offset") {
            hit.p
        } else if self.bug("no-shadow-offset-single") {
            // Uncatalogued as such: no offset, with the distance kept in single precision (a
            // Unity `float`), so the point lies off the surface by up to about 1e-7 of the
            // distance, below it wherever rounding says: acne on other pixels than rayscope's.
            let single = f64::from(hit.t as f32);
            hit.p + hit.dir * (single - hit.t)
        } else if self.bug("huge-shadow-offset") {
            hit.p + n * 0.1
        } else if let Some(e) = self.opts.shadow_offset {
            hit.p + n * e
        } else {
            hit.p + n * self.eps()
        };
        let mut c = DVec3::ZERO;
        for (k, (pos, col)) in self.lights.iter().enumerate() {
            if k > 0 && self.bug("first-light-only") {
                break;
            }
            // Uncatalogued: the light's direction and distance taken from the shadow ray's
            // start, off the surface, instead of from the hit point.
            let to = *pos
                - if self.bug("light-from-shadow-origin") {
                    origin
                } else {
                    hit.p
                };
            let dist = to.length();
            let l = to / dist;
            let reach = if self.bug("shadow-past-light") {
                f64::INFINITY
            } else {
                dist
            };
            // The closest hit on the whole ray, nearer than the light: the template's way.
            // Uncatalogued, `shadows-from-spheres-only`: the shadow test loops over the spheres
            // alone.
            let blockers = |g: &Geo| !self.bug("shadows-from-spheres-only") || matches!(g, Geo::Sphere { .. });
            if self
                .closest_among(Ray { o: origin, d: l }, f64::INFINITY, &blockers)
                .is_some_and(|h| h.t < reach)
            {
                continue;
            }
            let cos = if self.bug("n-dot-l-unclamped") {
                ns.dot(l)
            } else {
                ns.dot(l).max(0.0)
            };
            // Uncatalogued: the light's colour left out, as if every light were white.
            let light = if self.bug("light-colour-ignored") {
                DVec3::ONE
            } else {
                *col
            };
            let mut add = color * light * cos;
            if self.bug("light-falloff") {
                add /= dist * dist;
            }
            c += add;
        }
        if self.bug("ambient-term") {
            c += color * 0.1;
        }
        // Uncatalogued: the lights' sum averaged instead of added.
        if self.bug("lights-averaged") {
            c /= self.lights.len().max(1) as f64;
        }
        c
    }

    fn glass(&self, ray: Ray, hit: &Hit, n: DVec3, outside: bool, ior: f64, depth: u32) -> DVec3 {
        // η = n instead of 1/n on the way in.
        let (n1, n2) = if outside && self.bug("eta-entering-inverted") {
            (ior, 1.0)
        } else if outside || self.bug("refraction-no-index-swap") {
            (1.0, ior)
        } else {
            (ior, 1.0)
        };
        // Without the flip, leaving the glass uses the outward normal.
        let n = if !outside && self.bug("refraction-no-normal-flip") {
            -n
        } else {
            n
        };
        let eta = n1 / n2;
        let cos_i = -ray.d.dot(n);
        let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
        let o = if self.bug("glass-reflection-along-ray") {
            hit.p + ray.d * self.eps()
        } else if self.bug("glass-reflection-outward") {
            hit.p + hit.n * self.eps()
        } else {
            hit.p + n * self.eps()
        };
        let reflected = Ray {
            o,
            d: self.reflect(ray.d, n),
        };
        if k < 0.0 {
            if self.bug("no-tir") {
                return DVec3::ZERO;
            }
            return self.trace(reflected, depth + 1);
        }
        let cos_t = k.sqrt();
        let ci = cos_i.abs();
        let kr = if let Some(c) = self.opts.fresnel_constant {
            c
        } else if self.bug("fresnel-one-plus-i-dot-n") {
            // Uncatalogued: (1 + I·N)² with the outward normal, as some students write it
            // (leaving the glass it is (1 + cos θi)², at least 1).
            (1.0 + ray.d.dot(hit.n)).powi(2)
        } else if self.bug("fresnel-one-plus-i-dot-n-facing") {
            // Uncatalogued: (1 + I·N)² with the normal facing the ray, (1 − cos θi)².
            (1.0 + ray.d.dot(n)).powi(2)
        } else if self.bug("no-fresnel") {
            0.0
        } else if self.bug("fresnel-half") {
            0.5
        } else if self.bug("schlick") {
            let r0 = ((n1 - n2) / (n1 + n2)).powi(2);
            let c = if n1 <= n2 { ci } else { cos_t };
            r0 + (1.0 - r0) * (1.0 - c).powi(5)
        } else {
            // Uncatalogued: cos θt taken to be cos θi in the Fresnel terms.
            let ct = if self.bug("cos-t-as-cos-i") { ci } else { cos_t };
            let rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct);
            let rp = if self.bug("fresnel-swapped") {
                (n2 * ct - n1 * ci) / (n2 * ct + n1 * ci)
            } else {
                (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct)
            };
            (rs * rs + rp * rp) / 2.0
        };
        // Uncatalogued: the refraction formula without its square root, which sends the ray
        // along the surface (its tangential part) instead of into the glass.
        let root = if self.bug("refraction-no-root") { 0.0 } else { cos_t };
        let t = (ray.d * eta + n * (eta * cos_i - root)).normalize();
        let side = if self.bug("refraction-offset-outside") {
            1.0
        } else {
            -1.0
        };
        let refracted = Ray {
            o: hit.p + n * (side * self.eps()),
            d: t,
        };
        // Uncatalogued: the two weights exchanged where the colours are mixed.
        let kr = if self.bug("fresnel-weights-exchanged") {
            1.0 - kr
        } else {
            kr
        };
        let mut c = self.trace(refracted, depth + 1) * (1.0 - kr);
        // Uncatalogued: the reflected ray left out where the glass also refracts (a reflection
        // "added later" and never added).
        if kr > 0.0 && !self.bug("glass-reflection-skipped") {
            c += self.trace(reflected, depth + 1) * kr;
        }
        c
    }

    /// The smallest t the student accepts.
    fn t_min(&self) -> f64 {
        if self.bug("min-hit-distance") {
            0.05
        } else {
            0.0
        }
    }

    /// The nearest hit below `t_max`; each entity's test rejects hits at or before `t_min`
    /// itself (the plane's, with `plane-hits-behind`, none).
    fn closest(&self, ray: Ray, t_max: f64) -> Option<Hit> {
        self.closest_among(ray, t_max, &|_| true)
    }

    /// [`Self::closest`] over the entities whose geometry `keep` accepts.
    fn closest_among(&self, ray: Ray, t_max: f64, keep: &dyn Fn(&Geo) -> bool) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        // Whether the student compares hits by their distance along the ray.
        let by_t = !self.bug("nearest-by-origin-distance") && !self.bug("first-hit-in-scene-order");
        for (i, obj) in self.objs.iter().enumerate().filter(|(_, o)| keep(&o.geo)) {
            let limit = if by_t {
                best.as_ref().map_or(t_max, |b| b.t)
            } else {
                t_max
            };
            let found = match &obj.geo {
                Geo::Plane { p, n } => {
                    let dn = ray.d.dot(*n);
                    let t = (*p - ray.o).dot(*n) / dn;
                    // Only d · n ≠ 0 checked: a hit behind the origin is accepted.
                    let ahead = t > self.t_min() || self.bug("plane-hits-behind");
                    (dn.abs() >= 1e-12 && ahead).then_some((t, *n, *n))
                }
                Geo::Sphere { c, r } => self.sphere(ray, *c, *r).map(|t| {
                    let n = if self.bug("sphere-normal-unnormalised") {
                        ray.o + ray.d * t - *c
                    } else {
                        (ray.o + ray.d * t - *c) / *r
                    };
                    (t, n, n)
                }),
                Geo::Tri(tri) => self.triangle(ray, tri, limit),
                Geo::Mesh { tris, centre, radius } => {
                    if sphere_touches(ray, *centre, *radius) {
                        let mut b: Option<(f64, DVec3, DVec3)> = None;
                        for tri in tris {
                            let lim = b.map_or(limit, |x| x.0);
                            if let Some(h) = self.triangle(ray, tri, lim) {
                                b = Some(h);
                            }
                        }
                        b
                    } else {
                        None
                    }
                }
            };
            if let Some((t, n, shading)) = found {
                let p = ray.o + ray.d * t;
                let better = match &best {
                    None => true,
                    Some(_) if by_t => true,
                    Some(b) if self.bug("nearest-by-origin-distance") => p.length() < b.p.length(),
                    Some(_) => false,
                };
                if t < limit && better {
                    best = Some(Hit {
                        t,
                        p: ray.o + ray.d * t,
                        n,
                        shading,
                        dir: ray.d,
                        obj: i,
                    });
                }
            }
        }
        best
    }

    /// The nearer root ahead of the ray, or none. Uncatalogued, `sphere-near-root-only`: the
    /// near root or nothing, so a ray from inside the sphere (through glass) misses it.
    /// `sphere-near-root-behind`: the near root whenever the far one lies ahead, so a ray from
    /// inside hits the sphere behind its origin. Uncatalogued, `sphere-b-not-doubled`: the
    /// quadratic's roots (−b ± √(b² − 4ac)) / 2a with b = d·(o − c) instead of 2 d·(o − c), so
    /// the discriminant is negative for every sphere a unit or more away: no sphere is hit.
    fn sphere(&self, ray: Ray, c: DVec3, r: f64) -> Option<f64> {
        let t_min = self.t_min();
        let oc = ray.o - c;
        let b = oc.dot(ray.d);
        if self.bug("sphere-b-not-doubled") {
            let disc = b * b - 4.0 * (oc.dot(oc) - r * r);
            let s = disc.sqrt();
            return [(-b - s) / 2.0, (-b + s) / 2.0]
                .into_iter()
                .find(|&t| disc >= 0.0 && t > t_min);
        }
        let disc = b * b - (oc.dot(oc) - r * r);
        if disc < 0.0 {
            return None;
        }
        let s = disc.sqrt();
        let t0 = -b - s;
        if t0 > t_min {
            return Some(t0);
        }
        if self.bug("sphere-near-root-only") {
            return None;
        }
        let t1 = -b + s;
        let near = if self.bug("sphere-near-root-behind") { t0 } else { t1 };
        (t1 > t_min).then_some(near)
    }

    /// Möller–Trumbore; returns t, the face normal and the shading normal (interpolated for
    /// meshes with normals).
    fn triangle(&self, ray: Ray, tri: &Tri, limit: f64) -> Option<(f64, DVec3, DVec3)> {
        let [a, b, c] = tri.v;
        let (e1, e2) = (b - a, c - a);
        let face = if self.bug("reversed-normals") && tri.n.is_none() {
            e2.cross(e1).normalize()
        } else if self.bug("triangle-normal-unnormalised") && tri.n.is_none() {
            // Uncatalogued: the cross product's length kept, so N·L grows with the triangle.
            e1.cross(e2)
        } else {
            e1.cross(e2).normalize()
        };
        if self.bug("one-sided-triangles") && ray.d.dot(face) >= 0.0 {
            return None;
        }
        let pv = ray.d.cross(e2);
        let det = e1.dot(pv);
        if det.abs() < 1e-14 {
            return None;
        }
        let inv = 1.0 / det;
        let tv = ray.o - a;
        let u = tv.dot(pv) * inv;
        let m = if self.bug("strict-edges") { 0.02 } else { 0.0 };
        if u < m || u > 1.0 - m {
            return None;
        }
        let qv = tv.cross(e1);
        let v = ray.d.dot(qv) * inv;
        if v < m || u + v > 1.0 - m {
            return None;
        }
        let t = e2.dot(qv) * inv;
        if t <= self.t_min() || t >= limit {
            return None;
        }
        let shading = match tri.n {
            Some([na, nb, nc]) if !self.bug("obj-flat-normals") => {
                let s = (na * (1.0 - u - v) + nb * u + nc * v).normalize();
                // Keep the interpolated normal on the face's side, as the course's renderer does.
                if s.dot(face) < 0.0 {
                    -s
                } else {
                    s
                }
            }
            _ => face,
        };
        Some((t, face, shading))
    }
}

fn reflect(d: DVec3, n: DVec3) -> DVec3 {
    (d - n * 2.0 * d.dot(n)).normalize()
}

fn sphere_touches(ray: Ray, c: DVec3, r: f64) -> bool {
    let oc = ray.o - c;
    let b = oc.dot(ray.d);
    let cc = oc.dot(oc) - r * r;
    cc <= 0.0 || (b <= 0.0 && b * b >= cc)
}

/// The student's OBJ reader: `v`, `vn` and `f` (any of the slash forms), fan-triangulated.
fn read_obj(path: &Path, offset: DVec3, scale: f64, bugs: &HashSet<&'static str>) -> Vec<Tri> {
    let text = std::fs::read_to_string(path).expect("the OBJ file the scene names");
    let flip = if bugs.contains("obj-no-z-flip") { 1.0 } else { -1.0 };
    let (mut vs, mut ns, mut tris) = (Vec::new(), Vec::new(), Vec::new());
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => {
                let c: Vec<f64> = it.take(3).map(|x| x.parse().unwrap()).collect();
                vs.push(DVec3::new(c[0] * scale, c[1] * scale, flip * c[2] * scale) + offset);
            }
            Some("vn") => {
                let c: Vec<f64> = it.take(3).map(|x| x.parse().unwrap()).collect();
                ns.push(DVec3::new(c[0], c[1], flip * c[2]).normalize());
            }
            Some("f") => {
                let corners: Vec<(usize, Option<usize>)> = it
                    .map(|c| {
                        let mut p = c.split('/');
                        let v = p.next().unwrap().parse::<usize>().unwrap() - 1;
                        let n = p.nth(1).and_then(|s| s.parse::<usize>().ok()).map(|k| k - 1);
                        (v, n)
                    })
                    .collect();
                for k in 1..corners.len() - 1 {
                    let idx = [corners[0], corners[k], corners[k + 1]];
                    let n = idx.iter().map(|c| c.1).collect::<Option<Vec<usize>>>();
                    tris.push(Tri {
                        v: idx.map(|c| vs[c.0]),
                        n: n.map(|n| [ns[n[0]], ns[n[1]], ns[n[2]]]),
                    });
                }
            }
            _ => {}
        }
    }
    tris
}

/// A pixel's random numbers (SplitMix64), the stream set by the pixel and the seed.
struct Rng(u64);

impl Rng {
    /// A number in [0, 1).
    fn next(&mut self, seed: u64) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0 ^ seed.wrapping_mul(0xd1b5_4a32_d192_ed03);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        (z ^ (z >> 31)) as f64 / 2f64.powi(64)
    }
}
