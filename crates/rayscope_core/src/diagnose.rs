//! What does a wrong picture mean? [`diagnose`] compares a student's image with rayscope's,
//! says where they differ (attributed to the entities each differing pixel's ray tree ends on,
//! a mirror's reflection to the thing reflected), and searches the renderer's free settings and
//! the catalogue of [`Mistake`]s, alone and in pairs, for the render that explains the image.
//! Before any search it says what is plain ([`Obvious`]): a black, white or one-coloured image,
//! one upside down, mirrored or transposed, saved with gamma, or with an alpha channel.
//!
//! **The match rule.** An image *is* a render when every pixel lies within that pixel's tie
//! bounds (`ties.rs`): where a ray of the pixel's samples passes within rounding of an edge, a
//! rim, a seam of two surfaces at the same distance, a shadow boundary or the critical angle, or
//! a shadow ray's blocker lies within the offsets correct tracers use of its origin, two
//! correct tracers may see either side, and the bounds span the colours of both sides;
//! everywhere else they are rayscope's colour, and the byte next to it only where the colour
//! lies within rounding of a byte boundary. The decision never rests on a share of pixels or a
//! PSNR: a render is called the image (the image matches, or an explanation is offered as its
//! cause by matching) only by this rule.
//!
//! The search is two passes. The coarse pass renders every candidate on a sparse grid of the
//! image's pixels (about [`DiagnoseOptions::coarse_samples`] samples), and at the pixels where
//! the image lies beyond the ties of rayscope's render, and scores it against the same pixels
//! of the student's image; the best few are then rendered at full size, checked by the match
//! rule and ranked. Scores rank candidates, they decide nothing: the better of two PSNRs, pixel
//! for pixel and between block averages of both images (a "downsampled" comparison, which sees
//! speckle such as shadow acne as the darkening it is even where the speckles themselves fall
//! on other pixels). The pixel-for-pixel one is robust: it leaves out up to `OUTLIERS` of the
//! pixels, worst first, among those whose colour some pixel next to them has in rayscope's
//! render, so that a render off only at edges ranks above one off everywhere.

use std::collections::{BTreeMap, HashMap};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use glam::{DVec3, Vec3, Vec3A};
use rayon::prelude::*;
use rayscope_scene::{MaterialDef, MaterialKind, SceneFile};
use serde::{Serialize, Serializer};

use crate::camera::FovAxis;
use crate::compare::compare_rgb8;
use crate::contents::SceneContents;
use crate::edition::edition_matters;
use crate::film::to_byte;
use crate::integrator::{Counters, Integrator};
use crate::mistakes::{Mistake, Mistakes};
use crate::observer::NoObserver;
use crate::render::{render, Mistaken};
use crate::scene::{Intersect, Scene};
use crate::settings::{Channel, DepthLimit, Edition, RenderSettings, Setting, SettingsPatch, Stage};

mod acne;
mod explained;
mod families;
mod fov;
mod missing;
mod offset;
mod scale;
mod ties;

pub use acne::Recognised;
use explained::{block_means, Traced, BLOCK};
pub use explained::{Explained, NextStep, PartExplained};
pub use families::Fitted;

/// Largest share of the pixels the robust PSNR, a ranking score, leaves out (see the module's
/// notes).
pub(crate) const OUTLIERS: f64 = 0.01;

/// Slack, in levels, of the neighbourhood test that excuses a pixel (see [`near_in`]).
const NEIGHBOUR_LEVELS: u8 = 2;

/// How hard [`diagnose`] searches.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiagnoseOptions {
    /// Try pairs of mistakes and settings, not only single ones.
    pub pairs: bool,
    /// Samples the coarse pass renders per candidate (pixels × samples per pixel).
    pub coarse_samples: u64,
    /// Candidates the coarse pass hands to the full-size pass.
    pub confirm: usize,
    /// Explanations reported.
    pub report: usize,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        Self {
            pairs: true,
            coarse_samples: 10_000,
            confirm: 6,
            report: 5,
        }
    }
}

/// Serialises a PSNR, with `null` for identical images (infinite PSNR).
fn ser_db<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
    if v.is_finite() {
        s.serialize_f64((v * 100.0).round() / 100.0)
    } else {
        s.serialize_none()
    }
}

/// A share of the differing pixels, attributed to what the pixels' rays end on.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Share {
    /// The entity (or `(background)` where rayscope's ray hits nothing).
    pub entity: String,
    /// Mirrors the difference is seen in, nearest first (empty: seen directly).
    pub seen_in: Vec<String>,
    /// Differing pixels attributed to it (of those traced).
    pub pixels: u64,
    /// Their share of the differing pixels traced, in percent.
    pub percent: f64,
    /// How the image differs there, with the course's item it belongs to ("darker (diffuse
    /// shading and shadow rays, stage 1)"); empty where not judged.
    #[serde(skip_serializing_if = "String::is_empty")]
    pub how: String,
}

/// A rectangle of pixels, `x0..x1` × `y0..y1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Region {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

/// One explanation: settings changes and mistakes whose render matches the image better.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Explanation {
    /// Mistakes (catalogue names).
    pub mistakes: Vec<String>,
    /// Settings changed from the flags, as flags (`-x 1`, `--max-depth 3`, `--fov-axis vertical`).
    pub settings: Vec<String>,
    /// The same settings changes as data, in the debugger's settings API's keys (`aa`,
    /// `max_depth`, `depth_limit`, `fov_axis`): what a front end applies to render it.
    pub patch: SettingsPatch,
    /// Human-readable description.
    pub summary: String,
    /// Flags that render this explanation with rayscope: the size, stage, the settings the
    /// search varies and the mistakes (the camera flags given to `diagnose` are to be added).
    pub flags: String,
    /// PSNR of the image against this render, pixel for pixel.
    #[serde(serialize_with = "ser_db")]
    pub psnr_db: f64,
    /// The same without up to `OUTLIERS` of the pixels: the worst of those whose colour a
    /// neighbouring pixel of the render has (a ranking score).
    #[serde(serialize_with = "ser_db")]
    pub robust_db: f64,
    /// PSNR of the two images averaged over blocks of `BLOCK`×`BLOCK` pixels.
    #[serde(serialize_with = "ser_db")]
    pub psnr_downsampled_db: f64,
    /// True when the image is this render: every pixel lies within the render's tie bounds
    /// (see the module's notes).
    pub matches: bool,
    /// How much of the difference this render reproduces, overall and per part (null for a
    /// recursion limit found behind a match).
    pub explained: Option<Explained>,
    /// Offered as the cause: the image is this render ([`Self::matches`]), or the render
    /// reproduces the whole difference ([`Explained`]; speckle such as acne on average, since
    /// each tracer's rounding puts its speckles on other pixels). Otherwise the render explains
    /// only a part.
    pub cause: bool,
    /// Where rayscope's render with these entities (black in the image) painted black gives
    /// the picture as well as this render does: one way to get the picture, which any mistake
    /// that blackens them shares (empty otherwise). Not offered as the cause.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub blackens: Vec<String>,
    /// Where rayscope's render with every glass's refracted light lost (its reflection kept)
    /// gives the picture as well as this render does: the glass entities that differ, one way
    /// to get the picture that many mistakes share (empty otherwise). Not offered as the cause.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub loses_refraction: Vec<String>,
    /// Other single mistakes or settings of the search whose renders match the picture as this
    /// one's does, in words (empty otherwise): the picture cannot tell them apart, so none is
    /// offered as the cause.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub same_as: Vec<String>,
    /// Where rayscope's render with every entity of one kind casting no shadow gives the
    /// picture as well as this render does: that kind's scene command (`Triangle`), one way to
    /// get the picture that many mistakes share (empty otherwise). Not offered as the cause.
    #[serde(skip_serializing_if = "String::is_empty")]
    pub shadowless: String,
}

impl Explanation {
    /// True when this render is one way to get the picture that other mistakes share
    /// ([`Self::blackens`], [`Self::loses_refraction`], [`Self::same_as`],
    /// [`Self::shadowless`]), not its cause.
    fn one_way(&self) -> bool {
        !self.blackens.is_empty()
            || !self.loses_refraction.is_empty()
            || !self.same_as.is_empty()
            || !self.shadowless.is_empty()
    }
}

/// What [`diagnose`] found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Diagnosis {
    /// What is plain about the image before any search (a constant colour, a flip, an alpha
    /// channel, gamma), most important first.
    pub obvious: Vec<Obvious>,
    /// True when the image matches rayscope's render under the given settings (in
    /// [`Self::edition`] where the search chose one); false where it does only mirrored or
    /// transposed back (see [`Self::obvious`]).
    pub matches: bool,
    /// The course edition the image was judged by, where the scene's coloured glass makes the
    /// editions differ: the one whose render the image is closer to, searched whatever the
    /// flags say ("2021" or "2022"); null where both give the same render.
    pub edition: Option<String>,
    /// The edition the flags asked for was not the one the image follows.
    pub edition_changed: bool,
    /// PSNR of the image against rayscope's render (null when identical).
    #[serde(serialize_with = "ser_db")]
    pub psnr_db: f64,
    /// The same without up to `OUTLIERS` of the pixels (those a neighbour's colour explains);
    /// a score, not the match rule.
    #[serde(serialize_with = "ser_db")]
    pub robust_db: f64,
    /// PSNR after averaging both over `BLOCK`×`BLOCK` blocks.
    #[serde(serialize_with = "ser_db")]
    pub psnr_downsampled_db: f64,
    /// Pixels whose largest channel difference is at least `threshold`.
    pub differing_pixels: u64,
    /// Pixels in the image.
    pub(crate) total_pixels: u64,
    /// Channel difference (in 8-bit levels) counted as a difference.
    pub threshold: u8,
    /// Largest channel difference.
    pub max_channel_diff: u8,
    /// The box around the differing pixels.
    pub region: Option<Region>,
    /// The differing pixels against the ties of rayscope's render (the match rule).
    pub ties: TieSummary,
    /// Where the differences are, largest share first.
    pub attribution: Vec<Share>,
    /// Explanations, best first: those that match ([`Explanation::matches`]), then those that
    /// explain a part of the difference ([`Explained`]); a render that does neither is no
    /// explanation and is not listed. Empty when the image matches or nothing explains it.
    pub explanations: Vec<Explanation>,
    /// Families of mistakes whose parameter, fitted to the image, explains a part of it where
    /// the course's value does not (the Fresnel weight of glass): beneath a catalogued cause, the
    /// value the image shows; where no catalogued mistake explains that part, the finding itself.
    pub fitted: Vec<Fitted>,
    /// Mistakes recognised from how the picture looks (shadow acne: specks of lost light where
    /// rayscope's render is smooth), where no catalogued render is the cause.
    pub recognised: Vec<Recognised>,
    /// Where no explanation matches: the pixels to log with the student's own tracer and the
    /// commands that judge them.
    pub next: Option<NextStep>,
    /// Candidate renders the search tried.
    pub candidates: usize,
    /// Wall time of the diagnosis in seconds.
    pub seconds: f64,
}

/// The image against the ties of rayscope's render: how many of the pixels that differ lie
/// within their tie bounds (see the module's notes).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct TieSummary {
    /// Pixels whose colour is not rayscope's.
    pub differing_pixels: u64,
    /// Of those, the pixels checked against their tie bounds: all of them when the image
    /// matches; otherwise the check stops after the first batch with a pixel beyond them.
    pub checked_pixels: u64,
    /// Checked pixels within their tie bounds: where two correct tracers may disagree.
    pub tie_pixels: u64,
    /// Checked pixels beyond their tie bounds (none when the image matches).
    pub beyond_ties: u64,
    /// Largest distance, in levels, of a channel outside its tie bounds, over the checked
    /// pixels (0 when the image matches).
    pub worst_levels: u8,
}

impl TieSummary {
    fn of(v: &ties::Verdict) -> TieSummary {
        TieSummary {
            differing_pixels: v.differing,
            checked_pixels: v.checked,
            tie_pixels: v.ties,
            beyond_ties: v.beyond.len() as u64,
            worst_levels: v.worst,
        }
    }
}

/// Something plain about the image that [`diagnose`] says before any search.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Obvious {
    /// What it is: `black`, `white`, `constant`, `transposed`, `rotated-clockwise`,
    /// `rotated-anticlockwise`, `anti-transposed`, `rotated-180`, `upside-down`, `mirrored`,
    /// `channels`, `grey`, `channels-missing`, `gamma` or `alpha`.
    pub code: &'static str,
    /// One line for the student, with the figures that show it.
    pub text: String,
    /// Those figures by name (PSNRs in dB, counts of pixels, colours in levels).
    pub numbers: BTreeMap<&'static str, f64>,
    /// True when the rest of the diagnosis judges the image turned back (mirrored, rotated,
    /// transposed) or with its channels put back in order.
    pub turned_back: bool,
}

impl Obvious {
    fn new(code: &'static str, text: String, numbers: &[(&'static str, f64)]) -> Obvious {
        Obvious {
            code,
            text,
            turned_back: code == "channels" || TURNS.iter().any(|t| t.code == code && t.code != "upside-down"),
            // Two decimals, as the other PSNRs; an identical image's infinite PSNR is `null`.
            numbers: numbers
                .iter()
                .map(|&(k, v)| (k, if v.is_finite() { (v * 100.0).round() / 100.0 } else { v }))
                .collect(),
        }
    }

    /// The finding with the report's note that what follows judges the image turned back.
    fn judged_turned_back(mut self) -> Obvious {
        if self.turned_back {
            self.text.push_str(" The rest of this report judges it turned back.");
        }
        self
    }

    /// Rank in the report: what makes the rest meaningless first.
    fn rank(&self) -> usize {
        [
            "black",
            "white",
            "constant",
            "transposed",
            "rotated-clockwise",
            "rotated-anticlockwise",
            "anti-transposed",
            "rotated-180",
            "upside-down",
            "mirrored",
            "channels",
            "grey",
            "channels-missing",
            "gamma",
            "alpha",
        ]
        .iter()
        .position(|c| *c == self.code)
        .unwrap_or(usize::MAX)
    }
}

/// An image whose PSNR against a render changed by a transform (flipped, gamma-encoded) is at
/// least this is that transform of the render, for [`diagnose`]'s plain checks: far above the
/// 10–20 dB an unrelated picture of the same scene reaches, low enough to allow another
/// mistake besides.
const PLAIN_DB: f64 = 30.0;

/// How far (dB) a transform must bring the image closer than it is as stored.
const PLAIN_GAIN_DB: f64 = 6.0;

/// A PSNR for a report line.
fn db_text(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.1} dB")
    } else {
        "identical".to_string()
    }
}

/// How close a turned image is to a render, for a report line: "identical to" or "within PSNR …
/// of".
fn closeness(psnr: f64) -> String {
    if psnr.is_finite() {
        format!("within PSNR {psnr:.1} dB of")
    } else {
        "identical to".to_string()
    }
}

/// The one colour of every pixel of an RGB8 image, if it has one.
fn constant_colour(rgb: &[u8]) -> Option<[u8; 3]> {
    let first: [u8; 3] = rgb.get(..3)?.try_into().ok()?;
    rgb.chunks_exact(3).all(|p| p == first).then_some(first)
}

