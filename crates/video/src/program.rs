//! Which ffmpeg (and ffprobe) this process runs: `$DEXJOCO_FFMPEG`, else `ffmpeg` on PATH,
//! else the static build of the `imageio-ffmpeg` Python package installed in the same
//! environment as this program (`pip install 'dexjoco-data[ffmpeg]'`).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Where the ffmpeg in use was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FfmpegSource {
    /// `$DEXJOCO_FFMPEG`.
    Variable,
    /// `ffmpeg` on PATH (the system's).
    Path,
    /// imageio-ffmpeg's static build (`$IMAGEIO_FFMPEG_EXE`, or the package installed in
    /// this program's Python environment).
    ImageioFfmpeg,
}

impl FfmpegSource {
    /// How `doctor` says it.
    pub fn describe(self) -> &'static str {
        match self {
            Self::Variable => "from $DEXJOCO_FFMPEG",
            Self::Path => "on PATH",
            Self::ImageioFfmpeg => "imageio-ffmpeg's static build, in this Python environment",
        }
    }
}

/// The ffmpeg in use.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ffmpeg {
    /// The program.
    pub path: PathBuf,
    /// Where it was found.
    pub source: FfmpegSource,
}

/// The ffmpeg this process uses, found once; `None` when there is none.
pub fn locate_ffmpeg() -> Option<&'static Ffmpeg> {
    static FOUND: OnceLock<Option<Ffmpeg>> = OnceLock::new();
    FOUND.get_or_init(find_ffmpeg).as_ref()
}

fn find_ffmpeg() -> Option<Ffmpeg> {
    let found = |path: PathBuf, source| Some(Ffmpeg { path, source });
    if let Some(p) = std::env::var_os("DEXJOCO_FFMPEG") {
        return found(PathBuf::from(p), FfmpegSource::Variable);
    }
    if let Some(p) = which("ffmpeg") {
        return found(p, FfmpegSource::Path);
    }
    if let Some(p) = std::env::var_os("IMAGEIO_FFMPEG_EXE").map(PathBuf::from)
        && p.is_file()
    {
        return found(p, FfmpegSource::ImageioFfmpeg);
    }
    imageio_ffmpeg_beside_this_program().and_then(|p| found(p, FfmpegSource::ImageioFfmpeg))
}

/// The ffmpeg program to run: the one found, else `ffmpeg` (whose failure to start then
/// names it).
pub fn ffmpeg_program() -> PathBuf {
    locate_ffmpeg().map_or_else(|| "ffmpeg".into(), |f| f.path.clone())
}

/// ffprobe beside the ffmpeg in use, or on PATH; `None` (imageio-ffmpeg ships none)
/// means asking ffmpeg itself what a video holds.
pub fn locate_ffprobe() -> Option<PathBuf> {
    static FOUND: OnceLock<Option<PathBuf>> = OnceLock::new();
    FOUND
        .get_or_init(|| {
            let ffmpeg = locate_ffmpeg()?;
            let beside = ffmpeg.path.parent().map(|d| d.join("ffprobe"));
            match ffmpeg.source {
                FfmpegSource::ImageioFfmpeg => None,
                FfmpegSource::Path => beside.filter(|p| p.is_file()).or_else(|| which("ffprobe")),
                FfmpegSource::Variable => beside.filter(|p| p.is_file()),
            }
        })
        .clone()
}

/// `program` in a folder of PATH.
pub fn which(program: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join(program))
        .find(|p| p.is_file())
}

/// imageio-ffmpeg's `binaries/ffmpeg-*` in the site-packages of the environment this
/// program was installed into (`<env>/bin/dexjoco-data`, `<env>/lib/python3.*/
/// site-packages`), or of the active `$VIRTUAL_ENV`.
fn imageio_ffmpeg_beside_this_program() -> Option<PathBuf> {
    let exe = std::env::current_exe().ok()?.canonicalize().ok()?;
    let mut prefixes: Vec<PathBuf> = exe
        .parent()
        .and_then(Path::parent)
        .map(Into::into)
        .into_iter()
        .collect();
    prefixes.extend(std::env::var_os("VIRTUAL_ENV").map(PathBuf::from));
    prefixes.iter().find_map(|prefix| {
        let mut pythons: Vec<PathBuf> = fs_err::read_dir(prefix.join("lib"))
            .ok()?
            .filter_map(Result::ok)
            .map(|e| e.path())
            .filter(|p| {
                p.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with("python3"))
            })
            .collect();
        pythons.sort();
        pythons.iter().find_map(|py| {
            let bin = py.join("site-packages/imageio_ffmpeg/binaries");
            let mut found: Vec<PathBuf> = fs_err::read_dir(bin)
                .ok()?
                .filter_map(Result::ok)
                .map(|e| e.path())
                .filter(|p| {
                    p.is_file()
                        && p.file_name()
                            .is_some_and(|n| n.to_string_lossy().starts_with("ffmpeg"))
                })
                .collect();
            found.sort();
            found.pop()
        })
    })
}
