//! Headless OpenGL contexts through EGL devices (EGL_EXT_platform_device): Mesa's
//! software rasterizer on CPU machines, the NVIDIA driver on GPU machines.

use std::ffi::{CStr, c_char};
use std::num::NonZeroU32;

use glutin::api::egl::{
    context::PossiblyCurrentContext, device::Device, display::Display, surface::Surface,
};
use glutin::config::{ConfigSurfaceTypes, ConfigTemplateBuilder};
use glutin::context::{ContextApi, ContextAttributesBuilder, GlProfile, Version};
use glutin::display::GetDisplayExtensions;
use glutin::prelude::{GlDisplay, NotCurrentGlContext, PossiblyCurrentGlContext};
use glutin::surface::{PbufferSurface, SurfaceAttributesBuilder};
use serde::Serialize;

use crate::error::{DeviceAttempt, EglError, RenderError};

/// Environment variable that picks an EGL device by its index in [`probe_egl`]'s list.
pub const EGL_DEVICE_ENV: &str = "DEXJOCO_EGL_DEVICE";

/// An EGL device as [`probe_egl`] and the renderer report it.
#[derive(Debug, Clone, Serialize)]
pub struct EglDevice {
    /// Index in EGL's device list.
    pub index: usize,
    /// DRM node, `software`, or the device's name.
    pub description: String,
    /// True for a software rasterizer (Mesa llvmpipe).
    pub software: bool,
    /// EGL vendor string of the device, when it has one.
    pub vendor: Option<String>,
    /// `GL_RENDERER` of a context opened on it (e.g. `llvmpipe (LLVM 15.0.6, 256 bits)`).
    pub gl_renderer: Option<String>,
    /// `GL_VERSION` of that context.
    pub gl_version: Option<String>,
    /// Why no context opened on it, when none did.
    pub error: Option<String>,
}

impl EglDevice {
    /// `GL_RENDERER (software|GPU)`, as benchmark tables name the device.
    pub fn label(&self) -> String {
        format!(
            "{} ({})",
            self.gl_renderer.as_deref().unwrap_or("unknown GL"),
            if self.software { "software" } else { "GPU" }
        )
    }
}

/// Every EGL device and whether an offscreen context opens on it.
#[derive(Debug, Clone, Serialize)]
pub struct EglProbe {
    /// The devices in EGL's order.
    pub devices: Vec<EglDevice>,
    /// Index of the device the renderer uses ([`EGL_DEVICE_ENV`], else the first GPU that
    /// works, else the first software device that works).
    pub selected: Option<usize>,
}

/// An offscreen GL context, current on the thread that created it.
pub(crate) struct EglContext {
    context: PossiblyCurrentContext,
    /// A pbuffer, for drivers without surfaceless contexts; `None`: bound with no surface.
    surface: Option<Surface<PbufferSurface>>,
    pub(crate) device: EglDevice,
    /// `glFinish` of this context's driver, when it has one.
    finish: Option<GlFinish>,
    /// `GL_MAX_RENDERBUFFER_SIZE`: the largest offscreen buffer side, when the driver says.
    max_renderbuffer: Option<u32>,
}

/// `void glFinish(void)`.
type GlFinish = unsafe extern "C" fn();

impl std::fmt::Debug for EglContext {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EglContext")
            .field("device", &self.device)
            .finish()
    }
}

fn describe(device: &Device) -> (String, bool) {
    let software = device.extensions().contains("EGL_MESA_device_software");
    let name = if let Some(path) = device.drm_device_node_path() {
        path.display().to_string()
    } else if software {
        "software".to_owned()
    } else {
        device.name().unwrap_or("unnamed").to_owned()
    };
    (name, software)
}

fn devices() -> Result<Vec<Device>, RenderError> {
    Device::query_devices()
        .map(|d| d.collect())
        .map_err(|source| EglError::List { source }.into())
}

/// The device index [`EGL_DEVICE_ENV`] asks for (`None` when it is unset or empty); a
/// value that is not an index is an error, not a silent default.
pub fn requested_egl_device() -> Result<Option<usize>, RenderError> {
    let Some(value) = std::env::var_os(EGL_DEVICE_ENV) else {
        return Ok(None);
    };
    let value = value.to_string_lossy();
    let value = value.trim();
    if value.is_empty() {
        return Ok(None);
    }
    value.parse().map(Some).map_err(|_| {
        EglError::NotAnIndex {
            value: value.into(),
        }
        .into()
    })
}

/// Device indices in the order they are tried: hardware (GPU) devices first, in EGL's
/// order, then software ones (Mesa's llvmpipe), so a GPU node renders on its GPU even
/// when EGL lists the software device first.
fn preferred_order(devices: &[Device]) -> Vec<usize> {
    let software: Vec<bool> = devices.iter().map(|d| describe(d).1).collect();
    let mut order: Vec<usize> = (0..devices.len()).filter(|&i| !software[i]).collect();
    order.extend((0..devices.len()).filter(|&i| software[i]));
    order
}

