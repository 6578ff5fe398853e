//! The Warp batch renderer (`--renderer warp`): MuJoCo Warp's ray tracer, on a CUDA GPU
//! or Warp's CPU device, in a Python worker process of its own.
//!
//! Why a worker process: MuJoCo Warp is a Python library (its kernels are Warp Python
//! compiled at run time), so embedding it means embedding CPython in every binary and
//! worker; a child process keeps this binary free of Python, lets one Python environment
//! (setup.sh's or the wheel's `[warp]` extra) serve any number of runs, and turns a crash
//! of the GPU stack into an error naming it. The pipe carries ~50 bytes per geom and frame
//! in and 4 bytes per pixel out; the worker script is compiled into this binary
//! (`python/warp_worker.py`), so the wheel and the release bundle carry it unchanged.
//!
//! The world is MuJoCo's, simulated here: each batch carries the geoms' world poses of
//! its frames (what MuJoCo's OpenGL renderer draws from too), so the worker needs no
//! physics and no per-episode model edits; each *world* of a batch is one image (one
//! frame, one replay, one camera) with its own view, lights, headlight and table look.

use std::collections::{BTreeMap, VecDeque};
use std::io::{BufRead, BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use mujoco_rs::prelude::{MjData, MjModel};
use mujoco_rs::wrappers::mj_model::traits::ModelType;
use serde::{Deserialize, Serialize};

use crate::error::SimError;
use crate::render::{CameraView, Frame, RenderSettings};

/// The worker script, run as `python -c`.
const WORKER_SCRIPT: &str = include_str!("../python/warp_worker.py");

/// The Python packages the worker needs, pinned (`scripts/setup.sh --warp`, the wheel's
/// `[warp]` extra).
pub const WARP_PINS: [(&str, &str); 3] = [
    ("mujoco", "3.17.0"),
    ("mujoco-warp", "3.17.0"),
    ("warp-lang", "1.19.0"),
];

/// The variable naming the worker's Python (one with [`WARP_PINS`] installed).
pub const PYTHON_VARIABLE: &str = "DEXJOCO_WARP_PYTHON";

/// Largest JSON header accepted from the worker.
const MAX_HEADER: u32 = 1 << 24;

/// Which renderer draws the frames.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RendererKind {
    /// MuJoCo's own OpenGL renderer through EGL (the reference's look; the default).
    #[default]
    Opengl,
    /// MuJoCo Warp's batch ray tracer in a worker process.
    Warp,
}

impl RendererKind {
    /// `opengl` or `warp`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Opengl => "opengl",
            Self::Warp => "warp",
        }
    }

    /// Whether this is the default (for `skip_serializing_if`).
    pub fn is_opengl(&self) -> bool {
        *self == Self::Opengl
    }
}

/// How to start the worker.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct WarpOptions {
    /// The Python to run it with; `None`: found (see [`python_candidates`]).
    pub python: Option<PathBuf>,
    /// `auto` (the first CUDA device, else the CPU), `cpu` or `cuda:N`.
    pub device: String,
    /// Worlds (images) per batch; `None`: 2048 on a GPU, 16 on the CPU.
    pub worlds: Option<usize>,
    /// Rays per pixel and axis (supersampling); `None`: 2 where the quality asks for
    /// multisampling, else 1.
    pub supersample: Option<u32>,
}

impl Default for WarpOptions {
    fn default() -> Self {
        Self {
            python: None,
            device: "auto".into(),
            worlds: None,
            supersample: None,
        }
    }
}

/// Where the worker's Python is looked for when neither `--warp-python` nor
/// `$DEXJOCO_WARP_PYTHON` names one (those are used as given), in order: the Python of
/// the environment this program was installed into (the wheel's `[warp]` extra); the
/// active `$VIRTUAL_ENV`; the environment `scripts/setup.sh --warp` makes. The first
/// that imports `mujoco_warp` is taken.
pub fn python_candidates() -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Some(bin) = std::env::current_exe()
        .ok()
        .and_then(|e| e.canonicalize().ok())
        .and_then(|e| e.parent().map(Path::to_path_buf))
    {
        out.push(bin.join("python"));
    }
    if let Some(v) = std::env::var_os("VIRTUAL_ENV") {
        out.push(PathBuf::from(v).join("bin/python"));
    }
    out.push(setup_venv().join("bin/python"));
    out
}

