//! How worker processes are started, and the renderer probe that runs before any.

use std::collections::BTreeSet;
use std::ffi::OsString;
use std::path::PathBuf;
use std::time::Duration;

use crate::error::PoolError;

/// How long a worker process may take from its start to its first rendered frame.
pub const DEFAULT_FIRST_FRAME_TIMEOUT: Duration = Duration::from_secs(120);

/// How many first-frame deadlines a rendering worker may stay silent by default.
const SILENCE_FACTOR: u32 = 10;

/// How to start worker processes.
#[derive(Debug, Clone)]
pub struct WorkerProcesses {
    /// The program (the `dexjoco-data` binary).
    pub program: PathBuf,
    /// Its arguments that make it a worker.
    pub args: Vec<OsString>,
    /// Number of workers.
    pub count: usize,
    /// EGL device indices assigned to workers round-robin (`DEXJOCO_EGL_DEVICE`); empty:
    /// each picks the default device.
    pub egl_devices: Vec<usize>,
    /// A worker that has drawn no frame this long after its renderer began to open is
    /// killed, and its slot retired ([`DEFAULT_FIRST_FRAME_TIMEOUT`]).
    pub first_frame_timeout: Duration,
    /// A worker that has drawn and then says nothing this long is taken for hung and
    /// killed (default: ten first-frame deadlines).
    pub silence_timeout: Duration,
}

impl WorkerProcesses {
    /// Workers of `program` started with `args`, `count` of them, on the default EGL device
    /// with the default deadlines.
    pub fn new(program: PathBuf, args: Vec<OsString>, count: usize) -> Self {
        Self {
            program,
            args,
            count,
            egl_devices: Vec::new(),
            first_frame_timeout: DEFAULT_FIRST_FRAME_TIMEOUT,
            silence_timeout: DEFAULT_FIRST_FRAME_TIMEOUT * SILENCE_FACTOR,
        }
    }

    /// With this first-frame deadline (and ten times it as the silence deadline).
    pub fn with_first_frame_timeout(mut self, timeout: Duration) -> Self {
        self.first_frame_timeout = timeout;
        self.silence_timeout = timeout * SILENCE_FACTOR;
        self
    }

    /// With these EGL devices, dealt to the workers round-robin.
    pub fn with_egl_devices(mut self, devices: Vec<usize>) -> Self {
        self.egl_devices = devices;
        self
    }

    /// The EGL device the worker of `slot` is given, if any.
    pub(crate) fn device_of(&self, slot: usize) -> Option<usize> {
        (!self.egl_devices.is_empty()).then(|| self.egl_devices[slot % self.egl_devices.len()])
    }

    /// Opens an offscreen context on every EGL device the workers will render on (each
    /// one's assigned device, else the default one), each within the first-frame deadline,
    /// and closes it: a machine that cannot render fails in seconds, naming the device,
    /// before any work is spent.
    pub fn check_renderer(&self) -> Result<(), PoolError> {
        let devices: BTreeSet<Option<usize>> = if self.egl_devices.is_empty() {
            [None].into()
        } else {
            (0..self.count.max(1)).map(|s| self.device_of(s)).collect()
        };
        devices
            .into_iter()
            .try_for_each(|d| probe_renderer(d, self.first_frame_timeout))
    }
}

/// Probes `device` (`None`: the default one) on a thread of its own, so that a hung
/// driver fails the run at the deadline rather than hanging it.
pub fn probe_renderer(device: Option<usize>, deadline: Duration) -> Result<(), PoolError> {
    let words = device.map_or_else(
        || "the default EGL device".to_owned(),
        |i| format!("EGL device {i}"),
    );
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(dexjoco_render::probe_renderer(device));
    });
    let reason = match rx.recv_timeout(deadline) {
        Ok(Ok(opened)) => {
            tracing::debug!(
                "renderer probe: an offscreen context opens on EGL device {} ({})",
                opened.index,
                opened.label()
            );
            return Ok(());
        }
        Ok(Err(dexjoco_render::RenderError::Egl(why))) => why.to_string(),
        Ok(Err(e)) => e.to_string(),
        Err(_) => format!(
            "no offscreen context opened within {} s (--first-frame-timeout)",
            deadline.as_secs_f64()
        ),
    };
    Err(PoolError::RenderingUnavailable {
        device: words,
        reason,
    })
}
