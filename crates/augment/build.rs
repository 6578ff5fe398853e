//! Records the git commit this crate is built from as `DEXJOCO_GIT_COMMIT` (empty outside
//! a git checkout, e.g. a source tarball): with the package version it is the build's
//! identity in the augment fingerprint and in each replay's provenance. A build from a
//! checkout with uncommitted changes carries its last commit.

use std::path::Path;
use std::process::Command;

/// `git <args>` in this crate's folder, its trimmed output when it succeeds.
fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git")
        .args(args)
        .current_dir(std::env::var_os("CARGO_MANIFEST_DIR")?)
        .output()
        .ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_owned())
}

fn main() {
    let commit = git(&["rev-parse", "HEAD"]).unwrap_or_default();
    // Built again when HEAD moves: a checkout, a commit (a branch's ref is a loose file
    // under refs/heads, or a line of packed-refs; worktrees keep refs in the common dir).
    let mut watched = Vec::new();
    if let Some(dir) = git(&["rev-parse", "--absolute-git-dir"]) {
        watched.push(Path::new(&dir).join("HEAD"));
    }
    if let Some(common) = git(&["rev-parse", "--path-format=absolute", "--git-common-dir"]) {
        let common = Path::new(&common);
        watched.extend([common.join("packed-refs"), common.join("refs/heads")]);
    }
    for path in watched.iter().filter(|p| p.exists()) {
        println!("cargo:rerun-if-changed={}", path.display());
    }
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rustc-env=DEXJOCO_GIT_COMMIT={commit}");
}
