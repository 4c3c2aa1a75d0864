//! Shadow rays: the light each aims at, and whether what the tracer says blocks it is what lies
//! between the point and the light.

use super::*;

/// How a blocker logged without a name is shown beside rayscope's answer.
pub(super) const UNNAMED_BLOCKER: &str = "something (the log names no blocker)";

/// A shadow ray's segment to its light: its length, the scale of the ray and the light, and the
/// position tolerance at that scale.
#[derive(Debug, Clone, Copy)]
struct ToLight {
    dist: f64,
    l: f64,
    pos: f64,
}

impl Judge<'_> {
    /// The segment from shadow ray `r`'s origin to light `li`.
    fn to_light(&self, r: &LoggedRay, li: u32) -> ToLight {
        let light = d3(Vec3A::from(self.scene.lights[li as usize].position));
        let l = scale(&[r.origin, light]);
        ToLight {
            dist: (light - r.origin).length(),
            l,
            pos: self.tol.position * l,
        }
    }

    /// Which light a shadow ray aims at; a verdict when it aims at none (or not at the one named).
    /// The direction may be taken from the ray's origin or from the hit point it leaves (`from`),
    /// which the course's light − point is, before the origin is offset off the surface.
    pub(super) fn aim(&self, r: &LoggedRay, kind: &Kind, from: Option<DVec3>, f: &mut Vec<Finding>) -> Option<u32> {
        let lights = &self.scene.lights;
        let light_pos = |li: u32| d3(Vec3A::from(lights[li as usize].position));
        let to = |li: u32| light_pos(li) - r.origin;
        let off_from = |li: u32, o: DVec3| {
            let v = light_pos(li) - o;
            if v.length_squared() == 0.0 {
                0.0
            } else {
                angle(r.direction, v)
            }
        };
        // From the hit point only where the origin's direction is off: most rays are aimed right.
        let off = |li: u32| {
            let e = off_from(li, r.origin);
            match from {
                Some(p) if e > self.tol.direction => e.min(off_from(li, p)),
                _ => e,
            }
        };
        let pick = match r.light {
            Some(li) => Some((li, off(li))),
            None => (0..lights.len() as u32)
                .map(|li| (li, off(li)))
                .fold(None, |a: Option<(u32, f64)>, b| match a {
                    Some(a) if a.1 <= b.1 => Some(a),
                    _ => Some(b),
                }),
        };
        let (li, err) = pick?;
        if err <= self.tol.direction {
            return Some(li);
        }
        let target = to(li);
        // Aimed at another light than the one it is logged for.
        if let Some(other) = (0..lights.len() as u32).find(|&lj| lj != li && off(lj) <= self.tol.direction) {
            f.push(self.finding(
                r,
                kind,
                Code::ShadowOtherLight,
                format!(
                    "logged for light '{}' but aimed at light '{}'",
                    self.light_name(li),
                    self.light_name(other)
                ),
                vec![Value {
                    what: "direction".into(),
                    yours: vjson(r.direction),
                    rayscope: vjson(target.normalize()),
                }],
            ));
            return None;
        }
        let backwards = angle(r.direction, -target) <= self.tol.direction;
        let position = light_pos(li);
        let unshifted = position.length_squared() > 0.0 && angle(r.direction, position) <= self.tol.direction;
        let detail = if backwards {
            format!(
                "points straight away from light '{}': the direction looks like point − light instead of light − point",
                self.light_name(li)
            )
        } else if unshifted {
            format!(
                "{:.3}° away from the direction to light '{}', along the light's own position: the direction looks like light − point without the point",
                err.to_degrees(),
                self.light_name(li)
            )
        } else {
            format!(
                "{:.3}° away from the direction to light '{}'{}",
                err.to_degrees(),
                self.light_name(li),
                if r.light.is_none() { " (the nearest light)" } else { "" }
            )
        };
        f.push(self.finding(
            r,
            kind,
            Code::ShadowNotAtLight,
            detail,
            vec![Value {
                what: "direction".into(),
                yours: vjson(r.direction),
                rayscope: vjson(target.normalize()),
            }],
        ));
        None
    }

    /// The entity a shadow ray logged as blocked, without a name, stands for: rayscope's blocker
    /// on the segment where there is one, else the surface the ray leaves, met again at its
    /// origin, or another surface touching its origin. `None`: nothing is in the way, and what
    /// the tracer met cannot be told from the log ([`Self::blocked_by_nothing`] says what could
    /// have been).
    pub(super) fn unnamed_blocker(
        &self,
        r: &LoggedRay,
        li: u32,
        rs: Option<&RsHit>,
        leave: Option<&Leave>,
    ) -> Option<u32> {
        if let Some(b) = rs {
            return Some(b.entity);
        }
        let ToLight { dist, l, pos } = self.to_light(r, li);
        let (o, d) = (r.origin, r.direction);
        let near = SURFACE_ROUNDING * l;
        if let Some(lv) = leave {
            let t_self = self.geo.entity_intersect(lv.entity, o, d, -pos, dist).map(|x| x.0);
            if t_self.is_some_and(|t| t >= -T_ROUNDING * l) {
                return Some(lv.entity);
            }
        }
        // Another surface its origin touches (at a corner), met within rounding of t = 0.
        (0..self.scene.entities.len() as u32)
            .filter(|&e| leave.is_none_or(|lv| lv.entity != e))
            .find(|&e| {
                self.geo.entity_distance(e, o).0 <= near
                    && self.geo.entity_intersect(e, o, d, -T_ROUNDING * l, near).is_some()
            })
    }

    /// A shadow ray logged as blocked, without a name, where nothing lies between its origin and
    /// its light: what lies on its line elsewhere, each with the mistake that would count it.
    pub(super) fn blocked_by_nothing(&self, r: &LoggedRay, kind: &Kind, li: u32, f: &mut Vec<Finding>) {
        let ToLight { dist, l, pos } = self.to_light(r, li);
        let (o, d) = (r.origin, r.direction);
        let near = SURFACE_ROUNDING * l;
        let all = || 0..self.scene.entities.len() as u32;
        let mut could = Vec::new();
        let mut crossed = None;
        // The nearest crossing of a triangle's plane just outside it (within its own height), of
        // entities of a few triangles: a model's would be searched for every such ray.
        let outside = all()
            .filter(|&e| self.geo.prims(e).len() <= FEW_TRIANGLES)
            .flat_map(|e| self.geo.prims(e).iter().map(move |&p| (e, p)))
            .filter_map(|(e, p)| {
                let (t, share) = self.geo.plane_crossing_outside(p, o, d, near, dist - pos)?;
                (share > -1.0).then_some((e, t, share))
            })
            .max_by(|a, b| a.2.total_cmp(&b.2));
        if let Some((e, t, share)) = outside {
            crossed = Some(e);
            could.push(format!(
                "it crosses the plane of triangle '{}' at t = {t:.6}, outside the triangle by {:.1} % of its height (an inside test that lets points past an edge through counts it)",
                self.name(e),
                -share * 100.0
            ));
        }
        let beyond = all()
            .filter_map(|e| {
                self.geo
                    .entity_intersect(e, o, d, dist + pos, f64::INFINITY)
                    .map(|x| (e, x.0))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((e, t)) = beyond {
            could.push(format!(
                "'{}' lies beyond the light, at t = {t:.6} (a blocker test that does not stop at the light counts it)",
                self.name(e)
            ));
        }
        // The surface the ray leaves counts where it lies behind the origin by more than an f32
        // tracer's rounding of t.
        let behind = all()
            .filter_map(|e| {
                self.geo
                    .entity_intersect(e, o, d, f64::MIN, -T_ROUNDING * l)
                    .map(|x| (e, x.0))
            })
            .max_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((e, t)) = behind {
            could.push(format!(
                "'{}' lies behind the origin, at t = {t:.6} (a test that accepts t < 0 counts it)",
                self.name(e)
            ));
        }
        let detail = format!(
            "your tracer says light '{}' is blocked, but nothing lies between the point and the light (at t = {dist:.6}){}",
            self.light_name(li),
            if could.is_empty() {
                ", nor anywhere else on the ray's line".to_string()
            } else {
                format!("; your log names no blocker: {}", could.join("; "))
            }
        );
        let mut x = self.finding(
            r,
            kind,
            Code::ShadowPhantomBlocker,
            detail,
            vec![Value {
                what: format!("blocker of light '{}'", self.light_name(li)),
                yours: json!(UNNAMED_BLOCKER),
                rayscope: json!("none: light reached"),
            }],
        );
        // The triangle whose plane it crosses is the surface the verdict is about, for the
        // log-wide rule that gathers a surface's verdicts.
        x.entity = crossed;
        f.push(x);
    }

    /// Shadow rays blocked by nothing in their way (by what they name, where they name it) whose
    /// sibling cast just before them from the same hit is blocked and names the same: the flag
    /// or blocker of the light before, not reset. Judged in the log's order, so that a third
    /// light's ray follows a second that is itself carried over. Returns how many of them name
    /// no blocker.
    pub(super) fn carried_over(
        &self,
        rays: &[LoggedRay],
        parent: &[Option<usize>],
        kinds: &[Kind],
        findings: &mut [Vec<Finding>],
    ) -> u64 {
        let wrongly = |f: &Finding| matches!(f.code, Code::ShadowPhantomBlocker | Code::ShadowBlockedBeyondLight);
        if !findings.iter().flatten().any(wrongly) {
            return 0;
        }
        let mut unnamed = 0;
        for i in 0..rays.len() {
            let (Some(k), Some(p)) = (findings[i].iter().position(wrongly), parent[i]) else {
                continue;
            };
            let Some(j) = (0..i).rev().find(|&j| parent[j] == Some(p) && kinds[j] == Kind::Shadow) else {
                continue;
            };
            let Answer::Found(before) = rays[j].blocked_by else {
                continue;
            };
            if findings[j].iter().any(wrongly) || rays[i].blocked_by != Answer::Found(before) {
                continue;
            }
            unnamed += u64::from(before.is_none());
            let f = &mut findings[i][k];
            f.code = Code::ShadowBlockedCarriedOver;
            f.detail = format!(
                "nothing lies between the point and light '{}', but the shadow ray cast just before it from this point (line {}) is blocked{}",
                rays[i].light.map_or("?", |li| self.light_name(li)),
                rays[j].line,
                before.map_or(String::new(), |e| format!(" by '{}', the blocker this one names too", self.name(e)))
            );
        }
        unnamed
    }

    /// The verdict on a shadow ray that names `e` where rayscope finds `b` in the way and `e` is
    /// not on the segment: `e` lies beyond the light, or it is simply the wrong blocker.
    #[allow(clippy::too_many_arguments)]
    fn wrong_blocker(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        li: u32,
        seg: ToLight,
        e: u32,
        b: &RsHit,
        v: Vec<Value>,
        f: &mut Vec<Finding>,
    ) {
        let ToLight { dist, pos, .. } = seg;
        // Named after an entity beyond the light: the blocker test accepts hits past
        // the light, and this one came first in the tracer's list.
        if let Some((t, _)) = self
            .geo
            .entity_intersect(e, r.origin, r.direction, dist + pos, f64::INFINITY)
        {
            f.push(self.finding(
                r,
                kind,
                Code::ShadowBlockedBeyondLight,
                format!(
                    "your tracer names '{}', which is on the ray at t = {t:.6}, beyond light '{}' at {dist:.6} ('{}' does block it, at t = {:.6})",
                    self.name(e),
                    self.light_name(li),
                    self.name(b.entity),
                    b.t
                ),
                v,
            ));
            return;
        }
        f.push(self.finding(
            r,
            kind,
            Code::ShadowWrongBlocker,
            format!(
                "'{}' is not on the shadow ray; '{}' blocks it (t = {:.6})",
                self.name(e),
                self.name(b.entity),
                b.t
            ),
            v,
        ));
    }

    /// A shadow ray's blocker (or none) against rayscope's segment to the light.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn blocked(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        li: u32,
        rs: Option<&RsHit>,
        t_skip: f64,
        blocked: Answer<u32>,
        leave: Option<&Leave>,
        f: &mut Vec<Finding>,
        tally: &mut Tally,
    ) {
        let (o_trace, d) = (r.origin, r.direction);
        let seg = self.to_light(r, li);
        let ToLight { dist, l, pos } = seg;
        // `rs` is the ray's closest hit on the segment to this light.
        let b = rs.copied();
        let values = |yours: Option<u32>, rs: Option<u32>| {
            vec![Value {
                what: format!("blocker of light '{}'", self.light_name(li)),
                yours: yours.map_or(json!("none: light reached"), |e| json!(self.name(e))),
                rayscope: rs.map_or(json!("none: light reached"), |e| json!(self.name(e))),
            }]
        };
        match blocked {
            Answer::NotLogged => {}
            Answer::Nothing => {
                if let Some(b) = b {
                    let before = f.len();
                    self.reported_reached(r, kind, li, seg, &b, values(None, Some(b.entity)), f, tally);
                    // A blocker passed over, for the log-wide rule that may explain it.
                    let kept = || Some(self.kept_beyond(r.origin, r.direction, seg.dist));
                    self.passed_over(&f[before..], b.t, kept, &mut tally.skipped);
                }
            }
            Answer::Found(e) => {
                if b.is_some_and(|b| b.entity == e) {
                    return;
                }
                let on_segment = self.geo.entity_intersect(e, o_trace, d, t_skip, dist);
                if on_segment.is_some() && b.is_some() {
                    return;
                }
                let v = values(Some(e), b.map(|b| b.entity));
                if let (Some((t, _)), None) = (on_segment, b) {
                    // On the segment in double precision, not in rayscope's f32 trace: rounding.
                    let touching = t <= pos;
                    f.push(self.finding(
                        r,
                        kind,
                        if touching { Code::TieEdge } else { Code::TieGrazing },
                        format!(
                            "'{}' {} the shadow ray within rounding",
                            self.name(e),
                            if touching {
                                "touches the point it leaves, at"
                            } else {
                                "grazes"
                            }
                        ),
                        v,
                    ));
                    return;
                }
                if self.starts_on_named(r, kind, e, leave, l, &v, f) {
                    return;
                }
                if let Some(lv) = leave {
                    if e == lv.entity && on_segment.is_none() {
                        let t_self = self.geo.entity_intersect(e, r.origin, d, -pos, dist).map(|x| x.0);
                        // Acne only if the ray meets the surface it leaves at t ≈ 0 from its
                        // origin (no offset, or one within rounding); from an offset origin the
                        // name is wrong for another reason, judged below.
                        if t_self.is_some_and(|t| t >= -SURFACE_ROUNDING * l) {
                            let t_self = t_self.unwrap_or(0.0);
                            f.push(self.finding(r, kind, Code::ShadowAcne, self.acne_detail(r, lv, t_self), v));
                            return;
                        }
                    }
                } else if on_segment.is_none() && self.geo.entity_distance(e, r.origin).0 <= SURFACE_ROUNDING * l {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::ShadowAcne,
                        format!(
                            "it is blocked by '{}', the surface its origin lies on (no offset?)",
                            self.name(e)
                        ),
                        v,
                    ));
                    return;
                }
                if let Some(b) = b {
                    self.wrong_blocker(r, kind, li, seg, e, &b, v, f);
                    return;
                }
                self.blocker_off_segment(r, kind, li, seg, e, t_skip, v, f);
            }
        }
    }

    /// A blocker the tracer names that is not on the segment to the light.
    #[allow(clippy::too_many_arguments)]
    fn blocker_off_segment(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        li: u32,
        seg: ToLight,
        e: u32,
        t_skip: f64,
        v: Vec<Value>,
        f: &mut Vec<Finding>,
    ) {
        let (o_trace, d) = (r.origin, r.direction);
        let ToLight { dist, l, pos } = seg;
        match self.geo.entity_intersect(e, o_trace, d, t_skip, f64::INFINITY) {
            Some((t, _)) if (t - dist).abs() <= pos => f.push(self.finding(
                r,
                kind,
                Code::TieLightOnSurface,
                format!("light '{}' lies on '{}'", self.light_name(li), self.name(e)),
                v,
            )),
            Some((t, _)) => f.push(self.finding(
                r,
                kind,
                Code::ShadowBlockedBeyondLight,
                format!(
                    "'{}' is on the ray at t = {t:.6}, beyond light '{}' at {dist:.6}",
                    self.name(e),
                    self.light_name(li)
                ),
                v,
            )),
            None => {
                let (_, prim) = self.geo.entity_distance(e, o_trace);
                let graze = prim.is_some_and(|p| {
                    // Where the ray's line meets the primitive's surface, against its edge.
                    // Only ahead of the origin: a surface the line meets behind the ray is not in its way.
                    self.geo
                        .intersect(p, o_trace, d, -pos, f64::MAX)
                        .is_some_and(|t| is_tie(self.geo.margin(p, o_trace, d, o_trace + d * t), self.tol.tie, l))
                });
                if graze {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::TieGrazing,
                        format!("the shadow ray grazes the edge of '{}'", self.name(e)),
                        v,
                    ));
                } else {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::ShadowPhantomBlocker,
                        match self.geo.entity_intersect(e, o_trace, d, f64::MIN, -SURFACE_ROUNDING * l) {
                        Some((t, _)) => format!(
                            "'{}' is on the ray's line only behind its origin, at t = {t:.6}: your blocker test accepts t < 0; rayscope finds nothing between the point and light '{}'",
                            self.name(e),
                            self.light_name(li)
                        ),
                        None => format!(
                            "'{}' is not on the segment to light '{}'; rayscope finds nothing in the way",
                            self.name(e),
                            self.light_name(li)
                        ),
                    },
                        v,
                    ));
                }
            }
        }
    }

    /// The tracer says the light is reached where the oracle finds `b` in the way.
    #[allow(clippy::too_many_arguments)]
    fn reported_reached(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        li: u32,
        seg: ToLight,
        b: &RsHit,
        v: Vec<Value>,
        f: &mut Vec<Finding>,
        tally: &mut Tally,
    ) {
        let (o_trace, d) = (r.origin, r.direction);
        let ToLight { dist, l, pos } = seg;
        if (b.t - dist).abs() <= pos {
            f.push(self.finding(
                r,
                kind,
                Code::TieLightOnSurface,
                format!("light '{}' lies on '{}'", self.light_name(li), self.name(b.entity)),
                v,
            ));
        } else if is_tie(self.geo.margin(b.prim, o_trace, d, b.point), self.tol.tie, l) {
            f.push(self.finding(
                r,
                kind,
                Code::TieGrazing,
                format!("the shadow ray grazes the edge of '{}'", self.name(b.entity)),
                v,
            ));
        } else if let Some(share) = self.triangle_miss(b, tally) {
            f.push(self.finding(
                r,
                kind,
                Code::HitTriangleEdge,
                format!(
                    "{}, between the point and light '{}'",
                    self.edge_detail(b, share, "shadow ray"),
                    self.light_name(li)
                ),
                v,
            ));
        } else if matches!(b.prim, PrimRef::Triangle(_)) && !b.front {
            f.push(self.finding(
                r,
                kind,
                Code::ShadowOneSidedTriangle,
                format!(
                    "triangle '{}' lies between the point and light '{}' (t = {:.6} of {:.6}) and the ray meets its back face",
                    self.name(b.entity),
                    self.light_name(li),
                    b.t,
                    dist
                ),
                v,
            ));
        } else {
            f.push(self.finding(
                r,
                kind,
                Code::ShadowMissedBlocker,
                format!(
                    "'{}' lies between the point and light '{}' (t = {:.6} of {:.6})",
                    self.name(b.entity),
                    self.light_name(li),
                    b.t,
                    dist
                ),
                v,
            ));
        }
    }

    /// A named blocker the ray's origin lies on too (it starts where two surfaces meet): a tie,
    /// pushed, and true. `l` is the scale of the ray and its light.
    #[allow(clippy::too_many_arguments)]
    fn starts_on_named(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        e: u32,
        leave: Option<&Leave>,
        l: f64,
        v: &[Value],
        f: &mut Vec<Finding>,
    ) -> bool {
        let d = r.direction;
        // The origin lies on the named surface too (the point it leaves is where two
        // surfaces meet, an edge of the box): whether that surface blocks the ray at
        // t ≈ 0 is rounding.
        let on_named = self.geo.entity_distance(e, r.origin).0 <= SURFACE_ROUNDING * l
            && self
                .geo
                .entity_intersect(e, r.origin, d, -SURFACE_ROUNDING * l, SURFACE_ROUNDING * l)
                .is_some();
        if on_named && leave.is_some_and(|lv| lv.entity != e) {
            f.push(self.finding(
                r,
                kind,
                Code::TieEdge,
                format!(
                    "it starts where '{}' meets '{}', the surface it leaves: '{}' touches its origin within rounding",
                    self.name(e),
                    leave.map_or("?", |lv| self.name(lv.entity)),
                    self.name(e)
                ),
                v.to_vec(),
            ));
            return true;
        }
        if on_named && leave.is_none() && r.parent.is_some() {
            f.push(self.finding(
                r,
                kind,
                Code::TieEdge,
                format!(
                    "it starts on '{}', at a hit of its parent ray that is itself a tie (two surfaces meet there): which surface it leaves is rounding",
                    self.name(e)
                ),
                v.to_vec(),
            ));
            return true;
        }
        false
    }
}
