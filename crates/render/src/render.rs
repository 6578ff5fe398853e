//! Offscreen rendering of a MuJoCo scene: RGB and metric depth, with quality presets.

use std::path::Path;
use std::time::Instant;

use mujoco_rs::mujoco_c::mjtRndFlag;
use mujoco_rs::prelude::{
    MjData, MjModel, MjrContext, MjrRectangle, MjtCamera, MjvCamera, MjvOption, MjvPerturb,
    MjvScene,
};
use mujoco_rs::wrappers::mj_model::traits::ModelType;
use serde::{Deserialize, Serialize};

use crate::egl::{EglContext, EglDevice};
use crate::error::RenderError;
use crate::geometry::Geometry;

/// What the renderer spends time on. Multisampling, shadows, reflections and the skybox
/// each cost about as much as the geometry itself on a CPU rasterizer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct RenderQuality {
    /// Multisampling samples per pixel (0 = off; the DexJoCo reference uses 8).
    pub samples: u32,
    /// Shadow maps.
    pub shadows: bool,
    /// Reflective materials (the floor, the table).
    pub reflection: bool,
    /// The skybox texture.
    pub skybox: bool,
}

impl RenderQuality {
    /// As the DexJoCo reference renders: 8 samples, shadows, reflection, skybox.
    pub const PAPER: Self = Self {
        samples: 8,
        shadows: true,
        reflection: true,
        skybox: true,
    };
    /// Everything off: the fastest look that still shows materials, textures and lights.
    pub const FAST: Self = Self {
        samples: 0,
        shadows: false,
        reflection: false,
        skybox: false,
    };

    /// Named presets, from the most to the least expensive.
    pub const PRESETS: [(&'static str, Self); 4] = [
        ("paper", Self::PAPER),
        (
            "no-msaa",
            Self {
                samples: 0,
                ..Self::PAPER
            },
        ),
        (
            "no-msaa-no-shadows",
            Self {
                samples: 0,
                shadows: false,
                ..Self::PAPER
            },
        ),
        ("fast", Self::FAST),
    ];

    /// The preset's name, or `custom`.
    pub fn name(&self) -> &'static str {
        Self::PRESETS
            .iter()
            .find(|(_, q)| q == self)
            .map_or("custom", |(n, _)| n)
    }

    /// A preset by name (`paper`, `no-msaa`, `no-msaa-no-shadows`, `fast`).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::PRESETS
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, q)| *q)
    }
}

/// Image size and quality of a renderer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct RenderSettings {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Quality preset.
    pub quality: RenderQuality,
    /// Also read back depth (metres).
    pub depth: bool,
    /// The meshes as they are, or simplified for the image size (opt-in; not written when
    /// full, so settings and reports made before it read the same).
    #[serde(default, skip_serializing_if = "Geometry::is_full")]
    pub geometry: Geometry,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            width: 640,
            height: 640,
            quality: RenderQuality::FAST,
            depth: false,
            geometry: Geometry::Full,
        }
    }
}

/// Where to look from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum CameraView {
    /// A camera of the model, by id.
    Fixed(usize),
    /// An orbit camera around `lookat` (MuJoCo's free camera; elevation negative = above).
    Orbit {
        /// Point looked at (world frame).
        lookat: [f64; 3],
        /// Distance from it, metres.
        distance: f64,
        /// Azimuth, degrees.
        azimuth: f64,
        /// Elevation, degrees (negative looks down).
        elevation: f64,
    },
}

impl CameraView {
    fn to_mjv(self) -> MjvCamera {
        match self {
            Self::Fixed(id) => MjvCamera::new_fixed(id),
            Self::Orbit {
                lookat,
                distance,
                azimuth,
                elevation,
            } => MjvCamera {
                type_: MjtCamera::mjCAMERA_FREE as i32,
                fixedcamid: -1,
                trackbodyid: -1,
                lookat,
                distance,
                azimuth,
                elevation,
                orthographic: 0,
            },
        }
    }
}

/// One rendered image: RGB rows top to bottom, and depth in metres when asked for.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// RGB8, row-major, top row first.
    pub rgb: Vec<u8>,
    /// Distance along the view axis in metres (linearized z-buffer), top row first.
    pub depth: Option<Vec<f32>>,
}

impl Frame {
    /// RGB of pixel (x, y), y from the top.
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// Depth of pixel (x, y) in metres, when depth was rendered.
    pub fn depth_at(&self, x: u32, y: u32) -> Option<f32> {
        self.depth
            .as_ref()
            .map(|d| d[y as usize * self.width as usize + x as usize])
    }

    /// Writes the RGB image as PNG.
    pub fn save_png(&self, path: &Path) -> Result<(), RenderError> {
        image::save_buffer(
            path,
            &self.rgb,
            self.width,
            self.height,
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| RenderError::Image {
            path: path.into(),
            message: e.to_string(),
        })
    }

