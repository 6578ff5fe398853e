//! One worker process as the parent sees it: started with its share of the machine and
//! its EGL device, its messages read on a thread of their own, and deadlines: a renderer
//! must draw its first frame within the first-frame deadline of its opening, and a worker
//! that has drawn and then says nothing for the silence deadline is taken for hung.
//! Killed and reaped when dropped unless closed, so that no error path leaves one behind.

use std::io::{BufRead, BufReader};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::error::PoolError;
use crate::protocol::{FromWorker, SLOT_ENV, ToWorker, send};
use crate::spec::WorkerProcesses;

/// How long a closing worker may take to exit before it is killed.
const CLOSE_GRACE: Duration = Duration::from_secs(30);

/// How often a waiting parent looks whether the run was stopped.
const STOP_POLL: Duration = Duration::from_millis(100);

/// Why a worker gave no answer.
#[derive(Debug)]
pub(crate) enum Silence {
    /// It ended (crashed, killed, said something unreadable) or went silent after drawing;
    /// the worker is gone.
    Ended(String),
    /// It cannot render: its renderer failed to open or to draw a first frame in time (it
    /// was killed), or it ended before drawing one.
    CannotRender(String),
    /// The run was stopped (another job's run-wide failure): the worker was killed.
    Stopped,
}

/// One running worker process.
pub(crate) struct Worker {
    child: Child,
    stdin: Option<ChildStdin>,
    /// Its stdout's lines; `None` once stdout ended.
    lines: Receiver<Option<String>>,
    slot: usize,
    /// The EGL device the parent assigned.
    assigned: Option<usize>,
    /// The device its renderer reported opening.
    device: Option<String>,
    /// Whether its current renderer has drawn a frame.
    ready: bool,
    /// When its current renderer began to open (or the worker started).
    opening_since: Instant,
    first_frame: Duration,
    silence: Duration,
}