/// The environment `scripts/setup.sh --warp` makes:
/// `${XDG_CACHE_HOME:-~/.cache}/dexjoco-data/venv-warp-<mujoco-warp version>`.
pub fn setup_venv() -> PathBuf {
    let cache = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
        .unwrap_or_else(|| PathBuf::from(".cache"));
    cache
        .join("dexjoco-data")
        .join(format!("venv-warp-{}", WARP_PINS[1].1))
}

/// What the worker said about itself.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct WorkerInfo {
    /// The Python that runs it.
    pub python: PathBuf,
    /// Warp's device (`cpu`, `cuda:0`).
    pub device: String,
    /// The device's name (the GPU's model).
    pub device_name: String,
    /// Python and the pinned packages' versions.
    pub versions: BTreeMap<String, Option<String>>,
}

impl WorkerInfo {
    /// `warp 3.17.0 on cuda:0 (NVIDIA H200)`, as records name their renderer.
    pub fn describe(&self) -> String {
        let v = self
            .versions
            .get("mujoco-warp")
            .cloned()
            .flatten()
            .unwrap_or_default();
        if self.device == "cpu" {
            format!("warp {v} on cpu")
        } else {
            format!("warp {v} on {} ({})", self.device, self.device_name)
        }
    }
}

/// A running worker process.
pub struct WarpWorker {
    child: Child,
    stdin: BufWriter<ChildStdin>,
    stdout: BufReader<ChildStdout>,
    stderr: Arc<Mutex<VecDeque<String>>>,
    info: WorkerInfo,
    supersample: Option<u32>,
    worlds: Option<usize>,
}

