//! Units of work handed to worker slots, biggest first. A slot holds one worker process
//! at a time: a worker that dies mid-unit is replaced and the unit retried once; a worker
//! that cannot render (its renderer fails to open, or draws no first frame before the
//! deadline) retires its slot and its unit goes back to the queue, unattempted, for another
//! slot; with no slot left to render, or a worker that cannot be started, the run fails.

use std::collections::VecDeque;
use std::sync::{Condvar, Mutex, MutexGuard};

use dexjoco_core::Progress;

use super::executor::{UnitResult, WorkerProcesses};
use super::process::{Silence, Worker, WorkerPool};
use super::protocol::{FromWorker, ToWorker};
use crate::config::AugmentConfig;
use crate::error::AugmentError;
use crate::profile::StageTimes;
use crate::render::UnitJob;
use crate::staging::Outcome;

/// What to do when no worker can render.
const STALL_HINT: &str = "several processes opening EGL contexts on one GPU have been seen to \
hang on their first render (mujoco issue 3444): run fewer workers per GPU (-j), spread them over \
GPUs with --egl-devices, check `dexjoco-data doctor`, or allow more time with --first-frame-timeout";

/// The queue and what the slots are doing, under one lock.
struct Schedule {
    /// (job index, attempt) still to run.
    queue: VecDeque<(usize, u32)>,
    /// Units a slot is running.
    in_flight: usize,
    /// Slots that can still render.
    live: usize,
    results: Vec<Option<UnitResult>>,
    times: StageTimes,
    /// Frames rendered by attempts that failed (rendered again by the retry).
    extra_frames: u64,
    /// Why slots were retired.
    retired: Vec<String>,
    fatal: Option<AugmentError>,
}

impl Schedule {
    /// Rendering processes that have work now (their share of the cores).
    fn busy(&self) -> usize {
        self.live.min(self.queue.len() + self.in_flight).max(1)
    }

    /// Stops the run: no slot takes another unit.
    fn stop(&mut self, why: AugmentError) {
        self.fatal.get_or_insert(why);
        self.queue.clear();
    }
}

/// How one attempt at a unit ended.
enum Attempt {
    Done(Vec<Outcome>, StageTimes),
    /// The unit failed; `ended` when its worker process is gone (crashed, killed).
    Failed {
        reason: String,
        ended: bool,
    },
    /// The worker cannot render; the unit was not really tried.
    CannotRender(String),
}

pub(super) fn run_on_processes(
    w: &WorkerProcesses,
    pool: WorkerPool,
    jobs: &[(usize, UnitJob)],
    config: &AugmentConfig,
    cameras: usize,
    total: u64,
    progress: &dyn Progress,
) -> Result<(Vec<UnitResult>, StageTimes), AugmentError> {
    // Biggest units first, so the last ones to finish are small.
    let mut order: Vec<usize> = (0..jobs.len()).collect();
    order.sort_by_key(|&k| std::cmp::Reverse(jobs[k].1.frames(cameras)));
    let slots = pool.into_slots(w.count.min(jobs.len()).max(1));
    let schedule = Mutex::new(Schedule {
        queue: order.into_iter().map(|k| (k, 0)).collect(),
        in_flight: 0,
        live: slots.len(),
        results: vec![None; jobs.len()],
        times: StageTimes::default(),
        extra_frames: 0,
        retired: Vec::new(),
        fatal: None,
    });
    let changed = Condvar::new();
    let ctx = SlotContext {
        w,
        jobs,
        config,
        total,
        progress,
        schedule: &schedule,
        changed: &changed,
    };
    std::thread::scope(|scope| {
        for (slot, first) in slots.into_iter().enumerate() {
            let ctx = &ctx;
            scope.spawn(move || ctx.run_slot(slot, first));
        }
    });
    let s = schedule.into_inner().unwrap_or_else(|e| e.into_inner());
    if let Some(e) = s.fatal {
        return Err(e);
    }
    if !s.queue.is_empty() {
        return Err(AugmentError::Input(format!(
            "no worker process could render ({}); hint: {STALL_HINT}",
            s.retired.join("; ")
        )));
    }
    let results = s
        .results
        .into_iter()
        .map(|r| r.unwrap_or_else(|| Err("not run".into())))
        .collect();
    Ok((results, s.times))
}

/// What every slot shares.
struct SlotContext<'a> {
    w: &'a WorkerProcesses,
    jobs: &'a [(usize, UnitJob)],
    config: &'a AugmentConfig,
    total: u64,
    progress: &'a dyn Progress,
    schedule: &'a Mutex<Schedule>,
    changed: &'a Condvar,
}

/// A unit a slot has taken: it goes back to the queue or gets its result through one of
/// the [`SlotContext`] methods; dropped otherwise (a panicking slot), it stops the run so
/// that the other slots do not wait for it forever.
struct Taken<'a> {
    k: usize,
    attempt: u32,
    settled: bool,
    schedule: &'a Mutex<Schedule>,
    changed: &'a Condvar,
}

