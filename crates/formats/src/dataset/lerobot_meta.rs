//! The checked reading of a LeRobot v3.0 dataset's `meta/info.json`: every field the
//! format defines parsed into typed values ([`InfoMeta`]), with the format's own defaults
//! where lerobot has one (`chunks_size` 1000, the default path templates, no splits, no
//! robot type) or an error naming the file, the field, the value and what to do.
//! Shapes are multiplied with checked arithmetic and bounded; path templates are parsed
//! once ([`PathTemplate`]): only the format's own placeholders, with bounded widths, and
//! never a path that leaves the dataset's folder. A dataset downloaded from anywhere is
//! untrusted, so nothing of `info.json` reaches a format string, an allocation or a path
//! before it has been through here.

use std::collections::BTreeMap;
use std::path::{Component, Path};

use serde_json::{Map, Value};

use crate::error::DatasetError;

/// lerobot's `DEFAULT_CHUNK_SIZE`: files (v3.0) per chunk folder.
pub const DEFAULT_CHUNKS_SIZE: u64 = 1000;
/// lerobot's `DEFAULT_DATA_PATH`.
pub const DEFAULT_DATA_PATH: &str = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet";
/// lerobot's `DEFAULT_VIDEO_PATH`.
pub const DEFAULT_VIDEO_PATH: &str =
    "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4";
/// The widest number field of a path template (`{file_index:020d}`).
pub const MAX_TEMPLATE_WIDTH: usize = 20;
/// The most values one frame of any feature may hold (a 16K x 16K RGB image fits).
pub const MAX_FEATURE_VALUES: u64 = 1 << 30;
/// The most values one frame of a numeric feature may hold (statistics are kept per
/// value).
pub const MAX_NUMERIC_WIDTH: u64 = 1 << 20;
/// The largest `chunks_size`.
pub const MAX_CHUNKS_SIZE: u64 = 1 << 24;
/// The largest frame rate.
pub const MAX_FPS: f64 = 100_000.0;
/// The largest chunk or file index, episode length or frame index accepted in the
/// episode rows (2^40: far beyond any dataset, far below any overflow).
pub const MAX_INDEX: i64 = 1 << 40;

/// The placeholders of `data_path`.
pub const DATA_FIELDS: [Placeholder; 2] = [Placeholder::ChunkIndex, Placeholder::FileIndex];
/// The placeholders of `video_path`.
pub const VIDEO_FIELDS: [Placeholder; 3] = [
    Placeholder::VideoKey,
    Placeholder::ChunkIndex,
    Placeholder::FileIndex,
];

/// A placeholder of a path template.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Placeholder {
    /// `{chunk_index}`.
    ChunkIndex,
    /// `{file_index}`.
    FileIndex,
    /// `{video_key}` (video paths only).
    VideoKey,
}

impl Placeholder {
    fn name(self) -> &'static str {
        match self {
            Self::ChunkIndex => "chunk_index",
            Self::FileIndex => "file_index",
            Self::VideoKey => "video_key",
        }
    }
}

#[derive(Debug, Clone, PartialEq, Eq)]
enum Part {
    Text(String),
    Field(Placeholder, usize),
}

/// A checked path template of `info.json` (`data_path`, `video_path`): relative, inside
/// the dataset's folder, made of text and the format's placeholders (`{chunk_index}`,
/// `{file_index}`, and `{video_key}` for videos), numbers zero-padded to at most
/// [`MAX_TEMPLATE_WIDTH`] digits (`{chunk_index:03d}`), as Python's `str.format` fills them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PathTemplate {
    text: String,
    parts: Vec<Part>,
}

impl PathTemplate {
    /// Parses `text` as the template of `field` (`data_path` or `video_path`), which must
    /// hold each of `needed` (so that no two files share a path) and no other placeholder.
    pub fn parse(text: &str, field: &str, needed: &[Placeholder]) -> Result<Self, String> {
        let escapes = Path::new(text).is_absolute()
            || text.starts_with(['/', '\\'])
            || text.contains('\\')
            || Path::new(text)
                .components()
                .any(|c| !matches!(c, Component::Normal(_)));
        if text.is_empty() || escapes {
            return Err(format!(
                "{text:?} leaves the dataset folder (absolute, empty, or with ..); the \
                 format's own is {:?}",
                default_of(field)
            ));
        }
        let parts = parse_parts(text, needed)?;
        for p in needed {
            if !parts
                .iter()
                .any(|x| matches!(x, Part::Field(q, _) if q == p))
            {
                return Err(format!(
                    "{text:?} has no {{{}}}: its files would share one path",
                    p.name()
                ));
            }
        }
        Ok(Self {
            text: text.to_owned(),
            parts,
        })
    }

