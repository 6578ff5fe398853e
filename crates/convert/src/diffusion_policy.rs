//! The Diffusion Policy writer: `replay_buffer.zarr` (Zarr v2) as Diffusion Policy's
//! `ReplayBuffer` reads it, streamed episode by episode.
//!
//! - `data/action`, `data/state`: float64 (T, D) (the raw values, unrounded);
//!   `data/timestamp`: float64 (T,), `k / fps` from each episode's first kept frame;
//!   chunks along time of about 2 MB.
//! - `data/<camera>`: uint8 (T, H, W, 3) RGB frames decoded from the source video,
//!   chunks (1, H, W, 3).
//! - `meta/episode_ends`: int64, cumulative exclusive ends, uncompressed.
//! - data arrays use Diffusion Policy's default compressor, Blosc(lz4, clevel 5, no
//!   shuffle).
//! - with `videos`: `videos/<episode index>/<camera index>.mp4` beside the store (each
//!   starting at the episode's first kept frame), and `videos/name_map.json`
//!   (`{"cameras": [names by index], "episodes": [ids by index]}`).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use dexjoco_core::Location;
use dexjoco_formats::zarr_v2::{self, Blosc};
use dexjoco_video::VideoReader;
use serde_json::json;
use zarrs::array::{Array, ArrayMetadata, ArrayMetadataOptions, CodecOptions};
use zarrs::filesystem::FilesystemStore;

use crate::error::ConvertError;
use crate::lerobot_v3::write_json;
use crate::prepare::PreparedEpisode;

/// The store's folder name inside the output folder.
pub const REPLAY_BUFFER: &str = "replay_buffer.zarr";

/// Target bytes of one chunk of a low-dimensional array.
const CHUNK_BYTES: usize = 2_000_000;

/// Array names the cameras may not take.
const RESERVED: [&str; 3] = ["action", "state", "timestamp"];

fn zarr_err(path: &Path) -> impl Fn(String) -> ConvertError + '_ {
    move |message| ConvertError::Input {
        path: path.to_path_buf(),
        message: format!("writing Zarr: {message}"),
    }
}

fn metadata(
    path: &Path,
    shape: &[u64],
    chunks: &[u64],
    dtype: &str,
    compressed: bool,
) -> Result<ArrayMetadata, ConvertError> {
    let compressor = compressed.then_some(Blosc::DIFFUSION_POLICY);
    zarr_v2::array_metadata(shape, chunks, dtype, compressor).map_err(zarr_err(path))
}

/// A float64 array along time, written a chunk at a time.
struct Series {
    array: Array<FilesystemStore>,
    /// Columns (1 with a 1-D shape).
    width: usize,
    one_d: bool,
    chunk: usize,
    buf: Vec<f64>,
    rows: u64,
    chunks_written: u64,
}

impl Series {
    fn shape(&self, rows: u64) -> Vec<u64> {
        if self.one_d {
            vec![rows]
        } else {
            vec![rows, self.width as u64]
        }
    }

    fn store_chunk(&mut self, data: &[f64], opts: &CodecOptions) -> Result<(), String> {
        let mut idx = vec![self.chunks_written];
        if !self.one_d {
            idx.push(0);
        }
        self.array
            .store_chunk_opt(&idx, data, opts)
            .map_err(|e| e.to_string())?;
        self.chunks_written += 1;
        Ok(())
    }

    fn push(&mut self, rows: &[f64], opts: &CodecOptions) -> Result<(), String> {
        self.buf.extend_from_slice(rows);
        self.rows += (rows.len() / self.width) as u64;
        let per = self.chunk * self.width;
        while self.buf.len() >= per {
            let full = (self.chunks_written + 1) * self.chunk as u64;
            self.array
                .set_shape(self.shape(full))
                .map_err(|e| e.to_string())?;
            let rest = self.buf.split_off(per);
            let data = std::mem::replace(&mut self.buf, rest);
            self.store_chunk(&data, opts)?;
        }
        Ok(())
    }

