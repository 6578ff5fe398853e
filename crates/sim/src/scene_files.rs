//! The files a MuJoCo scene loads, found as MuJoCo 3 finds them, and their content
//! hashes ([`scene_hash`]), so that the fingerprint of an output made on a scene (augment's,
//! generate's) covers every byte that decides it: the MJCF file, the files it
//! `<include>`s (and theirs), `<model>` sub-models, and the meshes, height fields, skins
//! and textures they name.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Component, Path, PathBuf};

use dexjoco_core::TaskSpec;
use sha2::{Digest, Sha256};

use crate::SceneSource;
use crate::error::SimError;

/// `SimError::Io` of `action` on `path`.
fn io_err(action: &'static str, path: &Path) -> impl FnOnce(std::io::Error) -> SimError + use<> {
    let path = path.to_path_buf();
    move |source| SimError::Io {
        action,
        path,
        source,
    }
}

fn sha(bytes: &[u8]) -> String {
    format!("sha256:{:x}", Sha256::digest(bytes))
}

/// A task's scene as a run loads it, by content: its MJCF file and every file that loads.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SceneHashes {
    /// SHA-256 of the scene file (a built-in scene: its composed XML, which holds it all).
    pub scene: String,
    /// The other files, by path relative to the scene folder (`missing` for a name that
    /// resolves to no file).
    pub files: BTreeMap<String, String>,
}

/// What a file named by a scene but found nowhere hashes to.
const MISSING: &str = "missing";

/// The content hashes of `spec`'s scene as `source` loads it.
pub fn scene_hash(source: &SceneSource, spec: &TaskSpec) -> Result<SceneHashes, SimError> {
    match source {
        SceneSource::BuiltIn => {
            let xml = crate::builtin::scene_xml(spec)?;
            Ok(SceneHashes {
                scene: sha(xml.as_bytes()),
                files: BTreeMap::new(),
            })
        }
        SceneSource::Dir(dir) => {
            let path = dir.join(&spec.scene);
            let bytes = fs_err::read(&path).map_err(io_err("read", &path))?;
            let mut files = BTreeMap::new();
            // Names relative to the folder however it is written (`xmls`, `./xmls`).
            let dir = &tidy(dir);
            for file in scene_files(&path)?.into_iter().skip(1) {
                let hash = match fs_err::read(&file) {
                    Ok(bytes) => sha(&bytes),
                    Err(e) if e.kind() == std::io::ErrorKind::NotFound => MISSING.into(),
                    Err(e) => return Err(io_err("read", &file)(e)),
                };
                let name = file.strip_prefix(dir).unwrap_or(&file);
                files.insert(name.display().to_string(), hash);
            }
            Ok(SceneHashes {
                scene: sha(&bytes),
                files,
            })
        }
    }
}

/// The attributes of `<texture>` that name a file (a cube map may take one per face).
const TEXTURE_FILES: [&str; 7] = [
    "file",
    "fileright",
    "fileleft",
    "fileup",
    "filedown",
    "filefront",
    "fileback",
];

/// What the walk collects, in document order (includes expanded where they stand).
#[derive(Default)]
struct Walk {
    /// The MJCF files read (the scene first), each once.
    xml: Vec<PathBuf>,
    /// Asset names: (name, is a texture, folder of the file naming it, relative to the
    /// scene's folder).
    assets: Vec<(String, bool, PathBuf)>,
    /// `<model>` sub-models, walked as scenes of their own.
    models: Vec<PathBuf>,
    /// The compiler's `meshdir` and `texturedir` (the last setting wins).
    meshdir: PathBuf,
    texturedir: PathBuf,
}

/// Every file the MJCF scene `scene` loads, the scene first, each once, in the order
/// met. Names resolve as MuJoCo 3 resolves them (measured with MuJoCo 3.17), against the
/// scene's folder `root`, for a name found in a file lying in `root/D`:
///
/// - `<include file=F>` and `<model file=F>`: `root/F`, else `root/D/F`;
/// - `<compiler assetdir|meshdir|texturedir>`: one setting for the model (the last in
///   document order wins; `assetdir` sets both), relative to `root`;
/// - `<mesh|hfield|skin|flexcomp file=F>`: `root/meshdir/F`, else `root/meshdir/D/F`;
///   `<texture file|fileright|…=F>` the same with `texturedir`;
/// - an absolute `F` as it is.
///
/// A name found nowhere is returned as its first candidate (the load would have failed
/// on it; hashing it as missing still notices it appearing).
pub fn scene_files(scene: &Path) -> Result<Vec<PathBuf>, SimError> {
    let scene = tidy(scene);
    let root = scene.parent().unwrap_or(Path::new("")).to_path_buf();
    let mut walk = Walk::default();
    read_mjcf(&root, &scene, &mut walk)?;
    let mut files = walk.xml;
    for (name, texture, dir) in &walk.assets {
        let base = if *texture {
            &walk.texturedir
        } else {
            &walk.meshdir
        };
        files.push(resolve(&root.join(base), dir, name));
    }
    for model in &walk.models {
        files.extend(scene_files(model)?);
    }
    let mut seen = BTreeSet::new();
    files.retain(|f| seen.insert(f.clone()));
    Ok(files)
}