    /// The template as written.
    pub fn as_str(&self) -> &str {
        &self.text
    }

    /// The relative path of a file: the numbers zero-padded as asked, `video_key` (a
    /// checked feature key) where the template names it.
    pub fn fill(&self, video_key: &str, chunk: u64, file: u64) -> String {
        let mut out = String::with_capacity(self.text.len() + 16);
        for p in &self.parts {
            match p {
                Part::Text(t) => out.push_str(t),
                Part::Field(Placeholder::VideoKey, _) => out.push_str(video_key),
                Part::Field(Placeholder::ChunkIndex, w) => out.push_str(&format!("{chunk:0w$}")),
                Part::Field(Placeholder::FileIndex, w) => out.push_str(&format!("{file:0w$}")),
            }
        }
        out
    }
}

fn default_of(field: &str) -> &'static str {
    if field == "video_path" {
        DEFAULT_VIDEO_PATH
    } else {
        DEFAULT_DATA_PATH
    }
}

/// Splits a template into text and placeholders (`{{` and `}}` are literal braces).
fn parse_parts(text: &str, allowed: &[Placeholder]) -> Result<Vec<Part>, String> {
    let mut parts = Vec::new();
    let mut literal = String::new();
    let mut chars = text.char_indices().peekable();
    while let Some((at, c)) = chars.next() {
        match c {
            '{' if chars.peek().is_some_and(|(_, n)| *n == '{') => {
                chars.next();
                literal.push('{');
            }
            '}' if chars.peek().is_some_and(|(_, n)| *n == '}') => {
                chars.next();
                literal.push('}');
            }
            '{' => {
                let close = text[at..]
                    .find('}')
                    .ok_or_else(|| format!("{text:?}: a '{{' without its '}}'"))?;
                let spec = &text[at + 1..at + close];
                parts.push(Part::Text(std::mem::take(&mut literal)));
                parts.push(field_of(spec, allowed, text)?);
                while chars.peek().is_some_and(|(i, _)| *i <= at + close) {
                    chars.next();
                }
            }
            '}' => return Err(format!("{text:?}: a '}}' without its '{{'")),
            c => literal.push(c),
        }
    }
    parts.push(Part::Text(literal));
    parts.retain(|p| !matches!(p, Part::Text(t) if t.is_empty()));
    Ok(parts)
}

/// One `{name}` / `{name:0Nd}` field.
fn field_of(spec: &str, allowed: &[Placeholder], text: &str) -> Result<Part, String> {
    let (name, format) = spec.split_once(':').unwrap_or((spec, ""));
    let names: Vec<String> = allowed
        .iter()
        .map(|p| format!("{{{}}}", p.name()))
        .collect();
    let Some(p) = allowed.iter().copied().find(|p| p.name() == name) else {
        return Err(format!(
            "{text:?}: {{{spec}}} is no placeholder of this path (it may hold {})",
            names.join(", ")
        ));
    };
    if format.is_empty() {
        return Ok(Part::Field(p, 0));
    }
    let digits = format.strip_suffix('d').map(|d| d.trim_start_matches('0'));
    let width = match digits {
        Some("") => Some(0),
        Some(d) if d.len() <= 2 && d.bytes().all(|b| b.is_ascii_digit()) => d.parse().ok(),
        _ => None,
    };
    match width {
        Some(w) if w <= MAX_TEMPLATE_WIDTH && p != Placeholder::VideoKey => Ok(Part::Field(p, w)),
        _ => Err(format!(
            "{text:?}: {{{spec}}} is not a number field of at most {MAX_TEMPLATE_WIDTH} digits \
             (as {{{}:03d}})",
            p.name()
        )),
    }
}

/// One feature of `info.json`, checked.
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureMeta {
    /// `dtype` as written (`float32`, `int64`, `video`, `image`, `string`, `bool`...).
    pub dtype: String,
    /// `shape`.
    pub shape: Vec<u64>,
    /// Values per frame: the product of the shape (checked, at most
    /// [`MAX_FEATURE_VALUES`], and [`MAX_NUMERIC_WIDTH`] for numeric features).
    pub width: usize,
}

