//! `dexjoco-data doctor`: what this machine has for the pipeline.

use std::path::PathBuf;
use std::process::Command;

use serde::Serialize;

use crate::exit::ExitStatus;
use crate::locate::Located;
use crate::settings::DoctorSettings;

/// MuJoCo version the project is built for.
const EXPECTED_MUJOCO: &str = "3.17.0";
/// Video encoders the pipeline can use, in order of preference per codec.
const ENCODERS: [&str; 6] = [
    "libx264",
    "libsvtav1",
    "libaom-av1",
    "h264_nvenc",
    "av1_nvenc",
    "libopenh264",
];
/// Python modules the test suite checks outputs with.
const PY_MODULES: [&str; 9] = [
    "numpy",
    "scipy",
    "sklearn",
    "zarr",
    "mcap",
    "lerobot",
    "av",
    "torchcodec",
    "mujoco",
];

#[derive(Debug, Serialize)]
struct Report {
    dexjoco_data: &'static str,
    mujoco: MujocoReport,
    egl: Result<dexjoco_render::EglProbe, String>,
    ffmpeg: Option<FfmpegReport>,
    python: Option<PythonReport>,
    sample_data: Option<Located>,
    reference_scenes: Option<Located>,
    /// The Warp batch renderer (optional): its worker's device and versions, or why not.
    warp: Result<dexjoco_render::warp::WorkerInfo, String>,
}

#[derive(Debug, Serialize)]
struct MujocoReport {
    version: String,
    library: Option<PathBuf>,
    expected: &'static str,
}

#[derive(Debug, Serialize)]
struct FfmpegReport {
    path: PathBuf,
    /// Where it was found (PATH, $DEXJOCO_FFMPEG, imageio-ffmpeg).
    found_by: String,
    /// ffprobe beside it or on PATH; without one, ffmpeg alone is asked.
    ffprobe: Option<PathBuf>,
    version: String,
    encoders: Vec<(String, bool)>,
}

#[derive(Debug, Serialize)]
struct PythonReport {
    interpreter: PathBuf,
    found_by: String,
    version: String,
    modules: Vec<(String, Option<String>)>,
}

fn ffmpeg() -> Option<FfmpegReport> {
    let found = dexjoco_video::locate_ffmpeg()?;
    let path = found.path.clone();
    let version = Command::new(&path).arg("-version").output().ok()?;
    let version = String::from_utf8_lossy(&version.stdout)
        .lines()
        .next()
        .unwrap_or("")
        .to_owned();
    let list = Command::new(&path)
        .args(["-hide_banner", "-encoders"])
        .output()
        .ok()?;
    let list = String::from_utf8_lossy(&list.stdout).into_owned();
    let encoders = ENCODERS
        .iter()
        .map(|e| {
            (
                e.to_string(),
                list.lines().any(|l| l.split_whitespace().nth(1) == Some(e)),
            )
        })
        .collect();
    Some(FfmpegReport {
        path,
        found_by: found.source.describe().to_owned(),
        ffprobe: dexjoco_video::locate_ffprobe(),
        version,
        encoders,
    })
}

fn python_report() -> Option<PythonReport> {
    let located = crate::locate::python()?;
    let (interpreter, found_by) = (located.path, located.how);
    let script = format!(
        "import importlib, sys\nprint(sys.version.split()[0])\nfor m in {:?}:\n    try:\n        mod = importlib.import_module(m)\n        print(m, getattr(mod, '__version__', 'present'))\n    except Exception:\n        print(m, '-')\n",
        PY_MODULES
    );
    let out = Command::new(&interpreter)
        .args(["-c", &script])
        .output()
        .ok()?;
    let text = String::from_utf8_lossy(&out.stdout);
    let mut lines = text.lines();
    let version = lines.next()?.to_owned();
    let modules = lines
        .filter_map(|l| l.split_once(' '))
        .map(|(m, v)| (m.to_owned(), (v != "-").then(|| v.to_owned())))
        .collect();
    Some(PythonReport {
        interpreter,
        found_by,
        version,
        modules,
    })
}

/// The encoder every command that writes videos needs.
const REQUIRED_ENCODER: &str = "libx264";

/// How to get an ffmpeg with libx264, system-wide or into the Python environment.
const INSTALL_FFMPEG: &str = "sudo apt install ffmpeg (Debian/Ubuntu; dnf install ffmpeg from RPM Fusion on RHEL), \
     or pip install 'dexjoco-data[ffmpeg]' (imageio-ffmpeg's static build)";