    /// Writes depth as a 16-bit grey PNG, near (dark) to far (light) over this frame's
    /// finite range; returns that range in metres.
    pub fn save_depth_png(&self, path: &Path) -> Result<Option<(f32, f32)>, RenderError> {
        let Some(depth) = &self.depth else {
            return Ok(None);
        };
        let (lo, hi) = depth
            .iter()
            .filter(|v| v.is_finite())
            .fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        let span = (hi - lo).max(f32::EPSILON);
        let grey: Vec<u16> = depth
            .iter()
            .map(|&v| (((v - lo) / span).clamp(0.0, 1.0) * 65535.0) as u16)
            .collect();
        let img =
            image::ImageBuffer::<image::Luma<u16>, _>::from_raw(self.width, self.height, grey)
                .ok_or_else(|| RenderError::Image {
                    path: path.into(),
                    message: "size mismatch".into(),
                })?;
        img.save(path).map_err(|e| RenderError::Image {
            path: path.into(),
            message: e.to_string(),
        })?;
        Ok(Some((lo, hi)))
    }
}

/// Seconds a renderer spent per stage of its frames, summed (see [`Renderer::take_times`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RenderTimes {
    /// Frames drawn.
    pub frames: u64,
    /// Building the abstract scene from the simulation state (`mjv_updateScene`).
    pub scene: f64,
    /// Drawing it (`mjr_render`, until the driver has finished rasterizing: `glFinish`).
    pub render: f64,
    /// Reading the pixels back into memory (`mjr_readPixels`), flipped top-down (and
    /// depth linearized).
    pub readback: f64,
}

/// An offscreen renderer for one model, owned by one thread (its GL context is bound to
/// the thread that created it).
#[derive(Debug)]
pub struct Renderer {
    // Field order matters for Drop: the MuJoCo GL objects go before the context they live in.
    scene: MjvScene,
    context: MjrContext,
    egl: EglContext,
    option: MjvOption,
    settings: RenderSettings,
    near: f32,
    far: f32,
    times: RenderTimes,
    /// The context holds simplified meshes (light geometry).
    lightened: bool,
    /// Mesh triangles the context holds.
    triangles: usize,
    /// The GL context is bound to the creating thread: keep the renderer there.
    _not_send: std::marker::PhantomData<*const ()>,
}

impl Drop for Renderer {
    fn drop(&mut self) {
        // MuJoCo frees its GL objects (MjrContext's drop) in whatever context is current:
        // make it ours, in case another renderer on this thread drew last.
        let _ = self.egl.make_current();
    }
}

/// The largest image side the renderer draws, in pixels: H.264's largest level (6.2,
/// 8192 x 4320) and ffmpeg's largest picture are above it only for shapes no camera
/// here has, and an 8192 x 8192 frame with 8x multisampling already takes 4 GB of
/// buffers. A device whose `GL_MAX_RENDERBUFFER_SIZE` is smaller limits it further.
pub const MAX_IMAGE_SIDE: u32 = 8192;

impl Renderer {
    /// Creates a renderer for `model` on this thread.
    pub fn new(model: &MjModel, settings: RenderSettings) -> Result<Self, RenderError> {
        let RenderSettings {
            width,
            height,
            quality,
            geometry,
            ..
        } = settings;
        if width == 0 || height == 0 {
            return Err(RenderError::ImageSize {
                width,
                height,
                max: 0,
                device: None,
            });
        }
        if width.max(height) > MAX_IMAGE_SIDE {
            return Err(RenderError::ImageSize {
                width,
                height,
                max: MAX_IMAGE_SIDE,
                device: None,
            });
        }
        let egl = EglContext::new(width, height)?;
        if let Some(max) = egl.max_renderbuffer_size()
            && width.max(height) > max
        {
            return Err(RenderError::ImageSize {
                width,
                height,
                max,
                device: Some(egl.device.label()),
            });
        }
        // The meshes the context uploads: the model's, or simplified ones (the copy is only
        // read here; scenes are built from the simulation's own model).
        let lightened = (geometry == Geometry::Light)
            .then(|| crate::geometry::lighten(model, Geometry::max_error(height)));
        let (drawn, triangles) = match &lightened {
            Some(l) => (&l.model, l.triangles_after),
            None => (model, crate::geometry::mesh_triangles(model)),
        };
        // SAFETY: the EGL context created above is current on this thread, stays on it (the
        // Renderer owns it and is not Send) and outlives `context` (field order).
        let mut context = unsafe { MjrContext::new(drawn) };
        context.offscreen();
        // The offscreen buffer's sample count is taken at creation from the model; set ours
        // and re-create the buffer. mjr_resizeOffscreen skips same-size calls, hence the
        // detour through another size.
        // SAFETY: plain field write on an initialized context.
        unsafe { context.ffi_mut().offSamples = quality.samples as i32 };
        context.resize_offscreen(width + 1, height);
        context.resize_offscreen(width, height);
        context.offscreen();

        let mut scene = MjvScene::new(model, model.ffi().ngeom as usize + 100);
        // SAFETY: writing scene flags (plain bytes) of an initialized scene.
        unsafe {
            let flags = &mut scene.ffi_mut().flags;
            flags[mjtRndFlag::mjRND_SHADOW as usize] = quality.shadows as u8;
            flags[mjtRndFlag::mjRND_REFLECTION as usize] = quality.reflection as u8;
            flags[mjtRndFlag::mjRND_SKYBOX as usize] = quality.skybox as u8;
        }
        let extent = model.ffi().stat.extent as f32;
        let map = &model.ffi().vis.map;
        Ok(Self {
            scene,
            context,
            egl,
            option: MjvOption::default(),
            settings,
            near: map.znear * extent,
            far: map.zfar * extent,
            times: RenderTimes::default(),
            lightened: lightened.is_some(),
            triangles,
            _not_send: std::marker::PhantomData,
        })
    }

