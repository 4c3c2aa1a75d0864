//! Verdict codes: stable names, a one-line summary and a plain-English explanation of the likely
//! mistake behind each.

use serde::Serialize;

macro_rules! codes {
    ($( $variant:ident = $name:literal, $tie:literal, $summary:literal, $explain:literal; )*) => {
        /// A verdict's stable code (`camera.fov-axis`, `shadow.acne`, …).
        #[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
        pub enum Code {
            $(
                #[doc = $summary]
                $variant,
            )*
        }

        impl Code {
            /// Every code, in the order reports list them.
            pub const ALL: &'static [Code] = &[$(Code::$variant),*];

            /// The stable code.
            #[must_use]
            pub fn as_str(self) -> &'static str {
                match self { $(Code::$variant => $name),* }
            }

            /// True for a genuine tie, which is reported but not counted against the tracer.
            #[must_use]
            pub fn is_tie(self) -> bool {
                match self { $(Code::$variant => $tie),* }
            }

            /// True for a verdict on how a surface's colour was put together (`shading.*`).
            #[must_use]
            pub fn is_shading(self) -> bool {
                self.as_str().starts_with("shading.")
            }

            /// One line: what was found.
            #[must_use]
            pub fn summary(self) -> &'static str {
                match self { $(Code::$variant => $summary),* }
            }

            /// A paragraph: the likely mistake and how to fix it.
            #[must_use]
            pub fn explanation(self) -> &'static str {
                match self { $(Code::$variant => $explain),* }
            }

            /// The code named `s`.
            #[must_use]
            pub fn parse(s: &str) -> Option<Code> {
                match s { $($name => Some(Code::$variant),)* _ => None }
            }
        }
    };
}

