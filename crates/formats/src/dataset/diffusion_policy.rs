//! The Diffusion Policy writer: `replay_buffer.zarr` (Zarr v2) as Diffusion Policy's
//! `ReplayBuffer` reads it, streamed episode by episode.
//!
//! - `data/action`, `data/state`: float64 (T, D) (the raw values, unrounded);
//!   `data/timestamp`: float64 (T,), `k / fps` from each episode's first kept frame;
//!   chunks along time of about 2 MB.
//! - `data/<camera>`: uint8 (T, H, W, 3) RGB frames decoded from the source video,
//!   chunks (1, H, W, 3).
//! - `meta/episode_ends`: int64, cumulative exclusive ends, uncompressed.
//! - with `--privileged-state`: `data/privileged_state` float64 (T, P), its column
//!   names in its `.zattrs` (`names`).
//! - when the episodes carry subtasks: `data/subtask_index` int64 (T,), the index of the
//!   running subtasks' text (-1 before an episode's first), the texts in its `.zattrs`
//!   (`subtasks`).
//! - when an episode is a replay with a record: the labels of
//!   [`super::episode_labels`] as per-episode arrays `meta/success`, `meta/first_success`
//!   ... and the whole records in `meta/.zattrs` (`episodes`).
//! - data arrays use Diffusion Policy's default compressor, Blosc(lz4, clevel 5, no
//!   shuffle).
//! - with `videos`: `videos/<episode index>/<camera index>.mp4` beside the store (each
//!   starting at the episode's first kept frame), and `videos/name_map.json`
//!   (`{"cameras": [names by index], "episodes": [ids by index]}`).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use dexjoco_core::Location;
use dexjoco_video::VideoReader;
use serde_json::json;
use zarrs::array::{Array, ArrayMetadata, ArrayMetadataOptions, CodecOptions};
use zarrs::filesystem::FilesystemStore;

use super::episode_labels::write_zarr_labels;
use super::language::{SUBTASK_INDEX, SubtaskTexts};
use super::{DatasetWriter, PreparedEpisode, VectorFeature, VideoPart, place_video, write_json};
use crate::error::{DatasetError, ZarrWriteError};
use crate::raw::ReplayLabel;
use crate::zarr_v2::{self, Blosc};

/// The store's folder name inside the output folder.
pub const REPLAY_BUFFER: &str = "replay_buffer.zarr";

/// Target bytes of one chunk of a low-dimensional array.
const CHUNK_BYTES: usize = 2_000_000;

/// Array names the cameras may not take.
const RESERVED: [&str; 5] = [
    "action",
    "state",
    "timestamp",
    "privileged_state",
    "environment_state",
];

/// A zarrs error on the store at `path`, as [`DatasetError::Zarr`].
fn zarr_err(path: &Path, e: impl Into<ZarrWriteError>) -> DatasetError {
    DatasetError::Zarr {
        path: path.to_path_buf(),
        source: Box::new(e.into()),
    }
}

fn metadata(
    path: &Path,
    shape: &[u64],
    chunks: &[u64],
    dtype: &str,
    compressed: bool,
) -> Result<ArrayMetadata, DatasetError> {
    let compressor = compressed.then_some(Blosc::DIFFUSION_POLICY);
    zarr_v2::array_metadata(shape, chunks, dtype, compressor)
        .map_err(|e| zarr_err(path, ZarrWriteError::Layout(e)))
}

/// An array along time (float64 values, or int64 indices), written a chunk at a time.
struct Series<T = f64> {
    array: Array<FilesystemStore>,
    /// Columns (1 with a 1-D shape).
    width: usize,
    one_d: bool,
    chunk: usize,
    buf: Vec<T>,
    rows: u64,
    chunks_written: u64,
}

