//! The bounds that keep the debugger answering whatever its clients do: connections, time,
//! request bodies and heavy work in flight.

use std::time::Duration;

/// Uploads up to this size are kept in memory to judge again after a settings change; larger
/// ones are judged once and marked stale after a change (the page sends them again). The default
/// of [`ServerLimits::keep_log_bytes`].
pub const KEEP_LOG_BYTES: usize = 64 << 20;
/// Rays of a judged log kept for display by default ([`ServerLimits::ray_detail_cap`]): a kept
/// ray costs up to about 3 KiB with its verdicts (measured: 320,000 rays that disagree took
/// 950 MiB), so at most twice this many (samples that disagree) stay within about 150 MiB.
pub const RAY_DETAIL_CAP: usize = 25_000;
/// Largest uploaded reference image in bytes.
pub(crate) const COMPARE_BODY_LIMIT: usize = 32 * 1024 * 1024;

/// Bounds that keep the debugger answering whatever its clients do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ServerLimits {
    /// Most open connections; further clients wait in the kernel's listen backlog.
    pub max_connections: usize,
    /// Time a client has to send a request's head; also how long an idle keep-alive
    /// connection stays open.
    pub header_timeout: Duration,
    /// Longest a request's body may pause; also the grace before [`Self::min_body_rate`] applies.
    pub body_timeout: Duration,
    /// Slowest a body may arrive once [`Self::body_timeout`] has passed, in bytes a second
    /// averaged over the time spent waiting for it; a slower one is answered 408.
    pub min_body_rate: u64,
    /// Most bytes of request bodies (images, settings) held at once; a body that does not fit is
    /// answered 503 before any of it is read.
    pub body_budget: usize,
    /// A ray log upload up to this size is kept to judge again after a settings change.
    pub keep_log_bytes: usize,
    /// A judged ray log keeps at most this many rays for display (samples that disagree up to
    /// twice as many); the verdicts cover every ray.
    pub ray_detail_cap: usize,
    /// Longest a response write may make no progress (a client that stopped reading).
    pub write_timeout: Duration,
    /// Most heavy requests (views, traces, channel renders, checks, compares) in flight; one
    /// more is answered 503 with `Retry-After`.
    pub heavy_slots: usize,
}

impl Default for ServerLimits {
    /// 256 connections (well under the usual 1,024 open files), 10 s for a head or an idle
    /// connection, 30 s for a body's pause or a stalled write, bodies at 16 KiB/s at least after
    /// that, and 4 heavy requests: each of those already uses every core, so more in flight adds
    /// memory, not speed. Bodies held: 128 MiB (four of the largest images); ray logs kept:
    /// [`KEEP_LOG_BYTES`], rays for display: [`RAY_DETAIL_CAP`].
    fn default() -> Self {
        Self {
            max_connections: 256,
            header_timeout: Duration::from_secs(10),
            body_timeout: Duration::from_secs(30),
            min_body_rate: 16 * 1024,
            write_timeout: Duration::from_secs(30),
            heavy_slots: 4,
            body_budget: 4 * COMPARE_BODY_LIMIT,
            keep_log_bytes: KEEP_LOG_BYTES,
            ray_detail_cap: RAY_DETAIL_CAP,
        }
    }
}
