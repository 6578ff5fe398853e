//! The rendering errors, each naming the device, worker, file or scene concerned.

use std::path::PathBuf;

use dexjoco_sim::SimError;

/// Errors of the renderers, visual randomization and image files.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RenderError {
    /// The scene itself failed (loading it, a name it lacks).
    #[error(transparent)]
    Sim(#[from] SimError),
    /// No EGL device could open an offscreen OpenGL context.
    #[error("offscreen rendering is not available: {0}")]
    Egl(#[from] EglError),
    /// An image size the renderer cannot draw (empty, or larger than it or the device
    /// allows).
    #[error("rendering failed: image size {width}x{height}{}", limit_words(*max, device.as_deref()))]
    ImageSize {
        /// Width asked for.
        width: u32,
        /// Height asked for.
        height: u32,
        /// The largest side allowed (0: the size is empty).
        max: u32,
        /// The EGL device whose limit it is (`None`: the renderer's own limit).
        device: Option<String>,
    },
    /// Reading the pixels back failed.
    #[error("rendering failed: {0}")]
    ReadPixels(String),
    /// The Warp renderer's worker could not start or failed.
    #[error("warp renderer: {0}")]
    Warp(Box<WarpError>),
    /// Writing an image failed.
    #[error("cannot write image '{path}': {message}")]
    Image {
        /// The image file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A camera pool file is malformed or cannot be read.
    #[error("camera pool '{}': {message}", path.display())]
    Pool {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The scene lacks something visual randomization needs (the table-top geom).
    #[error("the scene has no {kind} '{name}'")]
    SceneLacks {
        /// Object kind.
        kind: &'static str,
        /// The name.
        name: String,
    },
}

/// The end of an [`RenderError::ImageSize`] message: why the size cannot be drawn.
fn limit_words(max: u32, device: Option<&str>) -> String {
    match (max, device) {
        (0, _) => " is empty".into(),
        (max, None) => format!(": the renderer draws at most {max} pixels a side"),
        (max, Some(d)) => {
            format!(": EGL device {d} draws at most {max} pixels a side (GL_MAX_RENDERBUFFER_SIZE)")
        }
    }
}

/// Why no offscreen OpenGL context opened through EGL.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EglError {
    /// EGL could not list its devices (no libEGL, or no vendor library).
    #[error(
        "cannot list EGL devices ({source}); is libEGL installed (Debian: libegl1 libegl-mesa0 libgl1-mesa-dri)?"
    )]
    List {
        /// EGL's error.
        source: glutin::error::Error,
    },
    /// `DEXJOCO_EGL_DEVICE` is not a device index.
    #[error(
        "{}='{value}' is not an EGL device index: give a number from the list of `dexjoco-data doctor`",
        crate::EGL_DEVICE_ENV
    )]
    NotAnIndex {
        /// The variable's value.
        value: String,
    },
    /// EGL lists no device at all.
    #[error("EGL lists no device")]
    NoDevice,
    /// The device asked for is not in EGL's list.
    #[error("EGL device {index} does not exist: EGL lists {count} device(s) ({listed})")]
    NoSuchDevice {
        /// The index asked for.
        index: usize,
        /// Devices EGL lists.
        count: usize,
        /// Those devices, `0 (software), 1 (/dev/dri/renderD128)`.
        listed: String,
    },
    /// Every device tried failed to open a context.
    #[error("{}", attempts.iter().map(|a| format!("device {} ({}): {}", a.index, a.device, a.source)).collect::<Vec<_>>().join("; "))]
    NoContext {
        /// Each device tried, in order, and why it failed.
        attempts: Vec<DeviceAttempt>,
    },
    /// The context could not be made current on this thread.
    #[error("{source}")]
    MakeCurrent {
        /// EGL's error.
        source: glutin::error::Error,
    },
}

/// One device on which no context opened, and why.
#[derive(Debug)]
pub struct DeviceAttempt {
    /// The device's index in EGL's list.
    pub index: usize,
    /// The device, in words.
    pub device: String,
    /// EGL's error.
    pub source: glutin::error::Error,
}