/// A black, white or one-coloured image, said with what rayscope's render `ours` shows there.
fn plain_colour(image: &[u8], ours: &[u8], w: u32, h: u32) -> Option<Obvious> {
    let c = constant_colour(image)?;
    let total = u64::from(w) * u64::from(h);
    let same = ours.chunks_exact(3).filter(|p| *p == c).count() as u64;
    if same == total {
        return None;
    }
    let (code, what) = match c {
        [0, 0, 0] => ("black", "entirely black: every byte is 0".to_string()),
        [255, 255, 255] => ("white", "entirely white: every byte is 255".to_string()),
        [r, g, b] => (
            "constant",
            format!("one constant colour: every pixel is ({r}, {g}, {b})"),
        ),
    };
    let text = format!(
        "Your image is {what} ({w}×{h} pixels), while {} of rayscope's {total} pixels ({:.1} %) are another colour.",
        total - same,
        100.0 * (total - same) as f64 / total.max(1) as f64
    );
    Some(Obvious::new(
        code,
        text,
        &[
            ("red", f64::from(c[0])),
            ("green", f64::from(c[1])),
            ("blue", f64::from(c[2])),
            ("pixels", total as f64),
            ("rayscope_other_pixels", (total - same) as f64),
        ],
    ))
}

/// The pixels an alpha channel makes see-through, said where there are any.
fn alpha_finding(alpha: &[u8], w: u32, h: u32) -> Option<Obvious> {
    let partial = alpha.iter().filter(|&&a| a != 255).count() as u64;
    if partial == 0 {
        return None;
    }
    let clear = alpha.iter().filter(|&&a| a == 0).count() as u64;
    let total = u64::from(w) * u64::from(h);
    let text = format!(
        "Your PNG has an alpha channel that hides colour: {partial} of its {total} pixels ({:.1} %) are not opaque, {clear} of them fully transparent; viewers and markers may show those pixels differently (over white, black or a checkerboard). rayscope judges the RGB beneath; write alpha 255 everywhere (or save RGB).",
        100.0 * partial as f64 / total.max(1) as f64
    );
    Some(Obvious::new(
        "alpha",
        text,
        &[
            ("not_opaque_pixels", partial as f64),
            ("transparent_pixels", clear as f64),
            ("pixels", total as f64),
        ],
    ))
}

/// One of the seven ways a picture can be turned or mirrored (the symmetries of a rectangle
/// other than leaving it alone), as the way to turn a stored image back: exchange its rows and
/// columns first (`swap`), then reverse its columns (`flip_x`) and its rows (`flip_y`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Turn {
    /// The finding's code.
    code: &'static str,
    swap: bool,
    flip_x: bool,
    flip_y: bool,
}

/// Every turn [`diagnose`] tries, those that keep the image's size first.
const TURNS: [Turn; 7] = [
    Turn {
        code: "upside-down",
        swap: false,
        flip_x: false,
        flip_y: true,
    },
    Turn {
        code: "mirrored",
        swap: false,
        flip_x: true,
        flip_y: false,
    },
    Turn {
        code: "rotated-180",
        swap: false,
        flip_x: true,
        flip_y: true,
    },
    Turn {
        code: "transposed",
        swap: true,
        flip_x: false,
        flip_y: false,
    },
    Turn {
        code: "rotated-clockwise",
        swap: true,
        flip_x: true,
        flip_y: false,
    },
    Turn {
        code: "rotated-anticlockwise",
        swap: true,
        flip_x: false,
        flip_y: true,
    },
    Turn {
        code: "anti-transposed",
        swap: true,
        flip_x: true,
        flip_y: true,
    },
];

impl Turn {
    /// The first sentence of the finding, with `figures` (how close the turned image is).
    fn sentence(self, figures: &str) -> String {
        match self.code {
            "upside-down" => format!(
                "Your image is upside down: flipped vertically it is {figures}; a PNG's first row is the top of the picture."
            ),
            "mirrored" => format!(
                "Your image is mirrored left to right: mirrored back it is {figures}; check the sign of the camera's x axis."
            ),
            "rotated-180" => format!(
                "Your image is turned 180° (upside down and mirrored left to right): turned back it is {figures}; both image axes run the wrong way, so check the signs of the camera's x and y axes (a PNG's first row is the top of the picture)."
            ),
            "transposed" => format!(
                "Your image has rows and columns exchanged: transposed it is {figures}; swap x and y where you write pixels."
            ),
            "rotated-clockwise" => format!(
                "Your image is turned 90° clockwise: turned back it is {figures}; x and y are exchanged where you write pixels, and one of them runs from the other end."
            ),
            "rotated-anticlockwise" => format!(
                "Your image is turned 90° anticlockwise: turned back it is {figures}; x and y are exchanged where you write pixels, and one of them runs from the other end."
            ),
            _ => format!(
                "Your image is mirrored across its other diagonal (rows and columns exchanged, both reversed): turned back it is {figures}; x and y are exchanged where you write pixels and both run the wrong way."
            ),
        }
    }

    /// The stored `w`×`h` RGB8 image turned back, with its size.
    fn back(self, rgb: &[u8], w: u32, h: u32) -> (Vec<u8>, u32, u32) {
        let (ow, oh) = if self.swap { (h, w) } else { (w, h) };
        let mut out = Vec::with_capacity(rgb.len());
        for y in 0..oh {
            for x in 0..ow {
                let (mut sx, mut sy) = if self.swap { (y, x) } else { (x, y) };
                if self.flip_x {
                    sx = w - 1 - sx;
                }
                if self.flip_y {
                    sy = h - 1 - sy;
                }
                let p = ((sy * w + sx) * 3) as usize;
                out.extend_from_slice(&rgb[p..p + 3]);
            }
        }
        (out, ow, oh)
    }
}

/// The orders other than red, green, blue a writer may put the channels in: stored channel `i`
/// holds rayscope's channel `order[i]`.
const ORDERS: [[usize; 3]; 5] = [[2, 1, 0], [1, 0, 2], [0, 2, 1], [1, 2, 0], [2, 0, 1]];

/// A channel's name for a report line.
const CHANNEL: [&str; 3] = ["red", "green", "blue"];

/// Colour channels stored in another order than red, green, blue, said when putting them back
/// in order brings the `w`×`h` image `judged` at least [`PLAIN_DB`] and [`PLAIN_GAIN_DB`]
/// closer to rayscope's render `ours`; `judged` is then put back in order.
fn channels_finding(ours: &[u8], judged: &mut Vec<u8>, w: u32, h: u32) -> Option<Obvious> {
    let as_is = Metrics::of(ours, judged, w, h, BLOCK, true);
    let (order, back, m) = ORDERS
        .iter()
        .map(|&order| {
            let mut back = vec![0u8; judged.len()];
            for (b, p) in back.chunks_exact_mut(3).zip(judged.chunks_exact(3)) {
                for c in 0..3 {
                    b[order[c]] = p[c];
                }
            }
            let m = Metrics::of(ours, &back, w, h, BLOCK, true);
            (order, back, m)
        })
        .max_by(|a, b| a.2.score().total_cmp(&b.2.score()))
        .filter(|(.., m)| m.score() >= PLAIN_DB && m.score() >= as_is.score() + PLAIN_GAIN_DB)
        .filter(|(_, back, _)| keeps_what_was_right(ours, judged, back))?;
    let stored: Vec<&str> = order.iter().map(|&c| CHANNEL[c]).collect();
    let which = if order == [2, 1, 0] {
        "red and blue exchanged (BGR: a bitmap's memory or a library that stores BGR, like OpenCV's imwrite, takes blue first)".to_string()
    } else {
        let moved: Vec<String> = (0..3)
            .filter(|&c| order[c] != c)
            .map(|c| format!("your {} byte holds {}", CHANNEL[c], CHANNEL[order[c]]))
            .collect();
        moved.join(", ")
    };
    let text = format!(
        "Your image's colour channels are in the order {}: {which}; put back in order it is {} rayscope's render (PSNR {} as stored). Write red, green, blue. The rest of this report judges it with its channels in order.",
        stored.join(", "),
        closeness(m.psnr),
        db_text(as_is.psnr)
    );
    *judged = back;
    Some(Obvious::new(
        "channels",
        text,
        &[("psnr_db_turned", m.psnr), ("psnr_db_as_stored", as_is.psnr)],
    ))
}

/// True when `turned` (the image `judged` transformed back) keeps the pixels `judged` has as
/// `ours` has them, but for one in twenty of those it puts right. A writer's transform moves
/// every pixel, so the pixels it leaves right stored are those it does not change (greys for a
/// channel order); an object whose material colour differs by a permutation of its channels
/// is put right while others, right as stored, go wrong.
fn keeps_what_was_right(ours: &[u8], judged: &[u8], turned: &[u8]) -> bool {
    let same = |a: &[u8], i: usize| (0..3).all(|c| a[i * 3 + c].abs_diff(ours[i * 3 + c]) < 2);
    let (mut broken, mut fixed) = (0u64, 0u64);
    for i in 0..ours.len() / 3 {
        match (same(judged, i), same(turned, i)) {
            (true, false) => broken += 1,
            (false, true) => fixed += 1,
            _ => {}
        }
    }
    broken * 20 <= fixed
}

/// Ways a writer may turn a colour into one grey value: the words for it and its weights of
/// red, green and blue.
const GREYS: [(&str, [f64; 3]); 6] = [
    ("copying its red into all three channels", [1.0, 0.0, 0.0]),
    ("copying its green into all three channels", [0.0, 1.0, 0.0]),
    ("copying its blue into all three channels", [0.0, 0.0, 1.0]),
    ("the mean of its three channels", [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0]),
    (
        "its luminance, 0.2126 R + 0.7152 G + 0.0722 B (Rec. 709)",
        [0.2126, 0.7152, 0.0722],
    ),
    (
        "its luma, 0.299 R + 0.587 G + 0.114 B (Rec. 601)",
        [0.299, 0.587, 0.114],
    ),
];

/// Pixels of rayscope's render that must have colour (in thousandths of the image) before an
/// image without it is said to have lost it: a render that is nearly grey anyway says nothing.
const COLOURED_PERMILLE: u64 = 10;

/// An image that has lost colour rayscope's render `ours` has: grey (red, green and blue equal
/// in every pixel) where a plain mix of rayscope's channels, times at most one factor, is that
/// grey — a picture grey for another reason (every ray meeting the same grey wall) is left to
/// the search — or with one or two channels 0 in every pixel.
fn colour_lost_finding(ours: &[u8], judged: &[u8], w: u32, h: u32) -> Option<Obvious> {
    let total = u64::from(w) * u64::from(h);
    let enough = |n: u64| n * 1000 >= total * COLOURED_PERMILLE && n > 0;
    let pct = |n: u64| 100.0 * n as f64 / total.max(1) as f64;
    if judged.chunks_exact(3).all(|p| p[0] == p[1] && p[1] == p[2]) {
        let coloured = ours.chunks_exact(3).filter(|p| p[0] != p[1] || p[1] != p[2]).count() as u64;
        if !enough(coloured) {
            return None;
        }
        let (words, factor, m) = GREYS
            .iter()
            .flat_map(|&(words, k)| {
                let grey: Vec<f64> = ours
                    .chunks_exact(3)
                    .map(|p| (0..3).map(|c| k[c] * f64::from(p[c])).sum::<f64>())
                    .collect();
                let bytes = |f: f64| -> Vec<u8> {
                    grey.iter()
                        .flat_map(|&v| [(v * f).round().min(255.0) as u8; 3])
                        .collect()
                };
                let plain = bytes(1.0);
                // A grey also darker or brighter by one factor (the lights averaged, say).
                let factors = scale::estimate(&plain, judged)
                    .map(|k| scale::candidates(k, 0, 1))
                    .unwrap_or_default();
                std::iter::once(1.0)
                    .chain(factors.into_iter().map(f64::from))
                    .map(move |f| (words, f, Metrics::of(&bytes(f), judged, w, h, BLOCK, true)))
                    .collect::<Vec<_>>()
            })
            .max_by(|a, b| a.2.score().total_cmp(&b.2.score()))
            .filter(|(.., m)| m.score() >= PLAIN_DB)?;
        let times = if factor == 1.0 {
            String::new()
        } else {
            format!(" and multiplied by {}", factor as f32)
        };
        let text = format!(
            "Your image has no colour: red, green and blue are equal in every pixel, while {coloured} of rayscope's {total} pixels ({:.1} %) are coloured. Each pixel is rayscope's colour made grey by {words}{times} ({} yours): write each channel from its own value.",
            pct(coloured),
            closeness(m.psnr)
        );
        return Some(Obvious::new(
            "grey",
            text,
            &[
                ("rayscope_coloured_pixels", coloured as f64),
                ("pixels", total as f64),
                ("factor", factor),
                ("psnr_db_grey", m.psnr),
            ],
        ));
    }
    let zero: Vec<usize> = (0..3)
        .filter(|&c| judged.chunks_exact(3).all(|p| p[c] == 0))
        .filter(|&c| enough(ours.chunks_exact(3).filter(|p| p[c] != 0).count() as u64))
        .collect();
    if zero.is_empty() || zero.len() == 3 {
        return None;
    }
    let names: Vec<&str> = zero.iter().map(|&c| CHANNEL[c]).collect();
    let kept: Vec<&str> = (0..3).filter(|c| !zero.contains(c)).map(|c| CHANNEL[c]).collect();
    let lit = ours.chunks_exact(3).filter(|p| zero.iter().any(|&c| p[c] != 0)).count() as u64;
    let text = format!(
        "Your image's {} {} 0 in every pixel, while rayscope's {} not in {lit} of its {total} pixels ({:.1} %): only {} is written. Write all three channels.",
        names.join(" and "),
        if zero.len() == 1 { "byte is" } else { "bytes are" },
        if zero.len() == 1 { "is" } else { "are" },
        pct(lit),
        kept.join(" and "),
    );
    Some(Obvious::new(
        "channels-missing",
        text,
        &[("rayscope_lit_pixels", lit as f64), ("pixels", total as f64)],
    ))
}

/// A student's image: 8-bit RGB, row-major from the top-left.
#[derive(Debug, Clone, Copy)]
pub struct Image<'a> {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width × height × 3` bytes.
    pub rgb: &'a [u8],
    /// The PNG's alpha channel where it has one: `width × height` bytes.
    pub alpha: Option<&'a [u8]>,
}

/// Why [`diagnose`] could not run.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DiagnoseError {
    /// The image's size is not the one the settings ask for.
    #[error("{}", size_message(*.image_w, *.image_h, *.flags_w, *.flags_h))]
    Size {
        /// The image's width.
        image_w: u32,
        /// The image's height.
        image_h: u32,
        /// The settings' width.
        flags_w: u32,
        /// The settings' height.
        flags_h: u32,
    },
    /// The pixel buffer does not hold `width × height` RGB pixels.
    #[error("the image buffer holds {0} bytes, not width × height × 3 (or its alpha not width × height)")]
    Buffer(usize),
}

