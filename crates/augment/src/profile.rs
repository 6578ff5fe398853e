//! Where a frame's time goes: the seconds an augment run spends per stage of making its
//! frames (physics, scene update, rasterization, read-back, encoding, render checks),
//! summed over its workers, so that `bench augment` and the dry run can show a machine's bottleneck.
//! Measuring costs a few clock reads per frame; outputs do not depend on it.

use std::time::Instant;

use dexjoco_render::RenderTimes;
use serde::{Deserialize, Serialize};

/// Seconds per stage, summed over the frames (every camera of every replay) of a run or a
/// unit of work. The encoder's CPU time runs in its own processes beside the rest, so the
/// stages overlap in wall time: they say what the machine works on, not a timeline.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct StageTimes {
    /// Frames rendered.
    pub frames: u64,
    /// Stepping the simulation (controller and `mj_step`) while rendering.
    pub physics: f64,
    /// Building the abstract scene from the state, plus the per-replay visual edits.
    pub scene: f64,
    /// Rasterizing (`mjr_render` until `glFinish` returns).
    pub render: f64,
    /// Reading the pixels back (`mjr_readPixels`) and flipping them top-down.
    pub readback: f64,
    /// Handing the frames to the encoders (a full pipe waits for the encoder here).
    pub encode_feed: f64,
    /// CPU seconds of the x264 encoder processes (their own cores).
    pub encode_cpu: f64,
    /// The render checks: every frame's colour share, repeat and depth scan, and the
    /// stored arrays' scan at commit (0 in profiles made before the checks existed).
    #[serde(default)]
    pub checks: f64,
}

impl StageTimes {
    /// The stages, named as tables print them, with their seconds; the render checks
    /// last (`bench augment` prints them after the bottleneck of making a frame).
    pub fn stages(&self) -> [(&'static str, f64); 7] {
        [
            ("physics", self.physics),
            ("scene update", self.scene),
            ("render", self.render),
            ("readback", self.readback),
            ("encode (x264 CPU)", self.encode_cpu),
            ("encoder feed", self.encode_feed),
            ("render checks", self.checks),
        ]
    }

    /// Seconds over all stages.
    pub fn total(&self) -> f64 {
        self.stages().iter().map(|(_, s)| s).sum()
    }

    /// Milliseconds per frame of a stage's seconds.
    pub fn ms_per_frame(&self, seconds: f64) -> f64 {
        1e3 * seconds / self.frames.max(1) as f64
    }

    /// The stage that takes the most time.
    pub fn bottleneck(&self) -> &'static str {
        self.stages()
            .into_iter()
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map_or("-", |(n, _)| n)
    }

    /// Adds `other` to these.
    pub fn add(&mut self, other: &Self) {
        self.frames += other.frames;
        self.physics += other.physics;
        self.scene += other.scene;
        self.render += other.render;
        self.readback += other.readback;
        self.encode_feed += other.encode_feed;
        self.encode_cpu += other.encode_cpu;
        self.checks += other.checks;
    }

    /// Adds a renderer's stages (its scene update counted with the visual edits already
    /// timed by the caller).
    pub(crate) fn add_render(&mut self, r: &RenderTimes) {
        self.frames += r.frames;
        self.scene += r.scene;
        self.render += r.render;
        self.readback += r.readback;
    }

    /// One line: each stage's milliseconds per frame and share, e.g. for the dry run.
    pub fn summary(&self) -> String {
        let total = self.total().max(f64::MIN_POSITIVE);
        self.stages()
            .iter()
            .map(|(n, s)| {
                format!(
                    "{n} {:.2} ms ({:.0} %)",
                    self.ms_per_frame(*s),
                    100.0 * s / total
                )
            })
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// The CPU time of the encoders that finish from now on (they run in child processes of
/// their own; their time is known once they are reaped). Only this process's children
/// count, so within one process it covers every unit that runs meanwhile.
pub(crate) struct EncoderClock(Option<f64>);

impl EncoderClock {
    /// Starts counting.
    pub(crate) fn start() -> Self {
        Self(dexjoco_video::finished_children_cpu_seconds())
    }

    /// CPU seconds of the encoders finished since the start (0 where it cannot be read).
    pub(crate) fn seconds(&self) -> f64 {
        match (self.0, dexjoco_video::finished_children_cpu_seconds()) {
            (Some(before), Some(now)) => now - before,
            _ => 0.0,
        }
    }
}

/// A stopwatch that adds what it measured to a total.
pub(crate) fn timed<T>(total: &mut f64, f: impl FnOnce() -> T) -> T {
    let started = Instant::now();
    let out = f();
    *total += started.elapsed().as_secs_f64();
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shares_add_up_and_the_largest_stage_is_the_bottleneck() {
        let t = StageTimes {
            frames: 10,
            physics: 0.1,
            scene: 0.1,
            render: 0.5,
            readback: 0.1,
            encode_feed: 0.0,
            encode_cpu: 0.2,
            checks: 0.0,
        };
        assert_eq!(t.bottleneck(), "render");
        assert!((t.total() - 1.0).abs() < 1e-12);
        assert!((t.ms_per_frame(t.render) - 50.0).abs() < 1e-9);
        let line = t.summary();
        assert!(line.contains("render 50.00 ms (50 %)"), "{line}");
        let mut sum = t;
        sum.add(&t);
        assert_eq!(sum.frames, 20);
        assert!((sum.render - 1.0).abs() < 1e-12);
    }
}