/// Whether ffmpeg was found and has [`REQUIRED_ENCODER`].
fn ffmpeg_ok(ffmpeg: Option<&FfmpegReport>) -> bool {
    ffmpeg.is_some_and(|f| {
        f.encoders
            .iter()
            .any(|(e, ok)| *ok && e == REQUIRED_ENCODER)
    })
}

/// Runs `doctor`; fails (exit 1) when MuJoCo or offscreen rendering is unusable, or
/// ffmpeg with libx264 is missing.
pub fn run(settings: DoctorSettings) -> anyhow::Result<ExitStatus> {
    let DoctorSettings { json } = settings;
    let report = Report {
        dexjoco_data: env!("CARGO_PKG_VERSION"),
        mujoco: MujocoReport {
            version: dexjoco_sim::mujoco_version(),
            library: dexjoco_sim::mujoco_library_path(),
            expected: EXPECTED_MUJOCO,
        },
        egl: dexjoco_render::probe_egl().map_err(|e| e.to_string()),
        ffmpeg: ffmpeg(),
        python: python_report(),
        sample_data: crate::locate::data_dir(),
        reference_scenes: crate::locate::reference_scenes(),
        warp:
            dexjoco_render::warp::WarpWorker::start(&dexjoco_render::warp::WarpOptions::default())
                .map(|w| w.info().clone())
                .map_err(|e| e.to_string()),
    };
    let mujoco_ok = report.mujoco.version == EXPECTED_MUJOCO;
    let egl_ok = report.egl.as_ref().is_ok_and(|p| p.selected.is_some());
    if json {
        outln!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_human(&report, mujoco_ok);
    }
    let ffmpeg_ok = ffmpeg_ok(report.ffmpeg.as_ref());
    Ok(if mujoco_ok && egl_ok && ffmpeg_ok {
        ExitStatus::Success
    } else {
        ExitStatus::Failure
    })
}

/// Prints the report for a person, one section per check.
fn print_human(r: &Report, mujoco_ok: bool) {
    outln!("dexjoco-data {}", r.dexjoco_data);
    outln!();
    print_mujoco(&r.mujoco, mujoco_ok);
    outln!();
    print_egl(&r.egl);
    outln!();
    print_ffmpeg(r.ffmpeg.as_ref());
    outln!();
    print_python(r.python.as_ref());
    outln!();
    print_sample_data(r.sample_data.as_ref());
    outln!();
    print_reference_scenes(r.reference_scenes.as_ref());
    outln!();
    print_warp(&r.warp);
}

/// Whether `--renderer warp` can run, and on which device (optional: not part of the
/// exit status).
fn print_warp(warp: &Result<dexjoco_render::warp::WorkerInfo, String>) {
    outln!("Warp batch renderer (--renderer warp; optional)");
    match warp {
        Ok(info) => {
            let version = |p: &str| info.versions.get(p).cloned().flatten().unwrap_or_default();
            outln!("  [ok  ] {}", info.describe());
            outln!(
                "         Python {} ({}), warp-lang {}",
                version("python"),
                info.python.display(),
                version("warp-lang")
            );
        }
        Err(e) => {
            outln!("  [absent] {e}");
        }
    }
}

/// MuJoCo's version and library.
fn print_mujoco(mujoco: &MujocoReport, mujoco_ok: bool) {
    outln!("MuJoCo");
    outln!(
        "  [{}] version {} (built for {})",
        if mujoco_ok { "ok  " } else { "WRONG" },
        mujoco.version,
        mujoco.expected
    );
    match &mujoco.library {
        Some(p) => outln!("         library {}", p.display()),
        None => outln!("         library (not found in the process map)"),
    }
}

/// How to get EGL and a driver behind it (pip cannot bring them).
const INSTALL_EGL: &str = "sudo apt install libegl1 libegl-mesa0 libgl1-mesa-dri (Mesa, rendering on the CPU; \
     RHEL: dnf install mesa-libEGL mesa-dri-drivers), or the NVIDIA driver's EGL on GPU nodes";

