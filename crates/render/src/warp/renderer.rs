//! A scene opened in a Warp worker: renders batches of worlds into frames and keeps the
//! time each stage took.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use mujoco_rs::prelude::MjModel;
use serde::Deserialize;

use super::worker::WarpWorker;
use super::worker::WorkerInfo;
use super::world::WarpBatch;
use crate::error::{RenderError, WarpError};
use crate::render::{Frame, RenderSettings};

/// A scene as the worker compiles it: the MJCF file, or the XML text of a built-in one.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SceneXml {
    /// An MJCF file (its assets beside it).
    Path(PathBuf),
    /// XML text with no file assets.
    Text(String),
}

/// Seconds the Warp renderer spent per stage, summed.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct WarpTimes {
    /// Images rendered.
    pub frames: u64,
    /// Batches.
    pub batches: u64,
    /// Packing a batch here and sending it (the pipe).
    pub send: f64,
    /// The worker unpacking it and copying it to the device.
    pub upload: f64,
    /// BVH refit and ray tracing, on the device.
    pub render: f64,
    /// Copying the images back to the worker's memory.
    pub readback: f64,
    /// Receiving them here and unpacking into RGB frames.
    pub receive: f64,
}

impl WarpTimes {
    fn add(&mut self, o: &Self) {
        self.frames += o.frames;
        self.batches += o.batches;
        self.send += o.send;
        self.upload += o.upload;
        self.render += o.render;
        self.readback += o.readback;
        self.receive += o.receive;
    }
}

#[derive(Deserialize)]
struct RenderReply {
    worlds: usize,
    times: BTreeMap<String, f64>,
}

/// A scene opened in a worker: renders batches of worlds.
pub struct WarpRenderer {
    worker: WarpWorker,
    settings: RenderSettings,
    worlds: usize,
    nlight: usize,
    table_geom: usize,
    slots: Vec<f64>,
    times: WarpTimes,
    open_seconds: f64,
}

impl WarpRenderer {
    /// Opens `scene` (whose compiled model is `model`) in `worker` for batches of up to
    /// `worlds` images of `settings`' size; `table_geom` is the geom whose look worlds set;
    /// `slots` the fields of view (degrees) of the views to render, one camera each (rays
    /// are precomputed per camera, which supersampling needs; see [`view_slots`]).
    pub fn open(
        mut worker: WarpWorker,
        scene: &SceneXml,
        model: &MjModel,
        settings: RenderSettings,
        worlds: usize,
        table_geom: usize,
        slots: &[f64],
    ) -> Result<Self, RenderError> {
        let q = settings.quality;
        let mut request = serde_json::json!({
            "op": "open",
            "device": worker.info().device,
            "width": settings.width,
            "height": settings.height,
            "worlds": worlds.max(1),
            "slots": slots,
            "depth": settings.depth,
            "shadows": q.shadows,
            "skybox": q.skybox,
            // Rays per pixel and axis: 2x2 stand for multisampling unless told.
            "samples_per_pixel": worker.supersample.unwrap_or(if q.samples > 0 { 2 } else { 1 }),
            "expect": {
                "ngeom": model.ffi().ngeom,
                "nlight": model.ffi().nlight,
                "nmat": model.ffi().nmat,
            },
        });
        match scene {
            SceneXml::Path(p) => request["xml_path"] = p.display().to_string().into(),
            SceneXml::Text(t) => request["xml"] = t.clone().into(),
        }
        let (reply, _) = worker.call(&request, &[], 0)?;
        let open_seconds = reply
            .get("open_seconds")
            .and_then(serde_json::Value::as_f64)
            .unwrap_or(0.0);
        Ok(Self {
            worker,
            settings,
            worlds: worlds.max(1),
            nlight: model.ffi().nlight as usize,
            table_geom,
            slots: slots.to_vec(),
            times: WarpTimes::default(),
            open_seconds,
        })
    }

    /// The slot rendering views of field of view `fovy`.
    pub fn slot_of(&self, fovy: f64) -> Result<usize, RenderError> {
        self.slots.iter().position(|&s| s == fovy).ok_or_else(|| {
            WarpError::NoSlot {
                fovy,
                slots: self.slots.clone(),
            }
            .into()
        })
    }

