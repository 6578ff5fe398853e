//! Units on this process's rayon threads, side by side, each retried once; a full disk
//! stops the run (no unit starts after it).

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

use dexjoco_core::Progress;
use rayon::prelude::*;

use super::executor::UnitResult;
use crate::assets::TaskAssets;
use crate::config::AugmentConfig;
use crate::error::AugmentError;
use crate::inputs::Source;
use crate::profile::{EncoderClock, StageTimes};
use crate::render::{UnitInputs, UnitJob, close_renderer, render_unit};
use crate::staging::Outcome;

/// What the parent holds to run units itself.
pub(crate) struct LocalInputs<'a> {
    pub(crate) sources: &'a [Source],
    pub(crate) assets: &'a BTreeMap<String, Arc<TaskAssets>>,
}

/// Runs every job on this process's threads (index-aligned results), retrying a failed
/// one once; also returns where the rendering's time went, summed over the units. Fails
/// at the first full disk.
pub(super) fn run_on_threads(
    jobs: &[(usize, UnitJob)],
    local: &LocalInputs<'_>,
    config: &AugmentConfig,
    total: u64,
    progress: &dyn Progress,
) -> Result<(Vec<UnitResult>, StageTimes), AugmentError> {
    let extra = std::sync::atomic::AtomicU64::new(0);
    let stopped = AtomicBool::new(false);
    let full_disk = OnceLock::new();
    // Units run side by side in this process: each unit's share of the finished encoders'
    // CPU time cannot be told apart, so it is taken once, for all of them.
    let encoders = EncoderClock::start();
    let attempts: Vec<Result<(Vec<Outcome>, StageTimes), String>> = jobs
        .par_iter()
        .map(|(i, job)| {
            let src = &local.sources[*i];
            let inputs = UnitInputs {
                src,
                assets: &local.assets[&src.spec.id],
                config,
                out: &config.out,
            };
            let mut first = None;
            for attempt in 0..2 {
                if stopped.load(Ordering::SeqCst) {
                    return Err("the run stopped".into());
                }
                let mut job = job.clone();
                job.attempt = attempt;
                let mut done = 0;
                let r = render_unit(&job, &inputs, &mut |n| {
                    done += n;
                    progress.advance(n, "");
                    Ok(())
                });
                match r {
                    Ok(done) => return Ok(done),
                    Err(e) => {
                        tracing::warn!(unit = %job.key(), "unit failed (attempt {}): {e}", attempt + 1);
                        job.clear_staging(&config.out);
                        if dexjoco_formats::fs::out_of_space(&e) {
                            stopped.store(true, Ordering::SeqCst);
                            let _ = full_disk.set(e.to_string());
                            return Err(e.to_string());
                        }
                        // The retry renders these frames again.
                        let more =
                            extra.fetch_add(done, std::sync::atomic::Ordering::SeqCst) + done;
                        progress.start(total + more);
                        progress.note(&format!("retrying {}: {e}", job.key()));
                        first = Some(e.to_string());
                    }
                }
            }
            Err(first.unwrap_or_default())
        })
        .collect();
    // Close every worker thread's renderer (and its EGL context) now, rather than at
    // process exit while other threads are still alive.
    rayon::broadcast(|_| close_renderer());
    if let Some(message) = full_disk.into_inner() {
        return Err(AugmentError::OutOfSpace {
            message,
            free: None,
            needed: None,
        });
    }
    let mut times = StageTimes::default();
    let results = attempts
        .into_iter()
        .map(|a| {
            a.map(|(outcomes, t)| {
                times.add(&t);
                outcomes
            })
        })
        .collect();
    times.encode_cpu = encoders.seconds();
    Ok((results, times))
}
