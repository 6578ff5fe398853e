//! Links the `dexjoco-data` binary with an rpath to `$ORIGIN/../lib`, the release bundle's
//! and the installed wheel's layout (`bin/dexjoco-data` beside `lib/libmujoco.so.3.17.0`,
//! see `scripts/package.sh`), so the program runs wherever it lies. A second entry,
//! `$ORIGIN/../data/lib`, is the same folder as seen inside the wheel file
//! (`<name>.data/scripts/` beside `<name>.data/data/lib/`), where `auditwheel show` looks
//! for MuJoCo; it names nothing once installed. `.cargo/config.toml` adds the rpaths that
//! find the checkout's `.deps/mujoco/lib` from `target/`.
fn main() {
    println!("cargo:rustc-link-arg-bins=-Wl,-rpath,$ORIGIN/../lib:$ORIGIN/../data/lib");
}
