//! Links the `dexjoco-data` binary with an rpath to `$ORIGIN/../lib`, the release bundle's
//! layout (`bin/dexjoco-data` beside `lib/libmujoco.so.3.17.0`, see `scripts/package.sh`),
//! so an extracted bundle runs wherever it lies. `.cargo/config.toml` adds the rpaths that
//! find the checkout's `.deps/mujoco/lib` from `target/`.
fn main() {
    println!("cargo:rustc-link-arg-bins=-Wl,-rpath,$ORIGIN/../lib");
}
