//! Where and with what a replay is made: the versions of the programs that decide its
//! bytes (this build, MuJoCo, ffmpeg and its x264; the output's fingerprint holds them and
//! a resume under others is refused) and the CPU it ran on (MuJoCo's floating point
//! depends on it: the same recording replayed by the same MuJoCo deviates by 0 on one
//! machine and by up to 0.09 on another, so each replay records it and the report warns
//! when a dataset mixes CPUs).

use std::sync::OnceLock;

use serde::{Deserialize, Serialize};

/// What a version reads when it was not recorded (an output folder made before it was).
const NOT_RECORDED: &str = "not recorded";

/// The programs that decide an augment output's bytes, as they name themselves.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct ToolVersions {
    /// This program: its version and the git commit it was built from
    /// (`0.1.0 (git 3f1ab45…)`; the version alone when built outside a git checkout).
    pub dexjoco_data: String,
    /// The MuJoCo library loaded (`3.17.0`).
    pub mujoco: String,
    /// ffmpeg as `ffmpeg -version` names itself (`5.1.9-0+deb12u1`), or why it could not
    /// be asked.
    pub ffmpeg: String,
    /// x264 as it names itself in the streams it writes (`x264 - core 164 r3095 baee400`).
    pub x264: String,
}

impl Default for ToolVersions {
    /// Every version "not recorded".
    fn default() -> Self {
        Self {
            dexjoco_data: NOT_RECORDED.into(),
            mujoco: NOT_RECORDED.into(),
            ffmpeg: NOT_RECORDED.into(),
            x264: NOT_RECORDED.into(),
        }
    }
}

impl ToolVersions {
    /// This process's versions, asked once (ffmpeg is run twice the first time).
    pub fn current() -> &'static Self {
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
            Self {
                dexjoco_data,
                mujoco: dexjoco_sim::mujoco_version(),
                ffmpeg,
                x264,
            }
        })
    }
}

/// Where a replay was made.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Provenance {
    /// The CPU model (`/proc/cpuinfo`'s `model name`, or its ARM equivalents).
    pub cpu_model: String,
    /// The CPU's feature flags (`/proc/cpuinfo`'s `flags` or `Features`), as listed there.
    pub cpu_flags: String,
    /// The programs' versions.
    pub versions: ToolVersions,
}

impl Provenance {
    /// This machine and process, read once.
    pub fn here() -> &'static Self {
        static HERE: OnceLock<Provenance> = OnceLock::new();
        HERE.get_or_init(|| {
            let cpuinfo = fs_err::read_to_string("/proc/cpuinfo").unwrap_or_default();
            let (cpu_model, cpu_flags) = cpu_of(&cpuinfo);
            Self {
                cpu_model,
                cpu_flags,
                versions: ToolVersions::current().clone(),
            }
        })
    }
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
        let v = ToolVersions::current();
        assert!(
            v.dexjoco_data.starts_with(env!("CARGO_PKG_VERSION")),
            "{v:?}"
        );
        assert_eq!(v.mujoco, dexjoco_sim::mujoco_version());
        assert!(v.x264.starts_with("x264 - core "), "{v:?}");
    }
}
