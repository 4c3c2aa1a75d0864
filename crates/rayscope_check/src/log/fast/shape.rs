//! A reader for records of one exact shape, the one rayscope's own logs and the kits write:
//! no spaces, the fields in the order `pixel`, `sample`, `id`, `parent`, `kind`, `origin`,
//! `direction`, `hit`, `light`, `blocked_by`, `color` (`hit` also after `blocked_by`), each one
//! optional. A record of that shape whose names the scene has, whose pixel and sample lie in the
//! image and whose direction has a length is read straight into the ray the check judges, each
//! field's text compared once and each value read once. Anything else returns `None` and is
//! read by the general path ([`super::parse`], then the checks of [`super::super::parse_line`]),
//! which gives the same ray for every record this reader accepts.

use glam::DVec3;
use rustc_hash::FxHashMap;

use super::{key, tight_vec3, Cursor, Lit};
use crate::log::{Answer, HitClaim, Kind, LogContext, LoggedRay};

/// The names of a scene's entities or of its lights by their bytes: the reader looks a name up
/// before it is decoded (a name found is the scene's, so it is UTF-8). Names of up to fifteen
/// bytes are found by the sixteen bytes that hold them, as one integer ([`key`]), longer ones by
/// their bytes.
#[derive(Debug, Clone, Default)]
pub(in crate::log) struct Names {
    short: FxHashMap<u128, u32>,
    long: FxHashMap<Box<[u8]>, u32>,
}

impl Names {
    /// `names` by their index; a name given twice is the last one's.
    pub(in crate::log) fn new(names: &[String]) -> Self {
        let mut index = Self::default();
        for (i, n) in names.iter().enumerate() {
            let b = n.as_bytes();
            if b.len() <= 15 {
                index.short.insert(key(b), i as u32);
            } else {
                index.long.insert(b.into(), i as u32);
            }
        }
        index
    }
}

/// A member's key as the shape writes it: `"key":` for the first member of its object, and
/// with the comma before it for the others.
struct Member {
    first: Lit,
    next: Lit,
}

impl Member {
    const fn new(k: &[u8]) -> Member {
        let mut t = [0u8; 16];
        t[0] = b',';
        t[1] = b'"';
        let mut j = 0;
        while j < k.len() {
            t[j + 2] = k[j];
            j += 1;
        }
        t[k.len() + 2] = b'"';
        t[k.len() + 3] = b':';
        let (_, with_comma) = t.split_at(0);
        let (with_comma, _) = with_comma.split_at(k.len() + 4);
        let (_, without) = with_comma.split_at(1);
        Member {
            first: Lit::new(without),
            next: Lit::new(with_comma),
        }
    }
}

const PIXEL: Member = Member::new(b"pixel");
const SAMPLE: Member = Member::new(b"sample");
const ID: Member = Member::new(b"id");
const PARENT: Member = Member::new(b"parent");
const KIND: Member = Member::new(b"kind");
const ORIGIN: Member = Member::new(b"origin");
const DIRECTION: Member = Member::new(b"direction");
const HIT: Member = Member::new(b"hit");
const LIGHT: Member = Member::new(b"light");
const BLOCKED_BY: Member = Member::new(b"blocked_by");
const COLOR: Member = Member::new(b"color");
const T: Member = Member::new(b"t");
const POINT: Member = Member::new(b"point");
const NORMAL: Member = Member::new(b"normal");
const ENTITY: Member = Member::new(b"entity");

/// The kind words rayscope writes, quoted.
const KINDS: [(Lit, Kind); 4] = [
    (Lit::new(b"\"camera\""), Kind::Camera),
    (Lit::new(b"\"shadow\""), Kind::Shadow),
    (Lit::new(b"\"reflection\""), Kind::Reflection),
    (Lit::new(b"\"refraction\""), Kind::Refraction),
];

