//! Subtasks in the datasets. An episode's subtask spans (augment's `replay.json`) become
//! change points: at each frame where the set of running subtasks changes, the text of
//! what runs from then on (the running subtasks' texts joined by " and ": both arms of a
//! bimanual task may run one each).
//!
//! - LeRobot v3.0 (lerobot 0.6's language columns, `lerobot.datasets.language`): a
//!   persistent `subtask` row (role `assistant`) per change point, at its frame's
//!   timestamp, each frame holding the row running there (`language_persistent`; see
//!   [`persistent_column`]); `language_events` is present and empty. lerobot resolves the
//!   row active at a frame (`active_at`): the latest row at or before the frame's
//!   timestamp. Declared in `info.json` as `{"dtype": "language", "shape": [1], "names":
//!   null}`.
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
    for f in 0..frames {
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

/// The `language_persistent` column of an episode of `frames` frames: on each frame,
/// one row: the `subtask` row (role `assistant`) running there, with the timestamp of
/// the frame it began on; where none runs yet (or the episode has no subtasks), a
/// `task_aug` row (role `user`) with the episode's instruction at timestamp 0.
///
/// One row per frame rather than the episode's whole slice on every frame: lerobot's
/// resolver (`active_at`) finds the same row either way, and every frame of every
/// episode then has the same shape, which lerobot-doctor 0.2's consistency check
/// requires (it fails a dataset whose episodes hold slices of different lengths).
pub fn persistent_column(
    rows: &[SubtaskRow],
    instruction: &str,
    fps: u32,
    frames: usize,
) -> ArrayRef {
    let running: Vec<Option<&SubtaskRow>> = {
        let mut k = 0;
        let mut current = None;
        (0..frames)
            .map(|f| {
                while k < rows.len() && rows[k].frame <= f {
                    current = Some(&rows[k]);
                    k += 1;
                }
                current
            })
            .collect()
    };
    let column = |f: &dyn Fn(Option<&SubtaskRow>) -> String| -> ArrayRef {
        Arc::new(StringArray::from_iter_values(running.iter().map(|r| f(*r))))
    };
    let mut calls = ListBuilder::new(StringBuilder::new());
    for _ in 0..frames {
        calls.append(false);
    }
    let structs = StructArray::new(
        persistent_fields(),
        vec![
            column(&|r| if r.is_some() { "assistant" } else { "user" }.to_owned()),
            column(&|r| r.map_or_else(|| instruction.to_owned(), |r| r.text.clone())),
            column(&|r| if r.is_some() { "subtask" } else { "task_aug" }.to_owned()),
            Arc::new(Float32Array::from_iter_values(
                running
                    .iter()
                    .map(|r| r.map_or(0.0, |r| timestamp(r.frame, fps))),
            )),
            arrow_array::new_null_array(&DataType::Utf8, frames),
            Arc::new(calls.finish()),
        ],
        None,
    );
    list_of(structs, 1, frames)
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
        let col = persistent_column(&rows, "the task", 30, 5);
        let list = col.as_any().downcast_ref::<ListArray>().unwrap();
        assert_eq!(list.len(), 5);
        assert_eq!(list.value_length(4), 1);
        let row = |f: usize| {
            let v = list.value(f);
            let s = v.as_any().downcast_ref::<StructArray>().unwrap();
            let text = |c: usize| {
                s.column(c)
                    .as_any()
                    .downcast_ref::<StringArray>()
                    .unwrap()
                    .value(0)
                    .to_owned()
            };
            let ts = s
                .column(3)
                .as_any()
                .downcast_ref::<Float32Array>()
                .unwrap()
                .value(0);
            (text(1), text(2), ts)
        };
        assert_eq!(row(2), ("a".to_owned(), "subtask".to_owned(), 0.0));
        assert_eq!(row(4), ("b".to_owned(), "subtask".to_owned(), 0.1));
        let none = persistent_column(&[], "the task", 30, 2);
        let list = none.as_any().downcast_ref::<ListArray>().unwrap();
        assert_eq!(list.value_length(1), 1, "the instruction's task_aug row");
        let events = events_column(5);
        let list = events.as_any().downcast_ref::<ListArray>().unwrap();
        assert_eq!((list.len(), list.value_length(0)), (5, 0));
    }
}