impl WarpWorker {
    /// Starts the worker with the first Python of [`python_candidates`] (or the one
    /// given) and checks it has the pinned packages.
    pub fn start(options: &WarpOptions) -> Result<Self, SimError> {
        let explicit = options
            .python
            .clone()
            .or_else(|| std::env::var_os(PYTHON_VARIABLE).map(PathBuf::from));
        let python = match explicit {
            Some(p) => p,
            None => python_candidates()
                .into_iter()
                .find(|p| p.is_file() && has_warp(p))
                .ok_or_else(|| {
                    SimError::Warp(format!(
                        "no Python with MuJoCo Warp found (tried the Python beside this \
                         program, $VIRTUAL_ENV's and {}); run `scripts/setup.sh --warp` or \
                         `pip install 'dexjoco-data[warp]'`, or name one with --warp-python or \
                         ${PYTHON_VARIABLE}",
                        setup_venv().display()
                    ))
                })?,
        };
        let mut child = Command::new(&python)
            .args(["-u", "-c", WORKER_SCRIPT])
            .env("PYTHONUNBUFFERED", "1")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| SimError::Warp(format!("cannot start {}: {e}", python.display())))?;
        let stderr = Arc::new(Mutex::new(VecDeque::new()));
        let tail = Arc::clone(&stderr);
        let err = child.stderr.take().expect("piped");
        std::thread::spawn(move || {
            for line in BufReader::new(err).lines().map_while(Result::ok) {
                tracing::debug!(target: "warp_worker", "{line}");
                let mut t = tail.lock().expect("tail");
                if t.len() == 20 {
                    t.pop_front();
                }
                t.push_back(line);
            }
        });
        let stdin = BufWriter::new(child.stdin.take().expect("piped"));
        let stdout = BufReader::new(child.stdout.take().expect("piped"));
        let mut worker = Self {
            child,
            stdin,
            stdout,
            stderr,
            info: WorkerInfo {
                python: python.clone(),
                device: String::new(),
                device_name: String::new(),
                versions: BTreeMap::new(),
            },
            supersample: options.supersample,
            worlds: options.worlds,
        };
        let (hello, _) = worker
            .call(
                &serde_json::json!({"op": "hello", "device": options.device}),
                &[],
            )
            .map_err(|e| {
                SimError::Warp(format!(
                    "{} cannot run the worker ({e}); run `scripts/setup.sh --warp` or `pip \
                     install 'dexjoco-data[warp]'` and use that Python",
                    python.display()
                ))
            })?;
        let info: HelloReply = serde_json::from_value(hello)
            .map_err(|e| SimError::Warp(format!("unexpected hello from the worker: {e}")))?;
        worker.info.device = info.device;
        worker.info.device_name = info.device_name;
        worker.info.versions = info.versions;
        worker.check_pins()?;
        Ok(worker)
    }

    /// What the worker runs on.
    pub fn info(&self) -> &WorkerInfo {
        &self.info
    }

    /// Images per batch: as asked, else 2048 on a GPU and 16 on the CPU.
    pub fn batch_worlds(&self) -> usize {
        self.worlds
            .unwrap_or(if self.info.device == "cpu" { 16 } else { 2048 })
            .max(1)
    }

    fn check_pins(&self) -> Result<(), SimError> {
        for (package, pin) in WARP_PINS {
            let have = self.info.versions.get(package).cloned().flatten();
            if have.as_deref() != Some(pin) {
                return Err(SimError::Warp(format!(
                    "{} has {package} {}, the Warp renderer needs {pin}; run `scripts/setup.sh \
                     --warp` or `pip install 'dexjoco-data[warp]'`",
                    self.info.python.display(),
                    have.as_deref().unwrap_or("missing")
                )));
            }
        }
        Ok(())
    }

    /// One request and its reply: JSON header and payload each way.
    fn call(
        &mut self,
        request: &serde_json::Value,
        payload: &[u8],
    ) -> Result<(serde_json::Value, Vec<u8>), SimError> {
        let sent = self.send(request, payload);
        let reply = sent.and_then(|()| self.receive());
        let (header, data) = reply.map_err(|e| self.died(&e))?;
        if header.get("ok") != Some(&serde_json::Value::Bool(true)) {
            let error = header
                .get("error")
                .and_then(|e| e.as_str())
                .unwrap_or("no message");
            tracing::debug!(
                trace = header.get("trace").and_then(|t| t.as_str()),
                "warp worker"
            );
            return Err(SimError::Warp(format!("the worker failed: {error}")));
        }
        Ok((header, data))
    }

    fn send(&mut self, request: &serde_json::Value, payload: &[u8]) -> std::io::Result<()> {
        let body = serde_json::to_vec(request).expect("json");
        self.stdin.write_all(&(body.len() as u32).to_le_bytes())?;
        self.stdin
            .write_all(&(payload.len() as u64).to_le_bytes())?;
        self.stdin.write_all(&body)?;
        self.stdin.write_all(payload)?;
        self.stdin.flush()
    }

    fn receive(&mut self) -> std::io::Result<(serde_json::Value, Vec<u8>)> {
        let mut head = [0u8; 12];
        self.stdout.read_exact(&mut head)?;
        let json_len = u32::from_le_bytes(head[..4].try_into().expect("4"));
        let payload_len = u64::from_le_bytes(head[4..].try_into().expect("8"));
        if json_len > MAX_HEADER {
            return Err(std::io::Error::other(format!(
                "a reply header of {json_len} bytes"
            )));
        }
        let mut body = vec![0u8; json_len as usize];
        self.stdout.read_exact(&mut body)?;
        let header = serde_json::from_slice(&body).map_err(std::io::Error::other)?;
        let mut data = Vec::new();
        (&mut self.stdout)
            .take(payload_len)
            .read_to_end(&mut data)?;
        if data.len() as u64 != payload_len {
            return Err(std::io::Error::other("the reply ended early"));
        }
        Ok((header, data))
    }

    /// The error of a broken pipe: the worker's last words.
    fn died(&mut self, e: &std::io::Error) -> SimError {
        let status = self.child.try_wait().ok().flatten();
        // Give the stderr reader a moment to collect what the worker printed last.
        std::thread::sleep(std::time::Duration::from_millis(100));
        let tail: Vec<String> = self.stderr.lock().expect("tail").iter().cloned().collect();
        SimError::Warp(format!(
            "the worker ({}) stopped answering ({e}; exit: {}); its last output:\n{}",
            self.info.python.display(),
            status.map_or_else(|| "running".into(), |s| s.to_string()),
            tail.join("\n")
        ))
    }
}

