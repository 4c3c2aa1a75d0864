//! What a fit finds, for the report and the JSON answer.

use std::collections::BTreeMap;

use serde::Serialize;

/// A family's parameter fitted to the student's pixels.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Fitted {
    /// What was fitted and which member fits: `fresnel-none`, `fresnel-half`,
    /// `fresnel-constant`, `fresnel-schlick` or `fresnel-curve`; `aa-level`, `aa-corner`,
    /// `aa-interior`, `aa-diagonal`, `aa-shifted`, `aa-jittered`, `aa-jittered-cells` or `aa-stage1`.
    pub code: &'static str,
    /// One sentence for the student, the fitted value against the course's.
    pub text: String,
    /// The figures: the pixels fitted, the residuals (levels, root mean square) of the fit and
    /// of the course's answer, and the family's values (weights as fractions, angles in degrees).
    pub numbers: BTreeMap<&'static str, f64>,
    /// True where what was fitted is a correct way too (random anti-aliasing samples, a stage-1
    /// picture anti-aliased as `-x` asks): said, not a mistake.
    pub allowed: bool,
}

impl Fitted {
    /// The family fitted, as the report names it: "glass's Fresnel weight" or "anti-aliasing".
    #[must_use]
    pub fn family(&self) -> &'static str {
        if self.code.starts_with("aa-") {
            "anti-aliasing"
        } else {
            "glass's Fresnel weight"
        }
    }
}
