//! Jobs handed to worker slots, heaviest first. A slot holds one worker process at a
//! time: a worker that dies mid-job (a crash, a kill) is replaced and the job retried
//! once, its leftovers cleared first; a job that fails is retried once, unless its
//! failure is run-wide, which stops the run; a worker that cannot render (its renderer
//! fails to open, or draws no first frame before the deadline) retires its slot and its
//! job goes back to the queue, unattempted, for another slot; with no slot left to
//! render, or a worker that cannot be started, the run fails.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Condvar, Mutex, MutexGuard};

use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::error::PoolError;
use crate::process::{Silence, Worker, WorkerPool};
use crate::protocol::{FromWorker, ToWorker};
use crate::spec::WorkerProcesses;

/// A job's final result: what it gave, or why it failed twice.
pub type JobResult<D> = Result<D, String>;

/// The jobs of a run as the schedule sees them, and what the stage does as they go.
pub trait JobSet: Sync {
    /// The run's configuration, sent to each worker first.
    type Hello: Serialize + Sync;
    /// One job, as sent to a worker.
    type Job: Serialize + Sync;
    /// What a finished job gives.
    type Done: DeserializeOwned + Send;

    /// The configuration.
    fn hello(&self) -> &Self::Hello;
    /// How many jobs.
    fn len(&self) -> usize;
    /// Whether there are none.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Job `k`.
    fn job(&self, k: usize) -> &Self::Job;
    /// Job `k` in words, for messages.
    fn key(&self, k: usize) -> String;
    /// Its weight: heavier jobs go first (ties in index order).
    fn weight(&self, _k: usize) -> u64 {
        1
    }
    /// Work reported done (frames, steps).
    fn progress(&self, _n: u64) {}
    /// Clears what a failed attempt at job `k` left (its staging).
    fn clear(&self, _k: usize) {}
    /// Job `k` failed (`reason`) and is retried; `redone` units of progress will be done
    /// again.
    fn retrying(&self, _k: usize, _reason: &str, _redone: u64) {}
    /// Job `k` finished.
    fn done(&self, _k: usize, _done: &Self::Done) {}
    /// Something the user should see (a retired worker).
    fn note(&self, _message: &str) {}
}

/// What to do when no worker can render.
const STALL_HINT: &str = "several processes opening EGL contexts on one GPU have been seen to \
hang on their first render (mujoco issue 3444): run fewer workers per GPU (-j), spread them over \
GPUs with --egl-devices, check `dexjoco-data doctor`, or allow more time with --first-frame-timeout";

/// How a worker rendering with the Warp batch renderer names its device
/// ([`crate::FromWorker::Device`]).
pub const WARP_WORDS: &str = "the Warp renderer";

/// What to do when no worker can render with the Warp renderer.
const WARP_STALL_HINT: &str = "a Warp worker compiles its kernels on its first render (minutes on \
a new machine, cached after) and may hang in its GPU driver: allow more time with \
--first-frame-timeout, check `dexjoco-data doctor`, or render with --renderer opengl";

/// The queue and what the slots are doing, under one lock.
struct Schedule<D> {
    /// (job index, attempt) still to run.
    queue: VecDeque<(usize, u32)>,
    /// Jobs a slot is running.
    in_flight: usize,
    /// Slots that can still render.
    live: usize,
    results: Vec<Option<JobResult<D>>>,
    /// Why slots were retired.
    retired: Vec<String>,
    fatal: Option<PoolError>,
}

impl<D> Schedule<D> {
    /// Processes that have work now (their share of the cores).
    fn busy(&self) -> usize {
        self.live.min(self.queue.len() + self.in_flight).max(1)
    }

    /// Stops the run: no slot takes another job.
    fn stop(&mut self, why: PoolError) {
        self.fatal.get_or_insert(why);
        self.queue.clear();
    }
}

/// How one attempt at a job ended.
enum Attempt<D> {
    Done(D),
    /// The job failed; `ended` when its worker process is gone (crashed, killed).
    Failed {
        reason: String,
        ended: bool,
    },
    /// The job's failure stops the run.
    RunWide(String),
    /// The worker cannot render; the job was not really tried.
    CannotRender(String),
    /// The run stopped while the job ran; its worker was killed.
    Stopped,
}