/// What [`DiagnoseError::Size`] tells the student: both sizes, the flags to pass, and whether
/// the aspect differs too.
fn size_message(iw: u32, ih: u32, fw: u32, fh: u32) -> String {
    let aspect = if u64::from(iw) * u64::from(fh) == u64::from(ih) * u64::from(fw) {
        format!("the aspect is the same ({:.3})", f64::from(iw) / f64::from(ih.max(1)))
    } else {
        format!(
            "the aspect differs too: {:.3} (width / height) against {:.3}",
            f64::from(iw) / f64::from(ih.max(1)),
            f64::from(fw) / f64::from(fh.max(1))
        )
    };
    format!(
        "your image is {iw}×{ih}, the scene was rendered at {fw}×{fh} (the flags ask for {fw}×{fh}); {aspect}; pass -w {iw} -h {ih} (or leave both out) to judge it at its own size"
    )
}

/// One setting of rayscope's that a student may have set differently.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum SettingChange {
    Aa(u32),
    MaxDepth(u32),
    /// `--depth-limit all --max-depth N`: every ray deeper than N returns black.
    DepthAll(u32),
    Fov(FovAxis),
    /// `--fov` in degrees, as the bits of an `f32` (fitted to the picture).
    FovDeg(u32),
}

/// One ingredient of a candidate render.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Atom {
    Setting(SettingChange),
    Mistake(Mistake),
    /// Shadow rays (`false`) or every ray leaving a surface (`true`) started this far off it
    /// (an `f32`'s bits), fitted to the picture.
    Offset(u32, bool),
    /// Every colour multiplied by this factor (an `f32`'s bits), fitted to the picture, in a
    /// scene with this many point lights, all of one grey level (an `f32`'s bits, 0 where the
    /// lights' colours differ or are not grey).
    Scale(u32, u32, u32),
}

/// A candidate render: the flags' settings with some atoms applied.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Candidate(Vec<Atom>);

impl Candidate {
    fn settings(&self, base: &RenderSettings) -> RenderSettings {
        let mut s = *base;
        for a in &self.0 {
            match *a {
                Atom::Setting(SettingChange::Aa(n)) => s.aa = n,
                Atom::Setting(SettingChange::MaxDepth(d)) => {
                    s.max_depth = d;
                    s.depth_limit = DepthLimit::MirrorGlass;
                }
                Atom::Setting(SettingChange::DepthAll(d)) => {
                    s.max_depth = d;
                    s.depth_limit = DepthLimit::All;
                }
                Atom::Setting(SettingChange::Fov(f)) => s.camera.fov_axis = f,
                Atom::Setting(SettingChange::FovDeg(bits)) => s.camera.fov_deg = f32::from_bits(bits),
                Atom::Mistake(m) => s.mistakes = s.mistakes.with(m),
                Atom::Offset(bits, every) => s.mistakes = offset::with(s.mistakes, f32::from_bits(bits), every),
                Atom::Scale(bits, ..) => s.mistakes = s.mistakes.with_colour_scale(f32::from_bits(bits)),
            }
        }
        s
    }

    /// Search order cost: settings are cheaper explanations than code mistakes.
    fn penalty(&self) -> f64 {
        self.0
            .iter()
            .map(|a| match a {
                Atom::Setting(_) => 0.25,
                Atom::Mistake(_) | Atom::Offset(..) | Atom::Scale(..) => 0.5,
            })
            .sum()
    }

    /// The explanation this candidate is, with its scores `m` and whether its render is the
    /// image (`matches`, by the tie rule).
    fn explain(&self, base: &RenderSettings, m: Metrics, matches: bool) -> Explanation {
        let mut mistakes = Vec::new();
        let mut settings = Vec::new();
        let mut words = Vec::new();
        for a in &self.0 {
            match *a {
                Atom::Mistake(m) => {
                    mistakes.push(m.name().to_string());
                    words.push(format!("'{}' ({})", m.name(), m.info().wrong));
                }
                Atom::Offset(bits, every) => {
                    let e = f32::from_bits(bits);
                    mistakes.push(offset::with(Mistakes::NONE, e, every).to_string());
                    words.push(offset::words(e, every));
                }
                Atom::Scale(bits, lights, grey) => {
                    let k = f32::from_bits(bits);
                    mistakes.push(Mistakes::NONE.with_colour_scale(k).to_string());
                    let grey = (grey != 0).then(|| f32::from_bits(grey));
                    words.push(scale::words(k, lights as usize, base.aa, grey));
                }
                Atom::Setting(c) => {
                    let (flag, word) = match c {
                        SettingChange::Aa(n) => (
                            format!("-x {n}"),
                            format!("-x {n} instead of -x {} (anti-aliasing)", base.aa),
                        ),
                        SettingChange::MaxDepth(d) if base.depth_limit == DepthLimit::All => (
                            format!("--depth-limit mirror-glass --max-depth {d}"),
                            format!(
                                "a recursion limit of {d} for mirrors and glass only instead of {} for every material",
                                base.max_depth
                            ),
                        ),
                        SettingChange::MaxDepth(d) => {
                            let mut word = if d == 3 {
                                format!(
                                    "a recursion limit of {d} instead of {} ('{}')",
                                    base.max_depth,
                                    Mistake::RecursionLimit3.name()
                                )
                            } else {
                                format!("a recursion limit of {d} instead of {}", base.max_depth)
                            };
                            // Students often stop every ray at a depth; where only mirrors and
                            // glass send rays on, that is this picture at one more.
                            if base.stage != Stage::Full {
                                word.push_str(&format!(
                                    " for mirrors and glass, the same picture as every ray from depth {} on returning black",
                                    d + 1
                                ));
                            }
                            (format!("--max-depth {d}"), word)
                        }
                        SettingChange::DepthAll(d) => (
                            format!("--depth-limit all --max-depth {d}"),
                            format!(
                                "a recursion limit of {d} for every material (each ray deeper than {d} returns black, whatever it hits) instead of {} for mirrors and glass only",
                                base.max_depth
                            ),
                        ),
                        SettingChange::Fov(f) => {
                            let name = match f {
                                FovAxis::Vertical => "vertical",
                                FovAxis::Horizontal => "horizontal",
                            };
                            let word = if f == FovAxis::Vertical {
                                format!(
                                    "the field of view on the vertical axis ('{}': {})",
                                    Mistake::FovVertical.name(),
                                    Mistake::FovVertical.info().wrong
                                )
                            } else {
                                "the field of view on the horizontal axis".to_string()
                            };
                            (format!("--fov-axis {name}"), word)
                        }
                        SettingChange::FovDeg(bits) => {
                            let f = f32::from_bits(bits);
                            let c = &base.camera;
                            (format!("--fov {f}"), fov::words(f, c.fov_deg, c.fov_axis.name()))
                        }
                    };
                    settings.push(flag);
                    words.push(word);
                }
            }
        }
        let candidate = self.settings(base);
        let flags = render_flags(&candidate);
        Explanation {
            mistakes,
            settings,
            patch: settings_patch(base, &candidate),
            summary: words.join(" + "),
            flags,
            psnr_db: m.psnr,
            robust_db: m.robust,
            psnr_downsampled_db: m.blurred,
            matches,
            explained: None,
            cause: matches,
            blackens: Vec::new(),
            loses_refraction: Vec::new(),
            same_as: Vec::new(),
            shadowless: String::new(),
        }
    }
}

/// The settings [`diagnose`] varies that `s` changes from `base`.
fn settings_patch(base: &RenderSettings, s: &RenderSettings) -> SettingsPatch {
    let changed = |setting: Setting| s.differs(base, setting);
    SettingsPatch {
        aa: changed(Setting::Aa).then_some(s.aa),
        max_depth: changed(Setting::MaxDepth).then_some(s.max_depth),
        depth_limit: changed(Setting::DepthLimit).then_some(s.depth_limit),
        fov_axis: changed(Setting::FovAxis).then_some(s.camera.fov_axis),
        fov: changed(Setting::Fov).then_some(s.camera.fov_deg),
        ..SettingsPatch::default()
    }
}

/// The flags of `s` that [`diagnose`] decides: size, stage, anti-aliasing, recursion limit,
/// edition, field of view and its axis, and mistakes.
fn render_flags(s: &RenderSettings) -> String {
    s.flags_only(&[
        Setting::Width,
        Setting::Height,
        Setting::Stage,
        Setting::Aa,
        Setting::DepthLimit,
        Setting::MaxDepth,
        Setting::Edition,
        Setting::Fov,
        Setting::FovAxis,
        Setting::Mistakes,
    ])
}

/// Atoms that cannot be combined: two values of one setting, or two ways of doing one thing.
fn exclusive(a: Atom, b: Atom) -> bool {
    use Mistake as M;
    let group = |x: Atom| match x {
        Atom::Setting(SettingChange::Aa(_)) => 1,
        Atom::Setting(SettingChange::MaxDepth(_) | SettingChange::DepthAll(_)) => 2,
        Atom::Setting(SettingChange::Fov(_) | SettingChange::FovDeg(_)) => 3,
        Atom::Mistake(M::NoShadowOffset | M::HugeShadowOffset) | Atom::Offset(..) => 4,
        Atom::Mistake(M::NoFresnel | M::FresnelHalf | M::Schlick | M::FresnelSwapped) => 5,
        Atom::Mistake(M::GlassReflectionAlongRay | M::GlassReflectionOutward) => 6,
        Atom::Mistake(M::NearestByOriginDistance | M::FirstHitInSceneOrder) => 7,
        Atom::Mistake(_) => 0,
        Atom::Scale(..) => 8,
    };
    // A never-reset sum turns the picture white whatever else is wrong: no pair can tell.
    let whitens = |x: Atom| x == Atom::Mistake(M::AccumulatorNotReset);
    let (ga, gb) = (group(a), group(b));
    whitens(a) || whitens(b) || ga != 0 && ga == gb
}

/// True when mistake `m` is worth trying as an atom: it can show in the scene, and no setting
/// atom gives the same renders (the field of view's axis, the recursion limits).
fn worth_trying(contents: &SceneContents, m: Mistake, s: &RenderSettings) -> bool {
    !matches!(m, Mistake::FovVertical | Mistake::RecursionLimit3) && contents.can_show(m, s)
}

/// The single atoms worth trying for this scene and these settings: anti-aliasing levels 1 to
/// 4, or only `aa_level` where the image's edges show that level (none at stage 1).
fn atoms(contents: &SceneContents, base: &RenderSettings, aa_level: Option<u32>) -> Vec<Atom> {
    let mut out = Vec::new();
    // Stage 1 takes one sample a pixel whatever -x says.
    let levels: Vec<u32> = match aa_level {
        _ if base.stage == Stage::One => Vec::new(),
        Some(n) => vec![n],
        None => (1..=4).collect(),
    };
    for n in levels {
        if n != base.aa {
            out.push(Atom::Setting(SettingChange::Aa(n)));
        }
    }
    out.extend(depth_atoms(contents, base));
    if base.width != base.height {
        let other = match base.camera.fov_axis {
            FovAxis::Horizontal => FovAxis::Vertical,
            FovAxis::Vertical => FovAxis::Horizontal,
        };
        out.push(Atom::Setting(SettingChange::Fov(other)));
    }
    for m in Mistake::ALL {
        if worth_trying(contents, m, base) && !base.mistakes.has(m) {
            out.push(Atom::Mistake(m));
        }
    }
    out
}

/// The recursion limits worth trying: other depths for mirrors and glass, and where the full
/// renderer sends rays from other surfaces too (`-l`, emissive or glossy surfaces), every
/// material stopped at a depth (at stage 2 that is the same image as some mirror-glass depth).
fn depth_atoms(contents: &SceneContents, base: &RenderSettings) -> Vec<Atom> {
    let mut out = Vec::new();
    let mut depths: Vec<u32> = (1..=5).collect();
    if base.max_depth <= 5 {
        depths.push(8);
    }
    let mirror_glass = base.depth_limit == DepthLimit::MirrorGlass;
    if contents.specular {
        for &d in &depths {
            if d != base.max_depth || !mirror_glass {
                out.push(Atom::Setting(SettingChange::MaxDepth(d)));
            }
        }
    }
    let full = base.stage == Stage::Full;
    if full && (base.ambient || contents.sampled) {
        if !depths.contains(&base.max_depth) {
            depths.push(base.max_depth);
        }
        for d in depths {
            if d != base.max_depth || mirror_glass {
                out.push(Atom::Setting(SettingChange::DepthAll(d)));
            }
        }
    }
    out
}

/// The scenes candidate renders need: one per combination of OBJ mistakes.
struct Scenes<'a> {
    file: &'a SceneFile,
    built: HashMap<Mistakes, Scene>,
}

impl Scenes<'_> {
    fn key(m: Mistakes) -> Mistakes {
        let mut k = Mistakes::NONE;
        for o in [Mistake::ObjNoZFlip, Mistake::ObjFlatNormals] {
            if m.has(o) {
                k = k.with(o);
            }
        }
        k
    }

    fn prepare(&mut self, m: Mistakes) {
        let k = Self::key(m);
        if !self.built.contains_key(&k) {
            let mut f = self.file.clone();
            k.apply_to_file(&mut f);
            self.built.insert(k, Scene::from_owned_file(f));
        }
    }

    fn get(&self, m: Mistakes) -> &Scene {
        &self.built[&Self::key(m)]
    }
}

/// Share of the differing pixels that rayscope's colours with an entity kind's shadows taken
/// away must give (within the threshold) before a whole render is made to judge it.
const SHADOWLESS_FIRST: f64 = 0.9;

/// The entity kind (`Sphere`, `Plane`, `Triangle`, `ObjModel`) whose shadows, taken away
/// from rayscope's render, give the picture as `gives` judges a whole render, with that render,
/// and the number of renders tried: each kind the scene has, its `differing` pixels first
/// ([`SHADOWLESS_FIRST`] of them must come out as the image has them), and only then a whole
/// render.
#[allow(clippy::too_many_arguments)]
fn shadowless_kind(
    scenes: &Scenes<'_>,
    base: &RenderSettings,
    image: &[u8],
    differing: &[u32],
    threshold: u8,
    full: &FullRender<'_>,
    gives: &dyn Fn(&[u8], &RenderSettings) -> bool,
) -> (Option<(&'static str, Vec<u8>)>, usize) {
    let scene = scenes.get(base.mistakes);
    let w = base.width.max(1);
    let pixels: Vec<(u32, u32)> = differing.iter().map(|&i| (i % w, i / w)).collect();
    let mut kinds: Vec<&'static str> = scene.entities.iter().map(|e| e.kind).collect();
    kinds.sort_unstable();
    kinds.dedup();
    let mut tried = 0;
    for kind in kinds {
        let s = RenderSettings {
            mistakes: base.mistakes.with_shadowless(kind),
            ..*base
        };
        tried += 1;
        let some = render_pixels(scene, &s, &pixels);
        let close = differing
            .iter()
            .enumerate()
            .filter(|&(k, &i)| {
                let (a, b) = (&some[3 * k..3 * k + 3], &image[3 * i as usize..3 * i as usize + 3]);
                (0..3).all(|c| a[c].abs_diff(b[c]) < threshold)
            })
            .count();
        if (close as f64) < SHADOWLESS_FIRST * differing.len() as f64 {
            continue;
        }
        tried += 1;
        let render = full(scenes, &s);
        if gives(&render, &s) {
            return (Some((kind, render)), tried);
        }
    }
    (None, tried)
}

/// A whole render under some settings, of the scene their mistakes make, as RGB8 bytes.
type FullRender<'a> = dyn Fn(&Scenes<'_>, &RenderSettings) -> Vec<u8> + Sync + 'a;