    /// The EGL device this renderer draws on.
    pub fn device(&self) -> &EglDevice {
        &self.egl.device
    }

    /// Mesh triangles it draws at most (fewer with the light geometry).
    pub fn triangles(&self) -> usize {
        self.triangles
    }

    /// Size and quality.
    pub fn settings(&self) -> RenderSettings {
        self.settings
    }

    /// Builds the abstract scene from `data` as seen from `view`.
    pub fn update_scene<M: ModelType>(&mut self, data: &mut MjData<M>, view: CameraView) {
        let started = Instant::now();
        let mut cam = view.to_mjv();
        self.scene
            .update(data, &self.option, &MjvPerturb::default(), &mut cam);
        self.times.scene += started.elapsed().as_secs_f64();
    }

    /// The time spent per stage since the renderer was created or this was last called.
    pub fn take_times(&mut self) -> RenderTimes {
        std::mem::take(&mut self.times)
    }

    /// The abstract scene, for per-render visual edits (lights, materials) before [`Self::draw`].
    pub fn scene_mut(&mut self) -> &mut MjvScene {
        &mut self.scene
    }

    /// The geoms of the abstract scene built by [`Self::update_scene`], for per-render
    /// material/colour edits (`matid`, `rgba`) before [`Self::draw`].
    pub fn scene_geoms_mut(&mut self) -> &mut [mujoco_rs::wrappers::mj_visualization::MjvGeom] {
        // SAFETY: the slice covers the `ngeom` initialized geoms of the scene buffer, which
        // this renderer owns; plain-data fields are edited between update and draw.
        unsafe { self.scene.geoms_mut() }
    }

    /// Draws the current abstract scene and reads back the image.
    pub fn draw(&mut self) -> Result<Frame, RenderError> {
        let (w, h) = (self.settings.width as usize, self.settings.height as usize);
        self.egl.make_current()?;
        let started = Instant::now();
        let vp = MjrRectangle::new(0, 0, w as i32, h as i32);
        if self.lightened {
            // SAFETY: the context was made from a copy of the scene's model that differs only
            // in its mesh faces (fewer per mesh, in the same arrays): every id mjr_render
            // reads from the scene (geoms, meshes, materials, textures, skins) indexes the
            // context's arrays as it would for the model itself; the context is current.
            // (`MjvScene::render` refuses it only because the face counts differ.)
            unsafe {
                mujoco_rs::mujoco_c::mjr_render(vp, self.scene.ffi_mut(), self.context.ffi());
            }
        } else {
            self.scene.render(&vp, &self.context);
        }
        // Rasterization ends here rather than inside the read-back, so that the two are
        // timed apart; the read-back would wait for it anyway.
        self.egl.finish();
        let drawn = Instant::now();
        let mut rgb = vec![0u8; w * h * 3];
        let mut depth = self.settings.depth.then(|| vec![0f32; w * h]);
        self.context
            .read_pixels(Some(&mut rgb), depth.as_deref_mut(), &vp)
            .map_err(|e| RenderError::ReadPixels(e.to_string()))?;
        flip_rows(&mut rgb, w * 3);
        if let Some(d) = depth.as_mut() {
            flip_rows(d, w);
            let (near, far) = (self.near, self.far);
            for v in d.iter_mut() {
                *v = near / (1.0 - *v * (1.0 - near / far));
            }
        }
        self.times.frames += 1;
        self.times.render += (drawn - started).as_secs_f64();
        self.times.readback += drawn.elapsed().as_secs_f64();
        Ok(Frame {
            width: w as u32,
            height: h as u32,
            rgb,
            depth,
        })
    }

    /// Updates the scene from `data` and draws it from `view`.
    pub fn render<M: ModelType>(
        &mut self,
        data: &mut MjData<M>,
        view: CameraView,
    ) -> Result<Frame, RenderError> {
        self.update_scene(data, view);
        self.draw()
    }
}

/// OpenGL reads bottom-up; images are stored top-down.
fn flip_rows<T>(buf: &mut [T], row: usize) {
    let rows = buf.len() / row;
    for i in 0..rows / 2 {
        let (top, bottom) = buf.split_at_mut((rows - 1 - i) * row);
        top[i * row..(i + 1) * row].swap_with_slice(&mut bottom[..row]);
    }
}