impl FeatureMeta {
    /// Stored as a video file.
    pub fn is_video(&self) -> bool {
        self.dtype == "video"
    }

    /// A camera's frames (a video, or images in the data files).
    pub fn is_visual(&self) -> bool {
        matches!(self.dtype.as_str(), "video" | "image")
    }

    /// Numbers in the data files, whose statistics are computed from every frame.
    pub fn is_numeric(&self) -> bool {
        !matches!(self.dtype.as_str(), "video" | "image" | "string")
    }
}

/// `meta/info.json` of a LeRobot v3.0 dataset, checked: what the commands read of it.
#[derive(Debug, Clone, PartialEq)]
pub struct InfoMeta {
    /// `codebase_version` (always v3.0 here).
    pub codebase_version: String,
    /// `fps`: finite, positive, at most [`MAX_FPS`].
    pub fps: f64,
    /// `robot_type` (absent or null: none).
    pub robot_type: Option<String>,
    /// `chunks_size`: files per chunk folder (default 1000).
    pub chunks_size: u64,
    /// `data_path`.
    pub data_path: PathTemplate,
    /// `video_path`: present whenever a feature is a video.
    pub video_path: Option<PathTemplate>,
    /// `splits` (absent: none).
    pub splits: BTreeMap<String, String>,
    /// `total_episodes`, when given.
    pub total_episodes: Option<u64>,
    /// Every feature, in `info.json`'s order.
    pub features: Vec<(String, FeatureMeta)>,
}

impl InfoMeta {
    /// Checks `info` (read from `path`) and completes it with the format's defaults for
    /// the fields it lacks (`chunks_size`, `data_path`, `video_path`, `splits`,
    /// `robot_type`), so a dataset written from it states them.
    pub fn parse(info: &mut Map<String, Value>, path: &Path) -> Result<Self, DatasetError> {
        let at = |field: &str, message: String| DatasetError::Metadata {
            path: path.to_path_buf(),
            field: field.to_owned(),
            message,
        };
        let features = features_of(info.get("features"), &at)?;
        let data_path = template(info, "data_path", &DATA_FIELDS, &at)?.unwrap_or_else(|| {
            PathTemplate::parse(DEFAULT_DATA_PATH, "data_path", &DATA_FIELDS).expect("valid")
        });
        let any_video = features.iter().any(|(_, f)| f.is_video());
        let video_path = match template(info, "video_path", &VIDEO_FIELDS, &at)? {
            Some(t) => Some(t),
            None if any_video => Some(
                PathTemplate::parse(DEFAULT_VIDEO_PATH, "video_path", &VIDEO_FIELDS)
                    .expect("valid"),
            ),
            None => None,
        };
        let meta = Self {
            codebase_version: version_of(info, &at)?,
            fps: fps_of(info, &at)?,
            robot_type: text_or_null(info, "robot_type", &at)?,
            chunks_size: chunks_size_of(info, &at)?,
            data_path,
            video_path,
            splits: splits_of(info, &at)?,
            total_episodes: match info.get("total_episodes") {
                None | Some(Value::Null) => None,
                Some(v) => Some(
                    v.as_u64()
                        .ok_or_else(|| at("total_episodes", format!("{} is no count", short(v))))?,
                ),
            },
            features,
        };
        info.insert("chunks_size".into(), meta.chunks_size.into());
        info.insert("data_path".into(), meta.data_path.as_str().into());
        let video = meta.video_path.as_ref();
        info.insert(
            "video_path".into(),
            video.map_or(Value::Null, |t| t.as_str().into()),
        );
        info.entry("splits")
            .or_insert_with(|| Value::Object(Map::new()));
        info.entry("robot_type").or_insert(Value::Null);
        Ok(meta)
    }

    /// The feature `key`.
    pub fn feature(&self, key: &str) -> Option<&FeatureMeta> {
        self.features.iter().find(|(k, _)| k == key).map(|(_, f)| f)
    }

    /// The keys of the video features, in `info.json`'s order.
    pub fn video_keys(&self) -> Vec<String> {
        self.features
            .iter()
            .filter(|(_, f)| f.is_video())
            .map(|(k, _)| k.clone())
            .collect()
    }
}

