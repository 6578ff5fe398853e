//! The augment report: per episode (success, first success, deviation, replays kept),
//! per replay (sample, success, videos, dynamics), the replays the render checks flagged,
//! skipped inputs; written as
//! `augment_report.json` and `augment_report.md`, with a contact sheet of the replays.

use std::collections::BTreeMap;
use std::path::Path;

use dexjoco_render::RenderSettings;

use crate::config::{PREVIEWS, REPORT_JSON, REPORT_MD};
use crate::error::{AugmentError, io_err};
use dexjoco_formats::augment_report::{self, Provenance};
use dexjoco_render::randomize::VisualSample;
use dexjoco_sim::dynamics::DynamicsValue;

pub use dexjoco_formats::augment_report::{EpisodeOutcome, FailedUnit, FlaggedReplay, MadeOn};

/// One replay's record (`replay.json`), with augment's randomization draw and dynamics.
pub type ReplayRecord = augment_report::ReplayRecord<VisualSample, DynamicsValue>;

/// The augment report (`augment_report.json`), with augment's own types in it.
pub type AugmentReport = augment_report::AugmentReport<VisualSample, RenderSettings, DynamicsValue>;

/// What an augment run returns: its report, and what the report files leave out (so a
/// resumed or sharded run writes the same report as one never interrupted).
#[derive(Debug, Clone)]
pub struct AugmentRun {
    /// The report, as written.
    pub report: AugmentReport,
    /// Replays rendered by this run (the rest were already there).
    pub rendered_now: usize,
    /// Where this run's time went, per stage of making its frames (the parent's
    /// validation pass counted as physics).
    pub times: crate::profile::StageTimes,
}

impl std::ops::Deref for AugmentRun {
    type Target = AugmentReport;

    fn deref(&self) -> &AugmentReport {
        &self.report
    }
}

/// The flagged replays among `replays`, in their order.
pub(crate) fn flagged_replays(replays: &[ReplayRecord]) -> Vec<FlaggedReplay> {
    replays
        .iter()
        .filter(|r| !r.flags.is_empty())
        .map(|r| FlaggedReplay {
            task: r.task.clone(),
            replay: r.name.clone(),
            flags: r.flags.clone(),
        })
        .collect()
}

/// Takes each record's provenance out (the report lists each once): the distinct ones
/// with their counts, sorted; replays made before it was recorded count as "not
/// recorded".
pub(crate) fn take_made_on(
    replays: &mut [ReplayRecord],
    dropped: &mut [ReplayRecord],
) -> Vec<MadeOn> {
    let mut counts: BTreeMap<Provenance, usize> = BTreeMap::new();
    for r in replays.iter_mut().chain(dropped.iter_mut()) {
        let p = r.made_on.take().unwrap_or_default();
        *counts.entry(p).or_default() += 1;
    }
    counts
        .into_iter()
        .map(|(provenance, replays)| MadeOn {
            provenance,
            replays,
        })
        .collect()
}

/// The success cell of a replay that has its folder.
fn kept_label(r: &ReplayRecord) -> &'static str {
    if r.success { "yes" } else { "FAILED (kept)" }
}

/// Writes the report as JSON and as Markdown (`augment_report.json`, `.md`).
pub(crate) fn write_report(out: &Path, report: &AugmentReport) -> Result<(), AugmentError> {
    let json = serde_json::to_vec_pretty(report).expect("serializable");
    dexjoco_formats::write_atomic(&out.join(REPORT_JSON), &json)?;
    let mut md = String::new();
    push_settings(&mut md, report);
    push_episodes(&mut md, report);
    push_instructions(&mut md, report);
    push_failed_and_skipped(&mut md, report);
    push_flagged(&mut md, report);
    push_replays(&mut md, report);
    push_dynamics(&mut md, report);
    push_made_on(&mut md, report);
    push_renderers(&mut md, report);
    dexjoco_formats::write_atomic(&out.join(REPORT_MD), md.as_bytes())?;
    Ok(())
}

/// The Markdown report's title and the run's settings.
fn push_settings(md: &mut String, report: &AugmentReport) {
    md.push_str("# Augment report\n\n");
    md.push_str(&format!(
        "Seed {}, {} replays per episode, {}x{}, {} render samples{}.\n\n",
        report.seed,
        report.replays_per_episode,
        report.settings.width,
        report.settings.height,
        report.settings.quality.samples,
        if report.settings.geometry.is_full() {
            ""
        } else {
            ", light geometry (meshes simplified for drawing)"
        },
    ));
}