/// Each EGL device and whether it opens a context; a hint when none does.
fn print_egl(egl: &Result<dexjoco_render::EglProbe, String>) {
    outln!("Offscreen rendering (EGL)");
    match egl {
        Err(e) => {
            outln!("  [MISSING] {e}");
            outln!("  hint: {INSTALL_EGL}");
        }
        Ok(probe) => {
            for d in &probe.devices {
                let chosen = probe.selected == Some(d.index);
                let kind = if d.software {
                    "software (CPU)"
                } else {
                    "hardware (GPU)"
                };
                match (&d.gl_renderer, &d.error) {
                    (Some(gl), _) => outln!(
                        "  [{}] device {}: {} - {} - {}{}",
                        if chosen { "used" } else { "ok  " },
                        d.index,
                        d.description,
                        kind,
                        gl,
                        d.gl_version
                            .as_deref()
                            .map(|v| format!(" (OpenGL {v})"))
                            .unwrap_or_default()
                    ),
                    (None, e) => outln!(
                        "  [fail] device {}: {} - {} - {}",
                        d.index,
                        d.description,
                        kind,
                        e.as_deref().unwrap_or("no context")
                    ),
                }
            }
            if probe.selected.is_none() {
                outln!("  [MISSING] no device opens an offscreen OpenGL context");
                outln!("  hint: {INSTALL_EGL}");
            }
        }
    }
}

/// ffmpeg and the encoders it has.
fn print_ffmpeg(ffmpeg: Option<&FfmpegReport>) {
    outln!("Video (ffmpeg)");
    match ffmpeg {
        None => {
            outln!(
                "  [MISSING] no ffmpeg: none on PATH, no $DEXJOCO_FFMPEG, no imageio-ffmpeg in this environment"
            );
            outln!("  hint: {INSTALL_FFMPEG}");
        }
        Some(f) => {
            outln!("  [ok  ] {} ({})", f.path.display(), f.version);
            outln!("         found: {}", f.found_by);
            match &f.ffprobe {
                Some(p) => outln!("         ffprobe {}", p.display()),
                None => outln!(
                    "         ffprobe: none beside it (ffmpeg itself is asked what a video holds)"
                ),
            }
            for (e, ok) in &f.encoders {
                let mark = match (*ok, e == REQUIRED_ENCODER) {
                    (true, _) => "ok  ",
                    (false, true) => "MISSING",
                    (false, false) => " -  ",
                };
                outln!("  [{mark}] encoder {e}");
            }
            if !ffmpeg_ok(Some(f)) {
                outln!(
                    "  hint: augment and render --video need {REQUIRED_ENCODER}: {INSTALL_FFMPEG}"
                );
            }
        }
    }
}

/// The Python interpreter and the modules it has.
fn print_python(python: Option<&PythonReport>) {
    outln!("Python readers (for the tests and interop checks)");
    match python {
        None => outln!("  [ -  ] no Python found (run scripts/setup.sh --python)"),
        Some(p) => {
            outln!(
                "  [ok  ] {} (Python {}; from {})",
                p.interpreter.display(),
                p.version,
                p.found_by
            );
            for (m, v) in &p.modules {
                match v {
                    Some(v) => outln!("  [ok  ] {m} {v}"),
                    None => outln!("  [ -  ] {m}"),
                }
            }
        }
    }
}

/// Where the sample data was found, or where it was looked for.
fn print_sample_data(found: Option<&Located>) {
    outln!("Sample data (the default input of augment and bench augment; the examples of stats)");
    print_located(
        found,
        &format!(
            "looked at ${}, beside the binary (a bundle's share/dexjoco-data/datasets, a checkout's datasets) and ./datasets",
            crate::locate::DATA_ENV
        ),
    );
}

/// Where the DexJoCo reference scenes were found, or where they were looked for.
fn print_reference_scenes(found: Option<&Located>) {
    outln!("DexJoCo reference scenes (for --scene-dir and the tests)");
    print_located(
        found,
        &format!(
            "looked at ${}/xmls and ../shared/dexjoco-upstream/xmls; pass --scene-dir to the commands",
            crate::locate::UPSTREAM_ENV
        ),
    );
}

/// One found-or-not line.
fn print_located(found: Option<&Located>, missing: &str) {
    match found {
        Some(l) if l.path.exists() => outln!("  [ok  ] {} (from {})", l.path.display(), l.how),
        Some(l) => outln!(
            "  [MISSING] {} (from {}) does not exist",
            l.path.display(),
            l.how
        ),
        None => outln!("  [ -  ] not found ({missing})"),
    }
}