impl From<WarpError> for RenderError {
    fn from(e: WarpError) -> Self {
        Self::Warp(Box::new(e))
    }
}

/// Why the Warp renderer's worker could not start, or what went wrong with a batch.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum WarpError {
    /// No Python with MuJoCo Warp was found.
    #[error(
        "no Python with MuJoCo Warp found (tried the Python beside this program, $VIRTUAL_ENV's and {}); run `scripts/setup.sh --warp` or `pip install 'dexjoco-data[warp]'`, or name one with --warp-python or ${variable}",
        setup_venv.display()
    )]
    NoPython {
        /// The setup script's venv, tried last.
        setup_venv: PathBuf,
        /// The environment variable that names a Python.
        variable: &'static str,
    },
    /// The Python could not be started.
    #[error("cannot start {}: {source}", python.display())]
    Start {
        /// The Python.
        python: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The Python started but cannot run the worker (MuJoCo Warp missing, or broken).
    #[error(
        "{} cannot run the worker ({reason}); run `scripts/setup.sh --warp` or `pip install 'dexjoco-data[warp]'` and use that Python",
        python.display()
    )]
    CannotRun {
        /// The Python.
        python: PathBuf,
        /// What happened when it was asked.
        reason: Box<RenderError>,
    },
    /// The worker's greeting or a reply is not what this program speaks.
    #[error("unexpected {what} from the worker: {source}")]
    Protocol {
        /// `hello` or `render reply`.
        what: &'static str,
        /// The parse error.
        source: serde_json::Error,
    },
    /// A package of the worker's Python is not the version the renderer needs.
    #[error(
        "{} has {package} {}, the Warp renderer needs {pin}; run `scripts/setup.sh --warp` or `pip install 'dexjoco-data[warp]'`",
        python.display(), found.as_deref().unwrap_or("missing")
    )]
    Pin {
        /// The Python.
        python: PathBuf,
        /// The package.
        package: String,
        /// Its version there (`None`: not installed).
        found: Option<String>,
        /// The version needed.
        pin: String,
    },
    /// The worker reported an error (its own words).
    #[error("the worker failed: {0}")]
    Failed(String),
    /// The worker stopped answering.
    #[error(
        "the worker ({}) stopped answering ({source}; exit: {exit}); its last output:\n{}",
        python.display(), output.join("\n")
    )]
    Stopped {
        /// The Python.
        python: PathBuf,
        /// The read or write that failed.
        source: std::io::Error,
        /// Its exit status, or `running`.
        exit: String,
        /// Its last lines on stderr.
        output: Vec<String>,
    },
    /// A view's field of view has no slot in the opened renderer.
    #[error("no view slot of field of view {fovy} (opened with {slots:?})")]
    NoSlot {
        /// The field of view asked for.
        fovy: f64,
        /// The slots opened.
        slots: Vec<f64>,
    },
    /// More images in a batch than the renderer was opened for.
    #[error("a batch of {images} images; the renderer was opened for {worlds}")]
    BatchTooLarge {
        /// Images in the batch.
        images: usize,
        /// Worlds opened.
        worlds: usize,
    },
    /// A world's field of view is not its batch's slot's.
    #[error("a world of field of view {fovy} in a batch of slot {slot} ({slot_fovy:?})")]
    WrongSlot {
        /// The world's field of view.
        fovy: f64,
        /// The batch's slot.
        slot: usize,
        /// That slot's field of view.
        slot_fovy: Option<f64>,
    },
    /// A world's lights do not match the scene's.
    #[error("a world has {world} lights, the scene {scene}")]
    Lights {
        /// The world's.
        world: usize,
        /// The scene's.
        scene: usize,
    },
    /// The reply's size is not the images asked for.
    #[error(
        "the worker answered {worlds} images in {bytes} bytes, expected {images} in {expected}"
    )]
    ReplySize {
        /// Images answered.
        worlds: usize,
        /// Bytes answered.
        bytes: usize,
        /// Images asked for.
        images: usize,
        /// Bytes expected.
        expected: usize,
    },
}
