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
type Key = log::SampleKey;

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

/// The rays of an open pixel sample: most samples' rays are one run of consecutive rays of one
/// batch, held there by their numbers in the log (counted from 0), so that grouping a ray
/// copies nothing; the rays of a sample that are not one such run (interleaved with another
/// sample's, or across two batches) are copied out.
#[derive(Debug)]
enum Rays {
    /// Rays `start..end`, all in one batch.
    Run(u64, u64),
    /// Copies of the sample's rays, in the log's order.
    Copied(Vec<LoggedRay>),
}

impl Rays {
    fn len(&self) -> usize {
        match self {
            Rays::Run(a, b) => (b - a) as usize,
            Rays::Copied(v) => v.len(),
        }
    }
}

/// Collects rays into pixel samples, closing those that are complete.
///
/// Tracers write most of a sample's rays one after another, so the sample of the last record is
/// kept out of the map: a record of the same sample costs a comparison, not a hash lookup. The
/// batches read are kept until no open sample can have rays in them, so that a sample's rays
/// are judged where the reader put them.
#[derive(Default)]
struct Grouper {
    /// Batches of rays that open samples, or samples closed but not yet judged, may have rays
    /// in, oldest first, each with the number of its first ray.
    batches: VecDeque<(u64, Vec<LoggedRay>)>,
    /// Open samples other than the current one, in the order they were parked, which is the
    /// order of their last rays: each with the record count at its last ray, and its rays until
    /// the sample is taken back as the current one (`None` from then on).
    parked: VecDeque<(Key, Option<Rays>, u64)>,
    /// Where each open sample other than the current one lies in `parked`, counted from the
    /// first sample ever parked; kept only once a sample comes back (see `returns`).
    open: FxHashMap<Key, u64>,
    /// Whether a record has come after one of a later sample, in the order of rows, columns and
    /// samples: until then every new sample is a new one (tracers that write their samples in
    /// that order never look one up), and `open` is not kept.
    returns: bool,
    /// The last sample in that order met so far.
    latest: Option<Key>,
    /// Open samples in `parked`.
    parked_open: usize,
    /// Samples taken off the front of `parked`.
    gone: u64,
    /// The sample of the last record, with its rays and the record count at its last ray.
    current: Option<(Key, Rays, u64)>,
    /// Rays grouped so far.
    seen: u64,
    /// Rays in `open` and `current`.
    pending: usize,
    /// Batches no sample refers to any more, for the reader to fill again.
    spare: Vec<Vec<LoggedRay>>,
}

/// The rays numbered `a..b`, all in one batch: in `batch` (whose first ray is numbered `base`)
/// or in one of `batches`.
fn rays_of<'b>(
    batches: &'b VecDeque<(u64, Vec<LoggedRay>)>,
    (base, batch): (u64, &'b [LoggedRay]),
    a: u64,
    b: u64,
) -> &'b [LoggedRay] {
    let (base, batch) = if a >= base {
        (base, batch)
    } else {
        // The last batch that starts at or before `a`.
        let k = batches.partition_point(|&(first, _)| first <= a) - 1;
        (batches[k].0, batches[k].1.as_slice())
    };
    &batch[(a - base) as usize..(b - base) as usize]
}

impl Grouper {
    /// [`Self::push_keyed`] with the keys taken from the rays.
    #[cfg(test)]
    fn push_batch(&mut self, batch: Vec<LoggedRay>, ready: &mut Vec<Rays>) {
        let keys: Vec<Key> = batch.iter().map(LoggedRay::sample_key).collect();
        self.push_keyed(batch, &keys, ready);
    }

    /// Groups the rays of `batch`, the next batch of the log, whose samples are `keys` (one a
    /// ray: the loop reads them from a few hundred KiB rather than from each ray's record);
    /// samples that reach [`MAX_GROUP`] rays go to `ready` as they stand.
    fn push_keyed(&mut self, batch: Vec<LoggedRay>, keys: &[Key], ready: &mut Vec<Rays>) {
        debug_assert_eq!(batch.len(), keys.len());
        let base = self.seen;
        for (j, &key) in keys.iter().enumerate() {
            let n = base + j as u64;
            self.seen += 1;
            let rays = if matches!(&self.current, Some((k, _, _)) if *k == key) {
                let Some((_, rays, _)) = self.current.take() else {
                    unreachable!("the current sample was just looked at")
                };
                rays
            } else {
                self.park();
                match self.reopen(key) {
                    Some(rays) => rays,
                    None => Rays::Run(n, n),
                }
            };
            let rays = match rays {
                // The next ray of a run in this batch (or a new sample's first).
                Rays::Run(a, b) if b == n && a >= base => Rays::Run(a, n + 1),
                other => {
                    let mut copied = self.copy_out(other, (base, &batch));
                    copied.push(batch[j].clone());
                    Rays::Copied(copied)
                }
            };
            self.current = Some((key, rays, self.seen));
            self.pending += 1;
            if self
                .current
                .as_ref()
                .is_some_and(|(_, rays, _)| rays.len() >= MAX_GROUP)
            {
                if let Some((_, rays, _)) = self.current.take() {
                    self.pending -= rays.len();
                    ready.push(rays);
                }
            }
        }
        self.batches.push_back((base, batch));
    }