impl Cursor<'_> {
    /// True, with the cursor moved past it, when the record has exactly `text` at the cursor.
    #[inline(always)]
    fn lit<const N: usize>(&mut self, text: &[u8; N]) -> bool {
        let found = self
            .b
            .get(self.i..self.i + N)
            .is_some_and(|w| <&[u8; N]>::try_from(w).is_ok_and(|w| w == text));
        if found {
            self.i += N;
        }
        found
    }

    /// The member `m` (its key, quoted, and the colon), after a comma unless it is the first
    /// member of its object; `first` is cleared when it is found.
    #[inline(always)]
    fn member(&mut self, m: &Member, first: &mut bool) -> bool {
        // Each text compared as a constant: most members are not the first.
        if !*first {
            return self.lit16(&m.next);
        }
        let found = self.lit16(&m.first);
        if found {
            *first = false;
        }
        found
    }

    /// `null` as `Some(None)`, digits as their integer of at most `most` digits; `None` for
    /// anything else.
    #[inline(always)]
    fn int_or_null(&mut self, most: usize) -> Option<Option<u64>> {
        if self.lit(b"null") {
            return Some(None);
        }
        self.plain_integer(most).map(Some)
    }

    /// A string naming one of `names`, by its index.
    #[inline(always)]
    fn name_in(&mut self, names: &Names) -> Option<u32> {
        let (s, _) = self.string_bytes()?;
        if s.len() > 15 {
            return names.long.get(s).copied();
        }
        // The sixteen bytes from the name's first one, masked to the name: one load.
        let v = u128::from_le_bytes(self.window(self.i - 1 - s.len()));
        let k = (v & ((1u128 << (8 * s.len())) - 1)) | ((s.len() as u128) << 120);
        names.short.get(&k).copied()
    }

    /// Three numbers in brackets: without spaces at once, else as [`Cursor::vec3`] reads them.
    #[inline(always)]
    fn shaped_vec3(&mut self) -> Option<[f64; 3]> {
        if let Some((v, end)) = tight_vec3(self.b, self.i) {
            self.i = end;
            return Some(v);
        }
        self.vec3()
    }

    /// A hit object of the shape: `t`, `point`, `normal` and `entity`, each optional.
    fn shaped_hit(&mut self, ctx: &LogContext) -> Option<HitClaim> {
        if !self.lit(b"{") {
            return None;
        }
        let mut h = HitClaim::default();
        let mut first = true;
        if self.member(&T, &mut first) {
            h.t = Some(self.f64()?);
        }
        if self.member(&POINT, &mut first) {
            h.point = Some(DVec3::from_array(self.shaped_vec3()?));
        }
        if self.member(&NORMAL, &mut first) {
            h.normal = Some(DVec3::from_array(self.shaped_vec3()?));
        }
        if self.member(&ENTITY, &mut first) {
            h.entity = Some(self.name_in(&ctx.entity_names)?);
        }
        self.lit(b"}").then_some(h)
    }

    /// A `hit` member's value: `null` or a hit of the shape.
    fn shaped_hit_answer(&mut self, ctx: &LogContext) -> Option<Answer<HitClaim>> {
        if self.lit(b"null") {
            return Some(Answer::Nothing);
        }
        self.shaped_hit(ctx).map(Answer::Found)
    }

    /// A `blocked_by` member's value: `null`, `true`, `false` or an entity's name.
    fn shaped_blocker(&mut self, ctx: &LogContext) -> Option<Answer<Option<u32>>> {
        if self.lit(b"null") || self.lit(b"false") {
            return Some(Answer::Nothing);
        }
        if self.lit(b"true") {
            return Some(Answer::Found(None));
        }
        Some(Answer::Found(Some(self.name_in(&ctx.entity_names)?)))
    }

    /// The kind words rayscope writes; `None` for any other string.
    #[inline(always)]
    fn shaped_kind(&mut self) -> Option<Kind> {
        KINDS.iter().find(|(w, _)| self.lit16(w)).map(|(_, k)| k.clone())
    }
}

