//! A ray record as logged, field by field, read by the fast reader or serde_json before it is
//! checked against the scene.

use std::borrow::Cow;

use serde::Deserialize;

/// Deserialises a field that may be absent (outer `None`), `null` or a value.
fn present<'de, D, T>(d: D) -> Result<Option<Option<T>>, D::Error>
where
    D: serde::Deserializer<'de>,
    T: Deserialize<'de>,
{
    Option::<T>::deserialize(d).map(Some)
}

/// A hit as logged.
#[derive(Debug, PartialEq, Deserialize)]
pub(super) struct RawHit<'a> {
    pub(super) t: Option<f64>,
    pub(super) point: Option<[f64; 3]>,
    pub(super) normal: Option<[f64; 3]>,
    #[serde(borrow)]
    pub(super) entity: Option<Cow<'a, str>>,
}

/// A shadow ray's light as logged: its name, or its position for tracers whose lights have none.
#[derive(Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub(super) enum LightRef<'a> {
    Name(#[serde(borrow)] Cow<'a, str>),
    Position([f64; 3]),
}

/// A shadow ray's blocker as logged: its name, or only whether something blocks the light.
#[derive(Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub(super) enum BlockerRef<'a> {
    Name(#[serde(borrow)] Cow<'a, str>),
    Blocked(bool),
}

/// A ray record as logged, before it is checked against the scene.
#[derive(Debug, PartialEq, Deserialize)]
pub(super) struct RawRay<'a> {
    pub(super) pixel: Option<[u32; 2]>,
    pub(super) sample: Option<u32>,
    pub(super) id: Option<i64>,
    pub(super) parent: Option<i64>,
    #[serde(borrow)]
    pub(super) kind: Option<Cow<'a, str>>,
    pub(super) origin: Option<[f64; 3]>,
    pub(super) direction: Option<[f64; 3]>,
    pub(super) from: Option<[f64; 3]>,
    pub(super) to: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "present", borrow)]
    pub(super) hit: Option<Option<RawHit<'a>>>,
    #[serde(borrow)]
    pub(super) light: Option<LightRef<'a>>,
    #[serde(default, deserialize_with = "present", borrow)]
    pub(super) blocked_by: Option<Option<BlockerRef<'a>>>,
    pub(super) color: Option<[f64; 3]>,
}
