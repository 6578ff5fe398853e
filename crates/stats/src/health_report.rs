//! The health section in words: its warnings (one line each, naming what and what to
//! do) and its Markdown tables.

use std::collections::BTreeSet;
use std::fmt::Write as _;

use crate::health::{ALL_TASKS, FlatDimension, Flatness, Health, NEAR_CONSTANT_REL, Outcomes};

fn pct(a: usize, b: usize) -> String {
    if b == 0 {
        format!("{a}")
    } else {
        format!("{a} ({:.0} %)", 100.0 * a as f64 / b as f64)
    }
}

/// Flat dimensions grouped by scope, array and flatness (constant first), in order of
/// first appearance of scope and array.
fn flat_groups(h: &Health) -> Vec<Vec<&FlatDimension>> {
    let mut out: Vec<Vec<&FlatDimension>> = Vec::new();
    for d in &h.flat_dimensions {
        let same = |g: &&mut Vec<&FlatDimension>| {
            (&g[0].scope, &g[0].array, g[0].flatness) == (&d.scope, &d.array, d.flatness)
        };
        match out.iter_mut().find(|g| same(g)) {
            Some(g) => g.push(d),
            None => out.push(vec![d]),
        }
    }
    // Constant before near-constant within a scope and array (a stable sort).
    let first_seen = |g: &Vec<&FlatDimension>| {
        h.flat_dimensions
            .iter()
            .position(|o| o.scope == g[0].scope && o.array == g[0].array)
    };
    out.sort_by_key(|g| (first_seen(g), g[0].flatness));
    out
}

/// Columns named in a warning line before "+N more" (the full list is in the tables).
const NAMED_COLUMNS: usize = 4;

/// One warning per scope (a task, or all tasks for columns not already flat in every
/// task): how many columns of which arrays are constant or near-constant, the first few
/// by name, the largest gain normalization gives a deviation, what to do.
fn flat_warnings(h: &Health, out: &mut Vec<String>) {
    let tasks: BTreeSet<&str> = h.lengths.iter().map(|l| l.task.as_str()).collect();
    let flat_everywhere = |d: &FlatDimension| {
        let flat_in: BTreeSet<&str> = h
            .flat_dimensions
            .iter()
            .filter(|o| o.scope != ALL_TASKS && o.array == d.array && o.index == d.index)
            .map(|o| o.scope.as_str())
            .collect();
        flat_in == tasks
    };
    let mut scopes: Vec<&str> = Vec::new();
    for d in &h.flat_dimensions {
        if !scopes.contains(&d.scope.as_str()) {
            scopes.push(&d.scope);
        }
    }
    for scope in scopes {
        let dims: Vec<&FlatDimension> = h
            .flat_dimensions
            .iter()
            .filter(|d| d.scope == scope && (scope != ALL_TASKS || !flat_everywhere(d)))
            .collect();
        if let Some(line) = flat_line(scope, &dims) {
            out.push(line);
        }
    }
}

/// The warning line of one scope's flat columns.
fn flat_line(scope: &str, dims: &[&FlatDimension]) -> Option<String> {
    dims.first()?;
    let count = |f: Flatness| dims.iter().filter(|d| d.flatness == f).count();
    let mut arrays: Vec<&str> = Vec::new();
    for d in dims {
        if !arrays.contains(&d.array.as_str()) {
            arrays.push(&d.array);
        }
    }
    let per_array: Vec<String> = arrays
        .iter()
        .map(|a| {
            let cols: Vec<&FlatDimension> =
                dims.iter().copied().filter(|d| d.array == *a).collect();
            let named: Vec<String> = cols
                .iter()
                .take(NAMED_COLUMNS)
                .map(|d| format!("'{}'", d.column))
                .collect();
            let more = cols.len().saturating_sub(NAMED_COLUMNS);
            let more = if more > 0 {
                format!(" +{more} more")
            } else {
                String::new()
            };
            format!("{a} {}{more}", named.join(", "))
        })
        .collect();
    let gain = |f: fn(&FlatDimension) -> f64| dims.iter().map(|d| f(d)).fold(0.0, f64::max);
    let scope = if scope == ALL_TASKS {
        "all tasks".to_owned()
    } else {
        format!("task {scope}")
    };
    Some(format!(
        "{scope}: {} constant and {} near-constant column(s) (std <= {NEAR_CONSTANT_REL:e} x \
         max(1, |mean|)): {}; normalized they train as a constant and a deviation d at \
         inference becomes up to d x {:.1e} (lerobot), {:.1e} (openpi z-score): drop them or \
         give them fixed statistics (all listed in summary.md, Health)",
        count(Flatness::Constant),
        count(Flatness::NearConstant),
        per_array.join("; "),
        gain(|d| d.lerobot_gain),
        gain(|d| d.openpi_gain),
    ))
}

