//! Check a student's own ray tracer: read the rays it logged, re-trace every one against the
//! scene with the checker's own double-precision geometry and camera ([`oracle`], kept apart
//! from rayscope's renderer so each checks the other), and judge both the tracer's answers and
//! the rays themselves, each verdict with a stable code and a plain-English explanation.
//!
//! The pieces are separate so the debugger can use them one at a time: [`log`] reads a log into
//! [`log::LoggedRay`]s, [`Judge`] judges the rays of a pixel sample, and [`check`] runs both over
//! a whole log (streaming, with the judging spread over rayon's pool) into a [`Report`];
//! [`check_pixels`] does the same and keeps a verdict per pixel and the rays of each pixel (up to
//! a cap), for the debugger's verdict map and its side-by-side ray trees.

pub mod geom;
pub mod image;
pub mod judge;
pub mod log;
pub mod oracle;
pub mod pixels;
pub mod probe;
pub mod probe_answer;
pub mod report;
pub mod selflog;
pub mod tie;
pub mod verdict;

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use rayon::prelude::*;
use rustc_hash::FxHashMap;

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

/// Most rays one pixel sample may gather before it is judged as it stands: a real sample has a
/// few thousand at most (a Whitted tree of depth 8 with its shadow rays), and judging a group
/// costs memory in proportion to it (400,000 rays of one sample peak at 140 MiB in groups of
/// this size, 345 MiB in groups four times as large).
const MAX_GROUP: usize = 1 << 14;

/// Most rays of unfinished pixel samples held at once (280 bytes a ray: 70 MiB, and up to twice
/// that with their vectors' spare room), after each batch is grouped: a log written
/// sample after sample holds about `WINDOW` rays, and one from a tracer whose threads interleave
/// their samples' rays (64 threads, each with a sample of up to 3,000 rays in flight) fits
/// comfortably. A log that interleaves more is refused with a note on how to write it.
pub const MAX_PENDING_RAYS: usize = 4 * WINDOW as usize;

/// Too many rays of unfinished samples: the last record read, the rays and the samples.
#[derive(Debug, PartialEq)]
struct Overfull {
    line: u64,
    rays: u64,
    samples: u64,
}

impl Overfull {
    fn error(self, source: &dyn RaySource) -> LogError {
        LogError::Interleaved {
            place: source.place(self.line),
            rays: self.rays,
            samples: self.samples,
            limit: MAX_PENDING_RAYS as u64,
        }
    }
}

/// Collects rays into pixel samples, closing those that are complete.
///
/// Tracers write most of a sample's rays one after another, so the sample of the last record is
/// kept out of the map: a record of the same sample costs a comparison, not a hash lookup.
#[derive(Default)]
struct Grouper {
    /// Open samples other than the current one, in the order they were parked, which is the
    /// order of their last rays: each with the record count at its last ray, and its rays until
    /// the sample is taken back as the current one (`None` from then on).
    parked: VecDeque<(Key, Option<Vec<LoggedRay>>, u64)>,
    /// Where each open sample other than the current one lies in `parked`, counted from the
    /// first sample ever parked.
    open: FxHashMap<Key, u64>,
    /// Samples taken off the front of `parked`.
    gone: u64,
    /// The sample of the last record, with the record count at its last ray.
    current: Option<(Key, (Vec<LoggedRay>, u64))>,
    seen: u64,
    /// Rays in `open` and `current`.
    pending: usize,
    /// A buffer that keeps its room from sample to sample, for the rays of a current sample that
    /// outgrows its first vector: they are copied out at their exact count when it is parked, so
    /// that a sample costs at most two allocations however many rays it has, and held samples
    /// (what a check's memory is mostly made of) take no more room than their rays.
    spare: Vec<LoggedRay>,
    /// The ray count of the last sample parked: a new sample's first vector has this room, which
    /// is its exact count where the tracer's samples are alike (no copy when it is parked).
    typical: usize,
}