/// Reads one MJCF file into `walk`, following its includes where they stand.
fn read_mjcf(root: &Path, file: &Path, walk: &mut Walk) -> Result<(), SimError> {
    if walk.xml.iter().any(|f| f == file) {
        return Ok(());
    }
    walk.xml.push(file.to_path_buf());
    let bytes = fs_err::read(file).map_err(io_err("read", file))?;
    let dir = match file.strip_prefix(root) {
        Ok(rel) => rel.parent().unwrap_or(Path::new("")).to_path_buf(),
        Err(_) => file.parent().unwrap_or(Path::new("")).to_path_buf(),
    };
    for (name, attributes) in start_tags(&String::from_utf8_lossy(&bytes)) {
        let attr = |key: &str| {
            attributes
                .iter()
                .find(|(k, _)| k == key)
                .map(|(_, v)| v.clone())
        };
        match name.as_str() {
            "include" => {
                if let Some(f) = attr("file") {
                    read_mjcf(root, &resolve(root, &dir, &f), walk)?;
                }
            }
            "model" => walk
                .models
                .extend(attr("file").map(|f| resolve(root, &dir, &f))),
            "compiler" => {
                if let Some(d) = attr("assetdir") {
                    walk.meshdir = d.clone().into();
                    walk.texturedir = d.into();
                }
                if let Some(d) = attr("meshdir") {
                    walk.meshdir = d.into();
                }
                if let Some(d) = attr("texturedir") {
                    walk.texturedir = d.into();
                }
            }
            "mesh" | "hfield" | "skin" | "flexcomp" => {
                if let Some(f) = attr("file") {
                    walk.assets.push((f, false, dir.clone()));
                }
            }
            "texture" => {
                for key in TEXTURE_FILES {
                    if let Some(f) = attr(key) {
                        walk.assets.push((f, true, dir.clone()));
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// The start tags of an XML text in order, each with its attributes (values with the
/// five predefined entities decoded); comments, processing instructions, declarations
/// and CDATA are passed over. As lenient as MuJoCo's parser on the MJCF it reads.
fn start_tags(text: &str) -> Vec<(String, Vec<(String, String)>)> {
    let mut tags = Vec::new();
    let mut rest = text;
    while let Some(open) = rest.find('<') {
        rest = &rest[open + 1..];
        let skip_to = [("!--", "-->"), ("![CDATA[", "]]>"), ("?", "?>"), ("!", ">")]
            .iter()
            .find(|(start, _)| rest.starts_with(start))
            .map(|(_, end)| *end);
        if let Some(end) = skip_to {
            rest = rest.find(end).map_or("", |e| &rest[e + end.len()..]);
            continue;
        }
        if rest.starts_with('/') {
            continue;
        }
        let name_end = rest
            .find(|c: char| c.is_whitespace() || c == '>' || c == '/')
            .unwrap_or(rest.len());
        let name = rest[..name_end].to_owned();
        rest = &rest[name_end..];
        let mut attributes = Vec::new();
        loop {
            rest = rest.trim_start();
            let Some(eq) = rest
                .find('=')
                .filter(|&eq| !rest[..eq].contains(['>', '<']))
            else {
                break;
            };
            let key = rest[..eq].trim().to_owned();
            let value = rest[eq + 1..].trim_start();
            let Some(quote) = value.chars().next().filter(|q| *q == '"' || *q == '\'') else {
                break;
            };
            let Some(len) = value[1..].find(quote) else {
                break;
            };
            attributes.push((key, unescape(&value[1..=len])));
            rest = &value[len + 2..];
        }
        tags.push((name, attributes));
    }
    tags
}

/// An attribute value with XML's predefined entities decoded.
fn unescape(value: &str) -> String {
    value
        .replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&quot;", "\"")
        .replace("&apos;", "'")
        .replace("&amp;", "&")
}

/// `base/name` if it exists, else `base/dir/name` if that does, else `base/name`.
fn resolve(base: &Path, dir: &Path, name: &str) -> PathBuf {
    let direct = tidy(&base.join(name));
    if direct.exists() || dir.as_os_str().is_empty() {
        return direct;
    }
    let nested = tidy(&base.join(dir).join(name));
    if nested.exists() { nested } else { direct }
}

/// `path` without its `.` components (`./a/./b` is `a/b`), so one file has one name.
pub fn tidy(path: &Path) -> PathBuf {
    path.components()
        .filter(|c| !matches!(c, Component::CurDir))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(path: &Path, text: &str) {
        fs_err::create_dir_all(path.parent().unwrap()).unwrap();
        fs_err::write(path, text).unwrap();
    }

    #[test]
    fn start_tags_pass_over_comments_and_decode_values() {
        let tags = start_tags(
            "<?xml version='1.0'?><!-- <include file=\"no\"/> --><mujoco model=\"a &amp; b\">\n\
             <mesh  name = 'm' file=\"x.stl\"/><![CDATA[<include file=\"no\"/>]]></mujoco>",
        );
        let pairs = |v: &[(&str, &str)]| -> Vec<(String, String)> {
            v.iter()
                .map(|(k, v)| ((*k).to_owned(), (*v).to_owned()))
                .collect()
        };
        assert_eq!(
            tags,
            [
                ("mujoco".to_owned(), pairs(&[("model", "a & b")])),
                (
                    "mesh".to_owned(),
                    pairs(&[("name", "m"), ("file", "x.stl")])
                ),
            ]
        );
    }

    /// A scene that includes a robot from a subfolder (which includes its hand beside
    /// it), sets the mesh folder in the included file, and names meshes, a cube texture
    /// and a height field.
    #[test]
    fn the_closure_follows_includes_and_the_compilers_folders() {
        let tmp = tempfile::tempdir().unwrap();
        let root = tmp.path();
        write(
            &root.join("scene.xml"),
            r#"<?xml version='1.0' encoding='utf-8'?>
<mujoco><!-- <include file="commented.xml"/> -->
  <include file="robot/arm.xml"/>
  <compiler texturedir="textures"/>
  <asset>
    <texture name="sky" type="cube" fileup="up.png" filedown="./down.png"/>
    <texture name="grid" builtin="checker" width="8" height="8"/>
    <hfield name="terrain" file="terrain.png"/>
  </asset>
</mujoco>"#,
        );
        write(
            &root.join("robot/arm.xml"),
            r#"<mujoco><compiler meshdir="assets"/><include file="hand.xml"/>
  <asset><mesh name="link0" file="link0.stl"/></asset></mujoco>"#,
        );
        write(
            &root.join("robot/hand.xml"),
            r#"<mujoco><asset><mesh name="palm" file="/abs/palm.obj"/></asset></mujoco>"#,
        );
        for f in [
            "assets/robot/link0.stl",
            "textures/up.png",
            "textures/down.png",
        ] {
            write(&root.join(f), "x");
        }
        let files = scene_files(&root.join("scene.xml")).unwrap();
        let names: Vec<String> = files
            .iter()
            .map(|f| f.strip_prefix(root).unwrap_or(f).display().to_string())
            .collect();
        assert_eq!(
            names,
            [
                "scene.xml",
                "robot/arm.xml",
                // Not beside the scene: found beside the file that includes it.
                "robot/hand.xml",
                // In document order, includes expanded where they stand.
                "/abs/palm.obj",
                // Named in robot/: meshdir/robot/link0.stl.
                "assets/robot/link0.stl",
                "textures/up.png",
                "textures/down.png",
                // Missing: its first candidate (meshdir/terrain.png).
                "assets/terrain.png",
            ]
        );
    }

    /// MuJoCo loads every reference scene, so each file their closures name is found.
    #[test]
    fn every_file_of_the_reference_scenes_is_found() {
        let xmls = dexjoco_testkit::reference_scene_dir();
        let scenes: Vec<PathBuf> = fs_err::read_dir(&xmls)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| {
                p.file_name()
                    .unwrap()
                    .to_string_lossy()
                    .starts_with("arena_")
            })
            .collect();
        assert!(scenes.len() > 5, "{scenes:?}");
        for scene in scenes {
            let files = scene_files(&scene).unwrap();
            assert!(files.len() > 10, "{}: {files:?}", scene.display());
            let missing: Vec<_> = files.iter().filter(|f| !f.is_file()).collect();
            assert!(missing.is_empty(), "{}: {missing:?}", scene.display());
        }
    }
}
