//! Embeds every built-in object fragment (`assets/builtin/objects/<task_id>.xml`) in the
//! crate: writes `$OUT_DIR/builtin_objects.rs`, a sorted table of (task id, XML text).

use std::fmt::Write as _;
use std::path::Path;

fn main() {
    // The manifest folder of this run, not of the build script's compilation: cargo
    // reuses a build script compiled for a copy of the workspace elsewhere.
    let manifest = std::env::var("CARGO_MANIFEST_DIR").expect("CARGO_MANIFEST_DIR");
    let dir = Path::new(&manifest).join("assets/builtin/objects");
    println!("cargo:rerun-if-changed={}", dir.display());
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()))
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "xml"))
        .collect();
    assert!(
        !files.is_empty(),
        "no built-in object fragments in {}",
        dir.display()
    );
    files.sort();
    let mut out = String::from("/// (task id, object fragment) of every built-in task scene.\n");
    out.push_str("pub static OBJECTS: &[(&str, &str)] = &[\n");
    for f in &files {
        println!("cargo:rerun-if-changed={}", f.display());
        let id = f.file_stem().and_then(|s| s.to_str()).expect("utf-8 name");
        writeln!(
            out,
            "    ({id:?}, include_str!({:?})),",
            f.display().to_string()
        )
        .expect("string write");
    }
    out.push_str("];\n");
    let dst = Path::new(&std::env::var("OUT_DIR").expect("OUT_DIR")).join("builtin_objects.rs");
    std::fs::write(dst, out).expect("write builtin_objects.rs");
}