    /// The rays of a sample as copies, to add more to.
    fn copy_out(&self, rays: Rays, current: (u64, &[LoggedRay])) -> Vec<LoggedRay> {
        match rays {
            Rays::Run(a, b) => {
                let mut v = Vec::with_capacity((b - a) as usize * 2);
                v.extend_from_slice(rays_of(&self.batches, current, a, b));
                v
            }
            Rays::Copied(v) => v,
        }
    }

    /// The rays of a sample pushed and not yet released.
    fn rays<'s>(&'s self, rays: &'s Rays) -> &'s [LoggedRay] {
        match rays {
            Rays::Run(a, b) => {
                let (base, batch) = self.batches.back().expect("a run lies in a batch");
                rays_of(&self.batches, (*base, batch), *a, *b)
            }
            Rays::Copied(v) => v,
        }
    }

    /// Moves the current sample to the parked ones.
    fn park(&mut self) {
        if let Some((k, rays, last)) = self.current.take() {
            if self.returns {
                self.open.insert(k, self.gone + self.parked.len() as u64);
            }
            self.parked.push_back((k, Some(rays), last));
            self.parked_open += 1;
        }
    }

    /// The rays of the open sample `key`, taken out of `parked`, if it is open.
    fn reopen(&mut self, key: Key) -> Option<Rays> {
        if !self.returns {
            // Rows, then columns, then samples.
            let order = |(p, s): Key| (p.map(|[x, y]| [y, x]), s);
            if self.latest.is_none_or(|l| order(key) > order(l)) {
                self.latest = Some(key);
                return None;
            }
            // A sample comes after a later one: from now on the open samples are indexed.
            self.returns = true;
            for (i, (k, rays, _)) in self.parked.iter().enumerate() {
                if rays.is_some() {
                    self.open.insert(*k, self.gone + i as u64);
                }
            }
        }
        let at = self.open.remove(&key)?;
        self.parked_open -= 1;
        let rays = self.parked[(at - self.gone) as usize].1.take();
        Some(rays.expect("an open sample has its rays"))
    }

    /// Moves the samples that got no ray in the last [`WINDOW`] records (all, at the end) to
    /// `ready`, in the order of their last ray; refuses the log when the samples left open hold
    /// more than [`MAX_PENDING_RAYS`] rays.
    fn close(&mut self, all: bool, ready: &mut Vec<Rays>) -> Result<(), Overfull> {
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
                if self.returns {
                    self.open.remove(&k);
                }
                self.parked_open -= 1;
                self.pending -= g.len();
                ready.push(g);
            }
        }
        if self.pending > MAX_PENDING_RAYS {
            // The current sample has the last ray grouped.
            let last = self
                .current
                .as_ref()
                .and_then(|_| self.batches.back())
                .and_then(|(_, b)| b.last())
                .map_or(0, |r| r.line);
            return Err(Overfull {
                line: last,
                rays: self.pending as u64,
                samples: (self.parked_open + usize::from(self.current.is_some())) as u64,
            });
        }
        Ok(())
    }

    /// Hands back the batches no open sample has rays in (all of them, at the end), once the
    /// samples closed have been judged: a sample whose rays are a run in a batch has its last
    /// ray there, so it is closed once [`WINDOW`] records have passed the batch's end.
    fn release(&mut self, all: bool) {
        let limit = self.seen.saturating_sub(WINDOW);
        while self
            .batches
            .front()
            .is_some_and(|(base, b)| all || base + b.len() as u64 <= limit)
        {
            if let Some((_, mut b)) = self.batches.pop_front() {
                b.clear();
                self.spare.push(b);
            }
        }
    }
}

