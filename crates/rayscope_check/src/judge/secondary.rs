//! Reflected and refracted rays against their parent's hit: where they start, the mirror direction,
//! Snell's law, total internal reflection and the share of the sample they carry.

use super::*;

/// Fresnel reflectance (unpolarised) where the parent ray meets glass of index `ior`.
pub(super) fn glass_fresnel(lv: &Leave, ior: f64) -> f64 {
    let (n1, n2) = if lv.front { (1.0, ior) } else { (ior, 1.0) };
    shading::fresnel((-lv.parent_dir.dot(lv.facing)).clamp(0.0, 1.0), n1, n2)
}

impl Judge<'_> {
    /// Glass hits where the tracer reflected and did not refract although rayscope refracts.
    pub(super) fn tir_invented(
        &self,
        rays: &[LoggedRay],
        parent: &[Option<usize>],
        evals: &[Option<Eval>],
        kinds: &[Kind],
        findings: &mut [Vec<Finding>],
    ) {
        // Only a reflection can be the invented half of a total internal reflection.
        if !kinds.contains(&Kind::Reflection) {
            return;
        }
        let mut children: FxHashMap<usize, Vec<usize>> = FxHashMap::default();
        for (i, p) in parent.iter().enumerate() {
            if let Some(p) = p {
                children.entry(*p).or_default().push(i);
            }
        }
        for (p, kids) in children {
            let Some(lv) = evals[p].and_then(|e| e.leave()) else {
                continue;
            };
            let m = &self.scene.materials[lv.material as usize];
            if !m.is_glass() {
                continue;
            }
            let refl = kids.iter().find(|&&k| kinds[k] == Kind::Reflection);
            let refr = kids.iter().any(|&k| kinds[k] == Kind::Refraction);
            let (Some(&k), false) = (refl, refr) else {
                continue;
            };
            let ior = f64::from(m.value);
            let eta = if lv.front { 1.0 / ior } else { ior };
            let cos_i = -lv.parent_dir.dot(lv.facing);
            let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
            // A refracted ray that would carry a negligible share of the sample may be pruned
            // (rayscope prunes Whitted branches below 1/4096 of a level): only a missing
            // refraction worth at least MIN_SHARE of the sample is a verdict.
            let share = self.path_weight(p, parent, evals, kinds) * (1.0 - glass_fresnel(&lv, ior));
            if sin2_t < 1.0 - 1e-3 && share >= MIN_SHARE {
                let t = refract(lv.parent_dir, lv.facing, eta).unwrap_or(DVec3::ZERO);
                let none_refracted = || {
                    vec![Value {
                        what: "refracted direction".into(),
                        yours: json!("none"),
                        rayscope: vjson(t),
                    }]
                };
                // A hit whose colour is its reflection's times a share below 1 is missing its
                // refracted share; whether a test kept it from refracting or the tracer never
                // refracts, the rest of the log decides (`Tally::finish`).
                let weight = match (rays[p].color, rays[k].color) {
                    (Some(c), Some(rc)) if rc.max_element() > 1e-3 => {
                        let s = c.dot(rc) / rc.length_squared();
                        (s < 0.999 && shading::fits(c, rc * s, DVec3::ZERO)).then_some(s)
                    }
                    _ => None,
                };
                if let Some(s) = weight {
                    findings[k].push(self.finding(
                        &rays[k],
                        &kinds[k],
                        Code::MissingRefraction,
                        format!(
                            "{} '{}' (index {}) sin²θt = {sin2_t:.4} < 1, so the ray refracts; your tracer cast this reflection and no refracted ray, its colour weighted by {s:.4} (Fresnel's kr here is {:.4})",
                            if lv.front { "entering" } else { "leaving" },
                            self.name(lv.entity),
                            m.value,
                            glass_fresnel(&lv, ior)
                        ),
                        none_refracted(),
                    ));
                    continue;
                }
                // With the index ratio upside down the ray is past the critical angle: that is
                // the mistake, and the reflection only its consequence.
                let sin2_inverted = (1.0 - cos_i * cos_i) / (eta * eta);
                if sin2_inverted >= 1.0 - 1e-3 {
                    // Entering, this ray alone cannot tell a ratio upside down from a critical-
                    // angle test with the leaving side's ratio: both are named, and the log's
                    // other refracted rays decide (see `Tally::finish`).
                    findings[k].push(self.finding(
                        &rays[k],
                        &kinds[k],
                        Code::RefractionTirInvented,
                        format!(
                            "entering '{}' your tracer reflected only, as if past the critical angle; sin²θt = {sin2_t:.4} < 1, so the ray refracts",
                            self.name(lv.entity)
                        ),
                        vec![],
                    ));
                    findings[k].push(self.finding(
                        &rays[k],
                        &kinds[k],
                        Code::RefractionIndicesNotSwapped,
                        format!(
                            "{} '{}' (index {}) your tracer reflected only, as η = {:.4} would have it (sin²θt = {sin2_inverted:.4} > 1, past the critical angle); with η = n1 / n2 = {eta:.4} sin²θt = {sin2_t:.4} and the ray refracts",
                            if lv.front { "entering" } else { "leaving" },
                            self.name(lv.entity),
                            m.value,
                            1.0 / eta
                        ),
                        none_refracted(),
                    ));
                    continue;
                }
                let f = self.finding(
                    &rays[k],
                    &kinds[k],
                    Code::RefractionTirInvented,
                    format!(
                        "at '{}' (index {}) sin²θt = {sin2_t:.4} < 1, so the ray refracts; your tracer cast this reflection and no refracted ray",
                        self.name(lv.entity),
                        m.value
                    ),
                    none_refracted(),
                );
                findings[k].push(f);
            }
        }
    }

    /// The share of its sample that ray `i` carries by Fresnel's weights at the glass hits above
    /// it (mirrors pass everything on).
    pub(super) fn path_weight(
        &self,
        i: usize,
        parent: &[Option<usize>],
        evals: &[Option<Eval>],
        kinds: &[Kind],
    ) -> f64 {
        let (mut w, mut k) = (1.0, i);
        for _ in 0..64 {
            let Some(p) = parent[k] else {
                break;
            };
            if let Some(lv) = evals[p].and_then(|e| e.leave()) {
                let m = &self.scene.materials[lv.material as usize];
                if m.is_glass() {
                    let kr = glass_fresnel(&lv, f64::from(m.value));
                    w *= match kinds[k] {
                        Kind::Reflection => kr,
                        Kind::Refraction => 1.0 - kr,
                        _ => 1.0,
                    };
                }
            }
            k = p;
        }
        w
    }

    /// How a secondary ray leaves its parent's hit: where it starts, and its direction for its kind.
    pub(super) fn derivation(&self, r: &LoggedRay, kind: &Kind, lv: &Leave, f: &mut Vec<Finding>) {
        let (o, d) = (r.origin, r.direction);
        let l = scale(&[o, lv.point, lv.parent_origin]);
        let away = (o - lv.point).length();
        if away > self.tol.offset * l {
            f.push(self.finding(
                r,
                kind,
                Code::SecondaryOriginNotAtHit,
                format!(
                    "starts {away:.4} away from its parent's hit on '{}'",
                    self.name(lv.entity)
                ),
                vec![Value {
                    what: "origin".into(),
                    yours: vjson(o),
                    rayscope: vjson(lv.point),
                }],
            ));
            return;
        }
        let m = &self.scene.materials[lv.material as usize];
        let material_mismatch = match kind {
            Kind::Refraction => !m.is_glass(),
            Kind::Reflection => !m.sends_reflection_rays(self.settings.stage),
            _ => false,
        };
        if material_mismatch {
            f.push(self.finding(
                r,
                kind,
                Code::SecondaryWrongMaterial,
                format!(
                    "a {} ray from '{}', whose material is {}",
                    kind.name(),
                    self.name(lv.entity),
                    m.kind.name()
                ),
                vec![],
            ));
            return;
        }
        let before = f.len();
        let expected = match kind {
            Kind::Reflection => Some(self.reflection(r, kind, lv, f)),
            Kind::Refraction => self.refraction(r, kind, lv, f),
            _ => None,
        };
        let direction_wrong = f.len() > before;
        // The side the ray starts on, against the side it should go to.
        let goes = expected.unwrap_or(d).dot(lv.facing);
        let sigma = (o - lv.point).dot(lv.facing);
        // A shadow ray toward a light behind the surface contributes nothing, wherever it starts.
        let judged = !(*kind == Kind::Shadow && goes <= 0.0);
        if judged && goes.abs() > 1e-9 && sigma * goes.signum() < -self.tol.side * l {
            // A wrong direction explains an origin on its own side.
            let consistent_with_own = sigma * d.dot(lv.facing) > 0.0;
            if !(direction_wrong && consistent_with_own) {
                f.push(self.finding(
                    r,
                    kind,
                    Code::SecondaryOffsetWrongSide,
                    format!(
                        "its origin is {:.2e} {} the surface of '{}', but the ray goes {}",
                        sigma.abs(),
                        if sigma > 0.0 { "in front of" } else { "behind" },
                        self.name(lv.entity),
                        if goes > 0.0 {
                            "back out on the incoming side"
                        } else {
                            "through the surface"
                        }
                    ),
                    vec![Value {
                        what: "offset along the normal facing the incoming ray".into(),
                        yours: njson(sigma),
                        rayscope: njson(goes.signum() * 1e-5 * l),
                    }],
                ));
            }
        }
    }

    /// A reflected ray against the mirror image of its parent; returns the expected direction.
    pub(super) fn reflection(&self, r: &LoggedRay, kind: &Kind, lv: &Leave, f: &mut Vec<Finding>) -> DVec3 {
        let want = reflect(lv.parent_dir, lv.facing).normalize();
        let err = angle(r.direction, want);
        if err > self.tol.direction + 2.0 * lv.un {
            let into = r.direction.dot(lv.facing) < 0.0;
            // The formula a student most often gets wrong, r = d − (d · n) n: the factor 2 lost.
            let no_two = (lv.parent_dir - lv.facing * lv.parent_dir.dot(lv.facing)).normalize_or_zero();
            let fits = if angle(r.direction, no_two) <= self.tol.direction + 2.0 * lv.un {
                "; it fits d − (d · n) n, the formula without its factor 2"
            } else if into {
                "; it goes into the surface"
            } else {
                ""
            };
            f.push(self.finding(
                r,
                kind,
                Code::ReflectionNotMirror,
                format!(
                    "{:.3}° from the mirror direction at '{}'{fits}",
                    err.to_degrees(),
                    self.name(lv.entity),
                ),
                vec![Value {
                    what: "direction".into(),
                    yours: vjson(r.direction),
                    rayscope: vjson(want),
                }],
            ));
        }
        want
    }

    /// A refracted ray against Snell's law at its parent's hit; returns the expected direction.
    pub(super) fn refraction(&self, r: &LoggedRay, kind: &Kind, lv: &Leave, f: &mut Vec<Finding>) -> Option<DVec3> {
        let m = &self.scene.materials[lv.material as usize];
        let ior = f64::from(m.value);
        let (n1, n2) = if lv.front { (1.0, ior) } else { (ior, 1.0) };
        let eta = n1 / n2;
        let (dp, nf) = (lv.parent_dir, lv.facing);
        let cos_i = -dp.dot(nf);
        let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
        let ds = r.direction;
        // Near grazing exit the refracted angle swings by dθt/dθi = η cos θi / cos θt per radian
        // of the normal's uncertainty.
        let amp = eta * cos_i.abs() / (1.0 - sin2_t).max(1e-12).sqrt();
        let tol = self.tol.direction + lv.un * (1.0 + amp);
        let name = self.name(lv.entity);
        let leaving = if lv.front { "entering" } else { "leaving" };
        let value = |want: Option<DVec3>| {
            vec![Value {
                what: "direction".into(),
                yours: vjson(ds),
                rayscope: want.map_or(json!("none: total internal reflection"), vjson),
            }]
        };
        // The formula with the normal left unflipped (the outward one where the ray leaves).
        let unflipped = |eta: f64| {
            let n = -nf;
            let c = -dp.dot(n);
            let k = 1.0 - eta * eta * (1.0 - c * c);
            (dp * eta + n * (eta * c - k.max(0.0).sqrt())).normalize()
        };
        let matches = |v: Option<DVec3>| v.is_some_and(|v| angle(ds, v) <= tol);
        let want = refract(dp, nf, eta);
        if (sin2_t - 1.0).abs() <= 1e-3 {
            if !matches(want) && want.is_none_or(|w| angle(ds, w) > 1e-2) {
                // Not even near the grazing refraction: judged below like any other ray.
            } else {
                if want.is_none() {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::TieCriticalAngle,
                        format!("sin²θt = {sin2_t:.6} at '{name}'"),
                        value(want),
                    ));
                }
                return want;
            }
        }
        if matches(want) {
            return want;
        }
        // The normal's sign does not change whether total internal reflection happens (the test
        // uses cos²θi), so under it a refracted ray means the test itself is missing.
        let tir = want.is_none();
        if !tir && !lv.front && matches(Some(unflipped(eta))) {
            f.push(self.finding(
                r,
                kind,
                Code::RefractionNormalNotFlipped,
                format!("{leaving} '{name}' the ray bends back into the glass, as the outward normal makes it"),
                value(want),
            ));
            return want;
        }
        if !tir && !lv.front && matches(Some(unflipped(1.0 / eta))) {
            for code in [Code::RefractionNormalNotFlipped, Code::RefractionIndicesNotSwapped] {
                f.push(self.finding(
                    r,
                    kind,
                    code,
                    format!("{leaving} '{name}' the ray fits the outward normal with the indices unswapped"),
                    value(want),
                ));
            }
            return want;
        }
        if matches(refract(dp, nf, 1.0 / eta)) {
            f.push(self.finding(
                r,
                kind,
                Code::RefractionIndicesNotSwapped,
                format!(
                    "{leaving} '{name}' the ray bends with η = {:.4} instead of {:.4}",
                    1.0 / eta,
                    eta
                ),
                value(want),
            ));
            return want;
        }
        if want.is_none() {
            f.push(self.finding(
                r,
                kind,
                Code::RefractionTirMissed,
                format!(
                    "{leaving} '{name}' at {:.2}° from the normal, past the critical angle of {:.2}° (sin²θt = {sin2_t:.4} > 1): nothing is transmitted",
                    cos_i.clamp(-1.0, 1.0).acos().to_degrees(),
                    (1.0 / eta).min(1.0).asin().to_degrees()
                ),
                value(want),
            ));
            return want;
        }
        // The formula t = η d + (η c − √(1 − η²(1 − c²))) n given a direction `d` and a cosine
        // `c` other than the unit direction's −d·n.
        let formula = |d: DVec3, c: f64| {
            let k = 1.0 - eta * eta * (1.0 - c * c);
            (k >= 0.0).then(|| (d * eta + nf * (eta * c - k.sqrt())).normalize())
        };
        // The same formula with cos θt's radicand `k(cos θi)` written another way, and its
        // square root taken (`root`) or left out.
        let written = |k_of: &dyn Fn(f64) -> f64, root: bool| {
            let k = k_of(cos_i);
            (k >= 0.0).then(|| (dp * eta + nf * (eta * cos_i - if root { k.sqrt() } else { k })).normalize())
        };
        let long = dp * lv.parent_len;
        let sin_i = dp.cross(nf).length();
        let sin_t = ds.cross(nf).length();
        let detail = if (lv.parent_len - 1.0).abs() > 1e-3 && matches(formula(long, -long.dot(nf))) {
            format!(
                "{leaving} '{name}' it fits the refraction formula given the incoming direction as your log has it, of length {:.4}: the formula needs a unit direction, so normalise the incoming ray's direction first",
                lv.parent_len
            )
        } else if matches(formula(dp, dp.dot(nf))) {
            format!(
                "{leaving} '{name}' it fits the refraction formula with cos θi = d·n = {:.4} instead of −d·n = {cos_i:.4}: the cosine's sign is not turned for a normal that faces the incoming ray",
                dp.dot(nf)
            )
        } else if matches(written(&|c| 1.0 - eta * (1.0 - c * c), true)) {
            format!(
                "{leaving} '{name}' it fits the refraction formula with η = {eta:.4} where η² belongs: cos θt = √(1 − η² (1 − cos²θi)), not √(1 − η (1 − cos²θi))"
            )
        } else if matches(written(&|c| 1.0 - eta * eta * (1.0 - c * c), false)) {
            format!(
                "{leaving} '{name}' it fits the refraction formula without its square root: cos θt = √(1 − η² (1 − cos²θi)), not 1 − η² (1 − cos²θi)"
            )
        } else if ds.dot(nf) > 0.0 {
            format!("{leaving} '{name}' the refracted ray goes back out on the side the ray came from")
        } else if sin_i > 1e-6 {
            format!(
                "{leaving} '{name}' it bends as if n1 / n2 were {:.4}, not {:.4}",
                sin_t / sin_i,
                eta
            )
        } else {
            format!("{leaving} '{name}' at normal incidence it should go straight through")
        };
        f.push(self.finding(r, kind, Code::RefractionSnell, detail, value(want)));
        want
    }
}