/// The table of episodes, and a note on those whose success came after the recording.
fn push_episodes(md: &mut String, report: &AugmentReport) {
    md.push_str("| task | episode | replay success | recorded steps | first success | shift | steps | max state deviation | replays kept |\n|---|---|---|---|---|---|---|---|---|\n");
    for e in &report.episodes {
        md.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} | {:e} | {} |\n",
            e.task,
            e.episode,
            if e.success { "yes" } else { "NO" },
            e.recorded_steps,
            e.first_success.map_or("-".into(), |k| k.to_string()),
            e.shift_label(),
            e.steps,
            e.max_state_deviation,
            e.replays_kept
        ));
    }
    let extended = report.episodes.iter().filter(|e| e.extended).count();
    if extended > 0 {
        md.push_str(&format!(
            "\n{extended} episode(s) reached their success only after the recording ended: \
             the last action was repeated (`--extend-steps`) and the extra frames are written \
             like the others.\n"
        ));
    }
}

/// The instructions per task (one table row each; `|` escaped, lines joined).
fn push_instructions(md: &mut String, report: &AugmentReport) {
    md.push_str("\n| task | instruction |\n|---|---|\n");
    for (task, instructions) in &report.instructions {
        for i in instructions {
            let cell = i.replace('|', "\\|").replace('\n', " ");
            md.push_str(&format!("| {task} | {cell} |\n"));
        }
    }
}

/// The units that failed twice and the inputs skipped, when any.
fn push_failed_and_skipped(md: &mut String, report: &AugmentReport) {
    if !report.failed_units.is_empty() {
        md.push_str(&format!(
            "\n**Failed units ({}, tried twice; a later run redoes them):**\n\n",
            report.failed_units.len()
        ));
        for u in &report.failed_units {
            md.push_str(&format!(
                "- `{}/{}` replays {:?}: {}\n",
                u.task, u.episode, u.replays, u.reason
            ));
        }
    }
    if !report.skipped.is_empty() {
        md.push_str(&format!(
            "\n**Skipped inputs ({}):**\n\n",
            report.skipped.len()
        ));
        for k in &report.skipped {
            md.push_str(&format!("- `{}`: {}\n", k.source, k.reason));
        }
    }
}

/// The replays a render check flagged, one row per flag, when any.
fn push_flagged(md: &mut String, report: &AugmentReport) {
    if report.flagged.is_empty() {
        return;
    }
    md.push_str(&format!(
        "\n## Flagged replays\n\n{} replay(s) failed a render check. They are kept on disk with \
         their `flags` in `replay.json`; `convert` leaves them out unless `--include-flagged`.\n\n\
         | replay | check | camera / array | frames | detail |\n|---|---|---|---|---|\n",
        report.flagged.len()
    ));
    for f in &report.flagged {
        for flag in &f.flags {
            let place = flag.camera.as_ref().or(flag.array.as_ref());
            md.push_str(&format!(
                "| {}/{} | {} | {} | {}-{} | {} |\n",
                f.task,
                f.replay,
                flag.check,
                place.map_or("-", String::as_str),
                flag.first_frame,
                flag.last_frame,
                flag.detail.replace('|', "\\|")
            ));
        }
    }
}

/// The table of kept replays and their randomization.
fn push_replays(md: &mut String, report: &AugmentReport) {
    md.push_str("\n| replay | seed | camera (az, el, d) | table | headlight ambient | success |\n|---|---|---|---|---|---|\n");
    for r in &report.replays {
        let c = &r.sample.camera;
        let a = r.sample.headlight_ambient;
        md.push_str(&format!(
            "| {}/{} | {} | #{} ({:.1}, {:.2}, {:.2}) | {} | ({:.2}, {:.2}, {:.2}) | {} |\n",
            r.task,
            r.name,
            r.sample.seed,
            r.sample.camera_index,
            c.azimuth,
            c.elevation,
            c.distance,
            r.sample.table,
            a[0],
            a[1],
            a[2],
            kept_label(r)
        ));
    }
}