impl SlotContext<'_> {
    fn lock(&self) -> MutexGuard<'_, Schedule> {
        self.schedule.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A slot's loop: take a unit, have its worker (started when needed) render it, record
    /// the result; until no unit is left or in flight, or the slot is retired.
    fn run_slot(&self, slot: usize, mut worker: Option<Worker>) {
        while let Some((mut taken, busy)) = self.take() {
            if worker.is_none() {
                match Worker::spawn(self.w, slot, busy, self.config, &[]) {
                    Ok(wk) => worker = Some(wk),
                    Err(e) => return self.retire(&mut taken, None, Some(e)),
                }
            }
            let wk = worker.as_mut().expect("spawned");
            let mut job = self.jobs[taken.k].1.clone();
            job.attempt = taken.attempt;
            let (attempt, done) = self.attempt(wk, &job);
            match attempt {
                Attempt::Done(o, t) => self.finish(&mut taken, Ok((o, t))),
                Attempt::Failed { reason, ended } => {
                    if ended {
                        // Crashed or killed: a fresh worker for the next unit.
                        worker = None;
                    }
                    job.clear_staging(&self.config.out);
                    self.failed(&mut taken, &job, reason, done);
                }
                Attempt::CannotRender(why) => {
                    job.clear_staging(&self.config.out);
                    tracing::warn!("{why}; its unit {} goes to another worker", job.key());
                    self.progress.note(&why);
                    return self.retire(&mut taken, Some(why), None);
                }
            }
        }
        if let Some(wk) = worker {
            wk.close();
        }
    }

    /// The next unit and the number of busy slots, waiting while others may still hand
    /// units back; `None` when all is done.
    fn take(&self) -> Option<(Taken<'_>, usize)> {
        let mut s = self.lock();
        loop {
            if let Some((k, attempt)) = s.queue.pop_front() {
                s.in_flight += 1;
                let busy = s.busy();
                let taken = Taken {
                    k,
                    attempt,
                    settled: false,
                    schedule: self.schedule,
                    changed: self.changed,
                };
                return Some((taken, busy));
            }
            if s.in_flight == 0 {
                return None;
            }
            s = self.changed.wait(s).unwrap_or_else(|e| e.into_inner());
        }
    }

    /// One attempt at a unit on `wk`, and the frames it rendered.
    fn attempt(&self, wk: &mut Worker, job: &UnitJob) -> (Attempt, u64) {
        let mut done = 0u64;
        if let Err(s) = wk.send(&ToWorker::Job(Box::new(job.clone()))) {
            return (silence(s), done);
        }
        loop {
            match wk.receive() {
                Ok(FromWorker::Frames(n)) => {
                    done += n;
                    self.progress.advance(n, "");
                }
                Ok(FromWorker::Done { outcomes, times }) => {
                    return (Attempt::Done(outcomes, times), done);
                }
                Ok(FromWorker::Error(reason)) => {
                    let ended = false;
                    return (Attempt::Failed { reason, ended }, done);
                }
                Ok(_) => {}
                Err(s) => return (silence(s), done),
            }
        }
    }

    /// Settles `taken` under the lock: `f` records its outcome, then the slots waiting
    /// for units are woken.
    fn settle(&self, taken: &mut Taken<'_>, f: impl FnOnce(&mut Schedule)) {
        let mut s = self.lock();
        s.in_flight -= 1;
        taken.settled = true;
        f(&mut s);
        self.changed.notify_all();
    }

    fn finish(&self, taken: &mut Taken<'_>, result: Result<(Vec<Outcome>, StageTimes), String>) {
        let k = taken.k;
        self.settle(taken, |s| {
            s.results[k] = Some(result.map(|(o, t)| {
                s.times.add(&t);
                o
            }));
        });
    }

    /// A failed attempt: the first is retried (its frames are rendered again), the second
    /// is the unit's result.
    fn failed(&self, taken: &mut Taken<'_>, job: &UnitJob, reason: String, done: u64) {
        tracing::warn!(unit = %job.key(), "unit failed (attempt {}): {reason}", job.attempt + 1);
        if job.attempt > 0 {
            return self.finish(taken, Err(reason));
        }
        let k = taken.k;
        self.settle(taken, |s| {
            s.extra_frames += done;
            self.progress.start(self.total + s.extra_frames);
            self.progress
                .note(&format!("retrying {}: {reason}", job.key()));
            s.queue.push_back((k, 1));
        });
    }

    /// Retires this slot: its unit goes back to the front of the queue, unattempted; a
    /// fatal error stops the run.
    fn retire(&self, taken: &mut Taken<'_>, why: Option<String>, fatal: Option<AugmentError>) {
        let (k, attempt) = (taken.k, taken.attempt);
        self.settle(taken, |s| {
            s.live -= 1;
            s.queue.push_front((k, attempt));
            s.retired.extend(why);
            if let Some(e) = fatal {
                s.stop(e);
            }
        });
    }
}

impl Drop for Taken<'_> {
    fn drop(&mut self) {
        if self.settled {
            return;
        }
        // A slot that panicked while it held this unit: the run stops, rather than the
        // other slots waiting for the unit forever.
        let mut s = self.schedule.lock().unwrap_or_else(|e| e.into_inner());
        s.in_flight -= 1;
        s.live -= 1;
        s.stop(AugmentError::Input(
            "a worker slot of this process failed (a bug: please report it)".into(),
        ));
        self.changed.notify_all();
    }
}

fn silence(s: Silence) -> Attempt {
    match s {
        Silence::Ended(reason) => Attempt::Failed {
            reason,
            ended: true,
        },
        Silence::CannotRender(why) => Attempt::CannotRender(why),
    }
}