/// Batches read and judged between two progress reports.
const STEPS: usize = 8;

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
fn judge_groups(judge: &Judge<'_>, groups: &[&[LoggedRay]], keep: usize, findings: bool) -> Judged {
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
        // The tally is boxed so that each sample passes a pointer along the fold, not the
        // tally's few hundred bytes.
        let t = groups
            .par_iter()
            .with_min_len(16)
            .fold(
                || Box::new(Tally::new(keep)),
                |mut t, g| {
                    judge.judge_group(g, &mut t);
                    t
                },
            )
            .reduce(|| Box::new(Tally::new(keep)), |a, b| Box::new(a.merge(*b)));
        (*t, None)
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
    // The pixel samples of the rays of `next` and of `read`, one a ray.
    let mut next_keys: Vec<Key> = Vec::with_capacity(log::BATCH);
    let mut read_keys: Vec<Key> = Vec::with_capacity(log::BATCH);
    let mut more = true;
    while more || read.is_some() {
        // Several batches at a time on one of the pool's threads: the joins within then need
        // no hand-over to and from the thread that called `run`, which reports the progress.
        let steps = rayon::scope(|_| -> Result<bool, LogError> {
            for _ in 0..STEPS {
                if !(more || read.is_some()) {
                    break;
                }
                if cancel.load(Ordering::Relaxed) {
                    return Ok(false);
                }
                let reader = || -> Result<(bool, Duration), LogError> {
                    let t0 = Instant::now();
                    next.clear();
                    next_keys.clear();
                    // With each ray's key, written as the ray is: the grouping, which runs on
                    // one thread, then reads 20 packed bytes a ray rather than a cache line of
                    // each ray's 312.
                    let again = more && source.next_batch_keyed(&mut next, &mut next_keys)?;
                    Ok((again, t0.elapsed()))
                };
                let judger = || -> Result<(Tally, Duration), Overfull> {
                    let t1 = Instant::now();
                    let mut ready = Vec::new();
                    let mut last = false;
                    if let Some((batch, end)) = read.take() {
                        grouper.push_keyed(batch, &read_keys, &mut ready);
                        grouper.close(end, &mut ready)?;
                        last = end;
                    }
                    let Some(sink) = sink.as_mut() else {
                        let groups: Vec<&[LoggedRay]> = ready.iter().map(|g| grouper.rays(g)).collect();
                        let t = judge_groups(judge, &groups, keep, false).0;
                        grouper.release(last);
                        return Ok((t, t1.elapsed()));
                    };
                    // 512 rays at a time (a thirty-second of a batch), so that the verdicts
                    // waiting for the sink (up to a few KiB a ray) stay bounded however many
                    // samples complete at once.
                    let mut tally = Tally::new(keep);
                    let mut ready = ready.into_iter().peekable();
                    while ready.peek().is_some() {
                        let mut rays = 0;
                        let mut part = Vec::new();
                        while let Some(g) = ready.next_if(|g| part.is_empty() || rays + g.len() <= log::BATCH / 32) {
                            rays += g.len();
                            part.push(g);
                        }
                        let groups: Vec<&[LoggedRay]> = part.iter().map(|g| grouper.rays(g)).collect();
                        let (t, f) = judge_groups(judge, &groups, keep, true);
                        tally = tally.merge(t);
                        for (g, f) in part.into_iter().zip(f.unwrap_or_default()) {
                            let g = match g {
                                Rays::Copied(v) => v,
                                run => grouper.rays(&run).to_vec(),
                            };
                            sink(g, f);
                        }
                    }
                    grouper.release(last);
                    Ok((tally, t1.elapsed()))
                };
                let (got, judged) = rayon::join(reader, judger);
                let (t, dt) = judged.map_err(|o: Overfull| o.error(source))?;
                judging += dt;
                tally = std::mem::replace(&mut tally, Tally::new(keep)).merge(t);
                let (again, dt) = got?;
                reading += dt;
                // The batch read goes to the grouper, which hands back batches it no longer
                // needs, so that none is allocated again.
                let spare = grouper.spare.pop().unwrap_or_else(|| Vec::with_capacity(log::BATCH));
                if more {
                    read = Some((std::mem::replace(&mut next, spare), !again));
                    std::mem::swap(&mut next_keys, &mut read_keys);
                } else {
                    next = spare;
                }
                more = again;
            }
            Ok(true)
        });
        if !steps? {
            return Ok(None);
        }
        let (done, total) = source.progress();
        progress(done, total);
    }
    tally.finish();
    judge.fold_surfaces(&mut tally);
    tally.phantom_blockers_with_phantom_hits();
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
    fn lines(g: &Grouper, groups: &[Rays]) -> Vec<Vec<u64>> {
        groups
            .iter()
            .map(|rays| g.rays(rays).iter().map(|r| r.line).collect())
            .collect()
    }

    #[test]
    fn samples_gather_their_rays_whether_written_together_or_interleaved() {
        let mut g = Grouper::default();
        let mut ready = Vec::new();
        // Sample (0,0)#0 written whole, then (1,0)#0 and (1,0)#1 interleaved as two threads
        // write them, then (0,0)#0 again after a gap, in the next batch.
        let log = [
            ([0, 0], 0),
            ([0, 0], 0),
            ([1, 0], 0),
            ([1, 0], 1),
            ([1, 0], 0),
            ([1, 0], 1),
            ([2, 0], 3),
        ];
        let batch = log
            .into_iter()
            .enumerate()
            .map(|(line, (p, s))| LoggedRay::for_tests(p, s, line as u64 + 1))
            .collect();
        g.push_batch(batch, &mut ready);
        g.push_batch(vec![LoggedRay::for_tests([0, 0], 0, 8)], &mut ready);
        g.close(false, &mut ready).unwrap();
        assert!(ready.is_empty(), "no sample is older than the window");
        g.close(true, &mut ready).unwrap();
        // In the order of each sample's last ray.
        assert_eq!(lines(&g, &ready), vec![vec![3, 5], vec![4, 6], vec![7], vec![1, 2, 8]]);
        // A sample written whole within a batch is judged where the batch holds it.
        assert!(matches!(ready[2], Rays::Run(6, 7)), "{:?}", ready[2]);
    }

    #[test]
    fn a_sample_across_two_batches_gathers_its_rays() {
        let mut g = Grouper::default();
        let mut ready = Vec::new();
        let ray = |p: u32, line: u64| LoggedRay::for_tests([p, 0], 0, line);
        g.push_batch(vec![ray(0, 1), ray(1, 2), ray(1, 3)], &mut ready);
        g.push_batch(vec![ray(1, 4), ray(2, 5)], &mut ready);
        g.close(true, &mut ready).unwrap();
        assert_eq!(lines(&g, &ready), vec![vec![1], vec![2, 3, 4], vec![5]]);
        assert!(matches!(ready[1], Rays::Copied(_)));
        g.release(true);
        assert!(g.batches.is_empty() && g.spare.len() == 2);
    }

    /// Pushes `rays` in batches of `batch` rays, closing after each.
    fn push_rays(g: &mut Grouper, rays: impl Iterator<Item = LoggedRay>, batch: usize, ready: &mut Vec<Rays>) {
        let mut b = Vec::new();
        for r in rays {
            b.push(r);
            if b.len() == batch {
                g.push_batch(std::mem::take(&mut b), ready);
                g.close(false, ready).unwrap();
            }
        }
        if !b.is_empty() {
            g.push_batch(b, ready);
        }
    }

    #[test]
    fn a_sample_closes_once_the_window_has_passed_it() {
        let mut g = Grouper::default();
        let mut ready = Vec::new();
        // Eight samples, each of fewer rays than a group holds.
        let rays = std::iter::once(LoggedRay::for_tests([0, 0], 0, 1))
            .chain((0..WINDOW).map(|i| LoggedRay::for_tests([1, 0], (i % 8) as u32, i + 2)));
        push_rays(&mut g, rays, log::BATCH, &mut ready);
        g.close(false, &mut ready).unwrap();
        assert_eq!(lines(&g, &ready), vec![vec![1]]);
        g.close(true, &mut ready).unwrap();
        assert_eq!(ready.len(), 9);
        assert_eq!(ready.iter().map(Rays::len).sum::<usize>() as u64, WINDOW + 1);
    }

    /// Pushes `rays` as the check's loop does: a batch at a time, closing after each and
    /// handing back the batches no longer needed; the rays judged, checked to be each
    /// sample's rays in the log's order.
    fn group_all(rays: impl Iterator<Item = LoggedRay>) -> Result<usize, Overfull> {
        let mut g = Grouper::default();
        let mut judged = 0;
        let mut batch = Vec::new();
        let mut rays = rays.peekable();
        while rays.peek().is_some() {
            batch.extend(rays.by_ref().take(log::BATCH));
            let last = rays.peek().is_none();
            let mut ready = Vec::new();
            g.push_batch(std::mem::take(&mut batch), &mut ready);
            g.close(last, &mut ready)?;
            for group in &ready {
                let group = g.rays(group);
                let key = (group[0].pixel, group[0].sample);
                assert!(group.iter().all(|r| (r.pixel, r.sample) == key));
                assert!(group.windows(2).all(|w| w[0].line < w[1].line));
                judged += group.len();
            }
            g.release(last);
            // The batches held cover the window and the batch being grouped.
            assert!(g.batches.len() <= (WINDOW as usize).div_ceil(log::BATCH) + 2);
            batch = g.spare.pop().unwrap_or_default();
        }
        Ok(judged)
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
