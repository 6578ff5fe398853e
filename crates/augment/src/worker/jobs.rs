//! augment's units as the worker schedule of `dexjoco-workers` sees them: heaviest (most
//! frames) first, progress in frames, a failed attempt's staging cleared, a retry's frames
//! added to the bar.

use std::sync::atomic::{AtomicU64, Ordering};

use dexjoco_core::Progress;
use dexjoco_workers::JobSet;

use super::protocol::{Hello, UnitDone};
use crate::render::UnitJob;

/// The units of a run.
pub(super) struct Units<'a> {
    pub(super) hello: Hello,
    pub(super) jobs: &'a [(usize, UnitJob)],
    pub(super) cameras: usize,
    /// Frames planned.
    pub(super) total: u64,
    pub(super) progress: &'a dyn Progress,
    /// Frames of failed attempts (rendered again by their retries).
    pub(super) extra: AtomicU64,
}

impl JobSet for Units<'_> {
    type Hello = Hello;
    type Job = UnitJob;
    type Done = UnitDone;

    fn hello(&self) -> &Hello {
        &self.hello
    }

    fn len(&self) -> usize {
        self.jobs.len()
    }

    fn job(&self, k: usize) -> &UnitJob {
        &self.jobs[k].1
    }

    fn key(&self, k: usize) -> String {
        self.jobs[k].1.key()
    }

    fn weight(&self, k: usize) -> u64 {
        self.jobs[k].1.frames(self.cameras)
    }

    fn progress(&self, n: u64) {
        self.progress.advance(n, "");
    }

    fn clear(&self, k: usize) {
        self.jobs[k].1.clear_staging(&self.hello.config.out);
    }

    fn retrying(&self, k: usize, reason: &str, redone: u64) {
        let extra = self.extra.fetch_add(redone, Ordering::SeqCst) + redone;
        self.progress.start(self.total + extra);
        self.progress
            .note(&format!("retrying {}: {reason}", self.key(k)));
    }

    fn note(&self, message: &str) {
        self.progress.note(message);
    }
}
