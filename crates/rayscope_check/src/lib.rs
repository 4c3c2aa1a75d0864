//! Check a student's own ray tracer: read the rays it logged, re-trace every one against the
//! scene with rayscope's intersection, and judge both the tracer's answers and the rays
//! themselves, each verdict with a stable code and a plain-English explanation.
//!
//! The pieces are separate so the debugger can use them one at a time: [`log`] reads a log into
//! [`log::LoggedRay`]s, [`Judge`] judges the rays of a pixel sample, and [`check`] runs both over
//! a whole log (streaming, with the judging spread over rayon's pool) into a [`Report`];
//! [`check_pixels`] does the same and keeps a verdict per pixel and the rays of each pixel (up to
//! a cap), for the debugger's verdict map and its side-by-side ray trees.

pub mod geom;
pub mod judge;
pub mod log;
pub mod pixels;
pub mod report;
pub mod selflog;
pub mod verdict;

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use rayon::prelude::*;

pub use judge::{Finding, Judge, Tally, Tolerances, Value};
pub use log::{LogContext, LogError, LoggedRay, RaySource};
pub use pixels::{align, check_pixels, AlignedRow, Alignment, PixelLog, PixelOptions, PixelStatus, Shape, ShownRay};
pub use report::Report;
pub use verdict::Code;

/// Rays of one pixel sample.
type Key = (Option<[u32; 2]>, Option<u32>);

/// Records after which a pixel sample that got no new ray is taken as complete. Tracers that
/// write each sample's rays together close every sample at once; a multi-threaded tracer whose
/// lines interleave keeps its samples open this long.
const WINDOW: u64 = 1 << 16;

/// Most rays one pixel sample may gather before it is judged as it stands.
const MAX_GROUP: usize = 1 << 16;

/// Collects rays into pixel samples, closing those that are complete.
#[derive(Default)]
struct Grouper {
    open: HashMap<Key, (Vec<LoggedRay>, u64)>,
    seen: u64,
}

impl Grouper {
    fn push(&mut self, r: LoggedRay, ready: &mut Vec<Vec<LoggedRay>>) {
        self.seen += 1;
        let key = (r.pixel, r.sample);
        let e = self.open.entry(key).or_default();
        e.0.push(r);
        e.1 = self.seen;
        if e.0.len() >= MAX_GROUP {
            if let Some((g, _)) = self.open.remove(&key) {
                ready.push(g);
            }
        }
    }

    /// Moves the samples that got no ray in the last [`WINDOW`] records (all, at the end) to
    /// `ready`, in the order of their last ray.
    fn close(&mut self, all: bool, ready: &mut Vec<Vec<LoggedRay>>) {
        let limit = self.seen.saturating_sub(WINDOW);
        let mut done: Vec<(u64, Key)> = self
            .open
            .iter()
            .filter(|(_, (_, last))| all || *last <= limit)
            .map(|(k, (_, last))| (*last, *k))
            .collect();
        done.sort_unstable_by_key(|x| x.0);
        for (_, k) in done {
            if let Some((g, _)) = self.open.remove(&k) {
                ready.push(g);
            }
        }
    }
}

/// Options of a check.
#[derive(Debug, Clone, Copy)]
pub struct CheckOptions {
    /// Examples kept per verdict code.
    pub examples: usize,
}

impl Default for CheckOptions {
    fn default() -> Self {
        Self { examples: 3 }
    }
}

/// Reads every ray of `source` and judges it with `judge`. `progress(done, total)` is called
/// with bytes of the log after each batch.
pub fn check(
    judge: &Judge<'_>,
    source: &mut dyn RaySource,
    opts: CheckOptions,
    progress: &dyn Fn(u64, u64),
) -> Result<Report, LogError> {
    let never = AtomicBool::new(false);
    run(judge, source, opts, progress, &never, None).map(|r| r.expect("not cancelled"))
}

/// What [`run`] hands each judged pixel sample to: its rays and their verdicts.
pub(crate) type Sink<'s> = &'s mut dyn FnMut(Vec<LoggedRay>, Vec<Vec<Finding>>);

/// The check's loop: reads batches, groups them into pixel samples, judges the complete ones in
/// parallel. With a `sink`, every sample's rays and verdicts go to it, in the order the samples
/// complete. `None` when `cancel` was set.
pub(crate) fn run(
    judge: &Judge<'_>,
    source: &mut dyn RaySource,
    opts: CheckOptions,
    progress: &dyn Fn(u64, u64),
    cancel: &AtomicBool,
    mut sink: Option<Sink<'_>>,
) -> Result<Option<Report>, LogError> {
    let start = Instant::now();
    let mut reading = Duration::ZERO;
    let mut judging = Duration::ZERO;
    let mut grouper = Grouper::default();
    let mut tally = Tally::new(opts.examples);
    let mut batch = Vec::with_capacity(log::BATCH);
    let mut ready: Vec<Vec<LoggedRay>> = Vec::new();
    loop {
        if cancel.load(Ordering::Relaxed) {
            return Ok(None);
        }
        let t0 = Instant::now();
        batch.clear();
        let more = source.next_batch(&mut batch)?;
        for r in batch.drain(..) {
            grouper.push(r, &mut ready);
        }
        grouper.close(!more, &mut ready);
        reading += t0.elapsed();
        let t1 = Instant::now();
        if !ready.is_empty() {
            let keep = opts.examples;
            if let Some(sink) = sink.as_mut() {
                let judged: Vec<(Tally, Vec<Vec<Finding>>)> = ready
                    .par_iter()
                    .with_min_len(16)
                    .map(|g| {
                        let mut t = Tally::new(keep);
                        let f = judge.judge_group_findings(g, &mut t);
                        (t, f)
                    })
                    .collect();
                for (g, (t, f)) in ready.drain(..).zip(judged) {
                    tally = tally.merge(t);
                    sink(g, f);
                }
            } else {
                let t = ready
                    .par_iter()
                    .with_min_len(16)
                    .fold(
                        || Tally::new(keep),
                        |mut t, g| {
                            judge.judge_group(g, &mut t);
                            t
                        },
                    )
                    .reduce(|| Tally::new(keep), Tally::merge);
                tally = tally.merge(t);
            }
            ready.clear();
        }
        judging += t1.elapsed();
        let (done, total) = source.progress();
        progress(done, total);
        if !more {
            break;
        }
    }
    tally.finish();
    let (skipped, first) = source.skipped();
    Ok(Some(Report::new(
        tally,
        skipped,
        first.map(ToString::to_string),
        judge.tol,
        report::Timing {
            reading,
            judging,
            total: start.elapsed(),
        },
    )))
}
