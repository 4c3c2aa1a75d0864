//! Camera rays against the checker's own camera for their pixel and sample: where a ray should
//! start and point, and which of the usual camera mistakes its direction fits.

use super::*;

/// A sample offset or image-plane half extents, with the mistake it stands for (none: rayscope's).
type Guess = ((f64, f64), Option<(Code, &'static str)>);

/// A position-and-projection guess for a camera ray.
#[derive(Debug, Clone, Copy)]
struct CamGuess {
    /// Offset of the sample in its pixel.
    off: (f64, f64),
    /// Half extents of the image plane (signs flip the image).
    half: (f64, f64),
    pos_code: Option<(Code, &'static str)>,
    proj_code: Option<(Code, &'static str)>,
}

/// The unit camera-space direction through image position (u, v) (0 to 1 across and down) of an
/// image plane at distance 1 with half extents `half`.
fn image_dir(u: f64, v: f64, half: (f64, f64)) -> DVec3 {
    DVec3::new((2.0 * u - 1.0) * half.0, (1.0 - 2.0 * v) * half.1, 1.0).normalize()
}

impl Judge<'_> {
    /// The camera ray against rayscope's camera for its pixel and sample.
    pub(super) fn camera(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        f: &mut Vec<Finding>,
        (shift, order): (&mut Shift, &mut SampleOrder),
    ) {
        let Some([x, y]) = r.pixel else {
            return;
        };
        if !self.pinhole {
            return;
        }
        let l = scale(&[r.origin, self.cam_origin]);
        if (r.origin - self.cam_origin).length() > self.tol.position * l {
            f.push(self.finding(
                r,
                kind,
                Code::CameraOrigin,
                format!(
                    "starts {:.3e} away from the camera",
                    (r.origin - self.cam_origin).length()
                ),
                vec![Value {
                    what: "origin".into(),
                    yours: vjson(r.origin),
                    rayscope: vjson(self.cam_origin),
                }],
            ));
            return;
        }
        if self.jitter {
            return;
        }
        let rs_dir = |s: u32| self.cam.ray(x, y, s).1;
        let d = r.direction;
        let candidates = match r.sample {
            Some(s) => s..s + 1,
            None => 0..self.spp,
        };
        let (s, err) = candidates
            .map(|s| (s, angle(d, rs_dir(s))))
            .fold((0, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a });
        // One sample a pixel has no other numbering.
        if let Some(s) = r.sample.filter(|_| self.grid > 1) {
            order.numbered((x, y), s, self.spp);
        }
        if err <= self.cam_tol {
            return;
        }
        if r.sample.is_some() {
            if let Some(cell) = (0..self.spp).find(|&k| angle(d, rs_dir(k)) <= self.cam_tol) {
                f.push(self.renumbered(r, kind, (x, y, s), cell, err, order));
                return;
            }
        }
        self.camera_wrong(r, kind, (x, y, s), err, f, shift);
    }

    /// Where rayscope puts sample `s` in its pixel, from (0, 0) at the top-left corner to (1, 1):
    /// the centre of cell (s mod N, s div N) of the N×N grid.
    fn cell_centre(&self, s: u32) -> (f64, f64) {
        let n = f64::from(self.grid);
        (
            (f64::from(s % self.grid) + 0.5) / n,
            (f64::from(s / self.grid) + 0.5) / n,
        )
    }

    /// The half extents of rayscope's image plane at distance 1, across and down.
    fn half_extents(&self) -> (f64, f64) {
        let (w, h) = (f64::from(self.settings.width), f64::from(self.settings.height));
        let t = (f64::from(self.settings.camera.fov_deg).to_radians() * 0.5).tan();
        let aspect = w / h;
        if self.settings.camera.fov_axis == FovAxis::Horizontal {
            (t, t / aspect)
        } else {
            (t * aspect, t)
        }
    }

    /// The verdict on a camera ray of pixel (x, y) numbered `s` that goes exactly where rayscope's
    /// sample `cell` goes, counted for the log-wide rule that decides whether it is a numbering.
    fn renumbered(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        (x, y, s): (u32, u32, u32),
        cell: u32,
        err: f64,
        order: &mut SampleOrder,
    ) -> Finding {
        let n = self.grid;
        let middle = n % 2 == 1 && cell == n * n / 2;
        order.add((x, y), s, cell, middle);
        let (at, own) = (self.cell_centre(cell), self.cell_centre(s));
        let through = if middle {
            "the centre of its pixel, ".to_string()
        } else {
            String::new()
        };
        let dc = (self.rot.transpose() * r.direction).normalize();
        let rs = self.cam.ray(x, y, s).1;
        let (_, _, values) = self.camera_values(r.direction, rs, dc, self.half_extents(), (x, y, own));
        self.finding(
            r,
            kind,
            Code::CameraSampleOrder,
            format!(
                "{:.4}° off; it goes through {through}({:.3}, {:.3}) of the way across and down its pixel: the centre of cell ({}, {}) of the {n}×{n} grid, where rayscope puts sample {cell}; rayscope puts sample {s} at ({:.3}, {:.3})",
                err.to_degrees(),
                at.0,
                at.1,
                cell % n,
                cell / n,
                own.0,
                own.1
            ),
            values,
        )
    }

    /// Names what a camera ray `err` radians off rayscope's sample `s` of pixel (x, y) fits: one
    /// of the usual camera mistakes, another distance to the image plane, another pixel, or none.
    fn camera_wrong(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        (x, y, s): (u32, u32, u32),
        err: f64,
        f: &mut Vec<Finding>,
        shift: &mut Shift,
    ) {
        let d = r.direction;
        let rs = self.cam.ray(x, y, s).1;
        let dc = (self.rot.transpose() * d).normalize();
        let (w, h) = (f64::from(self.settings.width), f64::from(self.settings.height));
        let t = (f64::from(self.settings.camera.fov_deg).to_radians() * 0.5).tan();
        let aspect = w / h;
        let horizontal = self.settings.camera.fov_axis == FovAxis::Horizontal;
        let half = self.half_extents();
        let offs = self.sample_offsets(s);
        let projs = self.projections(half, t, aspect, horizontal);
        let dir_of = |g: &CamGuess| image_dir((f64::from(x) + g.off.0) / w, (f64::from(y) + g.off.1) / h, g.half);
        let mut best: Option<(f64, CamGuess)> = None;
        for &(off, pc) in &offs {
            for &(hh, qc) in &projs {
                if pc.is_none() && qc.is_none() {
                    continue;
                }
                let g = CamGuess {
                    off,
                    half: hh,
                    pos_code: pc,
                    proj_code: qc,
                };
                let e = angle(dir_of(&g), dc);
                if best.is_none_or(|(b, _)| e < b) {
                    best = Some((e, g));
                }
            }
        }
        let (us, vs, values) = self.camera_values(d, rs, dc, half, (x, y, offs[0].0));
        shift.add(
            us * w - f64::from(x) - offs[0].0 .0,
            vs * h - f64::from(y) - offs[0].0 .1,
        );
        let off_by = format!("{:.4}° off", err.to_degrees());
        if let Some((_, g)) = best.filter(|(e, _)| *e <= self.cam_tol) {
            for (code, why) in [g.pos_code, g.proj_code].into_iter().flatten() {
                f.push(self.finding(
                    r,
                    kind,
                    code,
                    format!("{off_by}; it fits a camera ray {why}"),
                    values.clone(),
                ));
            }
            return;
        }
        // The pixel's column and row exchanged: (x, y) cast through where (y, x) goes.
        let (ox, oy) = offs[0].0;
        let swapped = image_dir((f64::from(y) + oy) / w, (f64::from(x) + ox) / h, half);
        if x != y && angle(swapped, dc) <= self.cam_tol {
            f.push(self.finding(
                r,
                kind,
                Code::CameraTransposed,
                format!(
                    "{off_by}; it goes through pixel ({y}, {x}) instead of ({x}, {y}): its column and row exchanged"
                ),
                values,
            ));
            return;
        }
        if let Some(detail) = self.turned(
            d,
            dir_of(&CamGuess {
                off: offs[0].0,
                half,
                pos_code: None,
                proj_code: None,
            }),
        ) {
            f.push(self.finding(r, kind, Code::CameraRotation, format!("{off_by}; {detail}"), values));
            return;
        }
        if dc.z <= 0.0 {
            f.push(self.finding(
                r,
                kind,
                Code::CameraDirection,
                "points backwards, away from the image plane: the course's camera looks along +z".into(),
                values,
            ));
            return;
        }
        // A uniformly scaled image plane: another distance to the plane, or another FOV.
        let p = dir_of(&CamGuess {
            off: offs[0].0,
            half,
            pos_code: None,
            proj_code: None,
        });
        let (px, py) = ((us * w).floor(), (vs * h).floor());
        let own_pixel = px == f64::from(x) && py == f64::from(y);
        if let Some(k) = self.plane_scale(p, dc) {
            let tan = if horizontal { half.0 } else { half.1 };
            let fov_deg = self.settings.camera.fov_deg;
            let detail = if k < 0.0 {
                // A negative half-width turns the picture half a turn: the tangent of an angle in
                // degrees taken as radians is one way to get it.
                let as_radians = (f64::from(fov_deg) / 2.0).tan();
                let why = if ((k * tan - as_radians) / as_radians).abs() < 1e-3 {
                    format!(
                        ": tan({}) with {} read as radians, as Math.Tan reads it; convert the half angle to radians (× π / 180) first",
                        fov_deg / 2.0,
                        fov_deg / 2.0
                    )
                } else {
                    String::new()
                };
                format!(
                    "{off_by}; it fits an image plane whose half-width is {:.4} instead of tan({}°) = {tan:.4}, a negative size that turns the picture half a turn{why}",
                    k * tan,
                    fov_deg / 2.0
                )
            } else {
                format!(
                    "{off_by}; it fits an image plane at distance {:.4} instead of 1 (or a field of view of {:.2}° instead of {fov_deg}°)",
                    1.0 / k,
                    (2.0 * (k * tan).atan()).to_degrees()
                )
            };
            if own_pixel && self.grid > 1 {
                // A ray a fraction of a pixel from its sample's place fits a slightly scaled
                // image plane as well as another sub-pixel layout: both are named, and the log
                // as a whole decides (`Tally::layout_or_plane`).
                let layout = self.where_in_pixel(s, (us * w - px, vs * h - py));
                f.push(self.finding(
                    r,
                    kind,
                    Code::CameraSubpixelGrid,
                    format!(
                        "{off_by}; {layout}; it also fits an image plane at distance {:.4} instead of 1",
                        1.0 / k
                    ),
                    values.clone(),
                ));
            }
            f.push(self.finding(r, kind, Code::CameraPlaneDistance, detail, values));
            return;
        }
        let detail = if own_pixel {
            let at = (us * w - px, vs * h - py);
            let detail = self.where_in_pixel(s, at);
            f.push(self.finding(r, kind, Code::CameraSubpixelGrid, format!("{off_by}; {detail}"), values));
            return;
        } else if px.is_finite() {
            format!("{off_by}; it passes through pixel ({px}, {py}) of rayscope's image instead of ({x}, {y})")
        } else {
            off_by
        };
        f.push(self.finding(r, kind, Code::CameraDirection, detail, values));
    }

    /// Where in pixel (x, y) a camera ray of sample `s` that passes through it goes, beside where
    /// rayscope puts the sample. `at` is where it crosses the pixel, from (0, 0) at its top-left
    /// corner to (1, 1). (A ray through the centre of another cell of the N×N grid is
    /// [`Self::renumbered`]'s.)
    fn where_in_pixel(&self, s: u32, at: (f64, f64)) -> String {
        let expected = self.cell_centre(s);
        format!(
            "it crosses its pixel at ({:.3}, {:.3}) of the way across and down, where rayscope puts sample {s} at ({:.3}, {:.3}) (random jitter, or a sub-pixel layout rayscope does not know)",
            at.0, at.1, expected.0, expected.1
        )
    }

    /// For a camera turned by `--cam-angle`: whether direction `d` is the unturned camera's `p`
    /// turned about the same axis by another angle, and which (said as the flags' angle read as
    /// radians where it is that).
    fn turned(&self, d: DVec3, p: DVec3) -> Option<String> {
        let cam = &self.settings.camera;
        let k = cam.axis.as_dvec3().normalize_or_zero();
        if cam.angle_deg == 0.0 || k == DVec3::ZERO {
            return None;
        }
        // A turn about k keeps the part along k and turns the rest by θ.
        let (pp, dp) = (p - k * k.dot(p), d - k * k.dot(d));
        if pp.length() < 1e-9 || dp.length() < 1e-9 {
            return None;
        }
        let theta = k.dot(pp.cross(dp)).atan2(pp.dot(dp));
        let turned = DMat3::from_axis_angle(k, theta) * p;
        if angle(turned, d) > self.cam_tol {
            return None;
        }
        let flags = f64::from(cam.angle_deg);
        let wrap = |a: f64| (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
        let deg = theta.to_degrees();
        Some(if wrap(theta - flags).abs() < 1e-4 {
            format!(
                "it fits the camera turned by {flags} radians ({deg:.2}° as a turn) about the axis: --cam-angle {flags} read as radians, not degrees"
            )
        } else {
            format!("it fits the camera turned by {deg:.2}° about the axis instead of {flags}°")
        })
    }

    /// The values shown beside a wrong camera ray: its direction and where it crosses rayscope's
    /// image plane (u, v), against rayscope's for pixel (x, y) at sample offset `off`.
    fn camera_values(
        &self,
        d: DVec3,
        rs: DVec3,
        dc: DVec3,
        half: (f64, f64),
        (x, y, (ox, oy)): (u32, u32, (f64, f64)),
    ) -> (f64, f64, Vec<Value>) {
        let (w, h) = (f64::from(self.settings.width), f64::from(self.settings.height));
        // Where the tracer's ray crosses rayscope's image plane.
        let (us, vs) = if dc.z > 0.0 {
            ((dc.x / dc.z / half.0 + 1.0) * 0.5, (1.0 - dc.y / dc.z / half.1) * 0.5)
        } else {
            (f64::NAN, f64::NAN)
        };
        let rs_uv = ((f64::from(x) + ox) / w, (f64::from(y) + oy) / h);
        let values = vec![
            Value {
                what: "direction".into(),
                yours: vjson(d),
                rayscope: vjson(rs),
            },
            Value {
                what: "image position (u, v)".into(),
                yours: if us.is_finite() {
                    json!([(us * 1e6).round() / 1e6, (vs * 1e6).round() / 1e6])
                } else {
                    json!("behind the camera")
                },
                rayscope: json!([(rs_uv.0 * 1e6).round() / 1e6, (rs_uv.1 * 1e6).round() / 1e6]),
            },
        ];
        (us, vs, values)
    }

    /// The factor `k` by which rayscope's image-plane direction `p` is scaled across the image
    /// to give the tracer's camera-space direction `dc`, when such a scaling fits it and is not 1:
    /// the image plane at distance 1/k, or another field of view.
    fn plane_scale(&self, p: DVec3, dc: DVec3) -> Option<f64> {
        let (xr, yr) = (p.x / p.z, p.y / p.z);
        let (xs, ys) = (dc.x / dc.z, dc.y / dc.z);
        let k = (xs * xr + ys * yr) / (xr * xr + yr * yr).max(1e-300);
        let fit = DVec3::new(k * xr, k * yr, 1.0).normalize();
        ((k - 1.0).abs() > 1e-4 && k != 0.0 && angle(fit, dc) <= self.cam_tol).then_some(k)
    }

    /// Where sample `s` lies in its pixel by rayscope's grid, and where the usual mistakes put it.
    fn sample_offsets(&self, s: u32) -> Vec<Guess> {
        let n = f64::from(self.grid);
        let (i, j) = (f64::from(s % self.grid), f64::from(s / self.grid));
        let mut offs: Vec<Guess> = vec![
            (self.cell_centre(s), None),
            (
                (i / n, j / n),
                Some((
                    Code::CameraPixelCorner,
                    if self.grid == 1 {
                        "through the top-left corner of its pixel, x / width, not its centre, (x + 0.5) / width"
                    } else {
                        "through the top-left corner of its sub-pixel cell, (x + i / N) / width, not the cell's centre, (x + (i + 0.5) / N) / width"
                    },
                )),
            ),
        ];
        if self.grid > 1 {
            offs.push((
                (i / (n - 1.0), j / (n - 1.0)),
                Some((
                    Code::CameraSubpixelGrid,
                    "on a grid that spans the pixel's corners instead of cell centres",
                )),
            ));
            // After the cell corners, which take the samples where the two coincide (sample 0 at
            // the pixel's corner, the cell whose corner is the pixel's centre): the log as a
            // whole tells the two apart (`Tally::one_point_or_corners`).
            offs.push((
                (0.5, 0.5),
                Some((
                    Code::CameraOnePoint,
                    "through the centre of its pixel, (x + 0.5) / width, with no sub-pixel offset for its sample",
                )),
            ));
            offs.push((
                (0.0, 0.0),
                Some((
                    Code::CameraOnePoint,
                    "through the top-left corner of its pixel, x / width, with no sub-pixel offset for its sample",
                )),
            ));
        }
        offs
    }

    /// The image plane's half extents `half` (from `t` = tan(fov/2), the image's `aspect` and
    /// whether the FOV is `horizontal`), and what the usual mistakes make of them.
    fn projections(&self, half: (f64, f64), t: f64, aspect: f64, horizontal: bool) -> Vec<Guess> {
        let mut projs: Vec<Guess> = vec![(half, None)];
        if self.settings.width != self.settings.height {
            let swapped = if horizontal { (t * aspect, t) } else { (t, t / aspect) };
            projs.push((
                swapped,
                Some((
                    Code::CameraFovAxis,
                    if horizontal {
                        "with a vertical field of view: the 60° spans the image height instead of its width"
                    } else {
                        "with a horizontal field of view where --fov-axis vertical was asked for"
                    },
                )),
            ));
            projs.push((
                (t, t),
                Some((
                    Code::CameraAspect,
                    "with the aspect ratio ignored: a square image plane on a non-square image",
                )),
            ));
            let inverted = if horizontal { (t, t * aspect) } else { (t / aspect, t) };
            projs.push((
                inverted,
                Some((
                    Code::CameraAspect,
                    "with the aspect ratio the wrong way round (height / width instead of width / height)",
                )),
            ));
        }
        projs.push((
            (half.0, -half.1),
            Some((Code::CameraFlipped, "with the image upside down (row 0 at the bottom)")),
        ));
        projs.push((
            (-half.0, half.1),
            Some((Code::CameraFlipped, "with the image mirrored left to right")),
        ));
        projs
    }
}