impl Worker {
    /// Starts the worker of `slot`, one of `busy` rendering processes (its share of
    /// llvmpipe's threads), and sends it the run's configuration.
    pub(crate) fn spawn<H: Serialize>(
        w: &WorkerProcesses,
        slot: usize,
        busy: usize,
        hello: &H,
    ) -> Result<Self, PoolError> {
        let mut cmd = Command::new(&w.program);
        cmd.args(&w.args)
            .env(SLOT_ENV, slot.to_string())
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit());
        let assigned = w.device_of(slot);
        if let Some(dev) = assigned {
            cmd.env(dexjoco_render::EGL_DEVICE_ENV, dev.to_string());
        }
        dexjoco_render::share_llvmpipe_threads(&mut cmd, busy);
        let mut child = cmd.spawn().map_err(|source| PoolError::Spawn {
            program: w.program.clone(),
            source,
        })?;
        tracing::debug!(slot, pid = child.id(), "started worker process {slot}");
        let stdin = child.stdin.take();
        let stdout = BufReader::new(child.stdout.take().expect("piped"));
        let (tx, lines) = std::sync::mpsc::channel();
        // The reader ends with the worker's stdout (it exits or is killed).
        std::thread::spawn(move || {
            for line in stdout.lines() {
                let Ok(line) = line else { break };
                if tx.send(Some(line)).is_err() {
                    break;
                }
            }
            let _ = tx.send(None);
        });
        let mut worker = Self {
            child,
            stdin,
            lines,
            slot,
            assigned,
            device: None,
            ready: false,
            opening_since: Instant::now(),
            first_frame: w.first_frame_timeout,
            silence: w.silence_timeout,
        };
        // On failure the worker is dropped: killed and reaped.
        worker
            .send(&ToWorker::<&H, ()>::Hello(hello))
            .map_err(|_| PoolError::EndedAtOnce { slot })?;
        Ok(worker)
    }

    /// Sends a message.
    pub(crate) fn send<T: Serialize>(&mut self, msg: &T) -> Result<(), Silence> {
        let stdin = self.stdin.as_mut().expect("open until closed");
        send(stdin, msg).map_err(|e| self.ended(&e.to_string()))
    }

    /// The next message about the job, or why there is none; the worker is killed as soon
    /// as `stop` is set.
    pub(crate) fn receive<D: DeserializeOwned>(
        &mut self,
        stop: &AtomicBool,
    ) -> Result<FromWorker<D>, Silence> {
        let mut heard = Instant::now();
        loop {
            let (deadline, silence) = if self.ready {
                (heard + self.silence, true)
            } else {
                (self.opening_since + self.first_frame, false)
            };
            if stop.load(Ordering::SeqCst) {
                self.kill();
                return Err(Silence::Stopped);
            }
            let left = deadline.saturating_duration_since(Instant::now());
            let line = match self.lines.recv_timeout(left.min(STOP_POLL)) {
                Ok(line) => line,
                Err(RecvTimeoutError::Timeout) if !left.is_zero() => continue,
                Err(RecvTimeoutError::Timeout) if silence => {
                    self.kill();
                    return Err(Silence::Ended(format!(
                        "worker process {} sent nothing for {} s after drawing ({}); it was killed",
                        self.slot,
                        self.silence.as_secs_f64(),
                        self.device_words()
                    )));
                }
                Err(RecvTimeoutError::Timeout) => return Err(Silence::CannotRender(self.stall())),
                Err(RecvTimeoutError::Disconnected) => None,
            };
            let Some(line) = line else {
                return Err(self.ended("its output ended"));
            };
            heard = Instant::now();
            match serde_json::from_str(&line) {
                Ok(FromWorker::Opening) => {
                    self.ready = false;
                    self.opening_since = Instant::now();
                }
                Ok(FromWorker::Device(d)) => self.device = Some(d),
                Ok(FromWorker::Ready) => self.ready = true,
                Ok(FromWorker::CannotRender(why)) => {
                    self.kill();
                    return Err(Silence::CannotRender(format!(
                        "worker process {} cannot render ({}): {why}",
                        self.slot,
                        self.device_words()
                    )));
                }
                Ok(msg) => {
                    if matches!(msg, FromWorker::Progress(n) if n > 0) {
                        self.ready = true;
                    }
                    return Ok(msg);
                }
                Err(e) => {
                    self.kill();
                    return Err(self.ended(&format!(
                        "unreadable message from a worker process ({e}): {}",
                        &line[..line.floor_char_boundary(300)]
                    )));
                }
            }
        }
    }

    /// Which device, in words (the worker names the renderer it opened: an EGL device,
    /// or the Warp renderer and its device).
    fn device_words(&self) -> String {
        match (&self.device, self.assigned) {
            (Some(d), _) => format!("on {d}"),
            (None, Some(i)) => format!("assigned EGL device {i}, which it had not opened yet"),
            (None, None) => "before its renderer opened".to_owned(),
        }
    }

    /// Kills a worker past its first-frame deadline and says which, on which device.
    fn stall(&mut self) -> String {
        self.kill();
        format!(
            "worker process {} drew no frame within {} s of opening its renderer ({}); it was killed",
            self.slot,
            self.first_frame.as_secs_f64(),
            self.device_words()
        )
    }

    /// Reaps the ended process and says how it ended: before its renderer drew, it cannot
    /// render; after, it crashed or was killed.
    fn ended(&mut self, what: &str) -> Silence {
        let how = match self.child.wait() {
            Ok(s) => format!("{what}; the worker process ended ({s})"),
            Err(e) => format!("{what}; the worker process ended ({e})"),
        };
        if self.ready {
            Silence::Ended(format!("worker process {}: {how}", self.slot))
        } else {
            Silence::CannotRender(format!(
                "worker process {} ended before its renderer drew ({}): {how}",
                self.slot,
                self.device_words()
            ))
        }
    }

    /// Ends the worker after its last job: its stdin closes and it exits, or is killed
    /// after a grace period.
    pub(crate) fn close(mut self) {
        drop(self.stdin.take());
        let until = Instant::now() + CLOSE_GRACE;
        while Instant::now() < until {
            match self.child.try_wait() {
                Ok(Some(_)) | Err(_) => return,
                Ok(None) => std::thread::sleep(Duration::from_millis(20)),
            }
        }
        tracing::warn!(
            "worker process {} did not exit after its last job; killed",
            self.slot
        );
    }

    fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        if !matches!(self.child.try_wait(), Ok(Some(_))) {
            self.kill();
        }
    }
}

/// Worker processes started ahead of the jobs: they load their scenes and renderers while
/// the parent prepares, so that loading is not paid twice in a row. Workers not taken by
/// the schedule (nothing to do, or the run stopped before) are ended on drop: they have
/// written nothing.
pub struct WorkerPool {
    pub(crate) workers: Vec<Worker>,
}

impl WorkerPool {
    /// No worker started ahead: the schedule starts each slot's worker when it takes a job.
    pub fn empty() -> Self {
        Self {
            workers: Vec::new(),
        }
    }

    /// Starts `min(w.count, max_jobs)` workers (none when `max_jobs` is 0), each sent
    /// `hello` and given its share of the cores.
    pub fn start<H: Serialize>(
        w: &WorkerProcesses,
        hello: &H,
        max_jobs: usize,
    ) -> Result<Self, PoolError> {
        let count = w.count.min(max_jobs);
        if count == 0 {
            tracing::debug!("nothing to do: no worker process started");
        }
        let workers = (0..count)
            .map(|slot| Worker::spawn(w, slot, count, hello))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self { workers })
    }

    /// One entry per slot: the started workers first, `None` for slots that start theirs
    /// when they take a job; workers beyond `slots` are ended.
    pub(crate) fn into_slots(mut self, slots: usize) -> Vec<Option<Worker>> {
        let keep = slots.min(self.workers.len());
        let mut out: Vec<Option<Worker>> = self.workers.drain(..keep).map(Some).collect();
        out.resize_with(slots, || None);
        out
    }
}
