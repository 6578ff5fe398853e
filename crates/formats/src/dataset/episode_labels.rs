//! The per-episode labels of a converted dataset: each replay's outcome (augment's
//! `replay.json`: success, first success, extension, render flags) and randomization draw
//! (camera pose, table look, lights, dynamics) as named columns, one value per episode,
//! null for an episode without a replay record (a recording).
//!
//! LeRobot v3.0 writes them as columns of `meta/episodes/` (lerobot 0.6.1's
//! `load_episodes` keeps every column not under `stats/`); Diffusion Policy's store as
//! per-episode arrays under `meta/` and the whole records in `meta/.zattrs`.

use std::path::Path;
use std::sync::Arc;

use arrow_array::builder::{BooleanBuilder, Float64Builder, ListBuilder, StringBuilder};
use arrow_array::{ArrayRef, Float64Array, Int64Array, StringArray, UInt64Array};
use serde_json::{Value, json};

use super::write_json;
use crate::error::DatasetError;
use crate::raw::ReplayLabel;

/// One label column's values by episode (`None`: the episode has no value).
#[derive(Debug, Clone, PartialEq)]
pub enum LabelValues {
    /// Booleans.
    Bool(Vec<Option<bool>>),
    /// Signed integers.
    Int(Vec<Option<i64>>),
    /// Unsigned integers (the seed).
    UInt(Vec<Option<u64>>),
    /// Floats.
    Float(Vec<Option<f64>>),
    /// Texts (names, JSON documents).
    Text(Vec<Option<String>>),
    /// Lists of texts.
    TextList(Vec<Option<Vec<String>>>),
    /// Lists of floats (RGB triples).
    FloatList(Vec<Option<Vec<f64>>>),
}

/// The label columns of a dataset whose episodes have these replay records, in the
/// order they are written; empty when no episode has one (the dataset then carries no
/// labels and stays as it was before labels existed).
pub fn label_columns(labels: &[Option<&ReplayLabel>]) -> Vec<(String, LabelValues)> {
    if labels.iter().all(Option::is_none) {
        return Vec::new();
    }
    let sample = |l: &ReplayLabel, k: &str| l.sample.get(k).cloned();
    let camera = |l: &ReplayLabel, k: &str| l.sample.get("camera").and_then(|c| c.get(k)?.as_f64());
    let floats = |v: Option<Value>| -> Option<Vec<f64>> {
        v?.as_array()?.iter().map(Value::as_f64).collect()
    };
    let int = |v: usize| Some(v as i64);
    use LabelValues as L;
    let c = |name: &str, v: LabelValues| (name.to_owned(), v);
    vec![
        c("outcome/success", L::Bool(per(labels, |l| Some(l.success)))),
        c(
            "outcome/first_success",
            L::Int(per(labels, |l| l.first_success.and_then(int))),
        ),
        c(
            "outcome/extended",
            L::Bool(per(labels, |l| Some(l.extended))),
        ),
        c("outcome/steps", L::Int(per(labels, |l| int(l.steps)))),
        c(
            "outcome/recorded_steps",
            L::Int(per(labels, |l| int(l.recorded_steps))),
        ),
        c("outcome/checked", L::Bool(per(labels, |l| Some(l.checked)))),
        c(
            "outcome/flagged",
            L::Bool(per(labels, |l| Some(l.flagged()))),
        ),
        c(
            "outcome/flags",
            L::TextList(per(labels, |l| Some(flag_names(l)))),
        ),
        c(
            "outcome/flag_details",
            L::TextList(per(labels, |l| {
                Some(l.flags.iter().map(|f| f.describe()).collect())
            })),
        ),
        c(
            "outcome/subtasks_done",
            L::Int(per(labels, |l| {
                (!l.subtasks.is_empty()).then(|| l.subtasks_done() as i64)
            })),
        ),
        c(
            "randomization/seed",
            L::UInt(per(labels, |l| sample(l, "seed")?.as_u64())),
        ),
        c(
            "randomization/camera_index",
            L::Int(per(labels, |l| sample(l, "camera_index")?.as_i64())),
        ),
        c(
            "randomization/camera_azimuth",
            L::Float(per(labels, |l| camera(l, "azimuth"))),
        ),
        c(
            "randomization/camera_elevation",
            L::Float(per(labels, |l| camera(l, "elevation"))),
        ),
        c(
            "randomization/camera_distance",
            L::Float(per(labels, |l| camera(l, "distance"))),
        ),
        c(
            "randomization/table_index",
            L::Int(per(labels, |l| sample(l, "table_index")?.as_i64())),
        ),
        c(
            "randomization/table",
            L::Text(per(labels, |l| {
                Some(sample(l, "table")?.as_str()?.to_owned())
            })),
        ),
        c(
            "randomization/headlight_ambient",
            L::FloatList(per(labels, |l| floats(sample(l, "headlight_ambient")))),
        ),
        c(
            "randomization/headlight_diffuse",
            L::FloatList(per(labels, |l| floats(sample(l, "headlight_diffuse")))),
        ),
        c(
            "randomization/lights",
            L::Text(per(labels, |l| Some(sample(l, "lights")?.to_string()))),
        ),
        c(
            "randomization/dynamics",
            L::Text(per(labels, |l| Some(l.dynamics.as_ref()?.to_string()))),
        ),
    ]
}

