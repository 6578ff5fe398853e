//! One worker process as the parent sees it: started with its share of the machine, its
//! messages read on a thread of their own, and deadlines: a renderer must draw its first
//! frame within the first-frame deadline of its opening, and a rendering worker that then
//! says nothing for ten times as long is taken for hung.

use std::io::{BufRead, BufReader};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use super::executor::{Executor, WorkerProcesses};
use super::protocol::{FromWorker, SLOT_ENV, ToWorker, send};
use crate::config::AugmentConfig;
use crate::error::AugmentError;

/// How many first-frame deadlines a rendering worker may stay silent.
const SILENCE_FACTOR: u32 = 10;

/// How long a closing worker may take to exit before it is killed.
const CLOSE_GRACE: Duration = Duration::from_secs(30);

/// Why a worker gave no answer.
pub(super) enum Silence {
    /// It ended (crashed, killed, said something unreadable) or went silent while
    /// rendering; the worker is gone.
    Ended(String),
    /// It cannot render: its renderer failed to open or to draw a first frame in time (it
    /// was killed), or it ended before drawing one.
    CannotRender(String),
}

/// One running worker process; killed and reaped when dropped unless closed.
pub(super) struct Worker {
    child: Child,
    stdin: Option<ChildStdin>,
    /// Its stdout's lines; `None` once stdout ended.
    lines: Receiver<Option<String>>,
    slot: usize,
    /// The EGL device the parent assigned (`--egl-devices`).
    assigned: Option<usize>,
    /// The device its renderer reported opening.
    device: Option<String>,
    /// Whether its current renderer has drawn a frame.
    ready: bool,
    /// When its current renderer began to open (or the worker started).
    opening_since: Instant,
    timeout: Duration,
}

impl Worker {
    /// Starts the worker of `slot`, one of `busy` rendering processes (its share of
    /// llvmpipe's threads), and sends it the run's configuration.
    pub(super) fn spawn(
        w: &WorkerProcesses,
        slot: usize,
        busy: usize,
        config: &AugmentConfig,
        preload: &[String],
    ) -> Result<Self, AugmentError> {
        let mut cmd = Command::new(&w.program);
        cmd.args(&w.args)
            .env(SLOT_ENV, slot.to_string())
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit());
        let assigned =
            (!w.egl_devices.is_empty()).then(|| w.egl_devices[slot % w.egl_devices.len()]);
        if let Some(dev) = assigned {
            cmd.env(dexjoco_sim::EGL_DEVICE_ENV, dev.to_string());
        }
        dexjoco_sim::share_llvmpipe_threads(&mut cmd, busy);
        let mut child = cmd.spawn().map_err(|e| {
            AugmentError::Input(format!(
                "cannot start a worker process '{}': {e}",
                w.program.display()
            ))
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
            timeout: w.first_frame_timeout,
        };
        let hello = ToWorker::Hello {
            config: Box::new(config.clone()),
            preload: preload.to_vec(),
        };
        // On failure the worker is dropped: killed and reaped.
        worker
            .send(&hello)
            .map_err(|_| AugmentError::Input(format!("worker process {slot} ended at once")))?;
        Ok(worker)
    }

    pub(super) fn send(&mut self, msg: &ToWorker) -> Result<(), Silence> {
        let stdin = self.stdin.as_mut().expect("open until closed");
        send(stdin, msg).map_err(|e| self.ended(&e.to_string()))
    }

    /// The next message about the unit, or why there is none.
    pub(super) fn receive(&mut self) -> Result<FromWorker, Silence> {
        loop {
            let (deadline, silence) = if self.ready {
                (Instant::now() + self.timeout * SILENCE_FACTOR, true)
            } else {
                (self.opening_since + self.timeout, false)
            };
            let line = match self
                .lines
                .recv_timeout(deadline.saturating_duration_since(Instant::now()))
            {
                Ok(line) => line,
                Err(RecvTimeoutError::Timeout) if silence => {
                    self.kill();
                    let secs = (self.timeout * SILENCE_FACTOR).as_secs_f64();
                    return Err(Silence::Ended(format!(
                        "worker process {} sent nothing for {secs} s while rendering ({}); it was killed",
                        self.slot,
                        self.device_words()
                    )));
                }
                Err(RecvTimeoutError::Timeout) => return Err(Silence::CannotRender(self.stall())),
                Err(RecvTimeoutError::Disconnected) => None,
            };
            let Some(line) = line else {
                return Err(self.ended("its output ended"));
            };
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
                    if matches!(msg, FromWorker::Frames(n) if n > 0) {
                        self.ready = true;
                    }
                    return Ok(msg);
                }
                Err(e) => {
                    self.kill();
                    return Err(self.ended(&format!(
                        "unreadable message from a worker process ({e}): {line}"
                    )));
                }
            }
        }
    }

    /// Which EGL device, in words.
    fn device_words(&self) -> String {
        match (&self.device, self.assigned) {
            (Some(d), _) => format!("on EGL device {d}"),
            (None, Some(i)) => format!("assigned EGL device {i}, which it had not opened yet"),
            (None, None) => "before its EGL renderer opened".to_owned(),
        }
    }

    /// Kills a worker past its first-frame deadline and says which, on which device.
    fn stall(&mut self) -> String {
        self.kill();
        format!(
            "worker process {} drew no frame within {} s of opening its renderer ({}); it was killed",
            self.slot,
            self.timeout.as_secs_f64(),
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
            Silence::Ended(how)
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
    pub(super) fn close(mut self) {
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
/// the parent loads and simulates, so that loading is not paid twice in a row. Workers
/// not taken by [`WorkerPool::into_slots`] (nothing to render, or the run stopped before
/// rendering) are ended on drop: they have written nothing.
pub(crate) struct WorkerPool {
    workers: Vec<Worker>,
}

impl WorkerPool {
    /// Starts `w.count` workers (no more than `max_units`, the most units the run can
    /// have: none when it is 0) that preload the scenes of `tasks`, each with its share of
    /// the cores; none for the thread executor.
    pub(crate) fn start(
        executor: &Executor,
        config: &AugmentConfig,
        tasks: &[String],
        max_units: usize,
    ) -> Result<Self, AugmentError> {
        let mut pool = Self {
            workers: Vec::new(),
        };
        if let Executor::Processes(w) = executor {
            let count = w.count.min(max_units);
            if count == 0 {
                tracing::debug!("nothing to render: no worker process started");
            }
            for slot in 0..count {
                pool.workers
                    .push(Worker::spawn(w, slot, count, config, tasks)?);
            }
        }
        Ok(pool)
    }

    /// One entry per slot: the started workers first, `None` for slots that start theirs
    /// when they take a job; workers beyond `slots` are ended.
    pub(super) fn into_slots(mut self, slots: usize) -> Vec<Option<Worker>> {
        let keep = slots.min(self.workers.len());
        let mut out: Vec<Option<Worker>> = self.workers.drain(..keep).map(Some).collect();
        out.resize_with(slots, || None);
        out
    }
}