impl Grouper {
    fn push(&mut self, r: LoggedRay, ready: &mut Vec<Vec<LoggedRay>>) {
        self.seen += 1;
        let key = (r.pixel, r.sample);
        if !matches!(&self.current, Some((k, _)) if *k == key) {
            self.park();
            let e = match self.open.remove(&key) {
                Some(at) => {
                    let (_, rays, last) = &mut self.parked[(at - self.gone) as usize];
                    (rays.take().expect("an open sample has its rays"), *last)
                }
                None => (Vec::with_capacity(self.typical.max(1)), 0),
            };
            self.current = Some((key, e));
        }
        let Some((_, entry)) = self.current.as_mut() else {
            unreachable!("the current sample was set above")
        };
        if entry.0.len() == entry.0.capacity() && self.spare.capacity() > entry.0.len() {
            // Full: the rays move to the spare buffer, which has more room, rather than grow.
            let mut more = std::mem::take(&mut self.spare);
            more.append(&mut entry.0);
            entry.0 = more;
        }
        entry.0.push(r);
        entry.1 = self.seen;
        self.pending += 1;
        if entry.0.len() >= MAX_GROUP {
            if let Some((_, (g, _))) = self.current.take() {
                self.pending -= g.len();
                ready.push(self.exact(g));
            }
        }
    }

    /// The rays of `g` in a vector of their exact count; `g`'s room is kept as the spare buffer
    /// when it is larger than the spare's.
    fn exact(&mut self, mut g: Vec<LoggedRay>) -> Vec<LoggedRay> {
        if g.capacity() == g.len() {
            return g;
        }
        let mut rays = Vec::with_capacity(g.len());
        rays.append(&mut g);
        if g.capacity() > self.spare.capacity() {
            self.spare = g;
        }
        rays
    }

    /// Moves the current sample to the parked ones.
    fn park(&mut self) {
        if let Some((k, (g, last))) = self.current.take() {
            self.typical = g.len();
            let g = self.exact(g);
            self.open.insert(k, self.gone + self.parked.len() as u64);
            self.parked.push_back((k, Some(g), last));
        }
    }

