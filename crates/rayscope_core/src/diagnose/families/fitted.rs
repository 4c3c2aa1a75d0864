//! What a fit finds, for the report and the JSON answer.

use std::collections::BTreeMap;

use serde::Serialize;

/// A family's parameter fitted to the student's pixels.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Fitted {
    /// What was fitted and which member fits: `fresnel-none`, `fresnel-half`,
    /// `fresnel-constant`, `fresnel-schlick` or `fresnel-curve`.
    pub code: &'static str,
    /// One sentence for the student, the fitted value against the course's.
    pub text: String,
    /// The figures: the pixels fitted, the residuals (levels, root mean square) of the fit and
    /// of the course's answer, and the family's values (weights as fractions, angles in degrees).
    pub numbers: BTreeMap<&'static str, f64>,
}