/// A field's error: the field and what is wrong with it.
type At<'a> = &'a dyn Fn(&str, String) -> DatasetError;

/// `codebase_version`: required, a text.
fn version_of(info: &Map<String, Value>, at: At<'_>) -> Result<String, DatasetError> {
    match info.get("codebase_version") {
        Some(Value::String(v)) => Ok(v.clone()),
        None => Err(at(
            "codebase_version",
            "missing: a LeRobot dataset states its version (\"v3.0\")".into(),
        )),
        Some(other) => Err(at(
            "codebase_version",
            format!("{} is no text", short(other)),
        )),
    }
}

/// `fps`: required, finite, positive, at most [`MAX_FPS`].
fn fps_of(info: &Map<String, Value>, at: At<'_>) -> Result<f64, DatasetError> {
    info.get("fps")
        .and_then(Value::as_f64)
        .filter(|f| f.is_finite() && *f > 0.0 && *f <= MAX_FPS)
        .ok_or_else(|| {
            at(
                "fps",
                format!(
                    "{}: a positive number of frames per second (at most {MAX_FPS}) is needed",
                    info.get("fps").map_or("missing".into(), short)
                ),
            )
        })
}

/// A text field that may be absent or null.
fn text_or_null(
    info: &Map<String, Value>,
    field: &str,
    at: At<'_>,
) -> Result<Option<String>, DatasetError> {
    match info.get(field) {
        None | Some(Value::Null) => Ok(None),
        Some(Value::String(r)) => Ok(Some(r.clone())),
        Some(other) => Err(at(field, format!("{} is no text", short(other)))),
    }
}

/// `chunks_size`: absent or null is lerobot's default.
fn chunks_size_of(info: &Map<String, Value>, at: At<'_>) -> Result<u64, DatasetError> {
    match info.get("chunks_size") {
        None | Some(Value::Null) => Ok(DEFAULT_CHUNKS_SIZE),
        Some(v) => v
            .as_u64()
            .filter(|n| (1..=MAX_CHUNKS_SIZE).contains(n))
            .ok_or_else(|| {
                at(
                    "chunks_size",
                    format!(
                        "{}: files per chunk folder, 1 to {MAX_CHUNKS_SIZE} (lerobot's default \
                         is {DEFAULT_CHUNKS_SIZE})",
                        short(v)
                    ),
                )
            }),
    }
}

/// `splits`: name -> "from:to"; absent or null is none.
fn splits_of(
    info: &Map<String, Value>,
    at: At<'_>,
) -> Result<BTreeMap<String, String>, DatasetError> {
    match info.get("splits") {
        None | Some(Value::Null) => Ok(BTreeMap::new()),
        Some(Value::Object(m)) => m
            .iter()
            .map(|(k, v)| match v {
                Value::String(s) => Ok((k.clone(), s.clone())),
                other => Err(at(
                    "splits",
                    format!(
                        "split {k:?} is {}, not a range text as \"0:10\"",
                        short(other)
                    ),
                )),
            })
            .collect(),
        Some(other) => Err(at(
            "splits",
            format!("{} is no object of name -> \"from:to\"", short(other)),
        )),
    }
}

/// The template `field` of `info` (`None`: absent or null, the default applies).
fn template(
    info: &Map<String, Value>,
    field: &str,
    needed: &[Placeholder],
    at: At<'_>,
) -> Result<Option<PathTemplate>, DatasetError> {
    match info.get(field) {
        None | Some(Value::Null) => Ok(None),
        Some(Value::String(t)) => PathTemplate::parse(t, field, needed)
            .map(Some)
            .map_err(|m| at(field, m)),
        Some(other) => Err(at(field, format!("{} is no path template", short(other)))),
    }
}

