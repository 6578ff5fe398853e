//! Where and with what a replay is made: the versions of the programs that decide its
//! bytes (this build, MuJoCo, ffmpeg and its x264; the output's fingerprint holds them and
//! a resume under others is refused) and the CPU it ran on (MuJoCo's floating point
//! depends on it: the same recording replayed by the same MuJoCo deviates by 0 on one
//! machine and by up to 0.09 on another, so each replay records it and the report warns
//! when a dataset mixes CPUs).

use std::sync::OnceLock;

pub use dexjoco_formats::augment_report::{Provenance, ToolVersions};

/// This process's versions, asked once (ffmpeg is run twice the first time).
pub fn current_versions() -> &'static ToolVersions {
    static CURRENT: OnceLock<ToolVersions> = OnceLock::new();
    CURRENT.get_or_init(|| {
        let commit = env!("DEXJOCO_GIT_COMMIT");
        let dexjoco_data = if commit.is_empty() {
            env!("CARGO_PKG_VERSION").to_owned()
        } else {
            format!("{} (git {commit})", env!("CARGO_PKG_VERSION"))
        };
        let (ffmpeg, x264) = match dexjoco_video::encoder_versions() {
            Ok(v) => (v.ffmpeg, v.x264),
            Err(e) => (format!("unavailable: {e}"), "unavailable".to_owned()),
        };
        ToolVersions {
            dexjoco_data,
            mujoco: dexjoco_sim::mujoco_version(),
            ffmpeg,
            x264,
        }
    })
}

/// This machine and process, read once.
pub fn this_machine() -> &'static Provenance {
    static HERE: OnceLock<Provenance> = OnceLock::new();
    HERE.get_or_init(|| {
        let cpuinfo = fs_err::read_to_string("/proc/cpuinfo").unwrap_or_default();
        let (cpu_model, cpu_flags) = cpu_of(&cpuinfo);
        Provenance {
            cpu_model,
            cpu_flags,
            versions: current_versions().clone(),
        }
    })
}

/// The first processor's model and flags in a `/proc/cpuinfo` text (`unknown` when it
/// names none).
fn cpu_of(cpuinfo: &str) -> (String, String) {
    let field = |keys: &[&str]| {
        keys.iter()
            .find_map(|key| {
                cpuinfo.lines().find_map(|line| {
                    let (k, v) = line.split_once(':')?;
                    (k.trim() == *key).then(|| v.split_whitespace().collect::<Vec<_>>().join(" "))
                })
            })
            .filter(|v| !v.is_empty())
            .unwrap_or_else(|| "unknown".into())
    };
    let model = field(&["model name", "Model", "cpu model", "CPU part"]);
    let flags = field(&["flags", "Features"]);
    (model, flags)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cpuinfo_gives_the_first_processors_model_and_flags() {
        let x86 = "processor\t: 0\nmodel name\t: AMD EPYC 7B13\nflags\t\t: fpu  sse2 avx2\n\n\
                   processor\t: 1\nmodel name\t: AMD EPYC 7B13\nflags\t\t: fpu sse2 avx2\n";
        assert_eq!(
            cpu_of(x86),
            ("AMD EPYC 7B13".into(), "fpu sse2 avx2".into())
        );
        let arm = "processor\t: 0\nFeatures\t: fp asimd\nCPU part\t: 0xd0c\n";
        assert_eq!(cpu_of(arm), ("0xd0c".into(), "fp asimd".into()));
        assert_eq!(cpu_of(""), ("unknown".into(), "unknown".into()));
    }

    #[test]
    fn versions_name_this_build_and_the_loaded_mujoco() {
        let v = current_versions();
        assert!(
            v.dexjoco_data.starts_with(env!("CARGO_PKG_VERSION")),
            "{v:?}"
        );
        assert_eq!(v.mujoco, dexjoco_sim::mujoco_version());
        assert!(v.x264.starts_with("x264 - core "), "{v:?}");
    }
}
