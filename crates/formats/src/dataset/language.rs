//! Subtasks in the datasets. An episode's subtask spans (augment's `replay.json`) become
//! change points: at each frame where the set of running subtasks changes, the text of
//! what runs from then on (the running subtasks' texts joined by " and ": both arms of a
//! bimanual task may run one each).
//!
//! - LeRobot v3.0 (lerobot 0.6's language columns, `lerobot.datasets.language`): a
//!   persistent `subtask` row (role `assistant`) per change point, at its frame's
//!   timestamp, and `task_aug` rows with the instruction; the episode's slice on every
//!   frame of it (`language_persistent`, see [`persistent_column`]); `language_events`
//!   is present and empty. lerobot resolves the row active at a frame (`active_at`): the
//!   latest row at or before the frame's timestamp. Declared in `info.json` as
//!   `{"dtype": "language", "shape": [1], "names": null}`.
//! - LeRobot v2.1 and Diffusion Policy: a per-frame `subtask_index` into the dataset's
//!   list of subtask texts (`meta/subtasks.jsonl`; `meta/.zattrs` `subtasks`).

use std::sync::Arc;

use arrow_array::builder::{ListBuilder, StringBuilder};
use arrow_array::{ArrayRef, Float32Array, ListArray, StringArray, StructArray};
use arrow_buffer::{NullBuffer, OffsetBuffer};
use arrow_schema::{DataType, Field, Fields};
use dexjoco_core::SubtaskSpan;

/// The column of rows that hold from their timestamp on.
pub const LANGUAGE_PERSISTENT: &str = "language_persistent";
/// The column of rows at one instant.
pub const LANGUAGE_EVENTS: &str = "language_events";
/// The per-frame subtask column of LeRobot v2.1 and Diffusion Policy.
pub const SUBTASK_INDEX: &str = "subtask_index";

/// What runs from `frame` on (a frame of the dataset's episode, after any skipped
/// leading frames).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SubtaskRow {
    /// The first frame.
    pub frame: usize,
    /// The running subtasks' texts, joined by " and ".
    pub text: String,
}

/// The change points of an episode of `frames` frames whose first `skipped` frames of
/// the replay were left out: a row at every frame where the set of running subtasks
/// changes (a subtask runs from its start to its end frame, or to the episode's end when
/// it never ended). A frame where none runs keeps the row before it.
pub fn subtask_rows(spans: &[SubtaskSpan], skipped: usize, frames: usize) -> Vec<SubtaskRow> {
    let mut rows: Vec<SubtaskRow> = Vec::new();
    let mut last: Option<Vec<usize>> = None;
    // The running set changes only where a span starts or ends: those frames (and the
    // first) are the only ones looked at, so the work is the spans', not the frames'.
    let mut changes: Vec<usize> = spans
        .iter()
        .flat_map(|s| [s.start, s.end.map(|e| e.saturating_add(1))])
        .flatten()
        .map(|at| at.saturating_sub(skipped))
        .chain([0])
        .filter(|f| *f < frames)
        .collect();
    changes.sort_unstable();
    changes.dedup();
    for f in changes {
        let at = f + skipped;
        let running: Vec<usize> = spans
            .iter()
            .enumerate()
            .filter(|(_, s)| s.start.is_some_and(|st| st <= at) && s.end.is_none_or(|e| at <= e))
            .map(|(i, _)| i)
            .collect();
        if running.is_empty() || last.as_ref() == Some(&running) {
            continue;
        }
        let text = running
            .iter()
            .map(|&i| {
                let s = &spans[i];
                if s.text.is_empty() {
                    s.id.as_str()
                } else {
                    s.text.as_str()
                }
            })
            .collect::<Vec<_>>()
            .join(" and ");
        if rows.last().is_none_or(|r| r.text != text) {
            rows.push(SubtaskRow { frame: f, text });
        }
        last = Some(running);
    }
    rows
}

/// The running subtask's text at each of `frames` frames: the latest row at or before it
/// (`None` before the first).
pub fn frame_texts(rows: &[SubtaskRow], frames: usize) -> Vec<Option<&str>> {
    let mut out = Vec::with_capacity(frames);
    let mut k = 0;
    let mut current = None;
    for f in 0..frames {
        while k < rows.len() && rows[k].frame <= f {
            current = Some(rows[k].text.as_str());
            k += 1;
        }
        out.push(current);
    }
    out
}

/// A frame's timestamp as the data column stores it (float32 of frame / fps).
fn timestamp(frame: usize, fps: u32) -> f32 {
    (frame as f64 / f64::from(fps)) as f32
}

/// The fields of a persistent row (lerobot's `language_persistent_row_arrow_type`, with
/// `tool_calls` as a list of JSON texts).
fn persistent_fields() -> Fields {
    Fields::from(vec![
        Field::new("role", DataType::Utf8, false),
        Field::new("content", DataType::Utf8, true),
        Field::new("style", DataType::Utf8, true),
        Field::new("timestamp", DataType::Float32, false),
        Field::new("camera", DataType::Utf8, true),
        Field::new(
            "tool_calls",
            DataType::List(Arc::new(Field::new("item", DataType::Utf8, true))),
            true,
        ),
    ])
}