    fn finish(mut self, opts: &CodecOptions, meta: &ArrayMetadataOptions) -> Result<(), String> {
        self.array
            .set_shape(self.shape(self.rows))
            .map_err(|e| e.to_string())?;
        if !self.buf.is_empty() {
            let mut data = std::mem::take(&mut self.buf);
            data.resize(self.chunk * self.width, 0.0);
            self.store_chunk(&data, opts)?;
        }
        self.array
            .store_metadata_opt(meta)
            .map_err(|e| e.to_string())
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
    images: Vec<Images>,
    episode_ends: Vec<i64>,
    episode_ids: Vec<String>,
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
    ) -> Result<Self, ConvertError> {
        let root = root.into();
        let zarr = root.join(REPLAY_BUFFER);
        let err = zarr_err(&zarr);
        fs_err::create_dir_all(&zarr)?;
        let store = Arc::new(FilesystemStore::new(&zarr).map_err(|e| err(e.to_string()))?);
        zarr_v2::create_groups(&store, &["/", "/data", "/meta"]).map_err(&err)?;
        let series = |name: &str, width: usize, one_d: bool| -> Result<Series, ConvertError> {
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
            .map_err(|e| err(e.to_string()))?;
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
        let mut images = Vec::new();
        for v in &first.videos {
            if RESERVED.contains(&v.name.as_str()) {
                return Err(ConvertError::episode(
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
                metadata(&zarr, &[0, h, w, 3], &[1, h, w, 3], "|u1", true)?,
            )
            .map_err(|e| err(e.to_string()))?;
            images.push(Images {
                name: v.name.clone(),
                array,
                height: v.info.height,
                width: v.info.width,
            });
        }
        Ok(Self {
            action: series("action", first.action.width(), false)?,
            state: series("state", first.state.width(), false)?,
            timestamp: series("timestamp", 1, true)?,
            root,
            zarr: zarr.clone(),
            store: store.clone(),
            fps: first.fps,
            images,
            episode_ends: Vec::new(),
            episode_ids: Vec::new(),
            videos,
            codec: CodecOptions::default().with_store_empty_chunks(true),
            meta: ArrayMetadataOptions::default().with_include_zarrs_metadata(false),
        })
    }

    /// Episodes written so far.
    pub fn episodes(&self) -> usize {
        self.episode_ends.len()
    }

    /// Frames written so far.
    pub fn frames(&self) -> usize {
        self.episode_ends.last().map_or(0, |e| *e as usize)
    }

    /// Checks that `ep` can join this store (fps, widths, cameras).
    pub(crate) fn check_compatible(&self, ep: &PreparedEpisode) -> Result<(), ConvertError> {
        let want: Vec<&str> = self.images.iter().map(|c| c.name.as_str()).collect();
        ep.check_layout(self.fps, self.action.width, self.state.width, &want)?;
        for (v, img) in ep.videos.iter().zip(&self.images) {
            if (v.info.width, v.info.height) != (img.width, img.height) {
                return Err(ConvertError::episode(
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
    pub fn write_episode(&mut self, ep: PreparedEpisode) -> Result<(), ConvertError> {
        self.check_compatible(&ep)?;
        let n = ep.len();
        let start = self.frames() as u64;
        let err = zarr_err(&self.zarr);
        self.action
            .push(ep.action.as_slice(), &self.codec)
            .map_err(&err)?;
        self.state
            .push(ep.state.as_slice(), &self.codec)
            .map_err(&err)?;
        let fps = f64::from(self.fps);
        let ts: Vec<f64> = (0..n).map(|k| k as f64 / fps).collect();
        self.timestamp.push(&ts, &self.codec).map_err(&err)?;

        let index = self.episode_ends.len();
        for (c, (part, img)) in ep.videos.iter().zip(&mut self.images).enumerate() {
            let at = || {
                Location::episode(&ep.id)
                    .field(format!("camera {}", part.name))
                    .path(&part.source)
            };
            let vid_err = |source: dexjoco_video::VideoError| ConvertError::Video {
                at: at().into(),
                source: source.into(),
            };
            let mut reader = VideoReader::open(&part.source, None).map_err(vid_err)?;
            if reader.size() != (img.width, img.height) {
                return Err(ConvertError::Episode {
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
                        .map_err(|e| err(e.to_string()))?;
                    img.array
                        .store_chunk_opt(&[t, 0, 0, 0], &frame[..], &self.codec)
                        .map_err(|e| err(e.to_string()))?;
                    kept += 1;
                }
                k += 1;
            }
            if kept as usize != n {
                return Err(ConvertError::Episode {
                    at: at().into(),
                    message: format!("decoded {kept} frames after the trimmed start, expected {n}"),
                });
            }
            if self.videos {
                let dst = self
                    .root
                    .join("videos")
                    .join(index.to_string())
                    .join(format!("{c}.mp4"));
                fs_err::create_dir_all(dst.parent().expect("has parent"))?;
                if part.temporary {
                    fs_err::rename(&part.path, &dst)?;
                } else {
                    fs_err::copy(&part.path, &dst)?;
                }
            } else if part.temporary {
                let _ = fs_err::remove_file(&part.path);
            }
        }
        self.episode_ends.push((start as usize + n) as i64);
        self.episode_ids.push(ep.id);
        Ok(())
    }

    /// Completes the arrays' metadata, writes `meta/episode_ends` and the name map.
    pub fn finish(self) -> Result<(), ConvertError> {
        let err = zarr_err(&self.zarr);
        let total = self.frames() as u64;
        let cameras: Vec<String> = self.images.iter().map(|i| i.name.clone()).collect();
        for s in [self.action, self.state, self.timestamp] {
            s.finish(&self.codec, &self.meta).map_err(&err)?;
        }
        for mut img in self.images {
            let (h, w) = (u64::from(img.height), u64::from(img.width));
            img.array
                .set_shape(vec![total, h, w, 3])
                .map_err(|e| err(e.to_string()))?;
            img.array
                .store_metadata_opt(&self.meta)
                .map_err(|e| err(e.to_string()))?;
        }
        let n = self.episode_ends.len() as u64;
        let array = Array::new_with_metadata(
            self.store.clone(),
            "/meta/episode_ends",
            metadata(&self.zarr, &[n], &[n.max(1)], "<i8", false)?,
        )
        .map_err(|e| err(e.to_string()))?;
        array
            .store_metadata_opt(&self.meta)
            .map_err(|e| err(e.to_string()))?;
        if n > 0 {
            array
                .store_array_subset_opt(&array.subset_all(), &self.episode_ends[..], &self.codec)
                .map_err(|e| err(e.to_string()))?;
        }
        if self.videos {
            let map = json!({
                "cameras": cameras,
                "episodes": self.episode_ids,
            });
            write_json(&self.root.join("videos").join("name_map.json"), &map)?;
        }
        Ok(())
    }
}
