//! MuJoCo scenes: loading an MJCF file or string into a model, with the version check
//! and the name lookups the rest of the crate uses.

use std::ffi::CStr;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use mujoco_rs::mujoco_c::mj_versionString;
use mujoco_rs::prelude::{MjModel, MjtObjBase};

use crate::error::SimError;

/// MuJoCo's version string, e.g. `3.17.0`.
pub fn mujoco_version() -> String {
    // SAFETY: mj_versionString returns a pointer to a static NUL-terminated string.
    unsafe {
        CStr::from_ptr(mj_versionString())
            .to_string_lossy()
            .into_owned()
    }
}

/// Sends MuJoCo's warnings to the log (`tracing`, target `mujoco`, on stderr) instead of
/// MuJoCo's default, a `printf` to stdout: stdout carries a command's results (`doctor
/// --json`) and a worker process's messages, which a stray line would corrupt. Call once,
/// early; later calls do nothing.
pub fn route_mujoco_warnings() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // SAFETY: MuJoCo reads this hook when it warns; it is set once, before any model is
        // loaded or any other thread uses MuJoCo, to a function that matches its signature.
        unsafe { mujoco_rs::mujoco_c::mju_user_warning = Some(log_warning) }
    });
}

/// MuJoCo's warning hook: the message to the log.
unsafe extern "C" fn log_warning(message: *const std::ffi::c_char) {
    if message.is_null() {
        return;
    }
    // SAFETY: MuJoCo passes a NUL-terminated message that lives for the call.
    let text = unsafe { CStr::from_ptr(message) }.to_string_lossy();
    tracing::warn!(target: "mujoco", "{}", text.trim());
}

/// The path of the loaded `libmujoco.so`, read from the process's memory map.
pub fn mujoco_library_path() -> Option<PathBuf> {
    // Touch the library so it is mapped before we look.
    let _ = mujoco_version();
    let maps = fs_err::read_to_string("/proc/self/maps").ok()?;
    maps.lines()
        .filter_map(|l| l.split_whitespace().nth(5))
        .find(|p| p.contains("libmujoco"))
        .map(PathBuf::from)
}

/// A compiled MuJoCo scene: the model, shared read-only between worker threads.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The compiled model (`Send + Sync`).
    pub model: Arc<MjModel>,
    /// The file it was loaded from.
    pub path: PathBuf,
}

impl Scene {
    /// Compiles an MJCF file. A missing asset is reported with its file name.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, SimError> {
        let path = path.as_ref().to_path_buf();
        if !path.is_file() {
            return Err(SimError::Missing(path));
        }
        let model = MjModel::from_xml(&path).map_err(|e| SimError::Load {
            path: path.clone(),
            message: e.to_string(),
        })?;
        Ok(Self {
            model: Arc::new(model),
            path,
        })
    }

    /// Compiles an MJCF document given as a string (assets resolve against the working
    /// directory); `label` names it in errors.
    pub fn from_xml_str(xml: &str, label: &str) -> Result<Self, SimError> {
        let model = MjModel::from_xml_string(xml).map_err(|e| SimError::Load {
            path: label.into(),
            message: e.to_string(),
        })?;
        Ok(Self {
            model: Arc::new(model),
            path: label.into(),
        })
    }

    /// Names of the scene's cameras, in id order.
    pub fn camera_names(&self) -> Vec<String> {
        (0..self.model.ffi().ncam as usize)
            .map(|i| {
                self.model
                    .id_to_name(MjtObjBase::mjOBJ_CAMERA, i)
                    .unwrap_or("")
                    .to_owned()
            })
            .collect()
    }

    /// The id of a named camera.
    pub fn camera_id(&self, name: &str) -> Result<usize, SimError> {
        self.model
            .name_to_id(MjtObjBase::mjOBJ_CAMERA, name)
            .ok_or_else(|| SimError::UnknownName {
                kind: "camera",
                name: name.into(),
                available: self.camera_names().join(", "),
            })
    }
}