    /// The worker's device and versions.
    pub fn info(&self) -> &WorkerInfo {
        self.worker.info()
    }

    /// Images per batch at most.
    pub fn worlds(&self) -> usize {
        self.worlds
    }

    /// The settings it renders with.
    pub fn settings(&self) -> RenderSettings {
        self.settings
    }

    /// Seconds the worker took to compile the scene and build its context.
    pub fn open_seconds(&self) -> f64 {
        self.open_seconds
    }

    /// The times of the batches since the last call.
    pub fn take_times(&mut self) -> WarpTimes {
        std::mem::take(&mut self.times)
    }

    /// Renders every world of `batch`, in order.
    pub fn render(&mut self, batch: &WarpBatch) -> Result<Vec<Frame>, RenderError> {
        let n = batch.worlds();
        if n == 0 {
            return Ok(Vec::new());
        }
        if n > self.worlds {
            return Err(WarpError::BatchTooLarge {
                images: n,
                worlds: self.worlds,
            }
            .into());
        }
        let fovy = self.slots.get(batch.slot).copied();
        if let Some((_, v)) = batch.worlds.iter().find(|(_, v)| Some(v.fovy) != fovy) {
            return Err(WarpError::WrongSlot {
                fovy: v.fovy,
                slot: batch.slot,
                slot_fovy: fovy,
            }
            .into());
        }
        let started = Instant::now();
        let payload = batch.payload(self.nlight)?;
        let request = serde_json::json!({
            "op": "render",
            "slot": batch.slot,
            "frames": batch.frames(),
            "worlds": n,
            "table_geom": self.table_geom,
        });
        let expect = self.reply_bytes(n);
        let (reply, data) = self.worker.call(&request, &payload, expect)?;
        let got = Instant::now();
        let reply: RenderReply =
            serde_json::from_value(reply).map_err(|source| WarpError::Protocol {
                what: "render reply",
                source,
            })?;
        let frames = self.unpack(n, reply.worlds, &data)?;
        let t = |k: &str| reply.times.get(k).copied().unwrap_or(0.0);
        let worker = t("upload") + t("render") + t("readback");
        self.times.add(&WarpTimes {
            frames: n as u64,
            batches: 1,
            send: ((got - started).as_secs_f64() - worker).max(0.0),
            upload: t("upload"),
            render: t("render"),
            readback: t("readback"),
            receive: got.elapsed().as_secs_f64(),
        });
        Ok(frames)
    }

    /// The bytes of `n` images as the worker packs them: 4 per pixel, twice with depth.
    fn reply_bytes(&self, n: usize) -> usize {
        let pixels = self.settings.width as usize * self.settings.height as usize;
        n * pixels * 4 * if self.settings.depth { 2 } else { 1 }
    }

    /// RGB (and depth) frames from the reply's packed pixels.
    fn unpack(&self, n: usize, worlds: usize, data: &[u8]) -> Result<Vec<Frame>, RenderError> {
        let (w, h) = (self.settings.width, self.settings.height);
        let pixels = w as usize * h as usize;
        let depth = self.settings.depth;
        let expect = self.reply_bytes(n);
        if worlds != n || data.len() != expect {
            return Err(WarpError::ReplySize {
                worlds,
                bytes: data.len(),
                images: n,
                expected: expect,
            }
            .into());
        }
        let (rgb, depths) = data.split_at(n * pixels * 4);
        Ok((0..n)
            .map(|i| {
                let px = &rgb[i * pixels * 4..(i + 1) * pixels * 4];
                let mut out = Vec::with_capacity(pixels * 3);
                for p in px.chunks_exact(4) {
                    // Little-endian 0xAARRGGBB: bytes B, G, R, A.
                    out.extend_from_slice(&[p[2], p[1], p[0]]);
                }
                let depth = depth.then(|| {
                    depths[i * pixels * 4..(i + 1) * pixels * 4]
                        .chunks_exact(4)
                        .map(|b| f32::from_le_bytes(b.try_into().expect("4")))
                        .collect()
                });
                Frame {
                    width: w,
                    height: h,
                    rgb: out,
                    depth,
                }
            })
            .collect())
    }
}