/// Runs every job of `jobs` on worker processes (the pool's started ones first), each
/// retried once; index-aligned results. Fails when a failure is run-wide, when no worker
/// can render, or when a worker cannot be started; every worker has ended by then.
pub fn run_jobs<J: JobSet>(
    w: &WorkerProcesses,
    pool: WorkerPool,
    jobs: &J,
) -> Result<Vec<JobResult<J::Done>>, PoolError> {
    let mut order: Vec<usize> = (0..jobs.len()).collect();
    order.sort_by_key(|&k| std::cmp::Reverse(jobs.weight(k)));
    let slots = pool.into_slots(w.count.min(jobs.len()).max(1));
    let schedule = Mutex::new(Schedule {
        queue: order.into_iter().map(|k| (k, 0)).collect(),
        in_flight: 0,
        live: slots.len(),
        results: (0..jobs.len()).map(|_| None).collect(),
        retired: Vec::new(),
        fatal: None,
    });
    let changed = Condvar::new();
    let stop = AtomicBool::new(false);
    let ctx = Slots {
        w,
        jobs,
        schedule: &schedule,
        changed: &changed,
        stop: &stop,
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
        let hint = if s.retired.iter().any(|r| r.contains(WARP_WORDS)) {
            WARP_STALL_HINT
        } else {
            STALL_HINT
        };
        return Err(PoolError::NoRenderer {
            retired: s.retired,
            hint,
        });
    }
    Ok(s.results
        .into_iter()
        .map(|r| r.unwrap_or_else(|| Err("not run".into())))
        .collect())
}

/// What every slot shares.
struct Slots<'a, J: JobSet> {
    w: &'a WorkerProcesses,
    jobs: &'a J,
    schedule: &'a Mutex<Schedule<J::Done>>,
    changed: &'a Condvar,
    /// Set when the run stops: the slots kill their workers.
    stop: &'a AtomicBool,
}

/// A job a slot has taken: it goes back to the queue or gets its result through one of
/// the [`Slots`] methods; dropped otherwise (a panicking slot), it stops the run so that
/// the other slots do not wait for it forever.
struct Taken<'a, D> {
    k: usize,
    attempt: u32,
    settled: bool,
    schedule: &'a Mutex<Schedule<D>>,
    changed: &'a Condvar,
}