/// One value per episode: `f` of its label, `None` without one.
fn per<T>(
    labels: &[Option<&ReplayLabel>],
    f: impl Fn(&ReplayLabel) -> Option<T>,
) -> Vec<Option<T>> {
    labels.iter().map(|l| l.and_then(&f)).collect()
}

/// The names of the checks a replay failed, each once, in check order.
fn flag_names(l: &ReplayLabel) -> Vec<String> {
    let mut checks: Vec<_> = l.flags.iter().map(|f| f.check).collect();
    checks.sort();
    checks.dedup();
    checks.iter().map(|c| c.name().to_owned()).collect()
}

impl LabelValues {
    /// The values as an arrow column (nulls where `None`).
    pub fn to_arrow(&self) -> ArrayRef {
        match self {
            Self::Bool(v) => {
                let mut b = BooleanBuilder::new();
                v.iter().for_each(|x| b.append_option(*x));
                Arc::new(b.finish())
            }
            Self::Int(v) => Arc::new(Int64Array::from(v.clone())),
            Self::UInt(v) => Arc::new(UInt64Array::from(v.clone())),
            Self::Float(v) => Arc::new(Float64Array::from(v.clone())),
            Self::Text(v) => Arc::new(StringArray::from(v.clone())),
            Self::TextList(v) => {
                let mut b = ListBuilder::new(StringBuilder::new());
                for x in v {
                    for s in x.iter().flatten() {
                        b.values().append_value(s);
                    }
                    b.append(x.is_some());
                }
                Arc::new(b.finish())
            }
            Self::FloatList(v) => {
                let mut b = ListBuilder::new(Float64Builder::new());
                for x in v {
                    if let Some(x) = x {
                        b.values().append_slice(x);
                    }
                    b.append(x.is_some());
                }
                Arc::new(b.finish())
            }
        }
    }

    /// Episode `i`'s value as JSON (null where `None`); unsigned values (the seed) as
    /// decimal strings, since a reader inferring types from JSON (pyarrow, under
    /// lerobot's v2.1 -> v3.0 script) takes integers as int64 and fails above its max.
    pub fn json(&self, i: usize) -> Value {
        match self {
            Self::Bool(v) => json!(v[i]),
            Self::Int(v) => json!(v[i]),
            Self::UInt(v) => json!(v[i].map(|x| x.to_string())),
            Self::Float(v) => json!(v[i]),
            Self::Text(v) => json!(v[i]),
            Self::TextList(v) => json!(v[i]),
            Self::FloatList(v) => json!(v[i]),
        }
    }
}

/// A replay's whole record as the labels keep it (the flags with their frames, the
/// randomization draw as written), `null` without one.
pub fn label_json(label: Option<&ReplayLabel>) -> Value {
    label.map_or(Value::Null, |l| {
        json!({
            "success": l.success,
            "first_success": l.first_success,
            "steps": l.steps,
            "recorded_steps": l.recorded_steps,
            "extended": l.extended,
            "checked": l.checked,
            "flags": l.flags,
            "sample": l.sample,
            "dynamics": l.dynamics,
        })
    })
}