/// With `--dynamics`, every replay's draw, kept or dropped.
fn push_dynamics(md: &mut String, report: &AugmentReport) {
    if report
        .replays
        .iter()
        .chain(&report.dropped)
        .any(|r| r.dynamics.is_some())
    {
        md.push_str(&format!(
            "\n## Dynamics (`--dynamics`)\n\n{} replay(s) kept, {} failed under their draw and dropped (rerun with `--keep-failed` to keep them).\n\n",
            report.replays.len(),
            report.dropped.len()
        ));
        md.push_str("| replay | success | max state deviation | drawn values (original -> used) |\n|---|---|---:|---|\n");
        let mut rows: Vec<(&ReplayRecord, &str)> = report
            .replays
            .iter()
            .map(|r| (r, kept_label(r)))
            .chain(report.dropped.iter().map(|r| (r, "FAILED (dropped)")))
            .collect();
        rows.sort_by(|(a, _), (b, _)| (&a.task, &a.name).cmp(&(&b.task, &b.name)));
        for (r, label) in rows {
            let values = r.dynamics.as_deref().unwrap_or_default();
            let cells: Vec<String> = values
                .iter()
                .map(|v| {
                    format!(
                        "{} {}: {:.4} -> {:.4}",
                        v.kind, v.target, v.original, v.value
                    )
                })
                .collect();
            md.push_str(&format!(
                "| {}/{} | {} | {:.3e} | {} |\n",
                r.task,
                r.name,
                label,
                r.max_state_deviation,
                cells.join("; ")
            ));
        }
    }
}

/// A warning when the replays were drawn by more than one renderer or device (a Warp
/// run resumed on another machine with `--warp-device auto`).
fn push_renderers(md: &mut String, report: &AugmentReport) {
    let mut counts: BTreeMap<&str, usize> = BTreeMap::new();
    // Records made before the renderer was recorded, or dropped before rendering, name none.
    for r in report.replays.iter().chain(&report.dropped) {
        if !r.renderer.is_empty() {
            *counts.entry(r.renderer.as_str()).or_default() += 1;
        }
    }
    if counts.len() > 1 {
        let list: Vec<String> = counts.iter().map(|(r, n)| format!("{n} by {r}")).collect();
        let warning = format!(
            "the replays were drawn by {} renderers ({}): their pixels differ in last bits; \
             render a dataset on one device (--warp-device)",
            counts.len(),
            list.join(", ")
        );
        tracing::warn!("{warning}");
        md.push_str(&format!("\n**Warning:** {warning}.\n"));
    }
}

/// Where the replays were made, and a warning when in more than one place.
fn push_made_on(md: &mut String, report: &AugmentReport) {
    if report.made_on.is_empty() {
        return;
    }
    md.push_str("\n## Where the replays were made\n\n| CPU | dexjoco-data | MuJoCo | ffmpeg | x264 | replays |\n|---|---|---|---|---|---:|\n");
    for m in &report.made_on {
        let (p, v) = (&m.provenance, &m.provenance.versions);
        md.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} |\n",
            p.cpu_model, v.dexjoco_data, v.mujoco, v.ffmpeg, v.x264, m.replays
        ));
    }
    if report.made_on.len() > 1 {
        let warning = format!(
            "the replays were made in {} different places (CPU model and flags, or program versions; \
             see augment_report.json's made_on): MuJoCo's floating point depends on the CPU and \
             the bytes on the versions, so this dataset is not what one machine would make",
            report.made_on.len()
        );
        tracing::warn!("{warning}");
        md.push_str(&format!("\n**Warning:** {warning}.\n"));
    }
}

/// A grid of the first frame of every replay's third-person view (`contact_sheet.png`).
pub(crate) fn contact_sheet(out: &Path, report: &AugmentReport) -> Result<(), AugmentError> {
    let dir = out.join(PREVIEWS);
    let mut tiles = Vec::new();
    for r in &report.replays {
        let p = dir.join(format!("{}__{}.png", r.task, r.name));
        if let Ok(img) = image::open(&p) {
            tiles.push(img.to_rgb8());
        }
    }
    let layout = dexjoco_render::SheetLayout {
        columns: report.replays_per_episode.clamp(1, 10) as u32,
        tile: Some(160),
        gap: 0,
        background: [0, 0, 0],
    };
    let Some(sheet) = dexjoco_render::contact_sheet(&tiles, layout) else {
        return Ok(());
    };
    let path = out.join("contact_sheet.png");
    let tmp = out.join(".contact_sheet.tmp.png");
    sheet
        .save_with_format(&tmp, image::ImageFormat::Png)
        .map_err(|e| AugmentError::Input(format!("cannot write '{}': {e}", tmp.display())))?;
    fs_err::rename(&tmp, &path).map_err(io_err("rename", &tmp))?;
    Ok(())
}