impl<T> Series<T>
where
    T: zarrs::array::Element + Copy + Default,
    for<'a> &'a [T]: zarrs::array::IntoArrayBytes<'a>,
{
    fn shape(&self, rows: u64) -> Vec<u64> {
        if self.one_d {
            vec![rows]
        } else {
            vec![rows, self.width as u64]
        }
    }

    fn store_chunk(&mut self, data: &[T], opts: &CodecOptions) -> Result<(), ZarrWriteError> {
        let mut idx = vec![self.chunks_written];
        if !self.one_d {
            idx.push(0);
        }
        self.array.store_chunk_opt(&idx, data, opts)?;
        self.chunks_written += 1;
        Ok(())
    }

    fn push(&mut self, rows: &[T], opts: &CodecOptions) -> Result<(), ZarrWriteError> {
        self.buf.extend_from_slice(rows);
        self.rows += (rows.len() / self.width) as u64;
        let per = self.chunk * self.width;
        while self.buf.len() >= per {
            let full = (self.chunks_written + 1) * self.chunk as u64;
            self.array.set_shape(self.shape(full))?;
            let rest = self.buf.split_off(per);
            let data = std::mem::replace(&mut self.buf, rest);
            self.store_chunk(&data, opts)?;
        }
        Ok(())
    }

    fn finish(
        mut self,
        opts: &CodecOptions,
        meta: &ArrayMetadataOptions,
    ) -> Result<(), ZarrWriteError> {
        self.array.set_shape(self.shape(self.rows))?;
        if !self.buf.is_empty() {
            let mut data = std::mem::take(&mut self.buf);
            data.resize(self.chunk * self.width, T::default());
            self.store_chunk(&data, opts)?;
        }
        Ok(self.array.store_metadata_opt(meta)?)
    }
}

struct Images {
    name: String,
    array: Array<FilesystemStore>,
    height: u32,
    width: u32,
}

/// Writes a Diffusion Policy replay buffer (and optionally videos) into `root`.
pub struct ZarrWriter {
    root: PathBuf,
    zarr: PathBuf,
    store: Arc<FilesystemStore>,
    fps: u32,
    action: Series,
    state: Series,
    timestamp: Series,
    /// `data/environment_state`, `data/privileged_state` (`--environment-state`,
    /// `--privileged-state`): per vector feature its array, key and column names.
    vectors: Vec<(Series, String, Vec<String>)>,
    /// `data/subtask_index` (int64 per frame, -1 before an episode's first subtask) and
    /// the texts it indexes, when the episodes carry subtasks (as the first one does).
    subtasks: Option<(Series<i64>, SubtaskTexts)>,
    images: Vec<Images>,
    /// `data/<camera>_depth` (`--depth`), in camera-name order.
    depth: Vec<DepthArray>,
    episode_ends: Vec<i64>,
    episode_ids: Vec<String>,
    labels: Vec<Option<ReplayLabel>>,
    videos: bool,
    codec: CodecOptions,
    meta: ArrayMetadataOptions,
}

impl std::fmt::Debug for ZarrWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ZarrWriter")
            .field("zarr", &self.zarr)
            .field("episodes", &self.episode_ends.len())
            .finish_non_exhaustive()
    }
}