impl Drop for WarpWorker {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[derive(Deserialize)]
struct HelloReply {
    device: String,
    device_name: String,
    versions: BTreeMap<String, Option<String>>,
}

/// Whether `python` imports `mujoco_warp` (a quick probe before starting the worker).
fn has_warp(python: &Path) -> bool {
    Command::new(python)
        .args(["-c", "import mujoco_warp"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

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

/// One world's look: view, lights, headlight and table.
#[derive(Debug, Clone, PartialEq)]
pub struct WorldView {
    /// Camera position (world frame).
    pub cam_pos: [f64; 3],
    /// Camera orientation, row-major (columns: right, up, backwards), as `cam_xmat`.
    pub cam_mat: [f64; 9],
    /// Vertical field of view, degrees.
    pub fovy: f64,
    /// The scene's lights, in id order.
    pub lights: Vec<LightState>,
    /// Headlight ambient RGB.
    pub head_ambient: [f64; 3],
    /// Headlight diffuse RGB.
    pub head_diffuse: [f64; 3],
    /// The table-top geom's material id (-1: none, its colour then).
    pub table_matid: i32,
    /// The table-top geom's colour.
    pub table_rgba: [f32; 4],
}

/// One light as it shines in a world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightState {
    /// Position (world frame).
    pub pos: [f64; 3],
    /// Direction.
    pub dir: [f64; 3],
    /// Diffuse RGB.
    pub diffuse: [f64; 3],
}

impl WorldView {
    /// The scene as it is in `data` seen from `view`: the model's lights, headlight and
    /// table-top look (`table_geom`).
    pub fn of<M: ModelType>(
        model: &MjModel,
        data: &MjData<M>,
        view: CameraView,
        table_geom: usize,
    ) -> Self {
        let (cam_pos, cam_mat, fovy) = camera_pose(model, data, view);
        let head = &model.ffi().vis.headlight;
        let lights = (0..model.ffi().nlight as usize)
            .map(|i| LightState {
                pos: data.light_xpos()[i],
                dir: data.light_xdir()[i],
                diffuse: model.light_diffuse()[i].map(f64::from),
            })
            .collect();
        Self {
            cam_pos,
            cam_mat,
            fovy,
            lights,
            head_ambient: head.ambient.map(f64::from),
            head_diffuse: head.diffuse.map(f64::from),
            table_matid: model.geom_matid()[table_geom],
            table_rgba: model.geom_rgba()[table_geom],
        }
    }
}

/// Position, orientation and field of view of `view` as MuJoCo's renderer places it: a
/// model camera where `data` has it; the free camera as `mjv_updateCamera` computes it.
pub fn camera_pose<M: ModelType>(
    model: &MjModel,
    data: &MjData<M>,
    view: CameraView,
) -> ([f64; 3], [f64; 9], f64) {
    match view {
        CameraView::Fixed(id) => (
            data.cam_xpos()[id],
            data.cam_xmat()[id],
            model.cam_fovy()[id],
        ),
        CameraView::Orbit {
            lookat,
            distance,
            azimuth,
            elevation,
        } => {
            let (sa, ca) = azimuth.to_radians().sin_cos();
            let (se, ce) = elevation.to_radians().sin_cos();
            let fwd = [ca * ce, sa * ce, se];
            let up = [-ca * se, -sa * se, ce];
            let right = [
                fwd[1] * up[2] - fwd[2] * up[1],
                fwd[2] * up[0] - fwd[0] * up[2],
                fwd[0] * up[1] - fwd[1] * up[0],
            ];
            let pos = [0, 1, 2].map(|i| lookat[i] - distance * fwd[i]);
            let mat = [
                right[0], up[0], -fwd[0], right[1], up[1], -fwd[1], right[2], up[2], -fwd[2],
            ];
            (pos, mat, f64::from(model.ffi().vis.global.fovy))
        }
    }
}

/// Frames' geom poses and the worlds (images) to render from them, all through one view
/// slot (one field of view: see [`WarpRenderer::open`]).
#[derive(Debug, Clone, Default)]
pub struct WarpBatch {
    slot: usize,
    frames: usize,
    geom_xpos: Vec<f32>,
    geom_xmat: Vec<f32>,
    worlds: Vec<(usize, WorldView)>,
}

impl WarpBatch {
    /// An empty batch for view slot `slot`.
    pub fn new(slot: usize) -> Self {
        Self {
            slot,
            ..Self::default()
        }
    }

    /// Its view slot.
    pub fn slot(&self) -> usize {
        self.slot
    }

    /// Adds the geom poses of `data`'s state; returns its frame index in the batch.
    pub fn push_frame<M: ModelType>(&mut self, data: &MjData<M>) -> usize {
        self.geom_xpos
            .extend(data.geom_xpos().iter().flatten().map(|&v| v as f32));
        self.geom_xmat
            .extend(data.geom_xmat().iter().flatten().map(|&v| v as f32));
        self.frames += 1;
        self.frames - 1
    }

    /// Adds an image of frame `frame` seen as `view` says.
    pub fn push_world(&mut self, frame: usize, view: WorldView) {
        debug_assert!(frame < self.frames);
        self.worlds.push((frame, view));
    }

    /// Images in the batch.
    pub fn worlds(&self) -> usize {
        self.worlds.len()
    }

    /// Frames in the batch.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Empties the batch (its slot stays).
    pub fn clear(&mut self) {
        *self = Self::new(self.slot);
    }

    /// The request payload, in the order the worker's `unpack` reads it.
    fn payload(&self, nlight: usize) -> Result<Vec<u8>, SimError> {
        let mut out = Vec::with_capacity((self.geom_xpos.len() + self.geom_xmat.len()) * 4);
        let f32s = |out: &mut Vec<u8>, v: &mut dyn Iterator<Item = f32>| {
            for x in v {
                out.extend_from_slice(&x.to_le_bytes());
            }
        };
        let f = |v: f64| v as f32;
        f32s(&mut out, &mut self.geom_xpos.iter().copied());
        f32s(&mut out, &mut self.geom_xmat.iter().copied());
        for (frame, _) in &self.worlds {
            out.extend_from_slice(&(*frame as i32).to_le_bytes());
        }
        let w = &self.worlds;
        if let Some((_, bad)) = w.iter().find(|(_, v)| v.lights.len() != nlight) {
            return Err(SimError::Warp(format!(
                "a world has {} lights, the scene {nlight}",
                bad.lights.len()
            )));
        }
        f32s(&mut out, &mut w.iter().flat_map(|(_, v)| v.cam_pos.map(f)));
        f32s(&mut out, &mut w.iter().flat_map(|(_, v)| v.cam_mat.map(f)));
        let lights = |g: fn(&LightState) -> [f64; 3]| {
            w.iter()
                .flat_map(move |(_, v)| v.lights.iter().flat_map(move |l| g(l).map(f)))
        };
        f32s(&mut out, &mut lights(|l| l.pos));
        f32s(&mut out, &mut lights(|l| l.dir));
        f32s(&mut out, &mut lights(|l| l.diffuse));
        f32s(
            &mut out,
            &mut w.iter().flat_map(|(_, v)| v.head_ambient.map(f)),
        );
        f32s(
            &mut out,
            &mut w.iter().flat_map(|(_, v)| v.head_diffuse.map(f)),
        );
        for (_, v) in w {
            out.extend_from_slice(&v.table_matid.to_le_bytes());
        }
        f32s(&mut out, &mut w.iter().flat_map(|(_, v)| v.table_rgba));
        Ok(out)
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
    ) -> Result<Self, SimError> {
        let q = settings.quality;
        let mut request = serde_json::json!({
            "op": "open",
            "device": worker.info.device,
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
        let (reply, _) = worker.call(&request, &[])?;
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
    pub fn slot_of(&self, fovy: f64) -> Result<usize, SimError> {
        self.slots.iter().position(|&s| s == fovy).ok_or_else(|| {
            SimError::Warp(format!(
                "no view slot of field of view {fovy} (opened with {:?})",
                self.slots
            ))
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
    pub fn render(&mut self, batch: &WarpBatch) -> Result<Vec<Frame>, SimError> {
        let n = batch.worlds();
        if n == 0 {
            return Ok(Vec::new());
        }
        if n > self.worlds {
            return Err(SimError::Warp(format!(
                "a batch of {n} images; the renderer was opened for {}",
                self.worlds
            )));
        }
        let fovy = self.slots.get(batch.slot).copied();
        if let Some((_, v)) = batch.worlds.iter().find(|(_, v)| Some(v.fovy) != fovy) {
            return Err(SimError::Warp(format!(
                "a world of field of view {} in a batch of slot {} ({fovy:?})",
                v.fovy, batch.slot
            )));
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
        let (reply, data) = self.worker.call(&request, &payload)?;
        let got = Instant::now();
        let reply: RenderReply = serde_json::from_value(reply)
            .map_err(|e| SimError::Warp(format!("unexpected render reply: {e}")))?;
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

    /// RGB (and depth) frames from the reply's packed pixels.
    fn unpack(&self, n: usize, worlds: usize, data: &[u8]) -> Result<Vec<Frame>, SimError> {
        let (w, h) = (self.settings.width, self.settings.height);
        let pixels = w as usize * h as usize;
        let depth = self.settings.depth;
        let expect = n * pixels * 4 * if depth { 2 } else { 1 };
        if worlds != n || data.len() != expect {
            return Err(SimError::Warp(format!(
                "the worker answered {worlds} images in {} bytes, expected {n} in {expect}",
                data.len()
            )));
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

/// Adds `other`'s times to `into` (for callers that keep running totals).
pub fn add_times(into: &mut WarpTimes, other: &WarpTimes) {
    into.add(other);
}

/// The field of view of `view` in `model` (degrees): the camera's, or the free camera's.
pub fn view_fovy(model: &MjModel, view: CameraView) -> f64 {
    match view {
        CameraView::Fixed(id) => model.cam_fovy()[id],
        CameraView::Orbit { .. } => f64::from(model.ffi().vis.global.fovy),
    }
}

/// The distinct fields of view of `views`, in first-seen order: the slots to open.
pub fn view_slots(model: &MjModel, views: impl IntoIterator<Item = CameraView>) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::new();
    for v in views {
        let f = view_fovy(model, v);
        if !out.contains(&f) {
            out.push(f);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pins_are_those_setup_and_the_wheel_install() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let requirements =
            fs_err::read_to_string(root.join("scripts/warp-requirements.txt")).unwrap();
        let pyproject = fs_err::read_to_string(root.join("pyproject.toml")).unwrap();
        for (package, version) in WARP_PINS {
            let pin = format!("{package}=={version}");
            assert!(requirements.lines().any(|l| l.trim() == pin), "{pin}");
            assert!(
                pyproject.contains(&format!("\"{pin};")),
                "{pin} in pyproject"
            );
        }
    }

    #[test]
    fn the_free_camera_looks_at_its_point_from_its_distance() {
        let model = MjModel::from_xml_string("<mujoco><worldbody/></mujoco>").unwrap();
        let data = MjData::new(&model);
        let view = CameraView::Orbit {
            lookat: [0.0, 0.0, 1.0],
            distance: 2.0,
            azimuth: 90.0,
            elevation: -30.0,
        };
        let (pos, mat, fovy) = camera_pose(&model, &data, view);
        // Backwards (column 2) points from the look-at point to the camera.
        let back = [mat[2], mat[5], mat[8]];
        for i in 0..3 {
            let expect = ([0.0, 0.0, 1.0][i] + 2.0 * back[i] - pos[i]).abs();
            assert!(expect < 1e-12, "{pos:?} {back:?}");
        }
        assert!(pos[2] > 1.0, "elevation -30 looks down from above");
        assert_eq!(fovy, f64::from(model.ffi().vis.global.fovy));
        // Orthonormal.
        let col = |c: usize| [mat[c], mat[3 + c], mat[6 + c]];
        for a in 0..3 {
            for b in 0..3 {
                let d: f64 = (0..3).map(|i| col(a)[i] * col(b)[i]).sum();
                assert!((d - f64::from(u8::from(a == b))).abs() < 1e-12);
            }
        }
    }
}