/// The colours `settings` give the pixels `pixels`, as bytes: what a full render writes there.
fn render_pixels(scene: &Scene, settings: &RenderSettings, pixels: &[(u32, u32)]) -> Vec<u8> {
    let m = settings.mistakes;
    if m.has(Mistake::AccumulatorNotReset) {
        // Each pixel holds the sum of every pixel before it: only a whole render gives it.
        let never = AtomicBool::new(false);
        let full = render(scene, settings, &|_, _| {}, &never)
            .map(|o| o.film.to_rgb8())
            .unwrap_or_default();
        let w = settings.width;
        return pixels
            .iter()
            .flat_map(|&(x, y)| {
                let p = ((y * w + x) * 3) as usize;
                full.get(p..p + 3).unwrap_or(&[0; 3]).to_vec()
            })
            .collect();
    }
    if m.is_empty() {
        pixel_bytes(&Integrator::new(scene, settings), m, pixels)
    } else {
        let wrapped = Mistaken {
            inner: scene,
            scene,
            mistakes: m,
        };
        let s = settings.mistaken(m);
        pixel_bytes(&Integrator::with_intersector(scene, &wrapped, &s), m, pixels)
    }
}

fn pixel_bytes<I: Intersect>(integ: &Integrator<'_, I>, m: Mistakes, pixels: &[(u32, u32)]) -> Vec<u8> {
    let spp = integ.samples_per_pixel();
    let inv = 1.0 / spp as f32;
    let mut c = Counters::default();
    let mut out = Vec::with_capacity(pixels.len() * 3);
    for &(x, y) in pixels {
        // The render loop's sum: samples in order, non-finite ones dropped.
        let mut sum = Vec3A::ZERO;
        for s in 0..spp {
            let v = integ.sample(x, y, s, &mut NoObserver, &mut c);
            if v.is_finite() {
                sum += v;
            }
        }
        let v = m.output(Vec3::from(sum * inv));
        out.extend_from_slice(&[to_byte(v.x), to_byte(v.y), to_byte(v.z)]);
    }
    out
}

/// How close a render is to the student's image.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Metrics {
    /// Plain PSNR.
    psnr: f64,
    /// PSNR without up to [`OUTLIERS`] of the pixels.
    robust: f64,
    /// PSNR of the block averages.
    blurred: f64,
}

impl Metrics {
    /// Of render `ours` against image `theirs`, RGB8 grids of `w`×`h`, with blocks of `k`×`k`
    /// for the blurred one. `adjacent`: the grid's pixels are neighbours in the image, so a
    /// pixel may be excused by its neighbours' colours; otherwise (the coarse pass's sparse
    /// grid) any of the worst pixels may be.
    fn of(ours: &[u8], theirs: &[u8], w: u32, h: u32, k: u32, adjacent: bool) -> Metrics {
        let per_pixel: Vec<(f64, bool)> = (0..w * h)
            .map(|i| {
                let p = (i * 3) as usize;
                let se: f64 = (0..3)
                    .map(|c| f64::from(ours[p + c].abs_diff(theirs[p + c])).powi(2))
                    .sum();
                let excusable = !adjacent || se == 0.0 || near_in(ours, theirs, w, h, i);
                (se, excusable)
            })
            .collect();
        let (ma, mb) = (block_means(ours, w, h, k), block_means(theirs, w, h, k));
        let se_blur: f64 = ma.iter().zip(&mb).map(|(x, y)| f64::from(x - y).powi(2)).sum();
        Metrics {
            psnr: compare_rgb8(ours, theirs).psnr,
            robust: robust_psnr(per_pixel),
            blurred: db_of(se_blur, ma.len()),
        }
    }

    /// The score candidates are ranked by.
    fn score(&self) -> f64 {
        self.robust.max(self.blurred)
    }
}

/// True when each channel of pixel `i` of `theirs` lies (within [`NEIGHBOUR_LEVELS`]) in the
/// range the pixels around it span in `ours`: a colour of one side of an edge, or a mix of both
/// (anti-aliased).
fn near_in(ours: &[u8], theirs: &[u8], w: u32, h: u32, i: u32) -> bool {
    let (x, y) = (i % w, i / w);
    let t = &theirs[(i * 3) as usize..(i * 3 + 3) as usize];
    let (mut lo, mut hi) = ([u8::MAX; 3], [0u8; 3]);
    for yy in y.saturating_sub(1)..=(y + 1).min(h - 1) {
        for xx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
            let q = ((yy * w + xx) * 3) as usize;
            for c in 0..3 {
                lo[c] = lo[c].min(ours[q + c]);
                hi[c] = hi[c].max(ours[q + c]);
            }
        }
    }
    (0..3).all(|c| t[c].saturating_add(NEIGHBOUR_LEVELS) >= lo[c] && t[c] <= hi[c].saturating_add(NEIGHBOUR_LEVELS))
}

/// PSNR of a squared error summed over `n` values.
fn db_of(se: f64, n: usize) -> f64 {
    if se == 0.0 {
        return f64::INFINITY;
    }
    10.0 * (255.0f64 * 255.0 / (se / n.max(1) as f64)).log10()
}

/// PSNR of per-pixel squared errors (summed over the three channels), leaving out up to
/// [`OUTLIERS`] of the pixels: the worst of those marked excusable.
fn robust_psnr(mut px: Vec<(f64, bool)>) -> f64 {
    let n = px.len();
    let limit = (n as f64 * OUTLIERS).floor() as usize;
    px.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut dropped = 0;
    let mut se = 0.0;
    for (e, excusable) in px {
        if excusable && dropped < limit && e > 0.0 {
            dropped += 1;
        } else {
            se += e;
        }
    }
    db_of(se, 3 * (n - dropped))
}

/// The sparse grid of the coarse pass: every `k`-th pixel both ways, `k` chosen so the grid
/// holds about `samples / spp` pixels; returns the pixels and the grid's size.
fn coarse_grid(w: u32, h: u32, spp: u64, samples: u64) -> (Vec<(u32, u32)>, u32, u32) {
    let want = (samples / spp.max(1)).max(400);
    let k = (((w as u64 * h as u64) as f64 / want as f64).sqrt().floor() as u32).max(1);
    let xs: Vec<u32> = (k / 2..w).step_by(k as usize).collect();
    let ys: Vec<u32> = (k / 2..h).step_by(k as usize).collect();
    let pixels = ys.iter().flat_map(|&y| xs.iter().map(move |&x| (x, y))).collect();
    (pixels, xs.len() as u32, ys.len() as u32)
}