impl ZarrWriter {
    /// Starts a replay buffer whose arrays are shaped after `first`; `videos` also
    /// keeps each episode's videos beside it.
    pub fn try_new(
        root: impl Into<PathBuf>,
        first: &PreparedEpisode,
        videos: bool,
    ) -> Result<Self, DatasetError> {
        let root = root.into();
        let zarr = root.join(REPLAY_BUFFER);
        fs_err::create_dir_all(&zarr)?;
        let store = Arc::new(FilesystemStore::new(&zarr).map_err(|e| zarr_err(&zarr, e))?);
        zarr_v2::create_groups(&store, &["/", "/data", "/meta"])
            .map_err(|e| zarr_err(&zarr, ZarrWriteError::Layout(e)))?;
        let series = |name: &str, width: usize, one_d: bool| -> Result<Series, DatasetError> {
            let chunk = (CHUNK_BYTES / (8 * width.max(1))).max(1);
            let (shape, chunks) = if one_d {
                (vec![0], vec![chunk as u64])
            } else {
                (vec![0, width as u64], vec![chunk as u64, width as u64])
            };
            let array = Array::new_with_metadata(
                store.clone(),
                &format!("/data/{name}"),
                metadata(&zarr, &shape, &chunks, "<f8", true)?,
            )
            .map_err(|e| zarr_err(&zarr, e))?;
            Ok(Series {
                array,
                width: width.max(1),
                one_d,
                chunk,
                buf: Vec::new(),
                rows: 0,
                chunks_written: 0,
            })
        };
        let subtasks = if first.subtasks.is_empty() {
            None
        } else {
            let chunk = CHUNK_BYTES / 8;
            let array = Array::new_with_metadata(
                store.clone(),
                &format!("/data/{SUBTASK_INDEX}"),
                metadata(&zarr, &[0], &[chunk as u64], "<i8", true)?,
            )
            .map_err(|e| zarr_err(&zarr, e))?;
            let series = Series {
                array,
                width: 1,
                one_d: true,
                chunk,
                buf: Vec::new(),
                rows: 0,
                chunks_written: 0,
            };
            Some((series, SubtaskTexts::default()))
        };
        let images = image_arrays(&store, &zarr, first)?;
        let depth = DepthArray::all(&store, &zarr, first)?;
        let vectors = first
            .vectors
            .iter()
            .map(|v| {
                let name = VectorFeature::zarr_name(&v.key);
                Ok((
                    series(&name, v.values.width(), false)?,
                    v.key.clone(),
                    v.names.clone(),
                ))
            })
            .collect::<Result<Vec<_>, DatasetError>>()?;
        Ok(Self {
            action: series("action", first.action.width(), false)?,
            state: series("state", first.state.width(), false)?,
            timestamp: series("timestamp", 1, true)?,
            vectors,
            subtasks,
            root,
            zarr: zarr.clone(),
            store: store.clone(),
            fps: first.fps,
            images,
            depth,
            episode_ends: Vec::new(),
            episode_ids: Vec::new(),
            labels: Vec::new(),
            videos,
            codec: CodecOptions::default().with_store_empty_chunks(true),
            meta: ArrayMetadataOptions::default().with_include_zarrs_metadata(false),
        })
    }

    /// Decodes one camera's frames from its source, after the trimmed start, into the
    /// camera's array from frame `start` on.
    fn write_frames(
        &mut self,
        c: usize,
        part: &VideoPart,
        ep: &PreparedEpisode,
        start: u64,
    ) -> Result<(), DatasetError> {
        let n = ep.len();
        let zarr = &self.zarr;
        let err = |e: ZarrWriteError| zarr_err(zarr, e);
        let img = &mut self.images[c];
        let at = || {
            Location::episode(&ep.id)
                .field(format!("camera {}", part.name))
                .path(&part.source)
        };
        let vid_err = |source: dexjoco_video::VideoError| DatasetError::Video {
            at: at().into(),
            source: source.into(),
        };
        let mut reader = VideoReader::open(&part.source, None).map_err(vid_err)?;
        if reader.size() != (img.width, img.height) {
            return Err(DatasetError::Episode {
                at: at().into(),
                message: format!(
                    "{}x{} frames differ from the dataset's {}x{}",
                    reader.size().0,
                    reader.size().1,
                    img.width,
                    img.height
                ),
            });
        }
        let (h, w) = (u64::from(img.height), u64::from(img.width));
        let mut frame = Vec::new();
        let mut k = 0usize;
        let mut kept = 0u64;
        while reader.next_frame(&mut frame).map_err(vid_err)? {
            if k >= ep.skipped && (kept as usize) < n {
                let t = start + kept;
                img.array
                    .set_shape(vec![t + 1, h, w, 3])
                    .map_err(|e| err(e.into()))?;
                img.array
                    .store_chunk_opt(&[t, 0, 0, 0], &frame[..], &self.codec)
                    .map_err(|e| err(e.into()))?;
                kept += 1;
            }
            k += 1;
        }
        if kept as usize != n {
            return Err(DatasetError::Episode {
                at: at().into(),
                message: format!("decoded {kept} frames after the trimmed start, expected {n}"),
            });
        }
        Ok(())
    }
}

