//! `rayscope trace`'s text: a ray tree as indented lines a student can follow, every decision
//! spelled out (offsets, blockers, glass, pruned branches).

use std::fmt::Write as _;

use rayscope_core::{BranchFate, GlassBranch, GlassDecision, RayHitInfo, RayKind, RayNode, RayTree};

/// Formats numbers with `digits` decimals, switching to scientific notation for magnitudes too
/// small to show that way (a shadow-acne blocker at t = 3e-7 must not read as 0).
#[derive(Debug, Clone, Copy)]
pub struct Digits(pub usize);

impl Digits {
    /// One number.
    #[must_use]
    pub fn num(self, x: f64) -> String {
        let p = self.0;
        if x != 0.0 && x.is_finite() && x.abs() < 0.5 * 10f64.powi(-(p as i32)) {
            format!("{:.*e}", p.saturating_sub(1), x)
        } else {
            format!("{x:.p$}")
        }
    }

    /// A vector.
    #[must_use]
    pub fn v3(self, v: [f32; 3]) -> String {
        format!(
            "({}, {}, {})",
            self.num(v[0].into()),
            self.num(v[1].into()),
            self.num(v[2].into())
        )
    }

    /// A small vector (an offset), in scientific notation.
    fn sci3(self, v: [f64; 3]) -> String {
        let p = self.0.saturating_sub(1);
        format!("({:.p$e}, {:.p$e}, {:.p$e})", v[0], v[1], v[2])
    }
}

/// What a node's `weight` is, by the kind of ray.
fn weight_name(k: RayKind) -> &'static str {
    match k {
        RayKind::Shadow => "N·L",
        RayKind::Reflection | RayKind::Refraction => "weight",
        RayKind::Emitter | RayKind::Bounce => "MIS weight",
        RayKind::Camera => "weight",
    }
}

/// Where a secondary ray starts, relative to its parent's hit point P and normal n.
fn origin_text(n: &RayNode, d: Digits) -> String {
    let at = d.v3(n.origin);
    match (n.offset, n.offset_along_normal) {
        (None, _) => at,
        (Some(o), _) if o == [0.0; 3] => format!("P (no offset) = {at}"),
        (Some(_), Some(k)) => {
            let sign = if k < 0.0 { '−' } else { '+' };
            format!("P {sign} {:.*e}·n = {at}", d.0.saturating_sub(1), k.abs())
        }
        (Some(o), None) => format!("P + {} = {at}", d.sci3(o)),
    }
}

fn surface_text(h: &RayHitInfo, d: Digits) -> String {
    format!(
        "'{}' ({} '{}') at t={} point {} normal {} {}",
        h.entity_name,
        h.material_kind,
        h.material,
        d.num(h.t.into()),
        d.v3(h.point),
        d.v3(h.normal),
        if h.front_face { "front face" } else { "back face" }
    )
}

fn branch_text(label: &str, b: &GlassBranch, child: Option<u32>, g: &GlassDecision, d: Digits) -> String {
    match b.fate {
        BranchFate::Traced => match child {
            Some(id) => format!("{label}: traced as #{id}, weight {}", d.num(b.weight.into())),
            None => format!("{label}: traced, weight {} (not recorded)", d.num(b.weight.into())),
        },
        BranchFate::Pruned => format!(
            "{label}: pruned, not traced: weight {} makes the path's weight {:.*e}, below {:.*e}; no light it could bring back would change an 8-bit value of the pixel (a tracer that traces it is not wrong)",
            d.num(b.weight.into()),
            d.0.saturating_sub(1),
            b.path_weight,
            d.0.saturating_sub(1),
            g.prune_below
        ),
        BranchFate::NotChosen => {
            format!("{label}: not chosen (after a sampled bounce glass follows one ray, picked by its Fresnel weight)")
        }
        BranchFate::Absent if g.tir && label == "refraction" => format!("{label}: none (total internal reflection)"),
        BranchFate::Absent => format!("{label}: none (weight 0)"),
    }
}