impl<J: JobSet> Slots<'_, J> {
    fn lock(&self) -> MutexGuard<'_, Schedule<J::Done>> {
        self.schedule.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A slot's loop: take a job, have its worker (started when needed) do it, record the
    /// result; until no job is left or in flight, or the slot is retired.
    fn run_slot(&self, slot: usize, mut worker: Option<Worker>) {
        while let Some((mut taken, busy)) = self.take() {
            if worker.is_none() {
                match Worker::spawn(self.w, slot, busy, self.jobs.hello()) {
                    Ok(wk) => worker = Some(wk),
                    Err(e) => return self.retire(&mut taken, None, Some(e)),
                }
            }
            let wk = worker.as_mut().expect("spawned");
            let (attempt, done) = self.attempt(wk, taken.k, taken.attempt);
            match attempt {
                Attempt::Done(d) => {
                    self.jobs.done(taken.k, &d);
                    self.finish(&mut taken, Ok(d));
                }
                Attempt::Failed { reason, ended } => {
                    if ended {
                        // Crashed or killed: a fresh worker for the next job.
                        worker = None;
                    }
                    self.jobs.clear(taken.k);
                    self.failed(&mut taken, reason, done);
                }
                Attempt::RunWide(reason) => {
                    self.jobs.clear(taken.k);
                    self.stop.store(true, Ordering::SeqCst);
                    self.settle(&mut taken, |s| s.stop(PoolError::RunWide(reason)));
                }
                Attempt::Stopped => {
                    self.jobs.clear(taken.k);
                    self.finish(&mut taken, Err("the run stopped".into()));
                    return;
                }
                Attempt::CannotRender(why) => {
                    self.jobs.clear(taken.k);
                    let key = self.jobs.key(taken.k);
                    tracing::warn!("{why}; its job {key} goes to another worker");
                    self.jobs.note(&why);
                    return self.retire(&mut taken, Some(why), None);
                }
            }
        }
        if let Some(wk) = worker {
            wk.close();
        }
    }

    /// The next job and the number of busy slots, waiting while others may still hand
    /// jobs back; `None` when all is done.
    fn take(&self) -> Option<(Taken<'_, J::Done>, usize)> {
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

    /// One attempt at job `k` on `wk`, and the progress it reported.
    fn attempt(&self, wk: &mut Worker, k: usize, attempt: u32) -> (Attempt<J::Done>, u64) {
        let mut done = 0u64;
        let job = ToWorker::<(), _>::Job {
            attempt,
            job: self.jobs.job(k),
        };
        if let Err(s) = wk.send(&job) {
            return (silence(s), done);
        }
        loop {
            match wk.receive::<J::Done>(self.stop) {
                Ok(FromWorker::Progress(n)) => {
                    done += n;
                    self.jobs.progress(n);
                }
                Ok(FromWorker::Done(d)) => return (Attempt::Done(d), done),
                Ok(FromWorker::Failed(f)) if f.run_wide => {
                    return (Attempt::RunWide(f.message), done);
                }
                Ok(FromWorker::Failed(f)) => {
                    let ended = false;
                    return (
                        Attempt::Failed {
                            reason: f.message,
                            ended,
                        },
                        done,
                    );
                }
                Ok(_) => {}
                Err(s) => return (silence(s), done),
            }
        }
    }

    /// Settles `taken` under the lock: `f` records its outcome, then the slots waiting
    /// for jobs are woken.
    fn settle(&self, taken: &mut Taken<'_, J::Done>, f: impl FnOnce(&mut Schedule<J::Done>)) {
        let mut s = self.lock();
        s.in_flight -= 1;
        taken.settled = true;
        f(&mut s);
        self.changed.notify_all();
    }

    fn finish(&self, taken: &mut Taken<'_, J::Done>, result: JobResult<J::Done>) {
        let k = taken.k;
        self.settle(taken, |s| s.results[k] = Some(result));
    }

    /// A failed attempt: the first is retried (its progress done again), the second is
    /// the job's result.
    fn failed(&self, taken: &mut Taken<'_, J::Done>, reason: String, done: u64) {
        let key = self.jobs.key(taken.k);
        if taken.attempt > 0 || self.stop.load(Ordering::SeqCst) {
            tracing::warn!("{key} failed (attempt {}): {reason}", taken.attempt + 1);
            return self.finish(taken, Err(reason));
        }
        tracing::warn!("{key} failed, retrying it once: {reason}");
        let k = taken.k;
        self.jobs.retrying(k, &reason, done);
        self.settle(taken, |s| s.queue.push_back((k, 1)));
    }

    /// Retires this slot: its job goes back to the front of the queue, unattempted; a
    /// fatal error stops the run.
    fn retire(
        &self,
        taken: &mut Taken<'_, J::Done>,
        why: Option<String>,
        fatal: Option<PoolError>,
    ) {
        let (k, attempt) = (taken.k, taken.attempt);
        if fatal.is_some() {
            self.stop.store(true, Ordering::SeqCst);
        }
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

impl<D> Drop for Taken<'_, D> {
    fn drop(&mut self) {
        if self.settled {
            return;
        }
        // A slot that panicked while it held this job: the run stops, rather than the
        // other slots waiting for the job forever.
        let mut s = self.schedule.lock().unwrap_or_else(|e| e.into_inner());
        s.in_flight -= 1;
        s.live -= 1;
        s.stop(PoolError::Bug);
        self.changed.notify_all();
    }
}

fn silence<D>(s: Silence) -> Attempt<D> {
    match s {
        Silence::Ended(reason) => Attempt::Failed {
            reason,
            ended: true,
        },
        Silence::CannotRender(why) => Attempt::CannotRender(why),
        Silence::Stopped => Attempt::Stopped,
    }
}