/// The image arrays of `first`'s cameras, (0, H, W, 3) in chunks of one frame.
fn image_arrays(
    store: &Arc<FilesystemStore>,
    zarr: &Path,
    first: &PreparedEpisode,
) -> Result<Vec<Images>, DatasetError> {
    let mut images = Vec::new();
    for v in &first.videos {
        if RESERVED.contains(&v.name.as_str()) {
            return Err(DatasetError::episode(
                &first.id,
                format!(
                    "camera name '{}' is taken by a data array (rename it in the camera mapping)",
                    v.name
                ),
            ));
        }
        let (h, w) = (u64::from(v.info.height), u64::from(v.info.width));
        let array = Array::new_with_metadata(
            store.clone(),
            &format!("/data/{}", v.name),
            metadata(zarr, &[0, h, w, 3], &[1, h, w, 3], "|u1", true)?,
        )
        .map_err(|e| zarr_err(zarr, e))?;
        images.push(Images {
            name: v.name.clone(),
            array,
            height: v.info.height,
            width: v.info.width,
        });
    }
    Ok(images)
}

/// `data/<camera>_depth`: float32 (T, H, W) metres from the camera's depth archive,
/// chunks (1, H, W), Blosc as the other data arrays.
struct DepthArray {
    name: String,
    array: Array<FilesystemStore>,
    height: usize,
    width: usize,
}

/// Why a depth array could not be written.
enum DepthWriteError {
    Zarr(ZarrWriteError),
    Dataset(DatasetError),
}

impl From<crate::error::FormatError> for DepthWriteError {
    fn from(e: crate::error::FormatError) -> Self {
        Self::Dataset(DatasetError::Episode {
            at: Location::default().into(),
            message: e.to_string(),
        })
    }
}

impl DepthWriteError {
    fn in_store(self, zarr: &Path) -> DatasetError {
        match self {
            Self::Zarr(e) => zarr_err(zarr, e),
            Self::Dataset(e) => e,
        }
    }
}

impl DepthArray {
    /// The depth arrays of `first`'s depth parts, (0, H, W) in chunks of one frame.
    fn all(
        store: &Arc<FilesystemStore>,
        zarr: &Path,
        first: &PreparedEpisode,
    ) -> Result<Vec<Self>, DatasetError> {
        let mut out = Vec::new();
        for d in &first.depth {
            let name = format!("{}_depth", d.name);
            if RESERVED.contains(&name.as_str()) || first.videos.iter().any(|v| v.name == name) {
                return Err(DatasetError::episode(
                    &first.id,
                    format!("depth array name '{name}' is taken (rename the camera)"),
                ));
            }
            let (h, w) = (d.height as u64, d.width as u64);
            let array = Array::new_with_metadata(
                store.clone(),
                &format!("/data/{name}"),
                metadata(zarr, &[0, h, w], &[1, h, w], "<f4", true)?,
            )
            .map_err(|e| zarr_err(zarr, e))?;
            out.push(Self {
                name,
                array,
                height: d.height,
                width: d.width,
            });
        }
        Ok(out)
    }