fn glass_text(g: &GlassDecision, d: Digits) -> String {
    let side = if g.entering { "entering" } else { "leaving" };
    let mut s = format!(
        "glass: {side}, n₁ {} → n₂ {}, cos θᵢ {}",
        d.num(g.n1.into()),
        d.num(g.n2.into()),
        d.num(g.cos_i.into())
    );
    if g.tir {
        let sin_i = (1.0 - f64::from(g.cos_i).powi(2)).max(0.0).sqrt();
        let _ = write!(
            s,
            ", total internal reflection (n₁/n₂·sin θᵢ = {} > 1)",
            d.num(f64::from(g.n1) / f64::from(g.n2) * sin_i)
        );
    } else if let Some(c) = g.cos_t {
        let _ = write!(s, ", cos θₜ {}", d.num(c.into()));
    } else {
        s.push_str(", no refracted ray");
    }
    let _ = write!(s, ", Fresnel reflectance {}", d.num(g.reflectance.into()));
    s
}

/// A ray tree as indented text, numbers with `digits` decimals.
#[must_use]
pub fn format_tree(t: &RayTree, digits: usize) -> String {
    let d = Digits(digits);
    let mut out = format!(
        "pixel ({}, {}) sample {}: colour {}\n(P, n: the hit point and normal of the ray's parent; t: distance along the ray)\n",
        t.x,
        t.y,
        t.sample,
        d.v3(t.color)
    );
    for n in &t.nodes {
        let indent = "  ".repeat(depth_of(t, n.id));
        let _ = write!(out, "{indent}#{} {}, depth {}", n.id, n.kind.name(), n.depth);
        if n.weight != 1.0 {
            let _ = write!(out, ", {} {}", weight_name(n.kind), d.num(n.weight.into()));
        }
        let _ = writeln!(out, ": from {} dir {}", origin_text(n, d), d.v3(n.direction));
        if let Some(light) = &n.light {
            let reach = n
                .t_max
                .map_or(String::new(), |t| format!(" (searched up to t={})", d.num(t.into())));
            match (&n.blocked_by, &n.blocker) {
                (_, Some(b)) => {
                    let _ = writeln!(
                        out,
                        "{indent}   to light '{light}'{reach}: blocked by {}",
                        surface_text(b, d)
                    );
                }
                (Some(b), None) => {
                    let _ = writeln!(out, "{indent}   to light '{light}'{reach}: blocked by '{b}'");
                }
                (None, None) => {
                    let _ = writeln!(out, "{indent}   to light '{light}'{reach}: reaches it");
                }
            }
        } else if let Some(h) = &n.hit {
            let _ = writeln!(out, "{indent}   hit {}", surface_text(h, d));
        } else {
            let _ = writeln!(out, "{indent}   miss");
        }
        if let Some(g) = &n.glass {
            let _ = writeln!(out, "{indent}   {}", glass_text(g, d));
            let child = |k: RayKind| {
                t.nodes
                    .iter()
                    .find(|c| c.parent == Some(n.id) && c.kind == k)
                    .map(|c| c.id)
            };
            for (label, b, k) in [
                ("reflection", &g.reflected, RayKind::Reflection),
                ("refraction", &g.refracted, RayKind::Refraction),
            ] {
                let _ = writeln!(out, "{indent}     {}", branch_text(label, b, child(k), g, d));
            }
        }
        let _ = writeln!(out, "{indent}   brings {}", d.v3(n.value));
    }
    out
}

fn depth_of(t: &RayTree, id: u32) -> usize {
    let mut d = 0;
    let mut cur = t.nodes.get(id as usize).and_then(|n| n.parent);
    while let Some(p) = cur {
        d += 1;
        cur = t.nodes.get(p as usize).and_then(|n| n.parent);
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_numbers_switch_to_scientific() {
        let d = Digits(4);
        assert_eq!(d.num(1.5), "1.5000");
        assert_eq!(d.num(0.0), "0.0000");
        assert_eq!(d.num(0.00004), "4.000e-5");
        assert_eq!(d.num(-0.0001), "-0.0001");
        assert_eq!(Digits(8).num(0.00004), "0.00004000");
    }
}