/// The fields of an event row (no timestamp).
fn event_fields() -> Fields {
    Fields::from(
        persistent_fields()
            .iter()
            .filter(|f| f.name() != "timestamp")
            .cloned()
            .collect::<Vec<_>>(),
    )
}

/// The rows of an episode's persistent slice, sorted as lerobot's writer sorts them
/// (timestamp, style, role): its `subtask` rows (role `assistant`), and on its first
/// frame a `task_aug` row (role `user`) per prompt variant (`task_aug`, the instruction
/// first), repeated in turn to make `slots` rows in all (lerobot draws the `${task}` of a
/// sample uniformly from the `task_aug` rows: taking turns keeps the draw near uniform).
fn slice_rows<'a>(
    rows: &'a [SubtaskRow],
    task_aug: &'a [String],
    slots: usize,
) -> Vec<SliceRow<'a>> {
    let aug_rows = slots.saturating_sub(rows.len()).max(task_aug.len()).max(1);
    let aug = (0..aug_rows).map(|k| {
        task_aug
            .get(k % task_aug.len().max(1))
            .map_or("", String::as_str)
    });
    let mut out: Vec<SliceRow<'a>> = rows
        .iter()
        .map(|r| SliceRow {
            frame: r.frame,
            style: "subtask",
            role: "assistant",
            content: &r.text,
        })
        .chain(aug.map(|content| SliceRow {
            frame: 0,
            style: "task_aug",
            role: "user",
            content,
        }))
        .collect();
    // Stable: the variants keep their order.
    out.sort_by(|a, b| (a.frame, a.style, a.role).cmp(&(b.frame, b.style, b.role)));
    out
}

/// One row of a persistent slice.
struct SliceRow<'a> {
    frame: usize,
    style: &'static str,
    role: &'static str,
    content: &'a str,
}

/// The `language_persistent` column of an episode of `frames` frames: its whole slice
/// ([`slice_rows`]) on every frame, as lerobot's writer lays it out (lerobot resolves the
/// row active at a frame, `active_at`; Rerun's importer shows the first frame's slice).
///
/// `slots` is the dataset's slice length: every episode's slice has the same number of
/// rows (filled with `task_aug` rows of its instruction), because lerobot-doctor 0.2's
/// consistency check fails a dataset whose episodes' slices differ in length.
pub fn persistent_column(
    rows: &[SubtaskRow],
    task_aug: &[String],
    slots: usize,
    fps: u32,
    frames: usize,
) -> ArrayRef {
    let slice = slice_rows(rows, task_aug, slots);
    let repeat = |f: fn(&SliceRow<'_>) -> String| -> ArrayRef {
        Arc::new(StringArray::from_iter_values(
            (0..frames).flat_map(|_| slice.iter().map(f)),
        ))
    };
    let n = slice.len() * frames;
    let mut calls = ListBuilder::new(StringBuilder::new());
    for _ in 0..n {
        calls.append(false);
    }
    let structs = StructArray::new(
        persistent_fields(),
        vec![
            repeat(|r| r.role.to_owned()),
            repeat(|r| r.content.to_owned()),
            repeat(|r| r.style.to_owned()),
            Arc::new(Float32Array::from_iter_values(
                (0..frames).flat_map(|_| slice.iter().map(|r| timestamp(r.frame, fps))),
            )),
            arrow_array::new_null_array(&DataType::Utf8, n),
            Arc::new(calls.finish()),
        ],
        None,
    );
    list_of(structs, slice.len(), frames)
}

/// The slice length that fits every episode: the most subtask rows any of them has, plus
/// the most `task_aug` rows any gets (at least one, the instruction).
pub fn slots_for(rows_per_episode: impl IntoIterator<Item = usize>, most_task_aug: usize) -> usize {
    rows_per_episode.into_iter().max().unwrap_or(0) + most_task_aug.max(1)
}

/// The `language_events` column of an episode of `frames` frames: an empty list on each.
pub fn events_column(frames: usize) -> ArrayRef {
    let fields = event_fields();
    let columns = fields
        .iter()
        .map(|f| arrow_array::new_empty_array(f.data_type()))
        .collect();
    list_of(StructArray::new(fields, columns, None), 0, frames)
}

/// A list column of `frames` lists of `per` consecutive items each.
fn list_of(items: StructArray, per: usize, frames: usize) -> ArrayRef {
    let field = Arc::new(Field::new(
        "item",
        DataType::Struct(items.fields().clone()),
        true,
    ));
    let offsets = OffsetBuffer::from_lengths(std::iter::repeat_n(per, frames));
    Arc::new(ListArray::new(
        field,
        offsets,
        Arc::new(items),
        None::<NullBuffer>,
    ))
}