/// Diagnoses `image` against rayscope's render of `file` under `settings`.
///
/// # Errors
/// When the image's size is not the settings' or its buffer is the wrong length.
pub fn diagnose(
    file: &SceneFile,
    settings: &RenderSettings,
    image: Image<'_>,
    opts: &DiagnoseOptions,
) -> Result<Diagnosis, DiagnoseError> {
    let start = Instant::now();
    let (iw, ih) = (image.width, image.height);
    let pixels = iw as usize * ih as usize;
    if image.rgb.len() != pixels * 3 {
        return Err(DiagnoseError::Buffer(image.rgb.len()));
    }
    if let Some(a) = image.alpha.filter(|a| a.len() != pixels) {
        return Err(DiagnoseError::Buffer(a.len()));
    }
    let size_error = DiagnoseError::Size {
        image_w: iw,
        image_h: ih,
        flags_w: settings.width,
        flags_h: settings.height,
    };
    // Width and height exchanged: a tracer that writes pixel (x, y) at (y, x).
    let swapped = (ih, iw) == (settings.width, settings.height) && iw != ih;
    if (iw, ih) != (settings.width, settings.height) && !swapped {
        return Err(size_error);
    }
    let mut obvious: Vec<Obvious> = image.alpha.and_then(|a| alpha_finding(a, iw, ih)).into_iter().collect();
    let mut base = RenderSettings {
        channel: Channel::Color,
        ..*settings
    };
    let mut scenes = Scenes {
        file,
        built: HashMap::new(),
    };
    scenes.prepare(base.mistakes);
    let never = AtomicBool::new(false);
    let full = |scenes: &Scenes<'_>, s: &RenderSettings| -> Vec<u8> {
        render(scenes.get(s.mistakes), s, &|_, _| {}, &never)
            .map(|o| o.film.to_rgb8())
            .unwrap_or_default()
    };
    let mut ours = full(&scenes, &base);
    let (mut w, mut h) = (base.width, base.height);
    // The image the rest of the diagnosis judges: as stored, or turned back where it is
    // plainly turned (upside down is left: the catalogue's 'image-flipped' is that mistake).
    let mut judged: Vec<u8> = image.rgb.to_vec();
    let plain = if swapped {
        None
    } else {
        plain_colour(image.rgb, &ours, w, h)
    };
    let constant = plain.is_some();
    if swapped {
        // Width and height exchanged: one of the four turns that exchange them, at the flags' size.
        let best = TURNS
            .iter()
            .filter(|t| t.swap)
            .map(|&t| {
                let (back, ..) = t.back(image.rgb, iw, ih);
                let m = Metrics::of(&ours, &back, w, h, BLOCK, true);
                (t, back, m)
            })
            .max_by(|a, b| a.2.score().total_cmp(&b.2.score()))
            .filter(|(.., m)| m.score() >= PLAIN_DB);
        let Some((turn, back, m)) = best else {
            return Err(size_error);
        };
        obvious.push(Obvious::new(
            turn.code,
            format!(
                "Your image is {iw}×{ih} but the flags ask for {w}×{h}. {} The rest of this report judges it turned back.",
                turn.sentence(&format!("{} rayscope's render", closeness(m.psnr)))
            ),
            &[("psnr_db_turned", m.psnr), ("width", f64::from(iw)), ("height", f64::from(ih))],
        ));
        judged = back;
    } else if let Some(p) = plain {
        obvious.push(p);
    } else {
        let as_is = Metrics::of(&ours, &judged, w, h, BLOCK, true);
        if !ties::judge(scenes.get(base.mistakes), &base, &ours, &judged, false).matches {
            let other = RenderSettings {
                width: h,
                height: w,
                ..base
            };
            let theirs_t = if w == h { ours.clone() } else { full(&scenes, &other) };
            let best = TURNS
                .iter()
                .map(|&t| {
                    let (back, bw, bh) = t.back(&judged, w, h);
                    let m = Metrics::of(if t.swap { &theirs_t } else { &ours }, &back, bw, bh, BLOCK, true);
                    (t, back, m)
                })
                .max_by(|a, b| a.2.score().total_cmp(&b.2.score()))
                .filter(|(.., m)| m.score() >= PLAIN_DB && m.score() >= as_is.score() + PLAIN_GAIN_DB);
            if let Some((turn, back, m)) = best {
                let render = if w == h || !turn.swap {
                    "rayscope's render".to_string()
                } else {
                    format!("rayscope's render at {h}×{w}")
                };
                let figures = format!(
                    "{} {render} (PSNR {} as stored)",
                    closeness(m.psnr),
                    db_text(as_is.psnr)
                );
                let finding = Obvious::new(
                    turn.code,
                    turn.sentence(&figures),
                    &[("psnr_db_turned", m.psnr), ("psnr_db_as_stored", as_is.psnr)],
                );
                // Upside down is judged as stored: the catalogue's 'image-flipped' is that mistake.
                if finding.turned_back {
                    judged = back;
                    if turn.swap {
                        base = other;
                        ours = theirs_t;
                        (w, h) = (base.width, base.height);
                    }
                }
                obvious.push(finding.judged_turned_back());
            }
        }
        if let Some(finding) = channels_finding(&ours, &mut judged, w, h) {
            obvious.push(finding);
        }
        obvious.extend(colour_lost_finding(&ours, &judged, w, h));
        let now = Metrics::of(&ours, &judged, w, h, BLOCK, true);
        if !base.mistakes.has(Mistake::Gamma)
            && !ties::judge(scenes.get(base.mistakes), &base, &ours, &judged, false).matches
        {
            let encoded = RenderSettings {
                mistakes: base.mistakes.with(Mistake::Gamma),
                ..base
            };
            let g = Metrics::of(&full(&scenes, &encoded), &judged, w, h, BLOCK, true);
            if g.score() >= PLAIN_DB && g.score() >= now.score() + PLAIN_GAIN_DB {
                obvious.push(Obvious::new(
                    "gamma",
                    format!(
                        "Your image looks saved with gamma: its bytes are about 255·(v/255)^(1/2.2) of rayscope's linear ones (PSNR {} against rayscope's render so encoded, {} as it is); the course writes linear values.",
                        db_text(g.psnr),
                        db_text(now.psnr)
                    ),
                    &[("psnr_db_encoded", g.psnr), ("psnr_db_as_stored", now.psnr)],
                ));
            }
        }
    }
    obvious.sort_by_key(Obvious::rank);
    let image = Image {
        width: w,
        height: h,
        rgb: &judged,
        alpha: None,
    };
    let mut m0 = Metrics::of(&ours, image.rgb, w, h, BLOCK, true);
    // The edition is a free setting: a scene with coloured glass is judged by the edition whose
    // render the image is closer to, whatever the flags say.
    let edition = edition_matters(file, &base).then(|| {
        let other = RenderSettings {
            edition: match base.edition {
                Edition::Y2021 => Edition::Y2022,
                Edition::Y2022 => Edition::Y2021,
            },
            ..base
        };
        let theirs = full(&scenes, &other);
        let m = Metrics::of(&theirs, image.rgb, w, h, BLOCK, true);
        if (m.score(), m.psnr) > (m0.score(), m0.psnr) {
            base = other;
            ours = theirs;
            m0 = m;
        }
        base.edition
    });
    let cmp = compare_rgb8(&ours, image.rgb);
    let verdict = ties::judge(scenes.get(base.mistakes), &base, &ours, image.rgb, false);
    let mut matches = verdict.matches;

    let (differing, threshold) = differing_pixels(&ours, image.rgb);
    let region = (!differing.is_empty()).then(|| {
        let mut r = Region {
            x0: w,
            y0: h,
            x1: 0,
            y1: 0,
        };
        for &i in &differing {
            let (x, y) = (i % w, i / w);
            r.x0 = r.x0.min(x);
            r.y0 = r.y0.min(y);
            r.x1 = r.x1.max(x + 1);
            r.y1 = r.y1.max(y + 1);
        }
        r
    });
    let mut explanations = Vec::new();
    let mut tried = 1 + usize::from(edition.is_some());
    if matches && m0.psnr.is_finite() {
        // A match with pixels left over: the match rule must not hide a recursion limit, whose
        // differences are few pixels deep in mirrors or bounces.
        let contents = SceneContents::of(scenes.get(base.mistakes));
        let depths = depth_atoms(&contents, &base);
        tried += depths.len();
        if let Some(e) = closer_depth(&scenes, &base, image, &depths, &full, m0.psnr) {
            matches = false;
            explanations.push(e);
        }
    }
    // What the edges say about the anti-aliasing, before the search: it tries no other level.
    let aa = if matches || constant {
        families::AaReading::default()
    } else {
        families::read_aa(scenes.get(base.mistakes), &base, &ours, image.rgb)
    };
    let traced = if matches {
        Traced::default()
    } else {
        Traced::of(scenes.get(base.mistakes), &base, &differing)
    };
    let mut differs = vec![false; (w * h) as usize];
    for &i in &differing {
        differs[i as usize] = true;
    }
    let mut attribution = shares(&traced, |k| traced.how(k, &ours, image.rgb, w, h, &differs));
    if !matches && explanations.is_empty() {
        let against = Against {
            plain: constant,
            ours: &ours,
            threshold,
            differs: &differs,
            traced: &traced,
            beyond: &verdict.beyond,
            aa_level: aa.level,
        };
        let (found, n) = search(&mut scenes, &base, image, opts, &full, &against);
        explanations = found;
        tried += n;
        if explanations.first().is_none_or(|e| !e.cause) && !constant {
            let (fitted, n) = fitted_scale(&scenes, &base, image, &ours, &full);
            tried += n;
            explanations.splice(0..0, fitted);
        }
        if explanations.first().is_none_or(|e| !e.cause) && !constant {
            let (fitted, n) = fitted_fov(&scenes, &base, image, &full);
            tried += n;
            explanations.splice(0..0, fitted);
        }
        if explanations.first().is_none_or(|e| !e.cause) && !constant && base.stage == Stage::Two {
            let (fitted, n) = fitted_offset(&scenes, &base, image, &ours, &differing, &full);
            tried += n;
            explanations.splice(0..0, fitted);
        }
        if let Some(e) = explanations.first_mut().filter(|e| e.cause) {
            let black = traced.blackened(&ours, image.rgb);
            if !black.is_empty() {
                tried += 1;
                let matches = e.matches;
                let gives = |render: &[u8], scene: &Scene| {
                    if matches {
                        ties::judge(scene, &base, render, image.rgb, false).matches
                    } else {
                        Explained::of(render, &ours, image.rgb, (w, h), threshold, &differs, &traced).shows_all()
                    }
                };
                if painted_black(&scenes, &base, &black).is_some_and(|(render, scene)| gives(&render, &scene)) {
                    e.blackens = black;
                    e.cause = false;
                }
            }
        }
        if let Some(e) = explanations.first_mut().filter(|e| e.cause) {
            let glass = traced.glass_entities();
            if !glass.is_empty() {
                tried += 1;
                let lost = RenderSettings {
                    mistakes: base.mistakes.with_refraction_lost(),
                    ..base
                };
                let render = full(&scenes, &lost);
                let gives = if e.matches {
                    ties::judge(scenes.get(lost.mistakes), &lost, &render, image.rgb, false).matches
                } else {
                    Explained::of(&render, &ours, image.rgb, (w, h), threshold, &differs, &traced).full()
                };
                if gives {
                    // Every cause found is then one way among many: none is named.
                    for e in explanations.iter_mut().filter(|e| e.cause) {
                        e.loses_refraction.clone_from(&glass);
                        e.cause = false;
                    }
                }
            }
        }
        if let Some(e) = explanations.first_mut().filter(|e| e.cause) {
            let (kind, n) = shadowless_kind(&scenes, &base, image.rgb, &differing, threshold, &full, &|render, s| {
                if e.matches {
                    ties::judge(scenes.get(s.mistakes), s, render, image.rgb, false).matches
                } else {
                    Explained::of(render, &ours, image.rgb, (w, h), threshold, &differs, &traced).full()
                }
            });
            tried += n;
            if let Some((kind, _)) = kind {
                e.shadowless = kind.to_string();
                e.cause = false;
            }
        }
    }
    let mut fitted = if matches || constant || !fitted_applies(explanations.first()) {
        Vec::new()
    } else {
        families::fit(scenes.get(base.mistakes), &base, image.rgb)
    };
    // Where the samples sit in their pixels changes every edge of the picture alike: a member
    // of their family (another level, the cells' corners) that explains only a part of it does
    // so by chance (a shift of another size moves the same smooth walls the same way).
    explanations.retain(|e| e.cause || e.one_way() || !aa_members(e));
    let best = explanations.first();
    if let Some(f) = aa.fitted.filter(|_| best.is_none_or(|e| !e.cause || aa_members(e))) {
        fitted.insert(0, f);
    }
    let caused = best.is_some_and(|e| e.cause);
    let recognised = if matches || constant || caused {
        Vec::new()
    } else {
        // The scene as rendered under the flags' mistakes, with `edit` made to its file.
        let edited = |edit: &dyn Fn(&mut SceneFile)| {
            let mut f = scenes.file.clone();
            Scenes::key(base.mistakes).apply_to_file(&mut f);
            edit(&mut f);
            Scene::from_owned_file(f)
        };
        let without = |k: usize, pixels: &[(u32, u32)]| {
            render_pixels(
                &edited(&|f| {
                    f.lights.remove(k);
                }),
                &base,
                pixels,
            )
        };
        let renders = std::cell::Cell::new(0);
        let gone = |set: &[usize]| -> Vec<u8> {
            renders.set(renders.get() + 1);
            let kept = |f: &mut SceneFile| {
                f.entities = std::mem::take(&mut f.entities)
                    .into_iter()
                    .enumerate()
                    .filter(|(i, _)| !set.contains(i))
                    .map(|(_, e)| e)
                    .collect();
            };
            render(&edited(&kept), &base, &|_, _| {}, &never)
                .map(|o| o.film.to_rgb8())
                .unwrap_or_default()
        };
        let (lacks, left_out) = missing::recognise(
            scenes.file,
            &gone,
            &ours,
            image.rgb,
            (w, h),
            threshold,
            &differs,
            &traced,
        );
        tried += renders.get();
        // Entities the picture turns black: a render that explains no more than painting them
        // black does names nothing the picture shows, and where what lies behind them is black
        // a missing entity is one way among those to get it.
        // A render already said to be one way among those, beside painting them black, says it.
        let hedged = explanations.first().is_some_and(|e| !e.blackens.is_empty());
        let black = if hedged {
            Vec::new()
        } else {
            traced.blackened(&ours, image.rgb)
        };
        let painted = painted_black(&scenes, &base, &black)
            .map(|(r, _)| Explained::of(&r, &ours, image.rgb, (w, h), threshold, &differs, &traced));
        tried += usize::from(painted.is_some());
        let blackened = painted.as_ref().and_then(|p| Some((recognise_black(&black, p)?, p)));
        if let Some((_, p)) = &blackened {
            explanations.retain(|e| {
                e.explained
                    .as_ref()
                    .is_none_or(|x| e.one_way() || !no_more_than(x, p, true))
            });
        }
        let blackened = blackened.map(|(r, _)| r);
        // Glass that shows only the light through it: a render that explains no more than
        // losing every glass's reflection names nothing the picture shows.
        let glass = traced.glass_entities();
        let reflectionless = (!glass.is_empty() && base.stage == Stage::Two)
            .then(|| {
                tried += 1;
                let lost = RenderSettings {
                    mistakes: base.mistakes.with_reflection_lost(),
                    ..base
                };
                Explained::of(
                    &full(&scenes, &lost),
                    &ours,
                    image.rgb,
                    (w, h),
                    threshold,
                    &differs,
                    &traced,
                )
            })
            .filter(Explained::shows_part);
        if let Some(x) = &reflectionless {
            explanations.retain(|e| {
                e.explained
                    .as_ref()
                    .is_none_or(|y| e.one_way() || !no_more_than(y, x, false))
            });
        }
        let reflectionless = reflectionless.map(|x| recognise_reflectionless(&glass, &x));
        // Shadows the picture lacks: every shadow of one kind of entity, the rest as rayscope's
        // (unless a cause found is already said to be one way to get that).
        let shadows_of = |render: &[u8]| Explained::of(render, &ours, image.rgb, (w, h), threshold, &differs, &traced);
        let (kind, n) = if explanations.iter().any(|e| !e.shadowless.is_empty()) {
            (None, 0)
        } else {
            shadowless_kind(&scenes, &base, image.rgb, &differing, threshold, &full, &|render, _| {
                shadows_of(render).shows_all()
            })
        };
        tried += n;
        let shadowless = kind.map(|(kind, render)| {
            let x = shadows_of(&render);
            // The whole difference is the shadows taken away: a catalogued render explaining a
            // part of it is not its cause.
            explanations.clear();
            let names: Vec<String> = (scenes.get(base.mistakes).entities.iter())
                .filter(|e| e.kind == kind)
                .map(|e| e.name.clone())
                .collect();
            recognise_shadowless(kind, &names, &x)
        });
        let lacks = lacks.filter(|(r, x)| {
            blackened
                .as_ref()
                .is_none_or(|b| b.pixels < r.pixels || !r.entities.iter().all(|e| b.entities.contains(e)))
                // Where what it reproduces is black (three in four), what lies behind is black
                // and an entity that brings back nothing looks the same: no evidence it is missing.
                && x.black_share() < 0.75
        });
        // A catalogued render that explains no more than leaving some entities out (whether or
        // not that render shows a part itself) shows only that they are missing there, which
        // many mistakes (a model placed otherwise, a test that misses) share: it names nothing.
        explanations.retain(|e| {
            e.explained
                .as_ref()
                .is_none_or(|y| e.one_way() || !left_out.iter().any(|x| no_more_than(y, x, false)))
        });
        let lacks = lacks.map(|(r, x)| (r, x.shows_all()));
        // Where a catalogued render explains a part, entities missing from another part are
        // said only when they explain all of it.
        let lacks = lacks.filter(|(_, full)| *full || explanations.is_empty());
        if let Some((r, true)) = &lacks {
            // The whole difference is the entities left out: no catalogued render explains all
            // of it (none is a cause here), and one that explains a part of it is not its cause.
            explanations.clear();
            // A part on a missing entity, or seen in a missing mirror, shows what lies behind it.
            for s in &mut attribution {
                let front = s.seen_in.first().unwrap_or(&s.entity);
                if r.entities.contains(front) {
                    s.how = if s.seen_in.is_empty() {
                        "missing: your picture shows what lies behind it".to_string()
                    } else {
                        format!("{front} missing: your picture shows what lies behind it")
                    };
                }
            }
        }
        lacks
            .map(|(r, _)| r)
            .into_iter()
            .chain(blackened)
            .chain(reflectionless)
            .chain(shadowless)
            .chain(acne::recognise(
                scenes.file,
                &without,
                &base,
                &ours,
                image.rgb,
                &differing,
                &traced,
            ))
            .collect()
    };
    // An image that matches only turned back is still wrong as it stands.
    let turned = obvious.iter().any(|o| o.turned_back);
    let next = if matches || caused || only_allowed(&fitted) {
        None
    } else {
        NextStep::new(
            &traced.next_pixels(w),
            &render_flags(&base),
            &file.path.display().to_string(),
        )
    };
    Ok(Diagnosis {
        obvious,
        matches: matches && !turned,
        edition: edition.map(|e| e.year().to_string()),
        edition_changed: edition.is_some_and(|e| e != settings.edition),
        psnr_db: cmp.psnr,
        robust_db: m0.robust,
        psnr_downsampled_db: m0.blurred,
        differing_pixels: differing.len() as u64,
        total_pixels: cmp.total,
        threshold,
        max_channel_diff: cmp.max_diff,
        region,
        ties: TieSummary::of(&verdict),
        attribution,
        explanations,
        fitted,
        recognised,
        next,
        candidates: tried,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Renders the field-of-view fit tries at most, and the explanation it is when its render
/// matches `image` (the tie rule): the angle fitted by [`fov::fit`] on a sparse grid of pixels
/// and confirmed at full size, the known ways to get an angle near it first.
fn fitted_fov(
    scenes: &Scenes<'_>,
    base: &RenderSettings,
    image: Image<'_>,
    full: &FullRender<'_>,
) -> (Option<Explanation>, usize) {
    let scene = scenes.get(base.mistakes);
    let render = |fov: f32, pixels: &[(u32, u32)]| {
        let mut s = *base;
        s.camera.fov_deg = fov;
        render_pixels(scene, &s, pixels)
    };
    let Some(fitted) = fov::fit(base.width, base.height, image.rgb, base.camera.fov_deg, &render) else {
        return (None, 1);
    };
    let mut angles = fov::known_near(fitted, base.camera.fov_deg);
    for f in fov::round_first(fitted) {
        if !angles.contains(&f) {
            angles.push(f);
        }
    }
    let atoms = angles
        .into_iter()
        .map(|f| Atom::Setting(SettingChange::FovDeg(f.to_bits())));
    let (found, n) = first_confirmed(scenes, base, image, full, atoms);
    (found, 1 + n)
}

/// The first of `atoms` whose full render matches `image` by the tie rule, as the explanation
/// it is, and how many were rendered.
fn first_confirmed(
    scenes: &Scenes<'_>,
    base: &RenderSettings,
    image: Image<'_>,
    full: &FullRender<'_>,
    atoms: impl IntoIterator<Item = Atom>,
) -> (Option<Explanation>, usize) {
    let scene = scenes.get(base.mistakes);
    let mut tried = 0;
    for atom in atoms {
        tried += 1;
        let c = Candidate(vec![atom]);
        let s = c.settings(base);
        let bytes = full(scenes, &s);
        if ties::judge(scene, &s, &bytes, image.rgb, false).matches {
            let m = Metrics::of(&bytes, image.rgb, base.width, base.height, BLOCK, true);
            return (Some(c.explain(base, m, true)), tried);
        }
    }
    (None, tried)
}

/// Renders the colour-scale fit tries, and the explanation it is when its render matches
/// `image` (the tie rule): every colour of rayscope's render `ours` multiplied by the factor
/// [`scale::estimate`] reads from the bytes, round values first.
fn fitted_scale(
    scenes: &Scenes<'_>,
    base: &RenderSettings,
    image: Image<'_>,
    ours: &[u8],
    full: &FullRender<'_>,
) -> (Option<Explanation>, usize) {
    if base.mistakes.colour_scale().is_some() {
        return (None, 0);
    }
    let Some(k) = scale::estimate(ours, image.rgb) else {
        return (None, 0);
    };
    let scene = scenes.get(base.mistakes);
    let lights = scene.lights.len();
    // One grey level every light shares: a tracer that leaves the lights' colour out is that
    // level's inverse brighter.
    let grey = scene
        .lights
        .first()
        .map(|l| l.color)
        .filter(|c| c.x > 0.0 && c.x == c.y && c.y == c.z && scene.lights.iter().all(|l| l.color == *c))
        .map_or(0, |c| c.x.to_bits());
    let atoms = scale::candidates(k, lights, base.aa)
        .into_iter()
        .map(|f| Atom::Scale(f.to_bits(), lights as u32, grey));
    first_confirmed(scenes, base, image, full, atoms)
}

/// Renders the offset fit tries at most, and the explanation it is when its render matches
/// `image` (the tie rule): the offset of shadow rays, and where the scene has mirrors or glass
/// that of every ray leaving a surface, each fitted by [`offset::fit`] on the `differing`
/// pixels and a sparse grid; the closer fit is confirmed first at full size, round values
/// first.
fn fitted_offset(
    scenes: &Scenes<'_>,
    base: &RenderSettings,
    image: Image<'_>,
    ours: &[u8],
    differing: &[u32],
    full: &FullRender<'_>,
) -> (Option<Explanation>, usize) {
    let scene = scenes.get(base.mistakes);
    if scene.lights.is_empty() || base.mistakes.has(Mistake::NoShadowOffset) {
        return (None, 0);
    }
    let scopes: &[bool] = if SceneContents::of(scene).specular {
        &[false, true]
    } else {
        &[false]
    };
    let size = (base.width, base.height);
    let mut fits: Vec<(f32, f64, bool)> = Vec::new();
    for &every in scopes {
        let render = |e: f32, pixels: &[(u32, u32)]| {
            let s = RenderSettings {
                mistakes: offset::with(base.mistakes, e, every),
                ..*base
            };
            render_pixels(scene, &s, pixels)
        };
        if let Some((e, error)) = offset::fit(size, image.rgb, ours, differing, &render) {
            fits.push((e, error, every));
        }
    }
    fits.sort_by(|a, b| a.1.total_cmp(&b.1));
    let atoms = fits.into_iter().flat_map(|(fitted, _, every)| {
        offset::round_first(fitted)
            .into_iter()
            .map(move |e| Atom::Offset(e.to_bits(), every))
    });
    let (found, n) = first_confirmed(scenes, base, image, full, atoms);
    (found, scopes.len() + n)
}

/// Rayscope's render (RGB8) with `entities` painted black, and its scene; `None` for no
/// entities or a render that fails.
fn painted_black(scenes: &Scenes<'_>, base: &RenderSettings, entities: &[String]) -> Option<(Vec<u8>, Scene)> {
    if entities.is_empty() {
        return None;
    }
    let mut f = scenes.file.clone();
    Scenes::key(base.mistakes).apply_to_file(&mut f);
    let paint = f.materials.len();
    f.materials.push(MaterialDef {
        name: "(painted black)".into(),
        kind: MaterialKind::Diffuse,
        color: DVec3::ZERO,
        value: 0.0,
        line: 0,
    });
    for e in f.entities.iter_mut().filter(|e| entities.contains(&e.name)) {
        e.material = paint;
    }
    let scene = Scene::from_owned_file(f);
    let never = AtomicBool::new(false);
    let out = render(&scene, base, &|_, _| {}, &never).ok()?;
    Some((out.film.to_rgb8(), scene))
}

/// The entities the picture turns black, recognised where rayscope's render with them painted
/// black (`painted`) explains a part of the difference: a statement of what the picture shows
/// that every mistake making their rays bring back nothing shares, with the pixels it accounts
/// for. `None` where painting them black explains no part.
fn recognise_black(entities: &[String], painted: &Explained) -> Option<Recognised> {
    if entities.is_empty() || !painted.shows_part() {
        return None;
    }
    let (are, their, them) = if entities.len() == 1 {
        ("is", "its", "it")
    } else {
        ("are", "their", "them")
    };
    let names = acne::list(entities, 6);
    let what = how_much(painted);
    let text = format!(
        "Your {names} {are} black where rayscope's {are} lit: rayscope's render with {them} painted black gives {what}. Any mistake that makes {their} rays bring back nothing does it: on a diffuse surface a normal turned away from the lights (N·L below 0, clamped), every shadow ray blocked or a light placed or read wrong; on any surface a weight of 0 or past 1 (clipped), a NaN, a hit kept that is not the nearest and lies in shadow, or {them} not hit at all where what lies behind is black; so the picture alone cannot tell which is yours. Log the rays of a few of those pixels to find out (below)."
    );
    Some(seen("entities-black", entities, text, painted))
}

/// True when the parts `e` explains ([`Explained::partial`]'s sizeable parts at
/// [`explained::PART_PERCENT`]) are explained as well by `other` (a render of what the picture
/// shows: entities painted black, the glass's reflection lost), or, where `black` counts, by
/// pixels the image has black (three in four), and its whole share is no more than `other`'s:
/// the render names nothing that `other` does not show.
fn no_more_than(e: &Explained, other: &Explained, black: bool) -> bool {
    let traced: u64 = e.parts.iter().map(|p| p.pixels).sum();
    let black_share = |p: &explained::PartExplained| if black { p.black_share } else { 0.0 };
    let blacks: f64 = e
        .parts
        .iter()
        .map(|p| p.pixels as f64 * p.percent / 100.0 * black_share(p))
        .sum();
    let black_percent = 100.0 * blacks / traced.max(1) as f64;
    e.percent - black_percent <= other.percent + 5.0
        && e.parts.iter().zip(&other.parts).all(|(a, b)| {
            !e.sizeable(a)
                || a.percent < explained::PART_PERCENT
                || b.percent + 5.0 >= a.percent
                || black_share(a) >= 0.75
        })
}

/// The glass entities that show only the light through them, recognised where rayscope's
/// render with every glass's reflection lost (`lost`) explains a part of the difference.
fn recognise_reflectionless(glass: &[String], lost: &Explained) -> Recognised {
    let (shows, its, it) = if glass.len() == 1 {
        ("shows", "its", "it")
    } else {
        ("show", "their", "them")
    };
    let names = acne::list(glass, 4);
    let what = how_much(lost);
    let text = format!(
        "Your {names} {shows} only the light through {it}, with nothing of {its} reflection, where rayscope's {shows} both: rayscope's render with every glass's reflected ray bringing back black gives {what}. Any mistake that loses the reflected light does it: a reflected ray never traced, started inside the glass or sent the wrong way, its weight taken as 0; so the picture alone cannot tell which is yours. Log the rays of a few of those pixels to find out (below)."
    );
    seen("glass-reflection-lost", glass, text, lost)
}

/// The finding that the entities declared by `kind` (`names`) cast no shadow in the picture,
/// which rayscope's render with shadow rays passing through them (`by`) shows.
fn recognise_shadowless(kind: &str, names: &[String], by: &Explained) -> Recognised {
    let kinds = missing::plural(kind);
    let text = format!(
        "Your {kinds} ({}) cast no shadows where rayscope's do: rayscope's render with every shadow ray passing through them gives your picture. They are seen and show in mirrors, so your intersection test finds them; look at your shadow test: a loop that tries only some kinds of entity (or skips the one the ray leaves), or a blocker's distance compared wrongly, gives this picture. Log the rays of a few of those pixels to find out which (below).",
        acne::list(names, 6)
    );
    seen("shadows-missing", names, text, by)
}

/// A finding of what the picture shows (no catalogue name): `code`, the `entities` it is on,
/// its `text`, and what the render that shows it (`by`) explains.
fn seen(code: &'static str, entities: &[String], text: String, by: &Explained) -> Recognised {
    let mut numbers = BTreeMap::new();
    numbers.insert("entities", entities.len() as f64);
    numbers.insert("percent_explained", by.percent);
    numbers.insert("error_removed_percent", by.error_percent);
    Recognised {
        code,
        mistake: "",
        text,
        entities: entities.to_vec(),
        pixels: by.pixels,
        share: by.percent / 100.0,
        numbers,
    }
}

/// "your picture" where `by` shows all of the difference, "this part of your picture" otherwise.
fn how_much(by: &Explained) -> &'static str {
    if by.shows_all() {
        "your picture"
    } else {
        "this part of your picture"
    }
}

/// Catalogued mistakes that are members of the Fresnel family [`families`] fits.
const FRESNEL_MISTAKES: [Mistake; 4] = [
    Mistake::NoFresnel,
    Mistake::FresnelHalf,
    Mistake::Schlick,
    Mistake::FresnelSwapped,
];

/// True when `e` changes no setting and its mistakes are all members of the Fresnel family.
fn fresnel_members(e: &Explanation) -> bool {
    e.settings.is_empty()
        && !e.mistakes.is_empty()
        && e.mistakes
            .iter()
            .all(|m| FRESNEL_MISTAKES.iter().any(|f| f.name() == m))
}

/// True when `e` changes the anti-aliasing level or puts the samples at the cells' corners
/// ('pixel-corners') and nothing else: a member of the anti-aliasing family.
fn aa_members(e: &Explanation) -> bool {
    !(e.settings.is_empty() && e.mistakes.is_empty())
        && e.settings.iter().all(|s| s.starts_with("-x "))
        && e.mistakes.iter().all(|m| m == Mistake::PixelCorners.name())
}

/// True when `fitted` holds findings and every one is a correct way too (random samples).
fn only_allowed(fitted: &[Fitted]) -> bool {
    !fitted.is_empty() && fitted.iter().all(|f| f.allowed)
}

/// True when the Fresnel family is fitted beside the best explanation `best`: there is none,
/// it is not the cause, or it is a member of the family.
fn fitted_applies(best: Option<&Explanation>) -> bool {
    best.is_none_or(|e| !e.cause || fresnel_members(e))
}

/// The recursion limit among `depths` whose full render is closest to `image`, pixel for pixel,
/// when it is at least 3 dB closer than `psnr` (the image's PSNR against `base`) and matches
/// (the tie rule).
fn closer_depth(
    scenes: &Scenes<'_>,
    base: &RenderSettings,
    image: Image<'_>,
    depths: &[Atom],
    full: &FullRender<'_>,
    psnr: f64,
) -> Option<Explanation> {
    let (w, h) = (base.width, base.height);
    let tried: Vec<(Candidate, Metrics, Vec<u8>)> = depths
        .par_iter()
        .map(|&a| {
            let c = Candidate(vec![a]);
            let bytes = full(scenes, &c.settings(base));
            let m = Metrics::of(&bytes, image.rgb, w, h, BLOCK, true);
            (c, m, bytes)
        })
        .collect();
    let (c, m) = tried
        .into_iter()
        .filter(|(c, m, bytes)| {
            let s = c.settings(base);
            m.psnr >= psnr + 3.0 && ties::judge(scenes.get(s.mistakes), &s, bytes, image.rgb, false).matches
        })
        .map(|(c, m, _)| (c, m))
        .max_by(|a, b| (a.1.psnr - a.0.penalty()).total_cmp(&(b.1.psnr - b.0.penalty())))?;
    Some(c.explain(base, m, true))
}

/// The pixels to log next when a student's ray log holds no mistake but their picture differs
/// from rayscope's render at pixels the log lacks (`unlogged`, row-major indices under
/// `settings`): a few, spread over what those pixels show, as the logging kits' environment and
/// the commands that judge them; `flags` reproduce `settings`, `scene_path` names the scene file
/// as the student does.
#[must_use]
pub fn next_step(
    scene: &Scene,
    settings: &RenderSettings,
    unlogged: &[u32],
    flags: &str,
    scene_path: &str,
) -> Option<NextStep> {
    let traced = Traced::of(scene, settings, unlogged);
    NextStep::new(&traced.next_pixels(settings.width.max(1)), flags, scene_path)
}

/// The pixels where two RGB8 images differ, as indices (row-major), and the threshold used:
/// pixels off by at least two levels in some channel, or by one where nothing differs by more
/// (so one-level rounding noise does not drown a real difference).
#[must_use]
pub fn differing_pixels(a: &[u8], b: &[u8]) -> (Vec<u32>, u8) {
    let diffs: Vec<u8> = a
        .chunks_exact(3)
        .zip(b.chunks_exact(3))
        .map(|(a, b)| a.iter().zip(b).map(|(x, y)| x.abs_diff(*y)).max().unwrap_or(0))
        .collect();
    let threshold = if diffs.iter().any(|&d| d >= 2) { 2 } else { 1 };
    let differing = (0..diffs.len() as u32)
        .filter(|&i| diffs[i as usize] >= threshold)
        .collect();
    (differing, threshold)
}

/// The shares of the pixels `differing` (indices into an image of `base`'s width) by what
/// their ray trees under `base` end on: the first entity the camera ray's path meets that is
/// not a mirror, and the mirrors it is seen in. At most 20,000 of the pixels are traced, evenly
/// spread over them.
#[must_use]
pub fn attribution(scene: &Scene, base: &RenderSettings, differing: &[u32]) -> Vec<Share> {
    shares(&Traced::of(scene, base, differing), |_| String::new())
}

/// The attribution's shares of `traced`, largest first, with `how` of each part.
fn shares(traced: &Traced, how: impl Fn(usize) -> String) -> Vec<Share> {
    let total = traced.pixels.len() as f64;
    traced
        .parts
        .iter()
        .zip(&traced.counts)
        .enumerate()
        .map(|(k, (p, &pixels))| Share {
            entity: p.entity.clone(),
            seen_in: p.seen_in.clone(),
            pixels,
            percent: (1000.0 * pixels as f64 / total).round() / 10.0,
            how: how(k),
        })
        .collect()
}

/// What a candidate's full render is measured against for [`Explained`]: rayscope's render
/// under the flags, the differing pixels and their threshold, and the traced parts.
struct Against<'a> {
    /// The image is one colour: many renders come near it, so nothing short of it explains it.
    plain: bool,
    ours: &'a [u8],
    threshold: u8,
    differs: &'a [bool],
    traced: &'a Traced,
    /// Pixels (row-major) where the image lies beyond the ties of rayscope's render, as far as
    /// the match rule looked.
    beyond: &'a [u32],
    /// The anti-aliasing level the image's edges show, where they show one: no other level is
    /// tried.
    aa_level: Option<u32>,
}