/// Every feature of `features`, checked: a dtype, a shape of positive sizes whose product
/// is bounded, and video keys that can be folder names.
fn features_of(
    features: Option<&Value>,
    at: At<'_>,
) -> Result<Vec<(String, FeatureMeta)>, DatasetError> {
    let Some(Value::Object(features)) = features else {
        return Err(at(
            "features",
            format!(
                "{}: a dataset describes its features (an object of key -> dtype, shape)",
                features.map_or("missing".into(), short)
            ),
        ));
    };
    let mut out = Vec::with_capacity(features.len());
    for (key, f) in features {
        let field = format!("features.{key}");
        let dtype = match f.get("dtype") {
            Some(Value::String(d)) if !d.is_empty() => d.clone(),
            other => {
                return Err(at(
                    &field,
                    format!(
                        "dtype {} is no type name",
                        other.map_or("missing".into(), short)
                    ),
                ));
            }
        };
        let shape = shape_of(f.get("shape")).map_err(|m| at(&format!("{field}.shape"), m))?;
        let width = shape
            .iter()
            .try_fold(1u64, |acc, d| acc.checked_mul(*d))
            .filter(|w| *w <= MAX_FEATURE_VALUES)
            .ok_or_else(|| {
                at(
                    &format!("{field}.shape"),
                    format!("{shape:?} holds more than {MAX_FEATURE_VALUES} values per frame"),
                )
            })?;
        let meta = FeatureMeta {
            dtype,
            shape,
            width: width as usize,
        };
        if meta.is_numeric() && width > MAX_NUMERIC_WIDTH {
            return Err(at(
                &format!("{field}.shape"),
                format!(
                    "{:?} holds {width} numbers per frame; at most {MAX_NUMERIC_WIDTH} are supported",
                    meta.shape
                ),
            ));
        }
        if meta.is_video()
            && let Err(e) = dexjoco_core::safe_name("video feature key", key)
        {
            return Err(at(
                &field,
                format!("{e} (it names the feature's video folder)"),
            ));
        }
        out.push((key.clone(), meta));
    }
    Ok(out)
}

/// A shape: a list of at most 8 positive sizes (absent: `[1]`, as lerobot's scalars; an
/// empty list is a scalar too, as numpy's `()`).
fn shape_of(v: Option<&Value>) -> Result<Vec<u64>, String> {
    let Some(v) = v else {
        return Ok(vec![1]);
    };
    let dims = v
        .as_array()
        .filter(|a| a.len() <= 8)
        .ok_or_else(|| format!("{} is no list of at most 8 sizes", short(v)))?;
    dims.iter()
        .map(|d| {
            d.as_u64().filter(|n| *n >= 1).ok_or_else(|| {
                format!("{} holds {}, which is no positive size", short(v), short(d))
            })
        })
        .collect()
}