    /// Checks that `ep` has the store's depth cameras, of the same sizes.
    fn check(arrays: &[Self], ep: &PreparedEpisode) -> Result<(), DatasetError> {
        let want: Vec<String> = arrays.iter().map(|a| a.name.clone()).collect();
        let have: Vec<String> = ep
            .depth
            .iter()
            .map(|d| format!("{}_depth", d.name))
            .collect();
        if want != have {
            return Err(DatasetError::episode(
                &ep.id,
                format!("depth arrays {have:?} differ from the store's {want:?}"),
            ));
        }
        for (a, d) in arrays.iter().zip(&ep.depth) {
            if (d.width, d.height) != (a.width, a.height) {
                return Err(DatasetError::episode(
                    &ep.id,
                    format!(
                        "depth of camera '{}': {}x{} differs from the store's {}x{}",
                        d.name, d.width, d.height, a.width, a.height
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Streams the kept frames of `part`'s archive into frames `start..` of the array.
    fn write(
        &mut self,
        part: &super::DepthPart,
        ep: &PreparedEpisode,
        start: u64,
        codec: &CodecOptions,
    ) -> Result<(), DepthWriteError> {
        let (h, w) = (self.height as u64, self.width as u64);
        let n = ep.len();
        let mut kept = 0u64;
        let at = || {
            Location::episode(&ep.id)
                .field(format!("depth of camera {}", part.name))
                .path(&part.path)
        };
        let result = crate::npz::for_each_depth_frame(&part.path, |k, frame| {
            if k < part.skip || kept as usize >= n {
                return Ok(());
            }
            let t = start + kept;
            self.array
                .set_shape(vec![t + 1, h, w])
                .map_err(|e| DepthWriteError::Zarr(e.into()))?;
            self.array
                .store_chunk_opt(&[t, 0, 0], frame, codec)
                .map_err(|e| DepthWriteError::Zarr(e.into()))?;
            kept += 1;
            Ok(())
        });
        match result {
            Err(DepthWriteError::Dataset(DatasetError::Episode { message, .. })) => {
                return Err(DepthWriteError::Dataset(DatasetError::Episode {
                    at: at().into(),
                    message,
                }));
            }
            Err(e) => return Err(e),
            Ok(_) => {}
        }
        if kept as usize != n {
            return Err(DepthWriteError::Dataset(DatasetError::Episode {
                at: at().into(),
                message: format!("{kept} depth frames after the trimmed start, expected {n}"),
            }));
        }
        Ok(())
    }

    /// Sets the final shape and writes the metadata.
    fn finish(
        mut self,
        zarr: &Path,
        total: u64,
        meta: &ArrayMetadataOptions,
    ) -> Result<(), DatasetError> {
        let (h, w) = (self.height as u64, self.width as u64);
        self.array
            .set_shape(vec![total, h, w])
            .map_err(|e| zarr_err(zarr, e))?;
        self.array
            .store_metadata_opt(meta)
            .map_err(|e| zarr_err(zarr, e))
    }
}

impl DatasetWriter for ZarrWriter {
    /// Checks that `ep` can join this store (fps, widths, cameras).
    fn check_compatible(&self, ep: &PreparedEpisode) -> Result<(), DatasetError> {
        let layout: Vec<(String, Vec<String>)> = self
            .vectors
            .iter()
            .map(|(_, k, n)| (k.clone(), n.clone()))
            .collect();
        ep.check_vectors(&layout)?;
        let want: Vec<&str> = self.images.iter().map(|c| c.name.as_str()).collect();
        ep.check_layout(self.fps, self.action.width, self.state.width, &want)?;
        DepthArray::check(&self.depth, ep)?;
        for (v, img) in ep.videos.iter().zip(&self.images) {
            if (v.info.width, v.info.height) != (img.width, img.height) {
                return Err(DatasetError::episode(
                    &ep.id,
                    format!(
                        "camera '{}': {}x{} differs from the store's {}x{}",
                        img.name, v.info.width, v.info.height, img.width, img.height
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Appends one episode: arrays, decoded camera frames, and its videos.
    fn write_episode(&mut self, ep: PreparedEpisode) -> Result<(), DatasetError> {
        self.check_compatible(&ep)?;
        let n = ep.len();
        let start = self.frames() as u64;
        let err = |e| zarr_err(&self.zarr, e);
        self.action
            .push(ep.action.as_slice(), &self.codec)
            .map_err(&err)?;
        self.state
            .push(ep.state.as_slice(), &self.codec)
            .map_err(&err)?;
        let fps = f64::from(self.fps);
        let ts: Vec<f64> = (0..n).map(|k| k as f64 / fps).collect();
        self.timestamp.push(&ts, &self.codec).map_err(&err)?;
        for ((series, _, _), v) in self.vectors.iter_mut().zip(&ep.vectors) {
            series
                .push(v.values.as_slice(), &self.codec)
                .map_err(&err)?;
        }
        if let Some((series, texts)) = self.subtasks.as_mut() {
            let idx = texts.frame_indices(&ep.subtasks, n);
            series.push(&idx, &self.codec).map_err(&err)?;
        }

        let index = self.episode_ends.len();
        for (c, part) in ep.videos.iter().enumerate() {
            self.write_frames(c, part, &ep, start)?;
            if self.videos {
                let dst = self
                    .root
                    .join("videos")
                    .join(index.to_string())
                    .join(format!("{c}.mp4"));
                place_video(part, &dst)?;
            } else if part.temporary {
                let _ = fs_err::remove_file(&part.path);
            }
        }
        for (d, part) in self.depth.iter_mut().zip(&ep.depth) {
            d.write(part, &ep, start, &self.codec)
                .map_err(|e| e.in_store(&self.zarr))?;
        }
        self.episode_ends.push((start as usize + n) as i64);
        self.episode_ids.push(ep.id);
        self.labels.push(ep.label);
        Ok(())
    }

    fn episodes(&self) -> usize {
        self.episode_ends.len()
    }

    fn frames(&self) -> usize {
        self.episode_ends.last().map_or(0, |e| *e as usize)
    }

    /// Completes the arrays' metadata, writes `meta/episode_ends` and the name map.
    fn finish(self: Box<Self>) -> Result<(), DatasetError> {
        let this = *self;
        let zarr = &this.zarr;
        let total = this.frames() as u64;
        let cameras: Vec<String> = this.images.iter().map(|i| i.name.clone()).collect();
        let mut names = Vec::new();
        let mut vectors = Vec::new();
        for (series, key, columns) in this.vectors {
            names.push((VectorFeature::zarr_name(&key), columns));
            vectors.push(series);
        }
        if let Some((series, texts)) = this.subtasks {
            series
                .finish(&this.codec, &this.meta)
                .map_err(|e| zarr_err(zarr, e))?;
            write_json(
                &zarr.join(format!("data/{SUBTASK_INDEX}/.zattrs")),
                &json!({ "subtasks": texts.list() }),
            )?;
        }
        let series = [this.action, this.state, this.timestamp]
            .into_iter()
            .chain(vectors);
        for s in series {
            s.finish(&this.codec, &this.meta)
                .map_err(|e| zarr_err(zarr, e))?;
        }
        for mut img in this.images {
            let (h, w) = (u64::from(img.height), u64::from(img.width));
            img.array
                .set_shape(vec![total, h, w, 3])
                .map_err(|e| zarr_err(zarr, e))?;
            img.array
                .store_metadata_opt(&this.meta)
                .map_err(|e| zarr_err(zarr, e))?;
        }
        for d in this.depth {
            d.finish(zarr, total, &this.meta)?;
        }
        let n = this.episode_ends.len() as u64;
        let array = Array::new_with_metadata(
            this.store.clone(),
            "/meta/episode_ends",
            metadata(zarr, &[n], &[n.max(1)], "<i8", false)?,
        )
        .map_err(|e| zarr_err(zarr, e))?;
        array
            .store_metadata_opt(&this.meta)
            .map_err(|e| zarr_err(zarr, e))?;
        if n > 0 {
            array
                .store_array_subset_opt(&array.subset_all(), &this.episode_ends[..], &this.codec)
                .map_err(|e| zarr_err(zarr, e))?;
        }
        write_zarr_labels(zarr, &this.episode_ids, &this.labels)?;
        for (name, columns) in names {
            write_json(
                &zarr.join(format!("data/{name}/.zattrs")),
                &json!({ "names": columns }),
            )?;
        }
        if this.videos {
            let map = json!({
                "cameras": cameras,
                "episodes": this.episode_ids,
            });
            write_json(&this.root.join("videos").join("name_map.json"), &map)?;
        }
        Ok(())
    }
}