/// Reads a GL string of the current context.
fn gl_string(display: &Display, name: u32) -> Option<String> {
    type GetString = unsafe extern "C" fn(u32) -> *const c_char;
    let f = display.get_proc_address(c"glGetString");
    if f.is_null() {
        return None;
    }
    // SAFETY: `glGetString` has this signature in every GL version; a context is current on
    // this thread (callers only use it after `make_current`), and the returned string is
    // static NUL-terminated storage owned by the driver (or null, handled below).
    unsafe {
        let get: GetString = std::mem::transmute::<*const std::ffi::c_void, GetString>(f);
        let s = get(name);
        (!s.is_null()).then(|| CStr::from_ptr(s).to_string_lossy().into_owned())
    }
}

/// Reads a GL integer of the current context.
fn gl_integer(display: &Display, name: u32) -> Option<i32> {
    type GetIntegerv = unsafe extern "C" fn(u32, *mut i32);
    let f = display.get_proc_address(c"glGetIntegerv");
    if f.is_null() {
        return None;
    }
    let mut value = 0i32;
    // SAFETY: `glGetIntegerv` has this signature in every GL version; a context is current
    // on this thread (callers only use it after `make_current`), and the names asked for
    // here have one value, written to the local.
    unsafe {
        let get: GetIntegerv = std::mem::transmute::<*const std::ffi::c_void, GetIntegerv>(f);
        get(name, &raw mut value);
    }
    (value > 0).then_some(value)
}

impl EglContext {
    /// Opens a context with a pbuffer of `width` x `height` on the selected device: the one
    /// named by [`EGL_DEVICE_ENV`], else the first GPU that opens one, else the first
    /// software device.
    pub(crate) fn new(width: u32, height: u32) -> Result<Self, RenderError> {
        Self::open(requested_egl_device()?, width, height)
    }

    /// Opens a context on device `requested`, or with `None` on the first GPU that opens
    /// one, else the first software device.
    fn open(requested: Option<usize>, width: u32, height: u32) -> Result<Self, RenderError> {
        let devices = devices()?;
        if devices.is_empty() {
            return Err(EglError::NoDevice.into());
        }
        let order: Vec<usize> = match requested {
            Some(i) if i < devices.len() => vec![i],
            Some(i) => {
                return Err(EglError::NoSuchDevice {
                    index: i,
                    count: devices.len(),
                    listed: listed(&devices),
                }
                .into());
            }
            None => preferred_order(&devices),
        };
        let mut attempts = Vec::new();
        for i in order {
            match Self::on_device(i, &devices[i], width, height) {
                Ok(c) => return Ok(c),
                Err(source) => attempts.push(DeviceAttempt {
                    index: i,
                    device: describe(&devices[i]).0,
                    source,
                }),
            }
        }
        Err(EglError::NoContext { attempts }.into())
    }

    fn on_device(
        index: usize,
        device: &Device,
        width: u32,
        height: u32,
    ) -> Result<Self, glutin::error::Error> {
        // SAFETY: `device` comes from EGL's own device list.
        let display = unsafe { Display::with_device(device, None)? };
        let template = ConfigTemplateBuilder::new()
            .with_surface_type(ConfigSurfaceTypes::PBUFFER)
            .with_alpha_size(0)
            .with_depth_size(24)
            .with_stencil_size(8)
            .build();
        // SAFETY: `display` is valid and the template asks for standard attributes.
        let config = unsafe { display.find_configs(template)? }
            .next()
            .ok_or_else(|| {
                glutin::error::Error::from(glutin::error::ErrorKind::NotSupported(
                    "no pbuffer config with depth 24",
                ))
            })?;
        let attrs = ContextAttributesBuilder::new()
            .with_profile(GlProfile::Compatibility)
            .with_context_api(ContextApi::OpenGl(Some(Version::new(2, 0))))
            .build(None);
        // Bound with no surface where the driver allows it, as MuJoCo's own EGL backend
        // does: MuJoCo then draws only into its offscreen framebuffer and sees no window
        // one (with a pbuffer, NVIDIA's driver raised GL_INVALID_OPERATION in
        // mjr_makeContext, printed as a warning for every renderer). Else, or when that
        // fails, a pbuffer.
        let surfaceless = display
            .extensions()
            .contains("EGL_KHR_surfaceless_context")
            // SAFETY: display and config are valid; MuJoCo needs a compatibility profile.
            .then(|| unsafe { display.create_context(&config, &attrs) })
            .transpose()?
            .and_then(|c| c.make_current_surfaceless().ok());
        let (context, surface) = match surfaceless {
            Some(context) => (context, None),
            None => {
                // SAFETY: as above.
                let not_current = unsafe { display.create_context(&config, &attrs)? };
                let w = NonZeroU32::new(width.max(1)).expect("max(1)");
                let h = NonZeroU32::new(height.max(1)).expect("max(1)");
                let surface_attrs = SurfaceAttributesBuilder::<PbufferSurface>::new().build(w, h);
                // SAFETY: display and config are valid; the size is non-zero.
                let surface = unsafe { display.create_pbuffer_surface(&config, &surface_attrs)? };
                (not_current.make_current(&surface)?, Some(surface))
            }
        };
        let (description, software) = describe(device);
        let device = EglDevice {
            index,
            description,
            software,
            vendor: device.vendor().map(str::to_owned),
            gl_renderer: gl_string(&display, 0x1F01),
            gl_version: gl_string(&display, 0x1F02),
            error: None,
        };
        let max_renderbuffer = gl_integer(&display, 0x84E8).map(|v| v as u32);
        let finish = display.get_proc_address(c"glFinish");
        // SAFETY: `glFinish` has this signature in every GL version; null means absent.
        let finish = (!finish.is_null())
            .then(|| unsafe { std::mem::transmute::<*const std::ffi::c_void, GlFinish>(finish) });
        Ok(Self {
            context,
            surface,
            device,
            finish,
            max_renderbuffer,
        })
    }