/// Most of the pixels beyond the ties of rayscope's render the coarse pass renders each
/// candidate at, besides its grid.
const FOCUS: usize = 64;

/// The search: every candidate on the coarse grid and at the pixels beyond the ties of
/// rayscope's render, then the best at full size. Returns the explanations (renders that are
/// the image, or explain a part of its difference) and the candidates tried.
fn search(
    scenes: &mut Scenes<'_>,
    base: &RenderSettings,
    image: Image<'_>,
    opts: &DiagnoseOptions,
    full: &FullRender<'_>,
    against: &Against<'_>,
) -> (Vec<Explanation>, usize) {
    let (w, h) = (base.width, base.height);
    let contents = SceneContents::of(scenes.get(base.mistakes));
    let singles = atoms(&contents, base, against.aa_level);
    let spp = u64::from(base.aa * base.aa);
    let (grid, gw, gh) = coarse_grid(w, h, spp, opts.coarse_samples);
    let theirs: Vec<u8> = grid
        .iter()
        .flat_map(|&(x, y)| {
            let p = ((y * w + x) * 3) as usize;
            image.rgb[p..p + 3].to_vec()
        })
        .collect();
    let score = |bytes: &[u8]| Metrics::of(bytes, &theirs, gw, gh, 2, gw == w).score();
    // A difference of a few pixels (a minimum hit distance, a recursion limit deep in a mirror)
    // may miss the grid: the pixels where the image lies beyond the ties are rendered too.
    let step = against.beyond.len().div_ceil(FOCUS).max(1);
    let focus: Vec<(u32, u32)> = (against.beyond.iter().step_by(step)).map(|&i| (i % w, i / w)).collect();
    let focus_theirs: Vec<u8> = focus
        .iter()
        .flat_map(|&(x, y)| {
            let p = ((y * w + x) * 3) as usize;
            image.rgb[p..p + 3].to_vec()
        })
        .collect();

    let mut candidates: Vec<Candidate> = vec![Candidate(Vec::new())];
    candidates.extend(singles.iter().map(|&a| Candidate(vec![a])));
    for c in &candidates {
        scenes.prepare(c.settings(base).mistakes);
    }
    // Each candidate's grid and focus pixels, as one byte string (grid first), and its score.
    let pixels: Vec<(u32, u32)> = grid.iter().chain(&focus).copied().collect();
    let eval = |scenes: &Scenes<'_>, cs: &[Candidate]| -> Vec<(Vec<u8>, f64)> {
        cs.par_iter()
            .map(|c| {
                let s = c.settings(base);
                let bytes = render_pixels(scenes.get(s.mistakes), &s, &pixels);
                let sc = score(&bytes[..grid.len() * 3]);
                (bytes, sc)
            })
            .collect()
    };
    let mut results = eval(scenes, &candidates);
    let coarse_base = results[0].0.clone();
    // Pairs of the singles that change the picture at all (an atom whose render is the correct
    // one's cannot be half of an explanation either).
    if opts.pairs {
        let live: Vec<Atom> = singles
            .iter()
            .zip(&results[1..])
            .filter(|(_, (bytes, _))| *bytes != coarse_base)
            .map(|(&a, _)| a)
            .collect();
        let mut pairs = Vec::new();
        for (i, &a) in live.iter().enumerate() {
            for &b in &live[i + 1..] {
                if !exclusive(a, b) {
                    pairs.push(Candidate(vec![a, b]));
                }
            }
        }
        for c in &pairs {
            scenes.prepare(c.settings(base).mistakes);
        }
        results.extend(eval(scenes, &pairs));
        candidates.extend(pairs);
    }
    let tried = candidates.len() - 1;

    // The best distinct renders go on to full size; the correct render is the baseline.
    let mut order: Vec<usize> = (1..candidates.len()).collect();
    order.sort_by(|&a, &b| {
        let sa = results[a].1 - candidates[a].penalty();
        let sb = results[b].1 - candidates[b].penalty();
        sb.total_cmp(&sa)
    });
    let mut picked: Vec<usize> = Vec::new();
    for i in order {
        if picked.len() >= opts.confirm {
            break;
        }
        if results[i].0 == coarse_base || picked.iter().any(|&p| results[p].0 == results[i].0) {
            continue;
        }
        picked.push(i);
    }
    // And those that reproduce the most of the grid's differing pixels while breaking few: a
    // mistake that explains one entity's difference moves the score little while another
    // mistake remains.
    if !against.plain {
        let thr = against.threshold;
        let same = |a: &[u8], b: &[u8]| a.iter().zip(b).all(|(x, y)| x.abs_diff(*y) < thr);
        let gain = |bytes: &[u8]| -> i64 {
            let mut g = 0i64;
            for ((c, t), o) in bytes
                .chunks_exact(3)
                .zip(theirs.chunks_exact(3).chain(focus_theirs.chunks_exact(3)))
                .zip(coarse_base.chunks_exact(3))
            {
                match (same(t, o), same(c, t)) {
                    (false, true) => g += 2,
                    (true, false) => g -= 1,
                    _ => {}
                }
            }
            g
        };
        let mut by_gain: Vec<(usize, i64)> = (1..candidates.len())
            .map(|i| (i, gain(&results[i].0)))
            .filter(|&(_, g)| g > 0)
            .collect();
        by_gain.sort_by(|a, b| {
            b.1.cmp(&a.1)
                .then(candidates[a.0].penalty().total_cmp(&candidates[b.0].penalty()))
        });
        let mut more = 0;
        for (i, _) in by_gain {
            if more >= opts.confirm {
                break;
            }
            if picked.iter().any(|&p| results[p].0 == results[i].0) {
                continue;
            }
            picked.push(i);
            more += 1;
        }
    }
    let confirmed: Vec<(usize, Metrics, Explained, bool)> = picked
        .into_iter()
        .map(|i| {
            let s = candidates[i].settings(base);
            let bytes = full(scenes, &s);
            let ex = Explained::of(
                &bytes,
                against.ours,
                image.rgb,
                (w, h),
                against.threshold,
                against.differs,
                against.traced,
            );
            let matches = ties::judge(scenes.get(s.mistakes), &s, &bytes, image.rgb, false).matches;
            (i, Metrics::of(&bytes, image.rgb, w, h, BLOCK, true), ex, matches)
        })
        .collect();
    // A candidate is an explanation when its render is the image (a match) or reproduces a
    // real part of the difference; one that merely scores better is not offered.
    let mut ranked: Vec<&(usize, Metrics, Explained, bool)> = confirmed
        .iter()
        .filter(|(_, _, ex, matches)| *matches || !against.plain && ex.partial())
        .collect();
    // Between equal scores (two renders that both match) the one closer pixel for pixel comes
    // first.
    let cause = |c: &(usize, Metrics, Explained, bool)| c.3 || !against.plain && c.2.full();
    // Explained differing pixels, less half of those broken: how partial explanations rank.
    let net = |ex: &Explained| ex.pixels as f64 - 0.5 * ex.new_pixels as f64;
    ranked.sort_by(|x, y| {
        let sx = x.1.score() - candidates[x.0].penalty();
        let sy = y.1.score() - candidates[y.0].penalty();
        let by_score = sy.total_cmp(&sx).then(y.1.psnr.total_cmp(&x.1.psnr));
        match (cause(x), cause(y)) {
            (true, true) => by_score,
            (false, false) => net(&y.2)
                .total_cmp(&net(&x.2))
                .then(candidates[x.0].penalty().total_cmp(&candidates[y.0].penalty())),
            (a, b) => b.cmp(&a),
        }
    });
    // A pair is no better an explanation than its half that does as well alone (as close a
    // render, or as many pixels explained), and far behind the best is no explanation at all.
    let alone = |a: &Atom| {
        confirmed
            .iter()
            .find(|(j, ..)| candidates[*j].0 == [*a])
            .map(|(_, m, ex, matches)| (m.score(), net(ex), *matches))
    };
    let best = ranked.first().map_or(f64::NEG_INFINITY, |(_, m, ..)| m.score());
    let kept: Vec<&(usize, Metrics, Explained, bool)> = ranked
        .into_iter()
        .filter(|c| {
            let (i, m, ex, matches) = c;
            let atoms = &candidates[*i].0;
            // A half that scores as well is as good only if it matches wherever the pair does.
            let redundant = atoms.len() > 1
                && atoms.iter().any(|a| {
                    alone(a).is_some_and(|(score, px, half)| {
                        (half || !matches) && score >= m.score() - 0.5 || !cause(c) && px >= 0.95 * net(ex)
                    })
                });
            !redundant && (*matches || m.score() >= best - 6.0 || !against.plain && ex.partial())
        })
        .take(opts.report)
        .collect();
    let mut explanations: Vec<Explanation> = kept
        .iter()
        .map(|c| Explanation {
            explained: Some(c.2.clone()),
            cause: cause(c),
            ..candidates[c.0].explain(base, c.1, c.3)
        })
        .collect();
    let mut tried = tried;
    // A match is confirmed against the single candidates that came as close on the grid and
    // were not confirmed: where one matches too, the picture cannot tell which mistake is the
    // student's.
    if let (Some(&&(i, _, _, true)), Some(e)) = (kept.first(), explanations.first_mut()) {
        let mut twins: Vec<usize> = (1..candidates.len())
            .filter(|&j| j != i && candidates[j].0.len() == 1 && results[j].1 >= results[i].1 - TWIN_DB)
            // Two values of one setting, or two ways of doing one thing, are one answer.
            .filter(|&j| !candidates[i].0.iter().any(|&a| exclusive(a, candidates[j].0[0])))
            .collect();
        twins.sort_by(|&a, &b| results[b].1.total_cmp(&results[a].1));
        twins.truncate(MAX_TWINS);
        for j in twins {
            // One confirmed already is judged as it was; the others are rendered in full.
            let matched = if let Some(&(_, m, _, matches)) = confirmed.iter().find(|c| c.0 == j) {
                matches.then_some(m)
            } else {
                let s = candidates[j].settings(base);
                let bytes = full(scenes, &s);
                tried += 1;
                ties::judge(scenes.get(s.mistakes), &s, &bytes, image.rgb, false)
                    .matches
                    .then(|| Metrics::of(&bytes, image.rgb, w, h, BLOCK, true))
            };
            if let Some(m) = matched {
                e.same_as.push(candidates[j].explain(base, m, true).summary);
            }
        }
        if !e.same_as.is_empty() {
            // Nothing the picture cannot tell apart from another is its cause.
            for e in &mut explanations {
                e.cause = false;
            }
        }
    }
    // A speckle-tolerant cause (no match) beside another that shares none of its mistakes or
    // settings: the picture cannot tell them apart either.
    if let Some(&&(i, _, _, false)) = kept.first().filter(|c| cause(c)) {
        let others: Vec<String> = kept
            .iter()
            .zip(&explanations)
            .skip(1)
            .filter(|(c, _)| cause(c) && !candidates[c.0].0.iter().any(|a| candidates[i].0.contains(a)))
            .map(|(_, e)| e.summary.clone())
            .take(MAX_TWINS)
            .collect();
        if !others.is_empty() {
            explanations[0].same_as = others;
            for e in &mut explanations {
                e.cause = false;
            }
        }
    }
    (explanations, tried)
}