/// Reads a record of the shape (see the module's documentation) on line `line` straight into
/// its ray, or `None` to leave it to the general path.
pub(in crate::log) fn ray(bytes: &[u8], line: u64, ctx: &LogContext) -> Option<LoggedRay> {
    let mut c = Cursor { b: bytes, i: 0 };
    if !c.lit(b"{") {
        return None;
    }
    let mut r = LoggedRay::blank(line);
    let mut first = true;
    if c.member(&PIXEL, &mut first) {
        if !c.lit(b"[") {
            return None;
        }
        // Nine digits cannot exceed a u32.
        let x = c.plain_integer(9)? as u32;
        if !c.lit(b",") {
            return None;
        }
        let y = c.plain_integer(9)? as u32;
        if !c.lit(b"]") || x >= ctx.width || y >= ctx.height {
            return None;
        }
        r.pixel = Some([x, y]);
    }
    let mut sample = 0;
    if c.member(&SAMPLE, &mut first) {
        sample = c.plain_integer(9)? as u32;
        if sample >= ctx.spp {
            return None;
        }
    }
    r.sample = Some(sample);
    // Eighteen digits cannot exceed an i64.
    if c.member(&ID, &mut first) {
        r.id = c.int_or_null(18)?.map(|v| v as i64);
    }
    if c.member(&PARENT, &mut first) {
        r.parent = c.int_or_null(18)?.map(|v| v as i64);
    }
    if c.member(&KIND, &mut first) {
        r.kind = Some(c.shaped_kind()?);
    }
    if !c.member(&ORIGIN, &mut first) {
        return None;
    }
    r.origin = DVec3::from_array(c.shaped_vec3()?);
    if !c.member(&DIRECTION, &mut first) {
        return None;
    }
    let d = DVec3::from_array(c.shaped_vec3()?);
    let mut hit = false;
    if c.member(&HIT, &mut first) {
        r.hit = c.shaped_hit_answer(ctx)?;
        hit = true;
    }
    if c.member(&LIGHT, &mut first) {
        r.light = Some(c.name_in(&ctx.light_names)?);
    }
    if c.member(&BLOCKED_BY, &mut first) {
        r.blocked_by = c.shaped_blocker(ctx)?;
    }
    if !hit && c.member(&HIT, &mut first) {
        r.hit = c.shaped_hit_answer(ctx)?;
    }
    if c.member(&COLOR, &mut first) {
        r.color = Some(DVec3::from_array(c.shaped_vec3()?));
    }
    if !c.lit(b"}") || c.i != bytes.len() {
        return None;
    }
    let len = d.length();
    if !(len > 0.0 && len.is_finite()) {
        return None;
    }
    r.direction = d / len;
    r.dir_len = len;
    Some(r)
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use proptest::prelude::*;

    use super::*;
    use crate::log::parse_general;

    fn ctx() -> LogContext {
        let src = "Material \"M\" Diffuse (1, 1, 1) 1\n\
            PointLight \"L1\" (0, 1, 0) (1, 1, 1)\n\
            PointLight \"Lé\" (0, 2, 0) (1, 1, 1)\n\
            Triangle \"A\" (-1, -1, 2) (-1, 1, 2) (1, 1, 2) \"M\"\n\
            Sphere \"Ball\" (0, 0, 5) 1 \"M\"\n\
            Plane \"Floor\" (0, 0, 9) (0, 0, -1) \"M\"\n";
        let file = rayscope_scene::parse_str(src, Path::new("t.txt")).expect("scene");
        let scene = rayscope_core::Scene::from_file(&file);
        LogContext::new(&scene, 40, 30, 4, 2)
    }

    /// The reader gives the general path's ray for `line`, or leaves the line to it.
    fn agrees(line: &str, ctx: &LogContext) -> Result<bool, String> {
        let Some(fast) = ray(line.as_bytes(), 7, ctx) else {
            return Ok(false);
        };
        match parse_general(line.as_bytes(), 7, Path::new("log.jsonl"), ctx) {
            Ok(Some(general)) if general == fast => Ok(true),
            other => Err(format!("{line}: read as {fast:?}, the general path gives {other:?}")),
        }
    }

    #[test]
    fn reads_rayscope_s_own_records_as_the_general_path_does() {
        let ctx = ctx();
        let lines = [
            r#"{"pixel":[0,0],"sample":0,"id":0,"parent":null,"kind":"camera","origin":[0,0,0],"direction":[-0.44704583,0.44704583,0.7747903],"hit":{"t":2.236907,"point":[-0.99999994,0.99999994,1.7331338],"normal":[0,-1,0],"entity":"Floor"},"color":[0.17660473,0.17660473,0.17660473]}"#,
            r#"{"pixel":[39,29],"sample":3,"id":1,"parent":0,"kind":"shadow","origin":[-0.99999994,0.9999826,1.7331338],"direction":[0.9559232,-0.191168,-0.22285801],"light":"L1","blocked_by":null}"#,
            r#"{"pixel":[1,2],"sample":1,"id":2,"parent":0,"kind":"shadow","origin":[-1,0.9,1.7],"direction":[0.3,-0.5,-0.8],"light":"Lé","blocked_by":"Ball"}"#,
            r#"{"pixel":[1,2],"sample":1,"id":3,"parent":0,"kind":"reflection","origin":[-1,0.9,1.7],"direction":[0.3,-0.5,-0.8],"hit":null,"color":[0,0,0]}"#,
            r#"{"pixel":[1,2],"sample":1,"id":4,"parent":3,"kind":"refraction","origin":[-1,0.9,1.7],"direction":[3e-1,-5,-8],"hit":{"point":[1,2,3],"normal":[0,0,1]},"color":[1.5,0.25,1e-7]}"#,
            r#"{"pixel":[1,2],"id":5,"parent":3,"kind":"shadow","origin":[-1,0.9,1.7],"direction":[0.3,-0.5,-0.8],"light":"L1","blocked_by":true,"hit":{"entity":"A"}}"#,
            r#"{"origin":[ 1, 2 ,3],"direction":[0,0,1],"blocked_by":false}"#,
        ];
        for line in lines {
            assert_eq!(agrees(line, &ctx), Ok(true), "{line}");
        }
    }

    #[test]
    fn leaves_other_records_to_the_general_path() {
        let ctx = ctx();
        let lines = [
            // Not the shape: spaces, another order, another key, a light by position.
            r#"{ "origin":[0,0,0],"direction":[0,0,1]}"#,
            r#"{"direction":[0,0,1],"origin":[0,0,0]}"#,
            r#"{"origin":[0,0,0],"direction":[0,0,1],"depth":2}"#,
            r#"{"origin":[0,0,0],"direction":[0,0,1],"light":[0,1,0]}"#,
            r#"{"origin":[0,0,0],"direction":[0,0,1]} "#,
            r#"{"origin":[0,0,0],"direction":[0,0,1],"kind":"primary"}"#,
            // The shape, but not a ray the check takes: the general path words why.
            r#"{"pixel":[40,0],"origin":[0,0,0],"direction":[0,0,1]}"#,
            r#"{"sample":4,"origin":[0,0,0],"direction":[0,0,1]}"#,
            r#"{"origin":[0,0,0],"direction":[0,0,0]}"#,
            r#"{"origin":[0,0,0],"direction":[0,0,1],"hit":{"entity":"Wall"}}"#,
            r#"{"origin":[0,0,0],"direction":[0,0,1],"light":"L2"}"#,
            r#"{"origin":[0,0,0],"direction":[0,0,1],"hit":{"t":1,"t":2}}"#,
            r#"{"origin":[0,0,0],"direction":[0,0,1],"color":[0,0,0],"color":[0,0,0]}"#,
        ];
        for line in lines {
            assert_eq!(agrees(line, &ctx), Ok(false), "{line}");
        }
    }

    fn number() -> impl Strategy<Value = String> {
        prop_oneof![
            any::<f32>()
                .prop_filter("finite", |v| v.is_finite())
                .prop_map(|v| format!("{v}")),
            any::<f64>()
                .prop_filter("finite", |v| v.is_finite())
                .prop_map(|v| format!("{v:e}")),
            (-1000i64..1000).prop_map(|v| v.to_string()),
            Just("null".to_string()),
        ]
    }

    fn vec3() -> impl Strategy<Value = String> {
        (number(), number(), number()).prop_map(|(x, y, z)| format!("[{x},{y},{z}]"))
    }

    fn name() -> impl Strategy<Value = String> {
        prop_oneof![
            Just("\"A\"".to_string()),
            Just("\"Ball\"".to_string()),
            Just("\"Floor\"".to_string()),
            Just("\"L1\"".to_string()),
            Just("\"Lé\"".to_string()),
            Just("null".to_string()),
            Just("true".to_string()),
            "\"[A-Za-z0-9\\\\]{0,6}\"",
        ]
    }

    fn hit() -> impl Strategy<Value = String> {
        (
            proptest::option::of(number()),
            proptest::option::of(vec3()),
            proptest::option::of(vec3()),
            proptest::option::of(name()),
        )
            .prop_map(|(t, p, n, e)| {
                let parts: Vec<String> = [
                    t.map(|v| format!("\"t\":{v}")),
                    p.map(|v| format!("\"point\":{v}")),
                    n.map(|v| format!("\"normal\":{v}")),
                    e.map(|v| format!("\"entity\":{v}")),
                ]
                .into_iter()
                .flatten()
                .collect();
                format!("{{{}}}", parts.join(","))
            })
    }

    /// The members of a record in the shape's order, each present or not.
    fn record() -> impl Strategy<Value = String> {
        let int = || {
            prop_oneof![
                (0u64..50).prop_map(|v| v.to_string()),
                Just("null".to_string()),
                Just("-1".to_string())
            ]
        };
        (
            (
                proptest::option::of((0u32..45, 0u32..35).prop_map(|(x, y)| format!("[{x},{y}]"))),
                proptest::option::of(int()),
                proptest::option::of(int()),
                proptest::option::of(int()),
                proptest::option::of(prop_oneof![
                    Just("\"camera\""),
                    Just("\"shadow\""),
                    Just("\"reflection\""),
                    Just("\"refraction\""),
                    Just("\"eye\""),
                ]),
            ),
            (
                proptest::option::of(vec3()),
                proptest::option::of(vec3()),
                proptest::option::of(prop_oneof![Just("null".to_string()), hit()]),
                proptest::option::of(name()),
                proptest::option::of(name()),
                proptest::option::of(vec3()),
                any::<bool>(),
            ),
        )
            .prop_map(|((px, s, id, parent, kind), (o, d, h, l, b, c, hit_last))| {
                let mut m: Vec<String> = Vec::new();
                let mut add = |k: &str, v: Option<String>| {
                    if let Some(v) = v {
                        m.push(format!("\"{k}\":{v}"));
                    }
                };
                add("pixel", px);
                add("sample", s);
                add("id", id);
                add("parent", parent);
                add("kind", kind.map(str::to_string));
                add("origin", o);
                add("direction", d);
                if !hit_last {
                    add("hit", h.clone());
                }
                add("light", l);
                add("blocked_by", b);
                if hit_last {
                    add("hit", h);
                }
                add("color", c);
                format!("{{{}}}", m.join(","))
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(3000))]
        /// Whatever record of the shape it reads, the reader reads as the general path does.
        #[test]
        fn random_records_of_the_shape_read_as_the_general_path_reads_them(line in record()) {
            let ctx = ctx();
            prop_assert_eq!(agrees(&line, &ctx).map(|_| ()), Ok(()));
        }
    }
}