    /// The largest offscreen buffer side this context's driver draws
    /// (`GL_MAX_RENDERBUFFER_SIZE`), when it says.
    pub(crate) fn max_renderbuffer_size(&self) -> Option<u32> {
        self.max_renderbuffer
    }

    /// Waits until the GL commands issued so far have completed (`glFinish`), so that a
    /// timer tells rasterization from the read-back that follows. Pixels are unaffected.
    pub(crate) fn finish(&self) {
        if let Some(f) = self.finish {
            // SAFETY: this context is current on this thread (the renderer made it so
            // before drawing); glFinish takes no arguments.
            unsafe { f() }
        }
    }

    /// Makes the context current on this thread.
    pub(crate) fn make_current(&self) -> Result<(), RenderError> {
        match &self.surface {
            Some(surface) => self.context.make_current(surface),
            None => self.context.make_current_surfaceless(),
        }
        .map_err(|source| EglError::MakeCurrent { source }.into())
    }
}

/// `0 (software), 1 (/dev/dri/renderD128)`: the devices as EGL lists them.
fn listed(devices: &[Device]) -> String {
    devices
        .iter()
        .enumerate()
        .map(|(i, d)| format!("{i} ({})", describe(d).0))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The EGL devices as EGL lists them (index, description, software or not), from EGL's
/// list alone: no context is opened, so this is cheap.
pub fn list_egl_devices() -> Result<Vec<EglDevice>, RenderError> {
    Ok(devices()?
        .iter()
        .enumerate()
        .map(|(index, d)| {
            let (description, software) = describe(d);
            EglDevice {
                index,
                description,
                software,
                vendor: d.vendor().map(str::to_owned),
                gl_renderer: None,
                gl_version: None,
                error: None,
            }
        })
        .collect())
}

/// Opens an offscreen context on device `device` (with `None`, the one the renderer
/// would choose: [`EGL_DEVICE_ENV`], else the first GPU that works, else the first
/// software device) and closes it again: whether this process can render there, before
/// any work is spent. Returns the device, with its GL strings.
pub fn probe_renderer(device: Option<usize>) -> Result<EglDevice, RenderError> {
    let device = match device {
        Some(i) => Some(i),
        None => requested_egl_device()?,
    };
    EglContext::open(device, 16, 16).map(|c| c.device.clone())
}

/// Indices of the EGL devices that are GPUs (not a software rasterizer), from EGL's list
/// alone: no context is opened, so this is cheap.
pub fn gpu_devices() -> Result<Vec<usize>, RenderError> {
    Ok(devices()?
        .iter()
        .enumerate()
        .filter(|(_, d)| !describe(d).1)
        .map(|(i, _)| i)
        .collect())
}

/// Lists the EGL devices and tries to open an offscreen context on each (for `doctor`).
pub fn probe_egl() -> Result<EglProbe, RenderError> {
    let list = devices()?;
    let mut out = Vec::new();
    for (i, device) in list.iter().enumerate() {
        match EglContext::on_device(i, device, 16, 16) {
            Ok(ctx) => out.push(ctx.device.clone()),
            Err(e) => {
                let (description, software) = describe(device);
                out.push(EglDevice {
                    index: i,
                    description,
                    software,
                    vendor: device.vendor().map(str::to_owned),
                    gl_renderer: None,
                    gl_version: None,
                    error: Some(e.to_string()),
                });
            }
        }
    }
    let selected = match requested_egl_device()? {
        Some(i) => out.get(i).filter(|d| d.error.is_none()).map(|d| d.index),
        None => preferred_order(&list)
            .into_iter()
            .find(|&i| out[i].error.is_none()),
    };
    Ok(EglProbe {
        devices: out,
        selected,
    })
}

/// Gives one of `processes` rendering processes its share of the cores for Mesa's
/// llvmpipe, which otherwise gives each process a raster thread per core (N processes
/// would oversubscribe the cores N times over). A value the user set is kept; other
/// drivers ignore the variable.
pub fn share_llvmpipe_threads(cmd: &mut std::process::Command, processes: usize) {
    const LP_THREADS_ENV: &str = "LP_NUM_THREADS";
    if std::env::var_os(LP_THREADS_ENV).is_none() {
        let cores = dexjoco_core::available_cores();
        cmd.env(
            LP_THREADS_ENV,
            (cores / processes.max(1)).max(1).to_string(),
        );
    }
}