/// Most single candidates confirmed beside the best match, and how far below its score on the
/// coarse grid (dB) one may be.
const MAX_TWINS: usize = 3;
const TWIN_DB: f64 = 3.0;

/// An attribution ([`attribution`]) as indented lines, largest share first: the first eight,
/// then the rest together.
#[must_use]
pub fn attribution_text(shares: &[Share]) -> String {
    let mut out = String::new();
    for s in shares.iter().take(8) {
        let seen = if s.seen_in.is_empty() {
            String::new()
        } else {
            format!(", seen in {}", s.seen_in.join(" in "))
        };
        let how = if s.how.is_empty() {
            String::new()
        } else {
            format!(": {}", s.how)
        };
        out.push_str(&format!("  {:5.1} %  {}{}{how}\n", s.percent, s.entity, seen));
    }
    if shares.len() > 8 {
        let rest: f64 = shares[8..].iter().map(|s| s.percent).sum();
        out.push_str(&format!("  {rest:5.1} %  elsewhere\n"));
    }
    out
}

/// The diagnosis as text for a terminal; `scene` names the scene file in the commands it shows.
#[must_use]
pub fn report_text(d: &Diagnosis, scene: &str) -> String {
    let db = |v: f64| {
        if v.is_finite() {
            format!("{v:.1} dB")
        } else {
            "identical".to_string()
        }
    };
    let mut out = String::new();
    for o in &d.obvious {
        out.push_str(&o.text);
        out.push('\n');
    }
    let edition = match d.edition.as_deref() {
        Some(year) => {
            let reading = if year == "2021" {
                "where a glass colour plays no part"
            } else {
                "where a glass colour is Beer's-law absorbance"
            };
            let flag = if d.edition_changed {
                format!(", not the edition the flags ask for: add --edition {year}")
            } else {
                String::new()
            };
            format!("Read as the {year} edition of the course ({reading}; --edition {year}){flag}.\n")
        }
        None => String::new(),
    };
    let turned = d.obvious.iter().any(|o| o.turned_back);
    let yours = if d.obvious.iter().any(|o| o.turned_back && o.code != "channels") {
        "Turned back, your image"
    } else if turned {
        "With its channels in order, your image"
    } else {
        "Your image"
    };
    // Turned back, the image is judged by the match rule too; no pixel beyond its ties is a
    // match there.
    if d.matches || (turned && d.explanations.is_empty() && d.ties.beyond_ties == 0) {
        if d.ties.differing_pixels == 0 {
            out.push_str(&format!(
                "{yours} matches rayscope's render: identical, pixel for pixel.\n"
            ));
        } else {
            out.push_str(&format!(
                "{yours} matches rayscope's render (PSNR {}; the {} of {} pixels that are not rayscope's colour differ only where two correct tracers may: a ray of theirs passes within rounding of an edge, a rim, a seam or a shadow's edge, or their colour lies within rounding of a byte boundary).\n",
                db(d.psnr_db),
                d.ties.differing_pixels,
                d.total_pixels
            ));
        }
        out.push_str(&edition);
        return out;
    }
    out.push_str(&headline(d));
    out.push_str(&format!(
        "{yours} differs from rayscope's: PSNR {} ({} downsampled {BLOCK}×), {} of {} pixels ({:.1} %) differ by {} or more levels (at most {}).\n",
        db(d.psnr_db),
        db(d.psnr_downsampled_db),
        d.differing_pixels,
        d.total_pixels,
        100.0 * d.differing_pixels as f64 / d.total_pixels.max(1) as f64,
        d.threshold,
        d.max_channel_diff
    ));
    out.push_str(&edition);
    if let Some(r) = d.region {
        out.push_str(&format!(
            "The differences lie in columns {}–{}, rows {}–{}.\n",
            r.x0,
            r.x1 - 1,
            r.y0,
            r.y1 - 1
        ));
    }
    if !d.attribution.is_empty() {
        out.push_str("Where they are:\n");
        out.push_str(&attribution_text(&d.attribution));
    }
    let (causes, partials): (Vec<&Explanation>, Vec<&Explanation>) =
        d.explanations.iter().partition(|e| e.cause || e.one_way());
    if !causes.is_empty() {
        let plain = d
            .obvious
            .iter()
            .find(|o| matches!(o.code, "black" | "white" | "constant"))
            .map(|o| if o.code == "constant" { "one colour" } else { o.code });
        if let Some(colour) = plain {
            out.push_str(&format!(
                "Many mistakes give a picture that is {colour} everywhere: a render below that is one too is a lead, not proof.\n"
            ));
        }
        out.push_str(if causes.iter().all(|e| e.cause) {
            "What explains it (best first):\n"
        } else {
            "What gives this picture (best first):\n"
        });
        for (i, e) in causes.iter().enumerate() {
            if let (Some(colour), true) = (plain, e.psnr_db.is_infinite()) {
                out.push_str(&format!(
                    "  {}. {} renders it too, {colour} everywhere (yours was {} from rayscope's render): one way to get this picture\n     see it: rayscope -f {scene} -o explained.png {}\n",
                    i + 1,
                    e.summary,
                    db(d.psnr_db),
                    e.flags
                ));
                continue;
            }
            let how = if !e.loses_refraction.is_empty() {
                format!(
                    "{} {}: one way to get this picture, as is losing the refracted light of {}",
                    e.summary,
                    found_how(d, e),
                    acne::list(&e.loses_refraction, 4)
                )
            } else if !e.blackens.is_empty() {
                format!(
                    "{} {}: one way to get this picture, as is painting {} black",
                    if e.matches {
                        format!("your image matches {}", e.summary)
                    } else {
                        e.summary.clone()
                    },
                    found_how(d, e),
                    acne::list(&e.blackens, 4)
                )
            } else if e.matches {
                format!("your image matches {} {}", e.summary, match_how(d, e))
            } else {
                format!("{} {}", e.summary, whole_how(e))
            };
            out.push_str(&format!(
                "  {}. {how}\n     see it: rayscope -f {scene} -o explained.png {}\n",
                i + 1,
                e.flags
            ));
        }
    }
    if !partials.is_empty() {
        out.push_str(if causes.is_empty() {
            "What explains a part of it (none explains all):\n"
        } else {
            "What explains only a part of it:\n"
        });
        for (i, e) in partials.iter().enumerate() {
            out.push_str(&format!(
                "  {}. {} {}\n     see it: rayscope -f {scene} -o explained.png {}\n",
                i + 1,
                e.summary,
                partial_how(e),
                e.flags
            ));
        }
    }
    if let Some(n) = &d.next {
        out.push_str(&format!(
            "To find out what your tracer does there, log its rays at {} of these pixels and let rayscope judge them (the logging kits: docs/check.md):\n  {} <run your tracer>\n  {}\n  rayscope's own rays at the first: {}\n",
            if n.pixels.len() == 1 { "one" } else { "a few" },
            n.log_env,
            n.check_command,
            n.trace_command
        ));
    }
    out
}