/// The dataset-wide list of subtask texts, in the order they first appear: what
/// `subtask_index` indexes.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SubtaskTexts(Vec<String>);

impl SubtaskTexts {
    /// The index of each of `frames` frames (-1 before the episode's first row),
    /// adding new texts to the list.
    pub fn frame_indices(&mut self, rows: &[SubtaskRow], frames: usize) -> Vec<i64> {
        frame_texts(rows, frames)
            .into_iter()
            .map(|t| t.map_or(-1, |t| self.index_of(t) as i64))
            .collect()
    }

    fn index_of(&mut self, text: &str) -> usize {
        match self.0.iter().position(|t| t == text) {
            Some(i) => i,
            None => {
                self.0.push(text.to_owned());
                self.0.len() - 1
            }
        }
    }

    /// The texts, by index.
    pub fn list(&self) -> &[String] {
        &self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use arrow_array::Array;

    fn span(text: &str, start: Option<usize>, end: Option<usize>) -> SubtaskSpan {
        SubtaskSpan {
            id: text.replace(' ', "_"),
            text: text.into(),
            start,
            end,
        }
    }

    #[test]
    fn rows_change_where_the_running_subtasks_change() {
        // One arm: grasp 0-9, strike 10-14, drive 15-16 (the episode has 20 frames).
        let one = [
            span("grasp", Some(0), Some(9)),
            span("strike", Some(10), Some(14)),
            span("drive", Some(15), Some(16)),
        ];
        let rows = subtask_rows(&one, 0, 20);
        let frames: Vec<usize> = rows.iter().map(|r| r.frame).collect();
        assert_eq!(frames, [0, 10, 15]);
        let texts = frame_texts(&rows, 20);
        assert_eq!(texts[9], Some("grasp"));
        assert_eq!(texts[10], Some("strike"));
        assert_eq!(texts[19], Some("drive"), "the last row holds to the end");
        // 5 leading frames skipped: the rows move 5 frames earlier.
        let rows = subtask_rows(&one, 5, 15);
        assert_eq!(
            rows[0],
            SubtaskRow {
                frame: 0,
                text: "grasp".into()
            }
        );
        assert_eq!(rows[1].frame, 5);
        // Two arms in parallel, then together; one never ends.
        let two = [
            span("open the door", Some(0), Some(4)),
            span("pick the food", Some(0), Some(7)),
            span("place it", Some(8), None),
        ];
        let rows = subtask_rows(&two, 0, 12);
        let texts: Vec<&str> = rows.iter().map(|r| r.text.as_str()).collect();
        assert_eq!(
            texts,
            [
                "open the door and pick the food",
                "pick the food",
                "place it"
            ]
        );
        assert_eq!(rows[2].frame, 8);
        let mut list = SubtaskTexts::default();
        let idx = list.frame_indices(&rows, 12);
        assert_eq!(idx[0], 0);
        assert_eq!(idx[5], 1);
        assert_eq!(idx[11], 2);
    }

    #[test]
    fn the_columns_repeat_the_rows_on_every_frame() {
        let rows = vec![
            SubtaskRow {
                frame: 0,
                text: "a".into(),
            },
            SubtaskRow {
                frame: 3,
                text: "b".into(),
            },
        ];
        let aug = ["the task".to_owned(), "do it".to_owned()];
        let col = persistent_column(&rows, &aug, 5, 30, 5);
        let list = col.as_any().downcast_ref::<ListArray>().unwrap();
        assert_eq!(list.len(), 5);
        assert_eq!(
            list.value_length(4),
            5,
            "2 subtask rows and 3 task_aug rows"
        );
        let slice = |f: usize| -> Vec<(String, String, f32)> {
            let v = list.value(f);
            let s = v.as_any().downcast_ref::<StructArray>().unwrap();
            let text = |c: usize, i: usize| {
                s.column(c)
                    .as_any()
                    .downcast_ref::<StringArray>()
                    .unwrap()
                    .value(i)
                    .to_owned()
            };
            let ts = s.column(3).as_any().downcast_ref::<Float32Array>().unwrap();
            (0..s.len())
                .map(|i| (text(1, i), text(2, i), ts.value(i)))
                .collect()
        };
        assert_eq!(slice(0), slice(4), "the same slice on every frame");
        let t = |f: usize| (f as f64 / 30.0) as f32;
        assert_eq!(
            slice(0),
            [
                ("a".to_owned(), "subtask".to_owned(), t(0)),
                ("the task".to_owned(), "task_aug".to_owned(), t(0)),
                ("do it".to_owned(), "task_aug".to_owned(), t(0)),
                ("the task".to_owned(), "task_aug".to_owned(), t(0)),
                ("b".to_owned(), "subtask".to_owned(), t(3)),
            ]
        );
        assert_eq!(slots_for([2, 0, 3], 3), 6);
        let events = events_column(5);
        let list = events.as_any().downcast_ref::<ListArray>().unwrap();
        assert_eq!((list.len(), list.value_length(0)), (5, 0));
    }
}
