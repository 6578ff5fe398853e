//! The worker process's side: read the parent's `hello` and jobs from stdin, tell it how
//! things go on stdout. A worker whose parent has gone (a write fails) exits at once,
//! before anything more is written or renamed into place.

use std::io::{BufRead, Lines, Write};

use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::protocol::{FromWorker, SLOT_ENV, ToWorker, send};

/// Tells the parent `msg`; exits the process when the parent has ended (killed, or gone
/// after a failure), so that a worker never outlives its run.
pub fn tell<D: Serialize>(out: &mut dyn Write, msg: &FromWorker<D>) {
    if send(out, msg).is_err() {
        tracing::debug!("the run that started this worker has ended");
        std::process::exit(1);
    }
}

/// The parent's messages, line by line.
pub struct FromParent<R> {
    lines: Lines<R>,
}

impl<R: BufRead> FromParent<R> {
    /// Reads the parent's messages from `input` (stdin).
    pub fn new(input: R) -> Self {
        Self {
            lines: input.lines(),
        }
    }

    /// The `hello`; `None` when the input ended first.
    pub fn hello<H: DeserializeOwned>(&mut self) -> Result<Option<H>, String> {
        match self.next::<H, serde::de::IgnoredAny>()? {
            None => Ok(None),
            Some(ToWorker::Hello(h)) => Ok(Some(h)),
            Some(ToWorker::Job { .. }) => Err("worker: expected a hello first".into()),
        }
    }

    /// The next job and its attempt; `None` when the parent closed the input (no more).
    pub fn job<J: DeserializeOwned>(&mut self) -> Result<Option<(u32, J)>, String> {
        match self.next::<serde::de::IgnoredAny, J>()? {
            None => Ok(None),
            Some(ToWorker::Job { attempt, job }) => Ok(Some((attempt, job))),
            Some(ToWorker::Hello(_)) => Err("worker: a second hello".into()),
        }
    }

    fn next<H: DeserializeOwned, J: DeserializeOwned>(
        &mut self,
    ) -> Result<Option<ToWorker<H, J>>, String> {
        let Some(line) = self.lines.next() else {
            return Ok(None);
        };
        let line = line.map_err(|e| format!("worker: reading from the parent: {e}"))?;
        serde_json::from_str(&line)
            .map(Some)
            .map_err(|e| format!("worker: unreadable message from the parent: {e}"))
    }
}

/// This worker's slot (as the parent numbered it), when it is a worker process.
pub fn slot() -> Option<usize> {
    std::env::var(SLOT_ENV).ok()?.parse().ok()
}
