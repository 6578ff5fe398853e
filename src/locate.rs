//! Where the binary finds what is not compiled into it: the sample data, the DexJoCo
//! reference scenes and the Python of the real readers. Nothing depends on where the
//! binary was compiled: each is looked up from an environment variable, then beside the
//! executable (a release bundle's `share/`, or the checkout a `target/` build sits in),
//! then from the current folder. `doctor` says which was found, and how.

use std::path::{Path, PathBuf};

/// The sample data's folder (holding `demos/` and `examples/`).
pub const DATA_ENV: &str = "DEXJOCO_DATA";
/// The DexJoCo reference scene pack (the folder holding `xmls/`).
pub const UPSTREAM_ENV: &str = "DEXJOCO_UPSTREAM";
/// The Python interpreter of the real readers.
pub const PYTHON_ENV: &str = "DEXJOCO_PYTHON";

/// A path, and how it was found.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Located {
    /// The path.
    pub path: PathBuf,
    /// How it was found, as `doctor` says it (`$DEXJOCO_DATA`, `beside the binary`...).
    pub how: String,
}

impl Located {
    fn new(path: PathBuf, how: impl Into<String>) -> Self {
        Self {
            path,
            how: how.into(),
        }
    }
}

/// The folder of the running executable (links resolved).
fn exe_dir() -> Option<PathBuf> {
    let exe = std::env::current_exe().ok()?.canonicalize().ok()?;
    exe.parent().map(Path::to_path_buf)
}

/// `share/dexjoco-data` beside the binary's `bin/`: an extracted release bundle, or the
/// Python environment the wheel was installed into.
fn bundle_share() -> Option<PathBuf> {
    Some(exe_dir()?.join("../share/dexjoco-data")).filter(|p| p.is_dir())
}

/// The checkout a `cargo build` binary sits in (`<checkout>/target/<profile>/`).
fn checkout_of_binary() -> Option<PathBuf> {
    let root = exe_dir()?.join("../..");
    Some(root).filter(|r| r.join("Cargo.toml").is_file() && r.join("datasets").is_dir())
}

/// The environment variable's value when set (it is taken as it is, so that a wrong
/// value shows rather than a silent fallback), else the first candidate that exists.
fn first(
    var: &str,
    candidates: Vec<Option<Located>>,
    exists: impl Fn(&Path) -> bool,
) -> Option<Located> {
    if let Some(v) = std::env::var_os(var) {
        return Some(Located::new(PathBuf::from(v), format!("${var}")));
    }
    let found = candidates.into_iter().flatten().find(|c| exists(&c.path))?;
    // Folders are shown resolved; files are not (a venv's python is a link to the base
    // interpreter, which lacks the venv's packages).
    let path = if found.path.is_dir() {
        found.path.canonicalize().unwrap_or(found.path)
    } else {
        found.path
    };
    Some(Located::new(path, found.how))
}

/// The source checkout: the one a `target/` build sits in, else the current folder when
/// it is one (for the developer tools that run the checkout's scripts).
pub fn checkout() -> Option<PathBuf> {
    checkout_of_binary().or_else(|| {
        Some(PathBuf::from("."))
            .filter(|d| d.join("Cargo.toml").is_file() && d.join("tests").is_dir())
    })
}

/// The sample data's folder (`demos/`, `examples/`): `$DEXJOCO_DATA`, the bundle's
/// `share/dexjoco-data/datasets`, the checkout's `datasets`, or `./datasets`.
pub fn data_dir() -> Option<Located> {
    first(
        DATA_ENV,
        vec![
            bundle_share().map(|s| {
                Located::new(
                    s.join("datasets"),
                    "share/dexjoco-data beside the binary (release bundle or pip install)",
                )
            }),
            checkout_of_binary()
                .map(|c| Located::new(c.join("datasets"), "the checkout the binary was built in")),
            Some(Located::new(
                PathBuf::from("datasets"),
                "the current folder",
            )),
        ],
        Path::is_dir,
    )
}

/// The DexJoCo reference scenes (`xmls/`): under `$DEXJOCO_UPSTREAM`, else the
/// `../shared/dexjoco-upstream` beside the current folder or the binary's checkout.
pub fn reference_scenes() -> Option<Located> {
    let shared =
        |base: PathBuf, how: &str| Located::new(base.join("../shared/dexjoco-upstream/xmls"), how);
    let found = first(
        UPSTREAM_ENV,
        vec![
            Some(shared(PathBuf::from("."), "beside the current folder")),
            checkout_of_binary().map(|c| shared(c, "beside the binary's checkout")),
        ],
        Path::is_dir,
    )?;
    Some(if found.how.starts_with('$') {
        Located::new(found.path.join("xmls"), found.how)
    } else {
        found
    })
}

/// The Python of the DexJoCo reference code's own pins (the parity tests' venv):
/// `$DEXJOCO_REFERENCE_PYTHON`, else `.deps/reference-python-path` of the binary's
/// checkout or the current folder.
pub fn reference_python() -> Option<Located> {
    let recorded = |root: PathBuf, how: &str| {
        let p = fs_err::read_to_string(root.join(".deps/reference-python-path")).ok()?;
        Some(Located::new(PathBuf::from(p.trim()), how))
    };
    first(
        "DEXJOCO_REFERENCE_PYTHON",
        vec![
            checkout_of_binary()
                .and_then(|c| recorded(c, "the reference venv of the binary's checkout")),
            recorded(
                PathBuf::from("."),
                "the reference venv of the current folder",
            ),
        ],
        Path::is_file,
    )
}

/// The Python of the readers: `$DEXJOCO_PYTHON`, the test venv `scripts/setup.sh
/// --python` recorded in a checkout's `.deps/python-path`, or `python3` on PATH.
pub fn python() -> Option<Located> {
    let recorded = |root: PathBuf, how: &str| {
        let p = fs_err::read_to_string(root.join(".deps/python-path")).ok()?;
        Some(Located::new(PathBuf::from(p.trim()), how))
    };
    first(
        PYTHON_ENV,
        vec![
            checkout_of_binary()
                .and_then(|c| recorded(c, "the test venv of the binary's checkout")),
            recorded(PathBuf::from("."), "the test venv of the current folder"),
            dexjoco_video::which("python3").map(|p| Located::new(p, "PATH")),
        ],
        Path::is_file,
    )
}
