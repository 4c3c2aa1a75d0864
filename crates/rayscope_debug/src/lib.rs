//! rayscope's visual ray debugger.
//!
//! - [`view`]: the scene view, drawn on the CPU: the scene from an orbit camera with the ray
//!   tracer's camera, frustum, image-plane pixel grid (carrying the rendered image), debug rays
//!   and ray trees as depth-tested, anti-aliased lines. `rayscope view` and the browser share it.
//! - [`server`]: the local web app behind `rayscope debug` (axum), with its UI embedded.
//! - [`student`]: a student's own ray log and image in the debugger: verdicts per pixel, their
//!   rays beside rayscope's, and the API behind them.
//!
//! Pixel coordinates are 0-based from the top-left everywhere.

pub mod canvas;
pub mod encode;
pub mod guard;
mod limits;
mod net;
pub mod server;
pub mod student;
pub mod view;

pub use limits::ServerLimits;
pub use server::{serve, start, DebugError, RunningServer, ServeConfig};
pub use view::{
    auto_view, pick, render_view, ForeignRay, ImageMode, RayMode, RgbImage, Selection, ViewCamera, ViewFrame,
    ViewOptions,
};
