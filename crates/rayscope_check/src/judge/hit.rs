//! What a ray met against what the oracle finds: missed and phantom hits, the wrong surface or
//! distance, self-intersection, ties at edges, and the normal logged at the hit.

use super::*;

impl Judge<'_> {
    /// A `from`/`to` segment's end as a claimed hit, when it lies on a surface of the scene.
    pub(super) fn segment_claim(&self, r: &LoggedRay, end: DVec3, t_max: f64) -> Option<Answer<HitClaim>> {
        let len = r.dir_len;
        let l = scale(&[r.origin, end]);
        let w = self.tol.position * l;
        if len > t_max {
            return None;
        }
        self.trace(r.origin, r.direction, (len - w).max(0.0), len + w, r.origin)
            .map(|_| {
                Answer::Found(HitClaim {
                    t: Some(1.0),
                    point: Some(end),
                    normal: None,
                    entity: None,
                })
            })
    }

    /// The entity a hit logged without a name lies on: rayscope's own where the point lies on
    /// it with the logged normal (either way round), else the one surface that holds the point
    /// and, where several do (a corner of the box), the one whose normal is the logged one.
    /// `None` where no surface holds it, or more than one does indistinguishably.
    pub(super) fn entity_at(&self, r: &LoggedRay, c: &HitClaim, rs: Option<&RsHit>) -> Option<u32> {
        let p = c
            .point
            .or_else(|| c.t.map(|t| r.origin + r.direction * (t * r.dir_len)))?;
        let tol = self.tol.position * scale(&[r.origin, p]);
        let fits = |prim: PrimRef| {
            c.normal.is_none_or(|n| {
                let n = n.normalize_or_zero();
                let own = self.geo.own_normal(prim, p);
                let shading = self.geo.shading_normal(prim, p).unwrap_or(own);
                [own, shading]
                    .iter()
                    .any(|s| angle(*s, n).min(angle(-*s, n)) <= self.tol.normal)
            })
        };
        let on = |e: u32| {
            let (dist, prim) = self.geo.entity_distance(e, p);
            prim.filter(|_| dist <= tol)
        };
        if let Some(h) = rs {
            if on(h.entity).is_some_and(fits) {
                return Some(h.entity);
            }
        }
        let holding: Vec<(u32, PrimRef)> = (0..self.scene.entities.len() as u32)
            .filter_map(|e| on(e).map(|prim| (e, prim)))
            .collect();
        if let [(e, _)] = holding[..] {
            return Some(e);
        }
        match holding.iter().filter(|(_, prim)| fits(*prim)).collect::<Vec<_>>()[..] {
            [(e, _)] => Some(*e),
            _ => None,
        }
    }

    /// The tracer's hit (or miss) against rayscope's.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn hit(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        claim: Answer<HitClaim>,
        rs: Option<&RsHit>,
        leave: Option<&Leave>,
        f: &mut Vec<Finding>,
        tally: &mut Tally,
    ) {
        let (o, d) = (r.origin, r.direction);
        let hit_values = |ts, ps, es| self.hit_values(rs, ts, ps, es);
        let c = match claim {
            Answer::NotLogged => return,
            Answer::Nothing => {
                if let Some(h) = rs {
                    self.reported_nothing(r, kind, h, f, tally);
                }
                return;
            }
            Answer::Found(c) => c,
        };
        let ts = c.t.map(|t| t * r.dir_len).or_else(|| c.point.map(|p| (p - o).dot(d)));
        let Some(ts) = ts else {
            // Only an entity (or a normal): judge the entity.
            if let (Some(e), Some(h)) = (c.entity, rs) {
                if e != h.entity {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::HitFarther,
                        format!(
                            "your tracer names '{}' but the nearest hit is '{}' at t = {:.6}",
                            self.name(e),
                            self.name(h.entity),
                            h.t
                        ),
                        hit_values(None, None, Some(e)),
                    ));
                }
            }
            return;
        };
        let ps = c.point.unwrap_or(o + d * ts);
        let l = scale(&[o, ps]);
        let pos = self.tol.position * l;
        let v = || hit_values(Some(ts), Some(ps), c.entity);
        if let (Some(p), Some(t)) = (c.point, c.t) {
            let on_ray = o + d * (t * r.dir_len);
            if (p - on_ray).length() > pos {
                f.push(self.finding(
                    r,
                    kind,
                    Code::HitPointOffRay,
                    format!(
                        "the point is {:.3e} from origin + t · direction (t = {t})",
                        (p - on_ray).length()
                    ),
                    vec![Value {
                        what: "point".into(),
                        yours: vjson(p),
                        rayscope: vjson(on_ray),
                    }],
                ));
                return;
            }
        }
        if ts < -pos {
            f.push(self.finding(
                r,
                kind,
                Code::HitBehindOrigin,
                format!("t = {ts:.6} is behind the ray's origin"),
                v(),
            ));
            return;
        }
        // Self-intersection: the surface the ray leaves, at t ≈ 0.
        if let Some(lv) = leave {
            let same = c.entity.map_or((ps - lv.point).length() <= pos, |e| e == lv.entity);
            let genuine = rs.is_some_and(|h| h.entity == lv.entity && h.t <= pos);
            let sigma = (o - lv.point).dot(lv.facing);
            let heading = d.dot(lv.facing);
            // From an origin offset the way the ray goes, the surface it leaves lies behind it:
            // a hit there at t clearly below 0 is a root behind the origin that the intersection
            // test accepted, not rounding.
            if same && ts < -SURFACE_ROUNDING * l && sigma * heading > 0.0 {
                f.push(self.finding(
                    r,
                    kind,
                    Code::HitBehindOrigin,
                    format!(
                        "it hits '{}', the surface it leaves, at t = {ts:.2e}, behind its origin, which is correctly offset {:.2e} off that surface: the intersection test accepted a root behind the ray (for a sphere, the near root of a ray that starts inside it)",
                        self.name(lv.entity),
                        sigma.abs()
                    ),
                    v(),
                ));
                return;
            }
            if same && ts <= pos && !genuine {
                let code = if *kind == Kind::Shadow {
                    Code::ShadowAcne
                } else {
                    // Which side of the surface the origin lies on, however little off it: the
                    // log-wide decision between acne and an offset to the wrong side.
                    if sigma * heading < 0.0 {
                        tally.acne_wrong_side += 1;
                        tally.acne_wrong_side_far += u64::from(sigma.abs() > T_ROUNDING * l);
                    } else {
                        tally.acne_other += 1;
                    }
                    Code::SecondaryAcne
                };
                f.push(self.finding(r, kind, code, self.acne_detail(r, lv, ts), v()));
                return;
            }
        }
        self.against_oracle(r, kind, &c, (ts, ps), (rs, leave), f, tally);
    }

    /// The tracer's entity, distance and point beside the oracle's, for a verdict on a hit.
    fn hit_values(&self, rs: Option<&RsHit>, ts: Option<f64>, ps: Option<DVec3>, es: Option<u32>) -> Vec<Value> {
        let mut v = vec![Value {
            what: "entity".into(),
            yours: es.map_or(
                if ps.is_some() || ts.is_some() {
                    json!("(not logged)")
                } else {
                    json!("nothing")
                },
                |e| json!(self.name(e)),
            ),
            rayscope: rs.map_or(json!("nothing"), |h| json!(self.name(h.entity))),
        }];
        if ts.is_some() || rs.is_some() {
            v.push(Value {
                what: "t".into(),
                yours: ts.map_or(json!(null), njson),
                rayscope: rs.map_or(json!(null), |h| njson(h.t)),
            });
        }
        if ps.is_some() || rs.is_some() {
            v.push(Value {
                what: "point".into(),
                yours: ps.map_or(json!(null), vjson),
                rayscope: rs.map_or(json!(null), |h| vjson(h.point)),
            });
        }
        v
    }

    /// The tracer reports no hit where the oracle finds `h`.
    fn reported_nothing(&self, r: &LoggedRay, kind: &Kind, h: &RsHit, f: &mut Vec<Finding>, tally: &mut Tally) {
        let before = f.len();
        self.reported_nothing_verdict(r, kind, h, f, tally);
        self.passed_over(&f[before..], h.t, || None, &mut tally.skipped);
    }

    /// [`Self::reported_nothing`]'s verdict on the ray alone.
    fn reported_nothing_verdict(&self, r: &LoggedRay, kind: &Kind, h: &RsHit, f: &mut Vec<Finding>, tally: &mut Tally) {
        let (o, d) = (r.origin, r.direction);
        let hit_values = |ts, ps, es| self.hit_values(Some(h), ts, ps, es);
        let m = self.geo.margin(h.prim, o, d, h.point);
        let l = scale(&[o, h.point]);
        let v = hit_values(None, None, None);
        if is_tie(m, self.tol.tie, l) {
            f.push(self.finding(
                r,
                kind,
                Code::TieGrazing,
                format!("passes {m:.2e} from the edge of '{}'", self.name(h.entity)),
                v,
            ));
        } else if let Some(share) = self.triangle_miss(h, tally) {
            f.push(self.finding(r, kind, Code::HitTriangleEdge, self.edge_detail(h, share, "trace"), v));
        } else if matches!(h.prim, PrimRef::Triangle(_)) && !h.front {
            f.push(self.finding(
                r,
                kind,
                Code::HitOneSidedTriangle,
                format!(
                    "rayscope hits the back face of triangle '{}' at t = {:.6}; your tracer reports no hit",
                    self.name(h.entity),
                    h.t
                ),
                v,
            ));
        } else {
            f.push(self.finding(
                r,
                kind,
                Code::HitMissed,
                format!(
                    "rayscope hits '{}' at t = {:.6}; your tracer reports no hit",
                    self.name(h.entity),
                    h.t
                ),
                v,
            ));
        }
    }

    /// A hit the tracer reports (at `ts`, point `ps`) that is not on the surface it leaves,
    /// against the oracle's nearest hit `rs`.
    #[allow(clippy::too_many_arguments)]
    fn against_oracle(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        c: &HitClaim,
        (ts, ps): (f64, DVec3),
        (rs, leave): (Option<&RsHit>, Option<&Leave>),
        f: &mut Vec<Finding>,
        tally: &mut Tally,
    ) {
        let (o, d) = (r.origin, r.direction);
        let l = scale(&[o, ps]);
        let pos = self.tol.position * l;
        let v = || self.hit_values(rs, Some(ts), Some(ps), c.entity);
        let Some(h) = rs else {
            let on = c.entity.map(|e| self.geo.entity_distance(e, ps));
            if let Some((dist, Some(prim))) = on {
                if dist <= pos && is_tie(self.geo.margin(prim, o, d, ps), self.tol.tie, l) {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::TieGrazing,
                        format!("the ray grazes the edge of '{}'", self.name(c.entity.unwrap_or(0))),
                        v(),
                    ));
                    return;
                }
            }
            let mut x = self.finding(
                r,
                kind,
                Code::HitPhantom,
                format!(
                    "your tracer reports {} at t = {ts:.6}; rayscope's trace of this ray hits nothing",
                    c.entity.map_or("a hit".to_string(), |e| format!("'{}'", self.name(e)))
                ),
                v(),
            );
            self.past_an_edge(&mut x, ps, pos);
            f.push(x);
            return;
        };
        let cos = h.own.dot(d).abs().max(1e-3);
        let same_t = (ts - h.t).abs() <= pos / cos;
        let same_entity = c.entity.is_none_or(|e| e == h.entity);
        if same_entity && same_t {
            tally.skipped.kept_min_t = tally.skipped.kept_min_t.min(h.t);
            self.walk_agreeing(r, h, pos / cos, &mut tally.skipped);
            if let Some(n) = c.normal {
                self.normal(r, kind, n, h, f, tally);
            }
            return;
        }
        let l2 = scale(&[o, ps, h.point]);

        if !same_entity {
            let e = c.entity.unwrap_or(h.entity);
            let (dist, prim) = self.geo.entity_distance(e, ps);
            if same_t && dist <= pos {
                f.push(self.finding(
                    r,
                    kind,
                    Code::TieEdge,
                    format!(
                        "'{}' and '{}' meet where the ray hits, at the same distance",
                        self.name(e),
                        self.name(h.entity)
                    ),
                    v(),
                ));
                return;
            }
            if ts < h.t {
                if dist <= pos && prim.is_some_and(|p| is_tie(self.geo.margin(p, o, d, ps), self.tol.tie, l2)) {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::TieGrazing,
                        format!("the ray grazes the edge of '{}'", self.name(e)),
                        v(),
                    ));
                } else {
                    let mut x = self.finding(
                        r,
                        kind,
                        Code::HitPhantom,
                        format!(
                            "your tracer reports '{}' at t = {ts:.6}, but {} there; rayscope's nearest hit is '{}' at t = {:.6}{}",
                            self.name(e),
                            if dist <= pos { "the ray misses it" } else { "it is not" },
                            self.name(h.entity),
                            h.t,
                            self.unit_sphere_note(r, e, Some(ts), pos)
                        ),
                        v(),
                    );
                    self.past_an_edge(&mut x, ps, pos);
                    f.push(x);
                }
                return;
            }
        } else if ts < h.t && c.entity.is_none() {
            let mut x = self.finding(
                r,
                kind,
                Code::HitPhantom,
                format!(
                    "your tracer reports a hit at t = {ts:.6}; rayscope's nearest is '{}' at t = {:.6}",
                    self.name(h.entity),
                    h.t
                ),
                v(),
            );
            self.past_an_edge(&mut x, ps, pos);
            f.push(x);
            return;
        }
        self.beyond_nearest(r, kind, c, (ts, ps), h, leave, f, tally);
    }

    /// Where a hit `p` that nothing holds lies in the plane of a triangle (within `pos`) just
    /// outside it, says so in `x` and makes that triangle's entity what `x` is about. Models are
    /// left out: every wrong ray would then search all their triangles.
    fn past_an_edge(&self, x: &mut Finding, p: DVec3, pos: f64) {
        let near = (0..self.scene.entities.len() as u32)
            .filter(|&e| self.geo.prims(e).len() <= FEW_TRIANGLES)
            .flat_map(|e| self.geo.prims(e).iter().map(move |&q| (e, q)))
            .filter(|&(_, q)| matches!(q, PrimRef::Triangle(_)) && self.geo.distance_to_plane(q, p) <= pos)
            .filter_map(|(e, q)| self.geo.edge_share(q, p).map(|s| (e, s)))
            .filter(|&(_, s)| (-1.0..0.0).contains(&s))
            .max_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((e, share)) = near {
            x.detail.push_str(&format!(
                "; the point lies in the plane of triangle '{}', outside the triangle by {:.1} % of its height: an inside test that lets points past an edge through gives it",
                self.name(e),
                -share * 100.0
            ));
            x.entity = Some(e);
        }
    }

    /// The tracer's hit lies beyond the oracle's nearest one, `h`.
    #[allow(clippy::too_many_arguments)]
    fn beyond_nearest(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        c: &HitClaim,
        (ts, ps): (f64, DVec3),
        h: &RsHit,
        leave: Option<&Leave>,
        f: &mut Vec<Finding>,
        tally: &mut Tally,
    ) {
        let l = scale(&[r.origin, ps, h.point]);
        let v = || self.hit_values(Some(h), Some(ts), Some(ps), c.entity);
        let before = f.len();
        self.beyond_nearest_verdict(r, kind, c, (ts, h), leave, f, tally, l, &v);
        // A hit on the nearest surface itself, short of where the ray meets it, passes nothing
        // over: its distance is wrong, not the choice among hits.
        if !(c.entity == Some(h.entity) && ts < h.t) {
            // A hit point on the edge two entities share names neither: it fits either order.
            let kept = || {
                Some(Kept {
                    earlier: c.entity.is_none_or(|e| e < h.entity),
                    later: c.entity.is_none_or(|e| e > h.entity),
                    nearer: ps.length() < h.point.length(),
                })
            };
            self.passed_over(&f[before..], h.t, kept, &mut tally.skipped);
        }
    }

    /// [`Self::beyond_nearest`]'s verdict on the ray alone.
    #[allow(clippy::too_many_arguments)]
    fn beyond_nearest_verdict(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        c: &HitClaim,
        (ts, h): (f64, &RsHit),
        leave: Option<&Leave>,
        f: &mut Vec<Finding>,
        tally: &mut Tally,
        l: f64,
        v: &dyn Fn() -> Vec<Value>,
    ) {
        let (o, d) = (r.origin, r.direction);
        // The tracer's hit lies beyond rayscope's nearest one.
        if c.entity == Some(h.entity) {
            f.push(self.finding(
                r,
                kind,
                Code::HitWrongT,
                format!(
                    "'{}' is hit at t = {:.6}, your tracer says t = {ts:.6}{}",
                    self.name(h.entity),
                    h.t,
                    self.unit_sphere_note(r, h.entity, Some(ts), self.tol.position * l)
                ),
                v(),
            ));
        } else if is_tie(self.geo.margin(h.prim, o, d, h.point), self.tol.tie, l) {
            f.push(self.finding(
                r,
                kind,
                Code::TieGrazing,
                format!("the ray grazes the edge of '{}'", self.name(h.entity)),
                v(),
            ));
        } else if let Some(share) = self.triangle_miss(h, tally) {
            f.push(self.finding(
                r,
                kind,
                Code::HitTriangleEdge,
                format!(
                    "{}, before the hit it reports at t = {ts:.6}",
                    self.edge_detail(h, share, "trace")
                ),
                v(),
            ));
        } else if matches!(h.prim, PrimRef::Triangle(_)) && !h.front {
            f.push(self.finding(
                r,
                kind,
                Code::HitOneSidedTriangle,
                format!(
                    "the ray passes through the back face of triangle '{}' at t = {:.6} before the hit your tracer reports",
                    self.name(h.entity),
                    h.t
                ),
                v(),
            ));
        } else if leave.is_some_and(|lv| lv.entity == h.entity && d.dot(lv.facing) < 0.0) {
            f.push(self.finding(
                r,
                kind,
                Code::HitMissedFromInside,
                format!(
                    "the ray goes into '{}', the entity it leaves, and meets its far side at t = {:.6}; your tracer passed it by and reports a hit at t = {ts:.6}",
                    self.name(h.entity),
                    h.t
                ),
                v(),
            ));
        } else {
            f.push(self.finding(
                r,
                kind,
                Code::HitFarther,
                format!(
                    "'{}' at t = {:.6} is nearer than the hit your tracer reports at t = {ts:.6}{}",
                    self.name(h.entity),
                    h.t,
                    self.unit_sphere_note(r, h.entity, None, 0.0)
                ),
                v(),
            ));
        }
    }

    /// What a sphere test that takes ray `r`'s logged direction as a unit vector (a = d·d = 1)
    /// finds on entity `e`, when that direction is not unit length and `e` is a sphere:
    /// `Some(Some(t))` its nearest root ahead, in the oracle's distances, `Some(None)` a miss.
    fn unit_sphere_root(&self, r: &LoggedRay, e: u32) -> Option<Option<f64>> {
        let &[PrimRef::Sphere(i)] = self.geo.prims(e) else {
            return None;
        };
        if (r.dir_len - 1.0).abs() <= 1e-6 {
            return None;
        }
        let s = &self.scene.spheres[i as usize];
        let d = r.direction * r.dir_len;
        let oc = r.origin - d3(s.center);
        let b = oc.dot(d);
        let disc = b * b - (oc.length_squared() - f64::from(s.radius).powi(2));
        if disc < 0.0 {
            return Some(None);
        }
        let q = disc.sqrt();
        Some([-b - q, -b + q].into_iter().find(|&t| t > 0.0).map(|t| t * r.dir_len))
    }

    /// Words for a hit on sphere `e` at `ts` (`None`: the tracer missed it) that a sphere test
    /// taking ray `r`'s direction as unit length gives, within `pos`; empty otherwise.
    fn unit_sphere_note(&self, r: &LoggedRay, e: u32, ts: Option<f64>, pos: f64) -> String {
        let fits = match (self.unit_sphere_root(r, e), ts) {
            (Some(Some(t)), Some(ts)) => (t - ts).abs() <= pos,
            (Some(None), None) => true,
            _ => false,
        };
        if fits {
            format!(
                "; that is what a sphere test gives that takes the direction as unit length (a = d·d = 1), and this ray's direction has length {:.4}: normalise the direction, or keep a = d·d in the quadratic",
                r.dir_len
            )
        } else {
            String::new()
        }
    }

    /// A triangle rayscope's trace meets and the tracer did not: a miss a little inside an
    /// edge on its front face is the inside test's margin (`Some` with the share of the altitude
    /// it passes inside); one on the back face is counted for the log-wide decision between a
    /// too strict inside test and a one-sided one (see [`Tally::finish`]).
    pub(super) fn triangle_miss(&self, h: &RsHit, tally: &mut Tally) -> Option<f64> {
        let share = self.geo.edge_share(h.prim, h.point)?;
        let near = share < EDGE_SHARE;
        if h.front {
            return near.then_some(share);
        }
        if near {
            tally.back_near_edge += 1;
        } else {
            tally.back_inside += 1;
        }
        None
    }

    pub(super) fn edge_detail(&self, h: &RsHit, share: f64, kind: &str) -> String {
        format!(
            "rayscope's {kind} meets triangle '{}' at t = {:.6}, {:.1} % of the triangle's height inside its nearest edge; your tracer does not",
            self.name(h.entity),
            h.t,
            100.0 * share
        )
    }

    pub(super) fn acne_detail(&self, r: &LoggedRay, lv: &Leave, ts: f64) -> String {
        let sigma = (r.origin - lv.point).dot(lv.facing);
        let where_ = if sigma.abs() <= 1e-9 * scale(&[lv.point]) {
            "it starts exactly on the surface (no offset)".to_string()
        } else if sigma * r.direction.dot(lv.facing) < 0.0 {
            format!(
                "its origin is offset {:.2e} to the wrong side of the surface",
                sigma.abs()
            )
        } else {
            format!("its origin is only {:.2e} off the surface", sigma.abs())
        };
        format!(
            "it hits '{}', the surface it leaves, at t = {ts:.2e}: {where_}",
            self.name(lv.entity)
        )
    }

    /// The logged normal against the surface's two acceptable normals.
    pub(super) fn normal(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        n: DVec3,
        h: &RsHit,
        f: &mut Vec<Finding>,
        tally: &mut Tally,
    ) {
        let len = n.length();
        // Built only for a verdict: this runs for every logged normal.
        let values = || {
            vec![Value {
                what: "normal".into(),
                yours: vjson(n),
                rayscope: vjson(if h.front { h.own } else { -h.own }),
            }]
        };
        if len.is_nan() || len <= 0.0 {
            f.push(self.finding(r, kind, Code::HitNormalWrong, "the normal is zero".into(), values()));
            return;
        }
        if (len - 1.0).abs() > self.tol.unit {
            f.push(self.finding(
                r,
                kind,
                Code::HitNormalNotUnit,
                format!("the normal has length {len:.6}"),
                values(),
            ));
        }
        let nh = n / len;
        let own = self.geo.shading_normal(h.prim, h.point).unwrap_or(h.own);
        // The angle to the nearer of a surface's normals, and to the nearer of their opposites;
        // the second is needed only where the first is out of tolerance.
        let nearer = |a: DVec3, b: DVec3| {
            let x = angle(nh, a);
            if a.to_array().map(f64::to_bits) == b.to_array().map(f64::to_bits) {
                x
            } else {
                x.min(angle(nh, b))
            }
        };
        let a_plus = nearer(own, h.own);
        let tol = self.tol.normal;
        let a_minus = if a_plus <= tol {
            f64::INFINITY
        } else {
            nearer(-own, -h.own)
        };
        if a_plus.min(a_minus) > tol {
            f.push(self.finding(
                r,
                kind,
                Code::HitNormalWrong,
                format!(
                    "{:.3}° from the surface's normal at this point",
                    a_plus.min(a_minus).to_degrees()
                ),
                values(),
            ));
            return;
        }
        let outward = a_plus <= tol;
        if h.front && !outward {
            let code = if matches!(h.prim, PrimRef::Triangle(i) if self.scene.vertex_normals(i).is_none()) {
                Code::HitNormalReversedWinding
            } else {
                Code::HitNormalWrong
            };
            f.push(self.finding(
                r,
                kind,
                code,
                format!(
                    "on the front of '{}' the normal points away from the ray and is not the outward normal",
                    self.name(h.entity)
                ),
                values(),
            ));
            return;
        }
        if !h.front {
            // A back-face hit: the outward normal or the facing one, as long as it is always the same.
            let detail = if outward {
                format!("on the back of '{}' this normal is the outward one, while most of your back-face normals face the ray", self.name(h.entity))
            } else {
                format!("on the back of '{}' this normal faces the ray, while most of your back-face normals are the outward ones", self.name(h.entity))
            };
            let fnd = self.finding(r, kind, Code::HitNormalInconsistent, detail, values());
            // Counted on the side; `Tally::finish` decides which convention is the odd one out.
            let side = if outward { &mut tally.outward } else { &mut tally.facing };
            side.0 += 1;
            if side.1.len() < tally.keep {
                side.1.push(fnd);
            }
        }
    }
}