/// Writes the labels into Diffusion Policy's store at `zarr`: per numeric or boolean
/// column an uncompressed array `meta/<name>` (the name after its `outcome/` or
/// `randomization/` prefix) with one value per episode, where an episode without one has
/// `false`, `-1` (integers), `0` (the seed) or NaN (floats, RGB triples as (E, 3)); and
/// `meta/.zattrs` `{"episodes": [{"episode": id, "label": record or null}]}`. Nothing is
/// written when no episode has a replay record.
pub(crate) fn write_zarr_labels(
    zarr: &Path,
    ids: &[String],
    labels: &[Option<ReplayLabel>],
) -> Result<(), DatasetError> {
    let refs: Vec<Option<&ReplayLabel>> = labels.iter().map(Option::as_ref).collect();
    let columns = label_columns(&refs);
    if columns.is_empty() {
        return Ok(());
    }
    let n = ids.len();
    for (name, values) in &columns {
        let short = name.rsplit('/').next().expect("a name");
        let (dtype, width, bytes): (&str, usize, Vec<u8>) = match values {
            LabelValues::Bool(v) => (
                "|b1",
                1,
                v.iter().map(|x| u8::from(x.unwrap_or(false))).collect(),
            ),
            LabelValues::Int(v) => (
                "<i8",
                1,
                v.iter()
                    .flat_map(|x| x.unwrap_or(-1).to_le_bytes())
                    .collect(),
            ),
            LabelValues::UInt(v) => (
                "<u8",
                1,
                v.iter()
                    .flat_map(|x| x.unwrap_or(0).to_le_bytes())
                    .collect(),
            ),
            LabelValues::Float(v) => (
                "<f8",
                1,
                v.iter()
                    .flat_map(|x| x.unwrap_or(f64::NAN).to_le_bytes())
                    .collect(),
            ),
            LabelValues::FloatList(v) => {
                let w = v.iter().flatten().map(Vec::len).max().unwrap_or(0);
                let mut b = Vec::with_capacity(n * w * 8);
                for x in v {
                    for k in 0..w {
                        let f = x
                            .as_ref()
                            .and_then(|x| x.get(k).copied())
                            .unwrap_or(f64::NAN);
                        b.extend(f.to_le_bytes());
                    }
                }
                ("<f8", w, b)
            }
            LabelValues::Text(_) | LabelValues::TextList(_) => continue,
        };
        if width == 0 {
            continue;
        }
        write_small_array(
            &zarr.join("meta").join(short),
            dtype,
            n,
            width,
            values,
            &bytes,
        )?;
    }
    let episodes: Vec<Value> = ids
        .iter()
        .zip(labels)
        .map(|(id, l)| json!({"episode": id, "label": label_json(l.as_ref())}))
        .collect();
    write_json(&zarr.join("meta/.zattrs"), &json!({"episodes": episodes}))
}

/// One uncompressed Zarr v2 array of `n` rows (`width` columns when it is a list
/// column), its values in one chunk.
fn write_small_array(
    dir: &Path,
    dtype: &str,
    n: usize,
    width: usize,
    values: &LabelValues,
    bytes: &[u8],
) -> Result<(), DatasetError> {
    let two_d = matches!(values, LabelValues::FloatList(_));
    let (shape, key) = if two_d {
        (json!([n, width]), "0.0")
    } else {
        (json!([n]), "0")
    };
    let fill = match values {
        LabelValues::Bool(_) => json!(false),
        LabelValues::Float(_) | LabelValues::FloatList(_) => json!("NaN"),
        LabelValues::Int(_) => json!(-1),
        _ => json!(0),
    };
    fs_err::create_dir_all(dir)?;
    write_json(
        &dir.join(".zarray"),
        &json!({
            "chunks": shape,
            "compressor": null,
            "dimension_separator": ".",
            "dtype": dtype,
            "fill_value": fill,
            "filters": null,
            "order": "C",
            "shape": shape,
            "zarr_format": 2,
        }),
    )?;
    fs_err::write(dir.join(key), bytes)?;
    Ok(())
}