/// The report's first line after what is plain: the cause, or what part of the picture is
/// explained, or that no known mistake explains it.
pub fn headline(d: &Diagnosis) -> String {
    // A one-coloured picture is said first, and many renders are that colour too: which one
    // is the cause the picture cannot tell.
    let plain = d
        .obvious
        .iter()
        .any(|o| matches!(o.code, "black" | "white" | "constant"));
    if plain && !d.explanations.is_empty() {
        return String::new();
    }
    let fitted = fitted_lines(d);
    match d.explanations.first() {
        Some(e) if e.one_way() => format!("{}\n{fitted}", one_way(d, e)),
        Some(e) if e.matches => format!(
            "Explained: your image is rayscope's render with {} ({}).\n{fitted}",
            e.summary,
            match_how(d, e)
        ),
        Some(e) if e.cause => format!("Explained: {} {}.\n{fitted}", e.summary, whole_how(e)),
        _ if !d.recognised.is_empty() => format!("{}{fitted}", recognised_lines(d)),
        _ if only_allowed(&d.fitted) => {
            let found: Vec<&str> = d.fitted.iter().map(|f| f.text.as_str()).collect();
            format!(
                "Your image is rayscope's render but for its anti-aliasing: {}\n",
                found.join(" ")
            )
        }
        e if !d.fitted.is_empty() && e.is_none_or(|e| !fresnel_members(e)) => {
            format!("No known mistake explains your picture; {}\n", fitted_findings(&d.fitted))
        }
        Some(e) => format!(
            "No known mistake explains all of your picture; {} {}.\n{fitted}",
            e.summary,
            partial_how(e)
        ),
        None => format!(
            "No known mistake explains your picture: no setting or catalogued mistake (alone or in pairs, {} renders tried) reproduces it or a part of it; `rayscope mistakes` lists the catalogue.\n",
            d.candidates
        ),
    }
}

/// The headline of an explanation whose render matches by turning entities black, as painting
/// them black does too ([`Explanation::blackens`]): one way to get the picture, not its cause.
fn one_way(d: &Diagnosis, e: &Explanation) -> String {
    if !e.same_as.is_empty() {
        let others = acne::list(&e.same_as, 3);
        return format!(
            "One way to get your picture, not necessarily yours: your image is rayscope's render with {} ({}), and just as much with {others}. These give the same picture, so the picture alone cannot tell which is yours, nor rule out another mistake with the same effect. Log the rays of a few of those pixels to find out (below).",
            e.summary,
            found_how(d, e)
        );
    }
    if !e.shadowless.is_empty() {
        let kinds = missing::plural(&e.shadowless);
        return format!(
            "One way to get your picture, not necessarily yours: your {kinds} cast no shadows where rayscope's do, and the rest is rayscope's render. Rendering {} gives it ({}), but so does rayscope's render with every shadow ray passing through the {kinds}: any mistake that makes your shadow test miss them gives this picture (a shadow test that tries only some kinds of entity, or skips the one the ray leaves; a blocker's distance compared wrongly), so the picture alone cannot tell which is yours. Log the rays of a few of those pixels to find out (below).",
            e.summary,
            found_how(d, e)
        );
    }
    if !e.loses_refraction.is_empty() {
        let names = acne::list(&e.loses_refraction, 4);
        let (is, their) = if e.loses_refraction.len() == 1 {
            ("shows", "its")
        } else {
            ("show", "their")
        };
        return format!(
            "One way to get your picture, not necessarily yours: your {names} {is} only {their} reflection, with nothing of the light through {} where rayscope's {is} both. Rendering {} gives it ({}), but so does rayscope's render with every glass's refracted ray bringing back black: any mistake that loses the refracted light gives this picture (a refracted ray that starts on the wrong side, goes the wrong way or leaves the glass at once; a weight of 0; a ray never traced), so the picture alone cannot tell which is yours. Log the rays of a few of those pixels to find out (below).",
            if e.loses_refraction.len() == 1 { "it" } else { "them" },
            e.summary,
            found_how(d, e)
        );
    }
    let names = acne::list(&e.blackens, 4);
    let (is, their) = if e.blackens.len() == 1 {
        ("is", "its")
    } else {
        ("are", "their")
    };
    format!(
        "One way to get your picture, not necessarily yours: your {names} {is} black where rayscope's {is} not, and the rest is rayscope's render. Rendering {} gives it ({}), but so does rayscope's render with {names} painted black: any mistake that makes {their} rays bring back nothing gives this picture (a weight of 0, or one past 1 that clips; a NaN; a ray never traced; a hit kept that is not the nearest, in shadow), so the picture alone cannot tell which is yours. Log the rays of a few of those pixels to find out (below).",
        e.summary,
        found_how(d, e)
    )
}

/// The headline of a mistake recognised from how the picture looks, and how much of the
/// difference it accounts for.
fn recognised_lines(d: &Diagnosis) -> String {
    let mut out = String::new();
    for r in &d.recognised {
        out.push_str(&format!("Recognised from how your picture looks: {}\n", r.text));
        if r.share < 0.9 {
            out.push_str(&format!(
                "  That is {} of the {} differing pixels ({:.0} %); the rest is not explained by it.\n",
                r.pixels,
                d.differing_pixels,
                100.0 * r.share
            ));
        }
    }
    out
}

/// The fitted families' findings as a headline: "your glass's Fresnel weight differs: …",
/// family by family.
fn fitted_findings(fitted: &[Fitted]) -> String {
    let mut families: Vec<&str> = fitted.iter().map(Fitted::family).collect();
    families.dedup();
    let said: Vec<String> = families
        .iter()
        .map(|&family| {
            let found: Vec<&str> = (fitted.iter().filter(|f| f.family() == family))
                .map(|f| f.text.as_str())
                .collect();
            format!("your {family} differs: {}", found.join(" "))
        })
        .collect();
    said.join("; ")
}

/// The fitted families beneath a catalogued cause, one indented line each.
fn fitted_lines(d: &Diagnosis) -> String {
    d.fitted
        .iter()
        .map(|f| match f.family() {
            "anti-aliasing" => format!("  and your anti-aliasing, fitted: {}\n", f.text),
            _ => format!("  and your glass's fitted weight: {}\n", f.text),
        })
        .collect()
}

/// How closely a matching explanation's render is the image, against what the image was.
fn match_how(d: &Diagnosis, e: &Explanation) -> String {
    let db = |v: f64| {
        if v.is_finite() {
            format!("{v:.1} dB")
        } else {
            "identical".to_string()
        }
    };
    let was = db(d.psnr_db);
    if e.psnr_db.is_infinite() {
        format!("exactly (was {was})")
    } else {
        format!(
            "at {}, each pixel that differs within its ties (was {was})",
            db(e.psnr_db)
        )
    }
}

/// How an explanation that is not the image pixel for pixel accounts for all of the difference.
fn whole_how(e: &Explanation) -> String {
    let (p, err) = e
        .explained
        .as_ref()
        .map_or((0.0, 0.0), |x| (x.percent, x.error_percent));
    format!(
        "accounts for the whole difference: its render reproduces {p:.0} % of the differing pixels, pixel for pixel or on average over {BLOCK}×{BLOCK} blocks (speckle falls where each tracer's rounding puts it), and removes {err:.0} % of the error"
    )
}

/// How a cause was found, in words: as a match ([`match_how`]) or as the whole difference
/// reproduced ([`whole_how`]).
fn found_how(d: &Diagnosis, e: &Explanation) -> String {
    if e.matches {
        match_how(d, e)
    } else {
        whole_how(e)
    }
}

/// How much of the difference a partial explanation reproduces, in words.
fn partial_how(e: &Explanation) -> String {
    let Some(x) = &e.explained else {
        return "explains a part of it".into();
    };
    match x.best_part() {
        Some(part) if x.percent < 95.0 => format!(
            "explains {part} ({:.0} % of all the differing pixels; the rest is something else)",
            x.percent
        ),
        _ => format!("explains {:.0} % of the differing pixels", x.percent),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_means_and_grids() {
        let img = [0u8, 0, 0, 10, 10, 10, 20, 20, 20, 30, 30, 30];
        assert_eq!(block_means(&img, 2, 2, 2), vec![15.0; 3]);
        assert!(Metrics::of(&img, &img, 2, 2, 2, true).score().is_infinite());
        // One pixel in a hundred may show its neighbour's colour…
        let mut a = vec![100u8; 300];
        a[3..6].copy_from_slice(&[0, 0, 0]);
        let mut b = a.clone();
        b[0..3].copy_from_slice(&[0, 0, 0]);
        let m = Metrics::of(&a, &b, 10, 10, 2, true);
        assert!(m.robust.is_infinite() && m.psnr < 30.0, "{m:?}");
        // …but not a colour outside what is near it, nor a second one.
        let mut c = a.clone();
        c[297..300].copy_from_slice(&[7, 7, 7]);
        assert!(Metrics::of(&a, &c, 10, 10, 2, true).robust.is_finite());
        b[30..33].copy_from_slice(&[0, 0, 0]);
        assert!(Metrics::of(&a, &b, 10, 10, 2, true).robust.is_finite());
        let (g, gw, gh) = coarse_grid(400, 400, 1, 10_000);
        assert_eq!((g.len(), gw, gh), (10_000, 100, 100));
        assert_eq!(g[0], (2, 2));
        let (g, ..) = coarse_grid(10, 10, 16, 10_000);
        assert_eq!(g.len(), 100, "small images are searched whole");
    }

    #[test]
    fn plain_findings_name_their_figures() {
        // A 3×2 render turned each of the seven ways (written out pixel by pixel as a tracer
        // would store it), then turned back by its turn.
        let (w, h) = (3u32, 2u32);
        let render: Vec<u8> = (0..18).collect();
        let at = |x: u32, y: u32| render[((y * w + x) * 3) as usize..][..3].to_vec();
        let stored = |code: &str| -> (Vec<u8>, u32, u32) {
            let (sw, sh) = if matches!(code, "upside-down" | "mirrored" | "rotated-180") {
                (w, h)
            } else {
                (h, w)
            };
            let mut out = Vec::new();
            for y in 0..sh {
                for x in 0..sw {
                    out.extend(match code {
                        "upside-down" => at(x, h - 1 - y),
                        "mirrored" => at(w - 1 - x, y),
                        "rotated-180" => at(w - 1 - x, h - 1 - y),
                        "transposed" => at(y, x),
                        "rotated-clockwise" => at(y, h - 1 - x),
                        "rotated-anticlockwise" => at(w - 1 - y, x),
                        _ => at(w - 1 - y, h - 1 - x),
                    });
                }
            }
            (out, sw, sh)
        };
        for turn in TURNS {
            let (img, sw, sh) = stored(turn.code);
            assert_ne!(img, render, "{}", turn.code);
            assert_eq!(turn.back(&img, sw, sh), (render.clone(), w, h), "{}", turn.code);
        }
        // Rotated clockwise, the render's top row is the stored image's right column.
        let (cw, ..) = stored("rotated-clockwise");
        assert_eq!(&cw[3..6], &render[..3], "stored (1, 0) is the render's (0, 0)");

        let ours = [0u8, 0, 0, 200, 100, 50, 0, 0, 0, 0, 0, 0];
        let black = plain_colour(&[0; 12], &ours, 2, 2).expect("black");
        assert_eq!(black.code, "black");
        assert_eq!(black.numbers["rayscope_other_pixels"], 1.0);
        assert!(
            black
                .text
                .contains("every byte is 0 (2×2 pixels), while 1 of rayscope's 4 pixels (25.0 %)"),
            "{}",
            black.text
        );
        let grey = plain_colour(&[9, 8, 7].repeat(4), &ours, 2, 2).expect("one colour");
        assert!(grey.code == "constant" && grey.text.contains("(9, 8, 7)"), "{grey:?}");
        assert!(plain_colour(&ours, &ours, 2, 2).is_none(), "not one colour");
        assert!(
            plain_colour(&[0; 12], &[0; 12], 2, 2).is_none(),
            "rayscope's render is black too"
        );

        assert!(alpha_finding(&[255; 4], 2, 2).is_none());
        let a = alpha_finding(&[0, 128, 255, 255], 2, 2).expect("see-through");
        assert_eq!(
            (a.numbers["not_opaque_pixels"], a.numbers["transparent_pixels"]),
            (2.0, 1.0)
        );
        assert!(
            a.text
                .contains("2 of its 4 pixels (50.0 %) are not opaque, 1 of them fully transparent"),
            "{}",
            a.text
        );

        let e = DiagnoseError::Size {
            image_w: 48,
            image_h: 64,
            flags_w: 64,
            flags_h: 48,
        }
        .to_string();
        assert!(
            e.contains("your image is 48×64, the scene was rendered at 64×48")
                && e.contains("aspect differs too: 0.750 (width / height) against 1.333")
                && e.contains("pass -w 48 -h 64"),
            "{e}"
        );
    }

    #[test]
    fn the_first_line_is_the_most_important_plain_finding() {
        let mut d = Diagnosis {
            obvious: vec![
                alpha_finding(&[0; 4], 2, 2).unwrap(),
                plain_colour(&[0; 12], &[9; 12], 2, 2).unwrap(),
            ],
            matches: false,
            edition: None,
            edition_changed: false,
            psnr_db: 10.0,
            robust_db: 10.0,
            psnr_downsampled_db: 10.0,
            differing_pixels: 4,
            total_pixels: 4,
            threshold: 2,
            max_channel_diff: 9,
            region: None,
            ties: TieSummary::default(),
            attribution: Vec::new(),
            explanations: Vec::new(),
            fitted: Vec::new(),
            recognised: Vec::new(),
            next: None,
            candidates: 1,
            seconds: 0.0,
        };
        d.obvious.sort_by_key(Obvious::rank);
        let text = report_text(&d, "s.txt");
        let lines: Vec<&str> = text.lines().collect();
        assert!(lines[0].starts_with("Your image is entirely black"), "{text}");
        assert!(lines[1].starts_with("Your PNG has an alpha channel"), "{text}");
        // Then the verdict of the search, then the figures.
        assert!(lines[2].starts_with("No known mistake explains your picture"), "{text}");
        assert!(lines[3].starts_with("Your image differs from rayscope's"), "{text}");
        let json = serde_json::to_value(&d).unwrap();
        assert_eq!(json["obvious"][0]["code"], "black");
        assert_eq!(json["obvious"][0]["numbers"]["pixels"], 4.0);
    }

    #[test]
    fn exclusive_atoms() {
        let aa = |n| Atom::Setting(SettingChange::Aa(n));
        assert!(exclusive(aa(1), aa(2)));
        assert!(exclusive(
            Atom::Mistake(Mistake::Schlick),
            Atom::Mistake(Mistake::NoFresnel)
        ));
        assert!(!exclusive(
            Atom::Mistake(Mistake::Schlick),
            Atom::Mistake(Mistake::NoTir)
        ));
        assert!(!exclusive(aa(1), Atom::Mistake(Mistake::NoTir)));
    }
}