codes! {
    CameraOrigin = "camera.origin", false,
        "camera ray does not start at the camera",
        "Camera rays start at the camera position (the origin unless --cam-pos moves it). Check the origin you give your camera rays.";
    CameraFovAxis = "camera.fov-axis", false,
        "field of view spans the wrong side of the image",
        "Your camera rays fit a field of view measured across the other side of the image: the course's 60° spans the image width (horizontal), and the height follows from the aspect ratio. The Unity workshop used a vertical FOV; on a square image the two agree, which is why this only shows on non-square images. Compute the half-width as tan(fov/2) and the half-height as tan(fov/2) × height / width (or check with --fov-axis vertical if that is what you meant).";
    CameraAspect = "camera.aspect", false,
        "wrong aspect ratio",
        "Your camera rays fit an image plane whose width-to-height ratio is wrong: either the aspect ratio is ignored (a square image plane on a non-square image) or it is applied the wrong way round (height / width instead of width / height). Objects look stretched. With a horizontal FOV the image plane is 2·tan(fov/2) wide and 2·tan(fov/2)·height/width high.";
    CameraPixelCorner = "camera.pixel-corner", false,
        "ray through the pixel's corner instead of its centre",
        "Your camera ray goes through the top-left corner of the pixel (or of the sub-pixel cell) rather than its centre: use (x + 0.5) / width and (y + 0.5) / height. The whole image shifts by half a pixel. With -x N it is each sample's own cell whose corner is taken: sample (i, j) goes through (x + (i + 0.5) / N) / width and (y + (j + 0.5) / N) / height, half a cell in from the corner, and the image shifts by half a cell.";
    CameraFlipped = "camera.flipped", false,
        "image upside down or mirrored",
        "Your camera rays fit rayscope's with the image flipped: row 0 is the top of the image, so the image-plane y is (1 − 2·(y + 0.5)/height)·half-height (positive at the top), and +x is to the right in the course's left-handed camera looking along +z.";
    CameraTransposed = "camera.transposed", false,
        "pixel column and row exchanged",
        "Your camera ray for pixel (x, y) goes where rayscope's ray for pixel (y, x) goes: the column and the row are exchanged where the pixel is mapped to the image plane (u from y and v from x, or the loops' variables swapped), so the picture is mirrored about its diagonal. The image-plane x comes from the column: (2·(x + 0.5)/width − 1)·half-width; y from the row: (1 − 2·(y + 0.5)/height)·half-height.";
    CameraPlaneDistance = "camera.plane-distance", false,
        "wrong distance to the image plane (or a wrong field of view)",
        "Your camera rays fit an image plane at a different distance from the camera than the one its size was computed for, which is the same as using a different field of view: the course puts the plane at distance 1 with a half-width of tan(fov/2). Check the image plane's distance, and whether the FOV is converted from degrees to radians and halved.";
    CameraSubpixelGrid = "camera.subpixel-grid", false,
        "sample not at rayscope's sub-pixel grid position",
        "With -x N each pixel is sampled on an N×N regular grid: sample s is cell (i, j) = (s mod N, s div N), at ((x + (i + 0.5)/N)/width, (y + (j + 0.5)/N)/height). Your ray lies elsewhere in its pixel: the details say where, and which layout that fits (rows and columns swapped, a grid that spans the pixel's corners, several samples through the same cell, or none: random jitter). Samples that are rayscope's cells numbered in another order are no mistake (`camera.sample-order`).";
    CameraSampleOrder = "camera.sample-order", false,
        "samples numbered in another order",
        "Your camera ray goes exactly through the centre of another cell of the pixel's N×N grid than rayscope's sample of that number. Where every pixel's samples still cover each cell once, that is only a numbering: the picture is the same, nothing is counted against you, and each ray is judged as the sample whose cell it crosses. rayscope numbers sample s as cell (i, j) = (s mod N, s div N), left to right, then top to bottom; numbering yours the same way lets the debugger pair your trees with rayscope's sample by sample. Where some cells get several of a pixel's samples and others none, it is a mistake, reported as one.";
    CameraOnePoint = "camera.one-point", false,
        "every sample of a pixel goes through the same point",
        "With -x N each pixel's N×N samples spread over its area: sample s goes through ((x + (i + 0.5)/N)/width, (y + (j + 0.5)/N)/height), with i = s mod N and j = s div N. Your camera rays go through one point of their pixel whatever their sample (the details say which: its centre or its top-left corner), so the sub-pixel offset is never added: each pixel traces one ray N² times and anti-aliasing does nothing. Add (i + 0.5)/N to x and (j + 0.5)/N to y inside the sample loop.";
    CameraShifted = "camera.shifted", false,
        "every camera ray shifted by the same fraction of a pixel",
        "Every camera ray your tracer got wrong crosses the image plane the same fraction of a pixel away from where rayscope puts its sample (the headline gives the shift), though each alone may fit another mistake by chance. Sample s of pixel (x, y) goes through (x + (i + 0.5)/N, y + (j + 0.5)/N) in pixels, with i = s mod N and j = s div N: look for an offset added twice (a half pixel on top of the sample's own half cell) or one left out.";
    CameraRotation = "camera.rotation", false,
        "camera turned by another angle about its axis",
        "Your camera rays fit the camera turned about the --cam-axis by an angle other than --cam-angle: the details give the angle they fit. --cam-angle is in degrees; most rotation functions (System.Numerics' Quaternion.CreateFromAxisAngle, Matrix4x4.CreateFromAxisAngle) take radians, so convert with angle · π / 180. A turn the wrong way round is the angle's sign, or the rotation applied as its inverse.";
    CameraDirection = "camera.direction", false,
        "camera ray points elsewhere",
        "Your camera ray's direction matches none of the usual mistakes rayscope knows. The details name the pixel your ray actually passes through. Check how you map pixel coordinates to the image plane, the FOV, and the camera's rotation.";
    HitMissed = "hit.missed", false,
        "missed a hit",
        "rayscope's trace of your ray hits a surface your tracer did not report. Common causes: a wrong intersection test (a sign in the quadratic, a wrong t range, rejecting t for the wrong root), or an object missing from the list you test.";
    HitPhantom = "hit.phantom", false,
        "reported a hit where there is none",
        "Your tracer reports a hit that rayscope does not find: nothing is there at that distance along the ray. Check the intersection test's acceptance conditions (a triangle's inside-outside test, a sphere's discriminant) and that t comes from the same ray you log.";
    HitFarther = "hit.farther", false,
        "chose a farther surface over a nearer one",
        "Your tracer reports a surface that lies beyond the nearest one: rayscope finds another entity in front of it. Keep the hit with the smallest positive t over all entities (not the first one found, and not the last one tested).";
    HitMissedFromInside = "hit.missed-from-inside", false,
        "missed the far side of the surface the ray leaves, from inside",
        "This ray starts on a surface and goes into it, like a ray refracted into a glass sphere: its nearest hit is the far side of that same entity, and your tracer passed it by and reported something beyond. Two mistakes do this: an intersection test that gives up when the near root is behind the origin instead of returning the far one (a sphere test must return t1 = −b + √disc when t0 ≤ ε), or a tracer that skips the entity a ray leaves (a cure for acne that also skips the way out of glass). Keep the far root, and offset the new ray's origin instead of skipping its entity.";
    HitNearSkipped = "hit.near-skipped", false,
        "hits nearer than a minimum distance are ignored",
        "Every hit your tracer passed over lies nearer to its ray's origin than every hit it kept: it ignores hits closer than a minimum distance (a test such as t > 0.05, often the cure for shadow acne). That distance is too large for the scene: surfaces that near (where objects touch, across a thin pane of glass, along a wall's foot) are missed. Ignore hits only within a tiny ε (about 1e-5 at the course's scale), or offset the new ray's origin by point + n·ε instead; the details give the distances passed over and kept.";
    HitSceneOrder = "hit.scene-order", false,
        "a hit chosen by the scene's order instead of the nearest",
        "Wherever your tracer passed over the nearest hit, the one it kept belongs to an entity listed earlier in the scene file (the first hit found wins), or one listed later (the last hit found wins: the nearest distance so far is never updated), as the details say. Typically the comparison that should pick the smallest t compares something that does not grow with distance (the length of a unit direction, always 1) or is missing. Keep the hit with the smallest positive t over all entities.";
    HitOriginDistance = "hit.origin-distance", false,
        "the hit nearest the world's origin kept instead of the nearest along the ray",
        "Wherever your tracer passed over the nearest hit, the one it kept lies nearer the world's origin (0, 0, 0): it compares hit positions' lengths, which is distance along the ray only for rays that start at the origin (the course's camera rays), not for reflected, refracted or shadow rays, or a moved camera. Compare t (or the distance from the ray's origin) instead.";
    HitOneSidedTriangle = "hit.one-sided-triangle", false,
        "ray passed through a triangle's back face",
        "Your ray went through a triangle from its back side, as a one-sided (back-face culling) intersection test does. The course's triangles are two-sided: accept the hit whatever the sign of the determinant (d · n), and flip the normal to face the ray when shading.";
    HitWrongT = "hit.wrong-t", false,
        "right surface, wrong distance",
        "Your tracer hits the right entity at the wrong distance along the ray: for spheres, the other root of the quadratic (the smaller positive root is the visible one, the larger one when the ray starts inside); elsewhere, t computed for an unnormalised direction, or from a different origin.";
    HitPointOffRay = "hit.point-off-ray", false,
        "hit point is not origin + t · direction",
        "The point you log is not where your own t puts it on your own ray. Usually the direction used to compute t was not normalised, or the point was computed from a different ray.";
    HitTriangleEdge = "hit.triangle-edge", false,
        "missed a triangle near its edge",
        "rayscope's trace of your ray meets a triangle a little inside one of its edges, and your tracer does not: its inside test rejects hits near the edges (a margin in the barycentric test such as u > ε or u + v < 1 − ε, or an epsilon scaled the wrong way), which leaves cracks along triangle edges and between a mesh's triangles. Accept 0 ≤ u, 0 ≤ v, u + v ≤ 1 exactly; the details say how far inside the edge the ray passes.";
    HitSurfaceWrong = "hit.surface-wrong", false,
        "one entity's (or one kind of surface's) intersection is wrong",
        "Rays that meet one entity, or every entity of one kind (all the spheres, say), go wrong in several ways at once (hits where there is nothing, misses, hits at the wrong distance, wrong blockers) and no other rays do. Your intersection test for that kind of surface, or the way you build that entity (its position, size or orientation, or for a model how its vertices are read), is wrong; the rest of your tracer is not at fault. The examples give your numbers beside rayscope's: compare your test with the course's definition of the surface.";
    HitBehindOrigin = "hit.behind-origin", false,
        "hit behind the ray's origin",
        "Your tracer accepts a hit with t < 0, behind where the ray starts. Only hits with t > 0 (or t > a small epsilon) are in front of the ray; for spheres, discard negative roots: a ray that starts inside a sphere (a refracted ray in glass) has one root behind it and one ahead, and the one ahead is the hit.";
    HitNormalNotUnit = "hit.normal-not-unit", false,
        "normal not of unit length",
        "The normal at this hit is not normalised. Lambert's cosine and the reflection and refraction formulas assume a unit normal: normalise it.";
    HitNormalReversedWinding = "hit.normal-reversed-winding", false,
        "triangle normal from the wrong winding",
        "The triangle's normal points away from the ray on the triangle's front face: it is the negation of (v1 − v0) × (v2 − v0), the course's convention (clockwise winding is the front face). Check the order of the cross product.";
    HitNormalWrong = "hit.normal-wrong", false,
        "normal is neither the outward normal nor the one facing the ray",
        "The normal at this hit is neither the surface's own (outward) normal nor that normal flipped to face the ray, which are the two conventions that work. For spheres it is (point − centre) / radius; for planes the normal given in the scene; for triangles (v1 − v0) × (v2 − v0), normalised.";
    HitNormalInconsistent = "hit.normal-inconsistent", false,
        "normals follow two conventions",
        "Where a ray hits the back of a surface, your tracer sometimes reports the outward normal and sometimes the one facing the ray. Either convention is fine, but mixing them means some of your shading and refraction code gets the wrong side. Pick one and use it everywhere.";
    ShadowAcne = "shadow.acne", false,
        "shadow ray blocked by the surface it leaves (shadow acne)",
        "Your shadow ray is blocked by the very surface it starts on, a rounding-error hit at t ≈ 0: the speckled dark pattern called shadow acne. Start the shadow ray a little off the surface, at point + normal · ε with the normal facing the incoming ray (ε about 1e-5 at the course's scale), or ignore hits closer than ε.";
    SecondaryAcne = "secondary.acne", false,
        "secondary ray hits the surface it leaves (self-intersection)",
        "Your reflected or refracted ray hits the surface it starts on at t ≈ 0, from rounding error. Offset its origin: point + n·ε for reflections and point − n·ε for refractions, with n facing the incoming ray.";
    SecondaryOriginNotAtHit = "secondary.origin-not-at-hit", false,
        "secondary ray does not start at its parent's hit point",
        "This ray should start where its parent ray hit (plus a tiny offset), but it starts somewhere else. Check which point you pass on, and that the parent's t is the closest hit.";
    SecondaryOffsetWrongSide = "secondary.offset-wrong-side", false,
        "origin offset to the wrong side of the surface",
        "The ray's origin is offset to the wrong side of the surface it leaves: shadow and reflected rays must start on the side the incoming ray came from (point + n·ε), refracted rays on the other side (point − n·ε), with n facing the incoming ray. Offsetting along the outward normal instead of the facing one does this on the inside of glass. Where every ray leaving a surface starts on the wrong side and diffuse surfaces come out black, the normal your tracer uses faces away from the incoming ray everywhere (a flip test with its sign reversed, if n·d < 0 then n = −n): turn n toward the ray (if n·d > 0 then n = −n), which puts the offsets and N·L right together.";
    SecondaryWrongMaterial = "secondary.wrong-material", false,
        "ray kind does not fit the material it leaves",
        "This ray's kind does not match the material of the surface its parent hit in rayscope's trace: refracted rays leave Refractive materials only, mirror reflections leave Reflective and Refractive ones. Check how you look up the material of the entity you hit.";
    ReflectionNotMirror = "reflection.not-mirror", false,
        "reflected ray is not the mirror image of its parent",
        "The reflected direction should be r = d − 2 (d · n) n, with d the incoming direction and n the unit normal. Yours differs: check the sign, the factor 2, that n is normalised, and that d points toward the surface (not away).";
    RefractionNormalNotFlipped = "refraction.normal-not-flipped", false,
        "refraction leaving glass used the outward normal",
        "Where the ray leaves the glass (it hits the inside of the surface), your refraction used the outward normal instead of the normal flipped to face the ray. With Snell's formula t = η d + (η cos θi − cos θt) n this bends the ray back into the glass. When d · n > 0, negate n (and swap the indices) before refracting.";
    RefractionIndicesNotSwapped = "refraction.indices-not-swapped", false,
        "refraction used the index ratio of the other side",
        "Your refracted ray bends with η = n2 / n1 where Snell's law needs n1 / n2 (n1 the side the ray comes from): η = n_air / n_glass = 1 / n on the way into the glass and n_glass / n_air = n on the way out. Usually the indices are not swapped when the ray hits the inside of the surface; the details say whether the ray was entering or leaving, and if it was entering, the ratio is upside down there. Entering with η = n also makes rays look past the critical angle, so your tracer may reflect them instead.";
    RefractionSnell = "refraction.snell", false,
        "refracted ray breaks Snell's law",
        "The refracted direction does not satisfy Snell's law, sin θt = (n1 / n2) sin θi, for the material's index. The details give the ratio your ray bends by. Check the formula t = η d + (η cos θi − √(1 − η² (1 − cos² θi))) n, with unit d and n and n facing the ray.";
    RefractionTirMissed = "refraction.tir-missed", false,
        "refracted ray where total internal reflection happens",
        "Past the critical angle nothing is transmitted: 1 − η² (1 − cos² θi) < 0, and all light is reflected (total internal reflection). Your tracer cast a refracted ray anyway. Check for a negative value under the square root and reflect instead.";
    RefractionTirInvented = "refraction.tir-invented", false,
        "total internal reflection where the ray refracts",
        "Your tracer reflected at glass and cast no refracted ray, as if the ray were past the critical angle, but it is not: rayscope refracts here. Check the total-internal-reflection test (it applies only when 1 − η² (1 − cos² θi) < 0, with η = n1 / n2 of the side the ray comes from).";
    ShadowOtherLight = "shadow.other-light", false,
        "shadow ray aimed at another light",
        "Your shadow ray is logged for one light but points exactly at another (the details name both): inside the loop over the lights, the shadow ray is cast towards a fixed light (the first, say, or the previous loop's) instead of the light the loop is at, or it is logged with the wrong light's name. Cast each light's shadow ray towards that light's own position, light − point.";
    ShadowNotAtLight = "shadow.not-at-light", false,
        "shadow ray not aimed at a light",
        "A shadow ray must point from the hit point toward a light: direction = normalise(light − point). This one points at no light of the scene (or not at the light it names). Check for light − point reversed as point − light, and for a direction left unnormalised.";
    ShadowBlockedBeyondLight = "shadow.blocked-beyond-light", false,
        "shadow ray blocked by something beyond the light",
        "Your tracer counts the light as blocked by an entity that lies farther away than the light itself. Only hits with t smaller than the distance to the light block it: compare t with |light − point|.";
    ShadowOneSidedTriangle = "shadow.one-sided-triangle", false,
        "triangle does not block a shadow ray arriving at its back face",
        "A triangle lies between the point and the light, but your shadow ray passes through it because it arrives at the triangle's back side: your triangle test is one-sided (it culls back faces). The course's triangles block light from both sides (scene 1's triangle casts its shadow that way): accept hits whatever the sign of d · n.";
    ShadowMissedBlocker = "shadow.missed-blocker", false,
        "shadow ray reached the light through an occluder",
        "An entity lies between the point and the light, but your tracer says the light is reached. Check that the shadow test intersects every entity (glass included) and accepts hits with 0 < t < distance to the light.";
    ShadowPhantomBlocker = "shadow.phantom-blocker", false,
        "shadow ray blocked by something that is not in the way",
        "Your tracer says this light is blocked by an entity that rayscope does not find on the segment from the point to the light. Check the intersection test's acceptance and that the shadow ray's direction is normalised before comparing t with the distance to the light.";
    ShadowBlockedCarriedOver = "shadow.blocked-carried-over", false,
        "shadow ray blocked only because the one before it from the same point was",
        "Nothing lies between this point and its light, but the shadow ray your tracer cast just before it from the same point, toward another light, is blocked (and where the log names blockers, this one names the same): a 'blocked' or 'in shadow' flag, or the blocker found, set for one light and not reset before the next. Declare it inside the loop over the lights, or reset it at the start of each pass.";
    ShadowWrongBlocker = "shadow.wrong-blocker", false,
        "light blocked, but not by the entity named",
        "The light is blocked, but the entity your tracer names is not on the shadow ray. The answer (in shadow) is right; the entity you report comes from somewhere else, perhaps an earlier ray.";
    ShadingDiffuse = "shading.diffuse", false,
        "diffuse colour does not follow the course's formula",
        "A diffuse hit's colour is albedo × Σ light colour × max(0, N·L) over the lights its shadow rays reach, with N the unit normal facing the incoming ray and L the unit direction to the light: no fall-off with distance, no ambient term, nothing for a light whose shadow ray is blocked. The details compare your colour with that sum over your own shadow rays and name the likely mistake when it fits one: N·L not clamped at 0 (lights behind the surface subtract), divided by the squared distance, L taken as the light's position without the hit point, the albedo or the light's colour left out or multiplied in twice, one light's term alone (the sum written over instead of added to), N·V in place of N·L, the whole sum times a plain factor (the lights averaged instead of added), or a constant ambient term added. Fix the diffuse term in your shading function.";
    ShadingShadowDirection = "shading.shadow-direction", false,
        "diffuse colour takes N·L along shadow rays that miss their lights",
        "The colour fits the course's diffuse sum, albedo × Σ light colour × max(0, N·L), with L taken along your own shadow rays; but those rays do not point at their lights, so N·L is wrong with them. It is what the shadow rays' mistake does to the colour: make the shadow ray's direction normalise(light − point) and use that same unit vector as L in N·L, and the colour follows.";
    ShadingMirror = "shading.mirror", false,
        "mirror colour is not its reflected ray's colour",
        "A Reflective hit brings back exactly what its reflected ray brought back: the course's mirror is perfect and its material colour plays no part at stage 2. Your colour differs from your own reflected ray's; the details say whether it fits the reflected colour multiplied by the material colour, or by one factor (which they give). Return the reflected ray's colour unchanged.";
    ShadingFresnelSchlick = "shading.fresnel-schlick", false,
        "glass mixed by Schlick's approximation instead of the Fresnel equations",
        "Your glass mixes its reflected and refracted colours as kr·R + (1 − kr)·T with kr from Schlick's approximation, R0 + (1 − R0)(1 − cos θ)⁵. The course asks for the exact unpolarised Fresnel equations: kr = (rs² + rp²) / 2 with rs = (n1 cos θi − n2 cos θt) / (n1 cos θi + n2 cos θt) and rp = (n2 cos θi − n1 cos θt) / (n2 cos θi + n1 cos θt). The two agree near normal incidence and part at grazing angles.";
    ShadingFresnelSwappedCosines = "shading.fresnel-swapped-cosines", false,
        "Fresnel reflectance with cos θi and cos θt exchanged in one term",
        "Your glass's reflected share fits the Fresnel equations with cos θi and cos θt (or n1 and n2) exchanged in one of the two reflectances, so that kr comes out as rs² or rp² instead of their mean. Write rs = (n1 cos θi − n2 cos θt) / (n1 cos θi + n2 cos θt) and rp = (n2 cos θi − n1 cos θt) / (n2 cos θi + n1 cos θt), then kr = (rs² + rp²) / 2. (Exchanging the cosines in both terms gives the same kr, and is fine.)";
    ShadingFresnelHalf = "shading.fresnel-half", false,
        "glass mixes reflection and refraction half and half",
        "Your glass brings back (R + T) / 2, an equal mix of its reflected and refracted colours. The share of reflection depends on the angle by the Fresnel equations: kr = (rs² + rp²) / 2 (about 3 % head-on for index 1.4, rising to 1 at grazing angles and past the critical angle); the colour is kr·R + (1 − kr)·T.";
    ShadingFresnelNone = "shading.fresnel-none", false,
        "glass brings back its refracted colour only (no Fresnel reflection)",
        "Your glass brings back only what its refracted ray brought back, as if nothing were reflected (kr = 0), although it cast a reflected ray. Glass reflects a share kr of the light by the Fresnel equations, kr = (rs² + rp²) / 2, and transmits the rest: the colour is kr·R + (1 − kr)·T. Without it glass looks too clear and loses its rim reflections.";
    ShadingFresnelWeightsExchanged = "shading.fresnel-weights-exchanged", false,
        "glass weights its reflected colour by 1 − kr and its refracted colour by kr",
        "Your glass mixes its colours as (1 − kr)·R + kr·T, with R the reflected and T the refracted ray's colour: the Fresnel reflectance kr, the share of light that is reflected, goes to the refracted colour instead. The colour is kr·R + (1 − kr)·T with kr = (rs² + rp²) / 2, about 3 % head-on for index 1.4: with the weights exchanged, glass seen head-on looks like a mirror and its rim like clear glass.";
    ShadingFresnel = "shading.fresnel", false,
        "glass reflects a share the Fresnel equations do not give",
        "Your glass mixes its reflected and refracted colours with a reflected share kr that is not the Fresnel reflectance at this angle, nor one of the usual mistakes rayscope knows. The details give the share your colour implies beside the exact one. Check cos θi (from the normal facing the ray, positive), cos θt = √(1 − η²(1 − cos² θi)), which index is n1 (the side the ray comes from), and that past the critical angle kr = 1.";
    ShadingGlass = "shading.glass", false,
        "glass colour is not a mix of its reflected and refracted colours",
        "A glass hit brings back kr·R + (1 − kr)·T, a weighted mix of what its reflected ray (R) and refracted ray (T) brought back, with weights that sum to 1; at stage 2 the glass's own colour plays no part. Your colour is no such mix: check for the material colour multiplied in, weights that do not sum to 1, or a term added twice.";
    ShadingGlassSum = "shading.glass-sum", false,
        "glass colour is its reflected and refracted colours added, with no weights",
        "Your glass brings back R + T, what its reflected and refracted rays brought back added together; the course's glass mixes them as kr·R + (1 − kr)·T, with kr from the Fresnel equations. Weight the two colours before adding them. If your tracer passes the weight down and each child multiplies its own colour by it, the colours your log holds for those children already carry kr and 1 − kr: log each ray's colour before that weight (docs/check.md, Colours), and rayscope names what is left.";
    ShadingTransmissionUnweighted = "shading.transmission-unweighted", false,
        "glass colour is kr·R + T: the refracted colour not weighted by 1 − kr",
        "Your glass brings back kr·R + T: its reflected colour weighted by the Fresnel reflectance, as it should be, but its refracted colour added whole instead of weighted by 1 − kr. The course's glass mixes them as kr·R + (1 − kr)·T, so that the two weights add up to 1; with T added whole the glass brings back more light than reaches it and looks too bright.";
    ShadingLoggedWeighted = "shading.logged-weighted", false,
        "colour logged after its parent glass weighted it",
        "The colour logged for this reflected or refracted ray is what it brought back multiplied by the share its parent glass gives it (kr for the reflected ray, 1 − kr for the refracted one). A log's `color` is what a ray brought back before its parent weighted it (docs/check.md, Colours), so rayscope cannot judge the decisions below and above it as logged. Log the colour before multiplying it by the Fresnel weight; if your tracer weights inside the child on purpose, your picture may well be right, and logging the unweighted colour lets rayscope judge the rest.";
    ShadingMissNotBlack = "shading.miss-not-black", false,
        "a ray that hits nothing brings back a colour",
        "A ray that leaves the scene hits nothing and brings back black at stage 2: there is no background colour or sky. Return (0, 0, 0) on a miss.";
    ShadingDepthLimit = "shading.depth-limit", false,
        "mirror or glass at the depth limit does not return black",
        "After the maximum number of mirror and glass bounces rayscope stops: a Reflective or Refractive hit at the limit returns black and casts no ray (diffuse hits are still shaded). Your tracer cast no ray there but returned a colour. Return black when the recursion stops, not the material colour or the last diffuse value.";
    MissingReflection = "missing.reflection", false,
        "glass hit without its reflected ray",
        "Glass reflects a share of the light by the Fresnel equations whichever way the ray goes, and all of it past the critical angle: a glass hit casts a reflected ray as well as the refracted one. Your log has no reflected ray at a glass hit where the reflected share is at least 1 % of the sample, although it logs refracted rays. Trace the reflection and mix: kr·R + (1 − kr)·T (or, if your tracer does cast it, log it).";
    MissingRefraction = "missing.refraction", false,
        "glass hit without its refracted ray",
        "Below the critical angle a glass hit casts two rays, the reflected one and the refracted one, and mixes their colours by Fresnel's kr: kr·R + (1 − kr)·T. Your tracer casts the reflected ray at glass and weights its colour by a share below 1, but no refracted ray leaves any glass hit in your log: the refraction is never cast (or never logged), and its share of the colour is missing. Cast the refracted ray by Snell's law and add (1 − kr)·T.";
    MissingShadowRay = "missing.shadow-ray", false,
        "diffuse hit without a shadow ray to a light that faces it",
        "A diffuse hit is lit by every light in front of it (N·L > 0) that nothing blocks, so it needs a shadow ray to each of them. Your log has none toward the light named in the details, although it logs shadow rays: check the loop over the scene's lights (an off-by-one in its bound skips the last one; a break at the first blocked light skips those after it, as the details say where that is what the log shows), and that every shadow ray cast is logged.";
    MissingSecondary = "missing.secondary", false,
        "mirror or glass hit without any ray before the depth limit",
        "A Reflective or Refractive hit casts its reflected (and refracted) ray until the depth limit is reached; this one has none in your log although it lies above the limit (rayscope's is --max-depth, 8 by default; the course's images need 7 to 12). Check your recursion's depth test (off by one, or a limit that is too low) and that every mirror and glass hit recurses.";
    ImageRounded = "image.rounded", false,
        "colours rounded to bytes instead of truncated",
        "Your picture's bytes are your logged colours rounded to the nearest byte. The course's template truncates: byte = (byte)(Math.Min(v, 1) * 255), so 0.999 · 255 = 254.7 becomes 254. About half the pixels come out one level too bright; invisible by eye, but not an exact match.";
    ImageTimes256 = "image.times-256", false,
        "colours multiplied by 256 instead of 255 when turned into bytes",
        "Your picture's bytes are your logged colours times 256, cut at 255: (byte)Math.Min(v * 256, 255). The course's template multiplies by 255 and truncates: byte = (byte)(Math.Min(v, 1) * 255), so 0.5 becomes 127, not 128. Many pixels come out one level too bright; invisible by eye, but not an exact match. Multiply the clamped colour by 255.";
    ImageGamma = "image.gamma", false,
        "colours gamma-corrected before they are written",
        "Your picture's bytes are your logged colours raised to a power (1/2.2, gamma correction, unless the details give another, such as 1/2: a square root) before the conversion. The course writes linear values: byte = (byte)(Math.Min(v, 1) * 255). Remove the power; with an exponent below 1 the picture is brighter and washed out.";
    ImageUnclamped = "image.unclamped", false,
        "colours over 1 not clamped: the byte wraps around",
        "Where a colour is over 1, your picture's byte wraps around (1.2 · 255 = 306 becomes 50) instead of saturating at 255: clamp each channel to at most 1 before multiplying by 255, as the template's Math.Min(v, 1) does. Bright spots come out dark.";
    ImageByteAverage = "image.byte-average", false,
        "samples averaged after their conversion to bytes",
        "Your picture's bytes are the average of each sample's bytes, not the bytes of the samples' average colour: with -x N, add the N×N samples' colours, divide by N², and only then clamp and convert. Where a sample is brighter than 1 the two differ (the clamp cuts it before the average).";
    ImageFlipped = "image.flipped", false,
        "picture written upside down",
        "Your picture's rows are in the opposite order to the pixels your camera rays logged: row 0 of the image is the top row. Either the rows are written bottom-up, or the camera and the output disagree on which way y goes.";
    ImageMirrored = "image.mirrored", false,
        "picture written mirrored left to right",
        "Your picture's columns are in the opposite order to the pixels your camera rays logged: column 0 of the image is its left edge, and your rays for it are right, so the mistake is in writing the picture. Either the columns are written right to left, or the loop that writes them counts x down from width − 1.";
    ImageRotated = "image.rotated", false,
        "picture written turned half a turn",
        "Your picture's rows and columns are both in the opposite order to the pixels your camera rays logged: the picture is turned half a turn (180°), while your rays are right. The loops that write the picture run backwards in x and in y, or the pixels are written last to first. Write row 0 (the top) first, each row from left to right.";
    ImageTransposed = "image.transposed", false,
        "rows and columns exchanged in the picture",
        "Your picture has at (x, y) the colours your camera rays logged for pixel (y, x): where the picture is written, x and y are exchanged — a [row, column] index given (x, y), or an index x · width + y instead of y · width + x. On a square picture nothing else shows it; on another size the picture is also the wrong shape.";
    ImageChannels = "image.channels", false,
        "red and blue exchanged in the picture",
        "Your picture's red and blue bytes are exchanged relative to the colours your camera rays logged (BGR order): write red, green, blue in that order.";
    ImageAccumulated = "image.accumulated", false,
        "each pixel adds up the pixels before it",
        "Each pixel of your picture is the sum of its own logged colour and those of every pixel before it, row by row from the top-left, or (the details say which) of those before it in its row: the variable that sums a pixel's anti-aliasing samples is set to black once, outside the loops over pixels, or once a row, and not for each pixel. Set it to black at the start of each pixel, before the loop over its samples.";
    ImageSummed = "image.summed", false,
        "samples added up, not averaged",
        "Your picture's bytes are the sum of each pixel's logged sample colours, not their average: with -x N, divide the sum of the N×N samples by N² before clamping and converting. The picture is N² times too bright, mostly white.";
    ImageOneSample = "image.one-sample", false,
        "each pixel is one sample's colour, not their average",
        "Your picture's pixels are the colour of one of their samples alone (the details say which: the first or the last), not the average of the pixel's N×N samples: anti-aliasing is traced but never shows. Add the samples' colours up over the whole sample loop and write the pixel once, after the loop, as the sum divided by N².";
    ImageScaled = "image.scaled", false,
        "colours multiplied by a plain factor before they are written",
        "Your picture's bytes are your logged colours' average times one factor, the same for every pixel (the details give it), then turned into bytes by the course's rule. With -x N the usual cause is the N×N samples' sum divided by N instead of N² (the picture N times too bright), or divided by N² twice; otherwise a brightness factor applied only when writing the picture, or the picture of another run. Divide the sum of the samples by N², then clamp and convert, with nothing else in between.";
    ImageDiffers = "image.differs", false,
        "picture not made from the logged colours",
        "Your picture's bytes are not your logged camera-ray colours turned into bytes by the course's rule (average the samples, clamp to [0, 1], byte = trunc(v · 255)), nor by any usual mistake, nor by two of them where one moves the pixels (flipped, mirrored, turned or transposed) and one changes their bytes. The picture may come from another run than the log (other flags, older code), or the colour your tracer logs is not the one it writes. The examples give your bytes beside the conversion of the logged colour; `rayscope diagnose` with the same flags compares the picture with rayscope's render instead of your log and tries pairs of mistakes.";
    TieEdge = "tie.edge", true,
        "two surfaces meet where the ray hits (a genuine tie)",
        "The ray hits where two entities meet, at the same distance (an edge of a box, a seam between two triangles): either answer is right, and which one a tracer returns is rounding. Not counted against you.";
    TieGrazing = "tie.grazing", true,
        "ray grazes an edge or silhouette (a genuine tie)",
        "The ray passes within the tolerance of a triangle's edge or a sphere's silhouette, so whether it hits depends on rounding. Not counted against you.";
    TieLightOnSurface = "tie.light-on-surface", true,
        "light lies on a surface (a genuine tie)",
        "The light sits on (or within rounding of) the surface in the way, so whether that surface blocks the shadow ray is rounding. Not counted against you.";
    TieCriticalAngle = "tie.critical-angle", true,
        "ray at the critical angle (a genuine tie)",
        "The ray meets the glass within rounding of the critical angle, so whether it refracts or is totally reflected is rounding. Not counted against you.";
}

impl Code {
    /// True for a verdict not counted against the tracer while the log is read: a tie, or a
    /// sample numbered in another order, which the log as a whole decides
    /// (`Tally::sample_order`).
    #[must_use]
    pub fn is_excused(self) -> bool {
        self.is_tie() || self == Code::CameraSampleOrder
    }
}

impl Serialize for Code {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_unique_and_round_trip() {
        let mut seen = std::collections::HashSet::new();
        for &c in Code::ALL {
            assert!(seen.insert(c.as_str()), "duplicate {}", c.as_str());
            assert_eq!(Code::parse(c.as_str()), Some(c));
            assert_eq!(c.is_tie(), c.as_str().starts_with("tie."));
            assert!(c.explanation().len() > 60, "{} needs an explanation", c.as_str());
        }
    }

    #[test]
    fn readme_lists_every_code() {
        let readme = include_str!("../../../docs/check.md");
        for &c in Code::ALL {
            assert!(
                readme.contains(&format!("`{}`", c.as_str())),
                "docs/check.md misses {}",
                c.as_str()
            );
        }
    }
}
