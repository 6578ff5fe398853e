//! One worker process as the parent sees it: started with its share of the machine,
//! its messages read on a thread of their own, and a deadline for its first frame.

use std::io::{BufRead, BufReader};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use super::WorkerProcesses;
use super::protocol::{FromWorker, SLOT_ENV, ToWorker, send};
use crate::config::AugmentConfig;
use crate::error::AugmentError;

/// Why a worker gave no answer.
pub(super) enum Silence {
    /// It ended (crashed, killed) or said something unreadable.
    Ended(String),
    /// It drew no frame before its first-frame deadline and was killed.
    Stalled(String),
}

/// One running worker process.
pub(super) struct Worker {
    child: Child,
    stdin: ChildStdin,
    /// Its stdout's lines; `None` once stdout ended.
    lines: Receiver<Option<String>>,
    slot: usize,
    /// The EGL device the parent assigned (`--egl-devices`).
    assigned: Option<usize>,
    /// The device its renderer reported opening.
    device: Option<String>,
    /// Whether it has drawn a frame.
    ready: bool,
    started: Instant,
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
        super::share_llvmpipe_threads(&mut cmd, busy);
        let mut child = cmd.spawn().map_err(|e| {
            AugmentError::Input(format!(
                "cannot start a worker process '{}': {e}",
                w.program.display()
            ))
        })?;
        let mut stdin = child.stdin.take().expect("piped");
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
        let hello = ToWorker::Hello {
            config: Box::new(config.clone()),
            preload: preload.to_vec(),
        };
        send(&mut stdin, &hello)
            .map_err(|e| AugmentError::Input(format!("worker process {slot}: {e}")))?;
        Ok(Self {
            child,
            stdin,
            lines,
            slot,
            assigned,
            device: None,
            ready: false,
            started: Instant::now(),
            timeout: w.first_frame_timeout,
        })
    }

    pub(super) fn send(&mut self, msg: &ToWorker) -> Result<(), Silence> {
        send(&mut self.stdin, msg).map_err(|e| Silence::Ended(format!("{e}; {}", self.ended())))
    }

    /// The next message about the unit, or why there is none. Until its first frame, a
    /// worker has until its deadline to speak.
    pub(super) fn receive(&mut self) -> Result<FromWorker, Silence> {
        loop {
            let line = if self.ready {
                self.lines.recv().ok().flatten()
            } else {
                let left = (self.started + self.timeout).saturating_duration_since(Instant::now());
                match self.lines.recv_timeout(left) {
                    Ok(line) => line,
                    Err(RecvTimeoutError::Timeout) => return Err(Silence::Stalled(self.stall())),
                    Err(RecvTimeoutError::Disconnected) => None,
                }
            };
            let Some(line) = line else {
                return Err(Silence::Ended(self.ended()));
            };
            match serde_json::from_str(&line) {
                Ok(FromWorker::Device(d)) => self.device = Some(d),
                Ok(FromWorker::Ready) => self.ready = true,
                Ok(msg) => {
                    if matches!(msg, FromWorker::Frames(n) if n > 0) {
                        self.ready = true;
                    }
                    return Ok(msg);
                }
                Err(e) => {
                    let _ = self.child.kill();
                    return Err(Silence::Ended(format!(
                        "unreadable message from a worker process ({e}): {line}; {}",
                        self.ended()
                    )));
                }
            }
        }
    }

    /// Kills a worker past its deadline and says which, on which device.
    fn stall(&mut self) -> String {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let device = match (&self.device, self.assigned) {
            (Some(d), _) => format!("on EGL device {d}"),
            (None, Some(i)) => format!("assigned EGL device {i}, which it had not opened yet"),
            (None, None) => "before its EGL renderer opened".to_owned(),
        };
        format!(
            "worker process {} drew no frame within {} s of starting ({device}); it was killed",
            self.slot,
            self.timeout.as_secs_f64()
        )
    }

    /// Reaps the process and says how it ended.
    fn ended(&mut self) -> String {
        match self.child.wait() {
            Ok(s) => format!("the worker process ended ({s})"),
            Err(e) => format!("the worker process ended ({e})"),
        }
    }

    /// Ends the worker after its last job (its stdin closes, it exits).
    pub(super) fn close(mut self) {
        drop(self.stdin);
        let _ = self.child.wait();
    }

    fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
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
    /// have) that preload the scenes of `tasks`, each with its share of the cores; none
    /// for the thread executor.
    pub(crate) fn start(
        executor: &super::Executor,
        config: &AugmentConfig,
        tasks: &[String],
        max_units: usize,
    ) -> Result<Self, AugmentError> {
        let mut workers = Vec::new();
        if let super::Executor::Processes(w) = executor {
            let count = w.count.min(max_units).max(1);
            for slot in 0..count {
                workers.push(Worker::spawn(w, slot, count, config, tasks)?);
            }
        }
        Ok(Self { workers })
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

impl Drop for WorkerPool {
    fn drop(&mut self) {
        for wk in &mut self.workers {
            wk.kill();
        }
    }
}