    /// Moves the samples that got no ray in the last [`WINDOW`] records (all, at the end) to
    /// `ready`, in the order of their last ray; refuses the log when the samples left open hold
    /// more than [`MAX_PENDING_RAYS`] rays.
    fn close(&mut self, all: bool, ready: &mut Vec<Vec<LoggedRay>>) -> Result<(), Overfull> {
        if all {
            self.park();
        }
        let limit = self.seen.saturating_sub(WINDOW);
        while self.parked.front().is_some_and(|&(_, _, last)| all || last <= limit) {
            let Some((k, rays, _)) = self.parked.pop_front() else {
                unreachable!("the front was just looked at")
            };
            self.gone += 1;
            if let Some(g) = rays {
                self.open.remove(&k);
                self.pending -= g.len();
                ready.push(g);
            }
        }
        if self.pending > MAX_PENDING_RAYS {
            let last = self
                .current
                .as_ref()
                .and_then(|(_, (g, _))| g.last())
                .map_or(0, |r| r.line);
            return Err(Overfull {
                line: last,
                rays: self.pending as u64,
                samples: (self.open.len() + usize::from(self.current.is_some())) as u64,
            });
        }
        Ok(())
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
    source: &mut (dyn RaySource + Send),
    opts: CheckOptions,
    progress: &dyn Fn(u64, u64),
) -> Result<Report, LogError> {
    let never = AtomicBool::new(false);
    run(judge, source, opts, progress, &never, None).map(|r| r.expect("not cancelled"))
}

/// What [`run`] hands each judged pixel sample to: its rays and their verdicts.
pub(crate) type Sink<'s> = &'s mut (dyn FnMut(Vec<LoggedRay>, Vec<Vec<Finding>>) + Send);

/// Pixel samples judged in one step: the tally and, when a sink wants them, each ray's findings.
type Judged = (Tally, Option<Vec<Vec<Vec<Finding>>>>);

/// Judges `groups` in parallel.
fn judge_groups(judge: &Judge<'_>, groups: &[Vec<LoggedRay>], keep: usize, findings: bool) -> Judged {
    if findings {
        let judged: Vec<(Tally, Vec<Vec<Finding>>)> = groups
            .par_iter()
            .with_min_len(16)
            .map(|g| {
                let mut t = Tally::new(keep);
                let f = judge.judge_group_findings(g, &mut t);
                (t, f)
            })
            .collect();
        let mut tally = Tally::new(keep);
        let mut all = Vec::with_capacity(judged.len());
        for (t, f) in judged {
            tally = tally.merge(t);
            all.push(f);
        }
        (tally, Some(all))
    } else {
        let t = groups
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
        (t, None)
    }
}

/// The check's loop, a pipeline of two steps that run at once: reading and parsing the next
/// batch, and grouping the batch read before into pixel samples and judging the complete ones in
/// parallel. With a `sink`, every sample's rays and verdicts go to it, in the order the samples
/// complete. `None` when `cancel` was set.
pub(crate) fn run(
    judge: &Judge<'_>,
    source: &mut (dyn RaySource + Send),
    opts: CheckOptions,
    progress: &dyn Fn(u64, u64),
    cancel: &AtomicBool,
    mut sink: Option<Sink<'_>>,
) -> Result<Option<Report>, LogError> {
    let start = Instant::now();
    let mut reading = Duration::ZERO;
    let mut judging = Duration::ZERO;
    let mut grouper = Grouper::default();
    let keep = opts.examples;
    let mut tally = Tally::new(keep);
    // The batch being read, and the one read before it with whether it was the log's last.
    let mut next: Vec<LoggedRay> = Vec::with_capacity(log::BATCH);
    let mut read: Option<(Vec<LoggedRay>, bool)> = None;
    let mut more = true;
    while more || read.is_some() {
        if cancel.load(Ordering::Relaxed) {
            return Ok(None);
        }
        let reader = || -> Result<(bool, Duration), LogError> {
            let t0 = Instant::now();
            next.clear();
            let again = more && source.next_batch(&mut next)?;
            Ok((again, t0.elapsed()))
        };
        let judger = || -> Result<(Tally, Duration), Overfull> {
            let t1 = Instant::now();
            let mut ready = Vec::new();
            if let Some((batch, last)) = read.as_mut() {
                for r in batch.drain(..) {
                    grouper.push(r, &mut ready);
                }
                grouper.close(*last, &mut ready)?;
            }
            let Some(sink) = sink.as_mut() else {
                return Ok((judge_groups(judge, &ready, keep, false).0, t1.elapsed()));
            };
            // A sixteenth of a batch's rays at a time, so that the verdicts waiting for the sink
            // (up to a few KiB a ray) stay bounded however many samples complete at once.
            let mut tally = Tally::new(keep);
            let mut ready = ready.into_iter().peekable();
            while ready.peek().is_some() {
                let mut rays = 0;
                let mut part = Vec::new();
                while let Some(g) = ready.next_if(|g| part.is_empty() || rays + g.len() <= log::BATCH / 16) {
                    rays += g.len();
                    part.push(g);
                }
                let (t, f) = judge_groups(judge, &part, keep, true);
                tally = tally.merge(t);
                for (g, f) in part.into_iter().zip(f.unwrap_or_default()) {
                    sink(g, f);
                }
            }
            Ok((tally, t1.elapsed()))
        };
        let (got, judged) = rayon::join(reader, judger);
        let (t, dt) = judged.map_err(|o: Overfull| o.error(source))?;
        judging += dt;
        tally = tally.merge(t);
        let (again, dt) = got?;
        reading += dt;
        // The buffers trade places, so neither is allocated again.
        let spare = read.take().map(|(b, _)| b).unwrap_or_default();
        if more {
            read = Some((std::mem::replace(&mut next, spare), !again));
        } else {
            next = spare;
        }
        more = again;
        let (done, total) = source.progress();
        progress(done, total);
    }
    tally.finish();
    judge.fold_surfaces(&mut tally);
    let (skipped, first) = source.skipped();
    let mut report = Report::new(
        tally,
        skipped,
        first.map(ToString::to_string),
        judge.tol,
        report::Timing {
            reading,
            judging,
            total: start.elapsed(),
        },
    );
    report.keep_catalogue(|m| judge.can_show(m));
    Ok(Some(report))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The log lines of each group, in the order the groups are handed on.
    fn lines(groups: &[Vec<LoggedRay>]) -> Vec<Vec<u64>> {
        groups.iter().map(|g| g.iter().map(|r| r.line).collect()).collect()
    }

    #[test]
    fn samples_gather_their_rays_whether_written_together_or_interleaved() {
        let mut g = Grouper::default();
        let mut ready = Vec::new();
        // Sample (0,0)#0 written whole, then (1,0)#0 and (1,0)#1 interleaved as two threads
        // write them, then (0,0)#0 again after a gap.
        let log = [
            ([0, 0], 0),
            ([0, 0], 0),
            ([1, 0], 0),
            ([1, 0], 1),
            ([1, 0], 0),
            ([1, 0], 1),
            ([2, 0], 3),
        ];
        for (line, (p, s)) in log.into_iter().enumerate() {
            g.push(LoggedRay::for_tests(p, s, line as u64 + 1), &mut ready);
        }
        g.push(LoggedRay::for_tests([0, 0], 0, 8), &mut ready);
        g.close(false, &mut ready).unwrap();
        assert!(ready.is_empty(), "no sample is older than the window");
        g.close(true, &mut ready).unwrap();
        // In the order of each sample's last ray.
        assert_eq!(lines(&ready), vec![vec![3, 5], vec![4, 6], vec![7], vec![1, 2, 8]]);
    }

    #[test]
    fn a_sample_closes_once_the_window_has_passed_it() {
        let mut g = Grouper::default();
        let mut ready = Vec::new();
        g.push(LoggedRay::for_tests([0, 0], 0, 1), &mut ready);
        for i in 0..WINDOW {
            // Eight samples, each of fewer rays than a group holds.
            g.push(LoggedRay::for_tests([1, 0], (i % 8) as u32, i + 2), &mut ready);
        }
        g.close(false, &mut ready).unwrap();
        assert_eq!(lines(&ready), vec![vec![1]]);
        g.close(true, &mut ready).unwrap();
        assert_eq!(ready.len(), 9);
        assert_eq!(ready.iter().map(Vec::len).sum::<usize>() as u64, WINDOW + 1);
    }

    /// Pushes `rays` as the check's loop does: a batch at a time, closing after each.
    fn group_all(rays: impl Iterator<Item = LoggedRay>) -> Result<usize, Overfull> {
        let mut g = Grouper::default();
        let mut ready = Vec::new();
        let mut judged = 0;
        let mut n = 0;
        for r in rays {
            g.push(r, &mut ready);
            n += 1;
            if n % log::BATCH == 0 {
                g.close(false, &mut ready)?;
                judged += ready.drain(..).map(|s| s.len()).sum::<usize>();
            }
        }
        g.close(true, &mut ready)?;
        Ok(judged + ready.iter().map(Vec::len).sum::<usize>())
    }

    #[test]
    fn logs_written_sample_by_sample_or_by_64_threads_fit_the_pending_cap() {
        // 2,000,000 rays, 20 a sample, one sample after another.
        let ordered =
            (0..2_000_000u64).map(|i| LoggedRay::for_tests([(i / 20 % 64) as u32, (i / 1280) as u32], 0, i + 1));
        assert_eq!(group_all(ordered), Ok(2_000_000));
        // 64 threads, each writing the rays of its own 3,000-ray samples as it traces them.
        let threads = (0..768_000u64).map(|i| {
            let (thread, step) = (i % 64, i / 64);
            LoggedRay::for_tests([thread as u32, (step / 3000) as u32], 0, i + 1)
        });
        assert_eq!(group_all(threads), Ok(768_000));
    }

    #[test]
    fn a_log_interleaving_more_samples_than_the_cap_holds_is_refused() {
        // 4,096 samples' rays round-robin: every sample stays open until the log ends.
        let rays = (0..400_000u64).map(|i| LoggedRay::for_tests([(i % 64) as u32, (i / 64 % 64) as u32], 0, i + 1));
        let o = group_all(rays).unwrap_err();
        assert_eq!(o.samples, 4096);
        assert!(o.rays > MAX_PENDING_RAYS as u64 && o.rays <= (MAX_PENDING_RAYS + log::BATCH) as u64);
        assert_eq!(
            o.line,
            MAX_PENDING_RAYS as u64 + log::BATCH as u64,
            "the batch after the cap was passed"
        );
    }
}