/// A JSON value for a message: at most 60 characters.
fn short(v: &Value) -> String {
    let s = v.to_string();
    if s.len() > 60 {
        format!("{}... ({} bytes)", &s[..s.floor_char_boundary(60)], s.len())
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DATA: [Placeholder; 2] = DATA_FIELDS;
    const VIDEO: [Placeholder; 3] = VIDEO_FIELDS;

    #[test]
    fn templates_fill_like_python_format() {
        let t = PathTemplate::parse(DEFAULT_VIDEO_PATH, "video_path", &VIDEO).unwrap();
        assert_eq!(
            t.fill("observation.images.top", 1, 12),
            "videos/observation.images.top/chunk-001/file-012.mp4"
        );
        let t = PathTemplate::parse(
            "d/{chunk_index}/{{x}}-{file_index:5d}.parquet",
            "data_path",
            &DATA,
        )
        .unwrap();
        assert_eq!(t.fill("", 7, 3), "d/7/{x}-00003.parquet");
    }

    #[test]
    fn templates_are_refused_naming_why() {
        for (bad, why) in [
            ("../x/{chunk_index}{file_index}.parquet", "leaves"),
            ("/etc/{chunk_index}{file_index}", "leaves"),
            ("data/../../x", "leaves"),
            ("", "leaves"),
            (
                "data/{chunk_index:070000d}/{file_index}.parquet",
                "at most 20 digits",
            ),
            (
                "data/{chunk_index:21d}/{file_index}.parquet",
                "at most 20 digits",
            ),
            (
                "data/{chunk_index:x}/{file_index}.parquet",
                "at most 20 digits",
            ),
            (
                "data/{episode_index}/{chunk_index}{file_index}",
                "no placeholder",
            ),
            ("data/{chunk_index}/file.parquet", "share one path"),
            ("data/{chunk_index/{file_index}", "no placeholder"),
            ("data/{chunk_index}}{file_index}", "without its"),
            ("data/{chunk_index}{file_index", "without its"),
        ] {
            let e = PathTemplate::parse(bad, "data_path", &DATA).unwrap_err();
            assert!(e.contains(why), "{bad:?}: {e}");
        }
        let e = PathTemplate::parse(
            "v/{video_key:03d}/{chunk_index}/{file_index}",
            "video_path",
            &VIDEO,
        )
        .unwrap_err();
        assert!(e.contains("number field"), "{e}");
    }

    fn info(more: Value) -> Map<String, Value> {
        let mut base = serde_json::json!({
            "codebase_version": "v3.0",
            "fps": 30,
            "features": {
                "action": {"dtype": "float32", "shape": [3], "names": null},
                "observation.images.top": {"dtype": "video", "shape": [4, 4, 3]}
            }
        });
        for (k, v) in more.as_object().unwrap() {
            base[k] = v.clone();
        }
        base.as_object().unwrap().clone()
    }

    #[test]
    fn absent_fields_take_the_formats_defaults() {
        let mut i = info(serde_json::json!({}));
        let m = InfoMeta::parse(&mut i, Path::new("meta/info.json")).unwrap();
        assert_eq!(m.chunks_size, 1000);
        assert_eq!(m.data_path.as_str(), DEFAULT_DATA_PATH);
        assert_eq!(m.video_path.as_ref().unwrap().as_str(), DEFAULT_VIDEO_PATH);
        assert!(m.splits.is_empty() && m.robot_type.is_none());
        assert_eq!(i["chunks_size"], 1000);
        assert_eq!(i["video_path"], DEFAULT_VIDEO_PATH);
        assert_eq!(m.feature("action").unwrap().width, 3);
    }

    #[test]
    fn damaged_fields_are_named() {
        let p = Path::new("x/meta/info.json");
        for (more, field, why) in [
            (
                serde_json::json!({"codebase_version": null}),
                "codebase_version",
                "no text",
            ),
            (serde_json::json!({"fps": -1}), "fps", "positive"),
            (serde_json::json!({"fps": "30"}), "fps", "positive"),
            (serde_json::json!({"chunks_size": 0}), "chunks_size", "1 to"),
            (
                serde_json::json!({"chunks_size": -3}),
                "chunks_size",
                "1 to",
            ),
            (
                serde_json::json!({"robot_type": 3}),
                "robot_type",
                "no text",
            ),
            (serde_json::json!({"splits": [1]}), "splits", "no object"),
            (
                serde_json::json!({"splits": {"train": 5}}),
                "splits",
                "range text",
            ),
            (
                serde_json::json!({"total_episodes": -1}),
                "total_episodes",
                "no count",
            ),
            (serde_json::json!({"features": 3}), "features", "describes"),
            (
                serde_json::json!({"features": {"a": {"dtype": "float32", "shape": [4294967296u64, 4294967296u64]}}}),
                "features.a.shape",
                "more than",
            ),
            (
                serde_json::json!({"features": {"a": {"dtype": "float32", "shape": [1_000_000_000_000u64]}}}),
                "features.a.shape",
                "more than",
            ),
            (
                serde_json::json!({"features": {"a": {"dtype": "float32", "shape": [2_000_000]}}}),
                "features.a.shape",
                "numbers per frame",
            ),
            (
                serde_json::json!({"features": {"a": {"dtype": "float32", "shape": [0]}}}),
                "features.a.shape",
                "positive size",
            ),
            (
                serde_json::json!({"features": {"a": {"shape": [1]}}}),
                "features.a",
                "dtype",
            ),
            (
                serde_json::json!({"features": {"..": {"dtype": "video", "shape": [1, 1, 3]}}}),
                "features...",
                "video folder",
            ),
            (
                serde_json::json!({"data_path": "{chunk_index:070000d}/{file_index}"}),
                "data_path",
                "digits",
            ),
        ] {
            let mut i = info(more.clone());
            if more.get("codebase_version").is_some() {
                i.remove("codebase_version");
                i.insert("codebase_version".into(), Value::Null);
            }
            let e = InfoMeta::parse(&mut i, p).unwrap_err().to_string();
            assert!(
                e.contains("x/meta/info.json") && e.contains(field) && e.contains(why),
                "{more}: {e}"
            );
        }
        let mut i = info(serde_json::json!({}));
        i.remove("codebase_version");
        let e = InfoMeta::parse(&mut i, p).unwrap_err().to_string();
        assert!(
            e.contains("codebase_version") && e.contains("missing"),
            "{e}"
        );
    }
}