fn outcome_warnings(o: &Outcomes, out: &mut Vec<String>) {
    let failed = o.replays - o.succeeded;
    if failed > 0 {
        out.push(format!(
            "task {}: {failed} of {} replays failed their task: convert leaves them out unless \
             --include-failed (then each carries its outcome)",
            o.task, o.replays
        ));
    }
    if o.checked < o.replays {
        out.push(format!(
            "task {}: {} of {} replay records predate the render checks (no 'flags'): replay \
             them again with augment to check their frames",
            o.task,
            o.replays - o.checked,
            o.replays
        ));
    }
    for (id, flags) in &o.flagged_episodes {
        out.push(format!(
            "task {} episode '{id}' is flagged: {}; convert leaves flagged replays out by \
             default",
            o.task,
            flags.join("; ")
        ));
    }
}

/// Every warning of a health section, in section order.
pub fn warnings(h: &Health) -> Vec<String> {
    let mut out = Vec::new();
    flat_warnings(h, &mut out);
    for s in &h.static_leading {
        for id in &s.never_moving {
            out.push(format!(
                "task {} episode '{id}': its action never changes: leave it out \
                 (convert --exclude {id})",
                s.task
            ));
        }
        for e in s.with_static.iter().filter(|e| 2 * e.frames >= e.length) {
            out.push(format!(
                "task {} episode '{}': {} of its {} frames are static leading frames (convert \
                 skips them); check the recording, or leave it out (convert --exclude {})",
                s.task, e.episode, e.frames, e.length, e.episode
            ));
        }
    }
    for l in &h.lengths {
        for e in &l.outliers {
            out.push(format!(
                "task {} episode '{}': {} frames against a median of {}: check it (cut short or \
                 stuck?), or leave it out (convert --exclude {})",
                l.task, e.episode, e.frames, l.median, e.episode
            ));
        }
    }
    let name = |g: &crate::health::DuplicateGroup| {
        g.episodes
            .iter()
            .map(|(t, e)| format!("{t}/{e}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    for g in &h.duplicates.full {
        out.push(format!(
            "episodes {} are duplicates (same arrays and videos): keep one (convert --exclude \
             the others)",
            name(g)
        ));
    }
    for g in h.duplicates.same_arrays.iter().filter(|g| !g.replays) {
        out.push(format!(
            "episodes {} have the same arrays (different videos) and are not replays of one \
             source: keep one (convert --exclude the others)",
            name(g)
        ));
    }
    for o in &h.outcomes {
        outcome_warnings(o, &mut out);
    }
    out
}

impl Health {
    /// The Markdown section (`### Health` and its tables, then the warnings).
    pub fn to_markdown(&self) -> String {
        let mut s = String::from("### Health\n\n");
        self.markdown_flat(&mut s);
        self.markdown_static(&mut s);
        self.markdown_lengths(&mut s);
        self.markdown_duplicates(&mut s);
        self.markdown_outcomes(&mut s);
        if self.warnings.is_empty() {
            s.push_str("No warnings.\n");
            return s;
        }
        // The flat-dimension warnings come first and repeat the first table's rows.
        let mut flat = Vec::new();
        flat_warnings(self, &mut flat);
        let _ = writeln!(
            s,
            "Warnings: {} ({} on the flat dimensions above{})\n",
            self.warnings.len(),
            flat.len(),
            if self.warnings.len() > flat.len() {
                "; the others:"
            } else {
                ""
            }
        );
        for w in &self.warnings[flat.len()..] {
            let _ = writeln!(s, "- {w}");
        }
        s
    }

    fn markdown_flat(&self, s: &mut String) {
        let _ = writeln!(
            s,
            "Constant (std 0) and near-constant (std <= {NEAR_CONSTANT_REL:e} x max(1, |mean|)) \
             dimensions, per task (`{ALL_TASKS}`: the whole dataset). Normalized they train as 0; \
             a deviation d at inference becomes d x gain: lerobot 1/(std + 1e-8), openpi \
             1/(std + 1e-6), openpi quantiles 2/(q99 - q01 + 1e-6).\n"
        );
        if self.flat_dimensions.is_empty() {
            s.push_str("None.\n\n");
            return;
        }
        s.push_str(
            "| Scope | Array | Kind | Columns (index `name`, std when near-constant) | Largest openpi gain |\n\
             |---|---|---|---|---:|\n",
        );
        for g in flat_groups(self) {
            let first = g[0];
            let (kind, columns): (&str, Vec<String>) = match first.flatness {
                Flatness::Constant => (
                    "constant",
                    g.iter()
                        .map(|d| format!("{} `{}`", d.index, d.column))
                        .collect(),
                ),
                Flatness::NearConstant => (
                    "near-constant",
                    g.iter()
                        .map(|d| format!("{} `{}` ({:.1e})", d.index, d.column, d.std))
                        .collect(),
                ),
            };
            let gain = g.iter().map(|d| d.openpi_gain).fold(0.0, f64::max);
            let _ = writeln!(
                s,
                "| {} | {} | {kind} | {} | {gain:.1e} |",
                first.scope,
                first.array,
                columns.join(", ")
            );
        }
        s.push('\n');
    }

    fn markdown_static(&self, s: &mut String) {
        s.push_str(
            "Static leading frames (the reference converter's rule on `action`; convert skips them):\n\n\
             | Task | Episodes | With static frames | Static frames | Most in one episode | Never moving |\n\
             |---|---:|---:|---:|---:|---:|\n",
        );
        for t in &self.static_leading {
            let most = t.with_static.iter().map(|e| e.frames).max().unwrap_or(0);
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {most} | {} |",
                t.task,
                t.episodes,
                t.with_static.len(),
                t.frames,
                t.never_moving.len()
            );
        }
        s.push('\n');
    }

    fn markdown_lengths(&self, s: &mut String) {
        s.push_str(
            "Episode lengths (frames; outliers: under half or over twice the median):\n\n\
             | Task | Episodes | Min | p10 | Median | p90 | Max | Outliers |\n\
             |---|---:|---:|---:|---:|---:|---:|---|\n",
        );
        for l in &self.lengths {
            let outliers: Vec<String> = l
                .outliers
                .iter()
                .map(|e| format!("{} ({})", e.episode, e.frames))
                .collect();
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:.1} | {:.1} | {:.1} | {} | {} |",
                l.task,
                l.count,
                l.min,
                l.p10,
                l.median,
                l.p90,
                l.max,
                outliers.join(", ")
            );
        }
        s.push('\n');
    }

    fn markdown_duplicates(&self, s: &mut String) {
        s.push_str("Duplicated episodes (same arrays and videos; same arrays only):\n\n");
        let d = &self.duplicates;
        if d.full.is_empty() && d.same_arrays.is_empty() {
            s.push_str("None.\n\n");
            return;
        }
        for (kind, groups) in [
            ("same arrays and videos", &d.full),
            ("same arrays", &d.same_arrays),
        ] {
            for g in groups {
                let members: Vec<String> =
                    g.episodes.iter().map(|(t, e)| format!("{t}/{e}")).collect();
                let replays = if g.replays { " (replays)" } else { "" };
                let _ = writeln!(s, "- {kind}{replays}: {}", members.join(", "));
            }
        }
        s.push('\n');
    }

    fn markdown_outcomes(&self, s: &mut String) {
        s.push_str(
            "Replay outcomes and render-check flags (from each episode's replay.json; episodes \
             without one are recordings):\n\n\
             | Task | Recordings | Replays | Succeeded | Checked | Flagged | blank_frame | frozen_video | non_finite |\n\
             |---|---:|---:|---:|---:|---:|---:|---:|---:|\n",
        );
        for o in &self.outcomes {
            let check = |c: &str| pct(o.per_check.get(c).copied().unwrap_or(0), o.checked);
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                o.task,
                o.recordings,
                o.replays,
                pct(o.succeeded, o.replays),
                o.checked,
                pct(o.flagged, o.checked),
                check("blank_frame"),
                check("frozen_video"),
                check("non_finite")
            );
        }
        s.push('\n');
    }
}
