//! The Warp worker process: finding its Python, starting it, and the framed JSON +
//! payload protocol both ways (`python/warp_worker.py` is the other side).

use std::collections::{BTreeMap, VecDeque};
use std::io::{BufRead, BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::sync::{Arc, Mutex};

use serde::{Deserialize, Serialize};

use crate::error::{RenderError, WarpError};

/// The worker script, run as `python -c`.
const WORKER_SCRIPT: &str = include_str!("../../python/warp_worker.py");

/// The Python packages the worker needs, pinned (`scripts/setup.sh --warp`, the wheel's
/// `[warp]` extra).
pub const WARP_PINS: [(&str, &str); 3] = [
    ("mujoco", "3.17.0"),
    ("mujoco-warp", "3.17.0"),
    ("warp-lang", "1.19.0"),
];

/// The variable naming the worker's Python (one with [`WARP_PINS`] installed).
pub const PYTHON_VARIABLE: &str = "DEXJOCO_WARP_PYTHON";

/// Largest JSON header accepted from the worker.
const MAX_HEADER: u32 = 1 << 24;

/// How to start the worker.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct WarpOptions {
    /// The Python to run it with; `None`: found (see [`python_candidates`]).
    pub python: Option<PathBuf>,
    /// `auto` (the first CUDA device, else the CPU), `cpu` or `cuda:N`.
    pub device: String,
    /// Worlds (images) per batch; `None`: 2048 on a GPU, 16 on the CPU.
    pub worlds: Option<usize>,
    /// Rays per pixel and axis (supersampling); `None`: 2 where the quality asks for
    /// multisampling, else 1.
    pub supersample: Option<u32>,
}

impl Default for WarpOptions {
    fn default() -> Self {
        Self {
            python: None,
            device: "auto".into(),
            worlds: None,
            supersample: None,
        }
    }
}

/// Where the worker's Python is looked for when neither `--warp-python` nor
/// `$DEXJOCO_WARP_PYTHON` names one (those are used as given), in order: the Python of
/// the environment this program was installed into (the wheel's `[warp]` extra); the
/// active `$VIRTUAL_ENV`; the environment `scripts/setup.sh --warp` makes. The first
/// that imports `mujoco_warp` is taken.
pub fn python_candidates() -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Some(bin) = std::env::current_exe()
        .ok()
        .and_then(|e| e.canonicalize().ok())
        .and_then(|e| e.parent().map(Path::to_path_buf))
    {
        out.push(bin.join("python"));
    }
    if let Some(v) = std::env::var_os("VIRTUAL_ENV") {
        out.push(PathBuf::from(v).join("bin/python"));
    }
    out.push(setup_venv().join("bin/python"));
    out
}

/// The environment `scripts/setup.sh --warp` makes:
/// `${XDG_CACHE_HOME:-~/.cache}/dexjoco-data/venv-warp-<mujoco-warp version>`.
pub fn setup_venv() -> PathBuf {
    let cache = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
        .unwrap_or_else(|| PathBuf::from(".cache"));
    cache
        .join("dexjoco-data")
        .join(format!("venv-warp-{}", WARP_PINS[1].1))
}

/// What the worker said about itself.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct WorkerInfo {
    /// The Python that runs it.
    pub python: PathBuf,
    /// Warp's device (`cpu`, `cuda:0`).
    pub device: String,
    /// The device's name (the GPU's model).
    pub device_name: String,
    /// Python and the pinned packages' versions.
    pub versions: BTreeMap<String, Option<String>>,
}

impl WorkerInfo {
    /// `warp 3.17.0 on cuda:0 (NVIDIA H200)`, as records name their renderer.
    pub fn describe(&self) -> String {
        let v = self
            .versions
            .get("mujoco-warp")
            .cloned()
            .flatten()
            .unwrap_or_default();
        if self.device == "cpu" {
            format!("warp {v} on cpu")
        } else {
            format!("warp {v} on {} ({})", self.device, self.device_name)
        }
    }
}

/// A running worker process.
pub struct WarpWorker {
    child: Child,
    stdin: BufWriter<ChildStdin>,
    stdout: BufReader<ChildStdout>,
    stderr: Arc<Mutex<VecDeque<String>>>,
    info: WorkerInfo,
    pub(super) supersample: Option<u32>,
    worlds: Option<usize>,
}

impl WarpWorker {
    /// Starts the worker with the first Python of [`python_candidates`] (or the one
    /// given) and checks it has the pinned packages.
    pub fn start(options: &WarpOptions) -> Result<Self, RenderError> {
        let explicit = options
            .python
            .clone()
            .or_else(|| std::env::var_os(PYTHON_VARIABLE).map(PathBuf::from));
        let python = match explicit {
            Some(p) => p,
            None => python_candidates()
                .into_iter()
                .find(|p| p.is_file() && has_warp(p))
                .ok_or_else(|| WarpError::NoPython {
                    setup_venv: setup_venv(),
                    variable: PYTHON_VARIABLE,
                })?,
        };
        let mut command = Command::new(&python);
        command
            .args(["-u", "-c", WORKER_SCRIPT])
            .env("PYTHONUNBUFFERED", "1")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        dies_with_parent(&mut command);
        let mut child = command.spawn().map_err(|source| WarpError::Start {
            python: python.clone(),
            source,
        })?;
        let stderr = Arc::new(Mutex::new(VecDeque::new()));
        let tail = Arc::clone(&stderr);
        let err = child.stderr.take().expect("piped");
        std::thread::spawn(move || {
            for line in BufReader::new(err).lines().map_while(Result::ok) {
                tracing::debug!(target: "warp_worker", "{line}");
                let mut t = tail.lock().expect("tail");
                if t.len() == 20 {
                    t.pop_front();
                }
                t.push_back(line);
            }
        });
        let stdin = BufWriter::new(child.stdin.take().expect("piped"));
        let stdout = BufReader::new(child.stdout.take().expect("piped"));
        let mut worker = Self {
            child,
            stdin,
            stdout,
            stderr,
            info: WorkerInfo {
                python: python.clone(),
                device: String::new(),
                device_name: String::new(),
                versions: BTreeMap::new(),
            },
            supersample: options.supersample,
            worlds: options.worlds,
        };
        let (hello, _) = worker
            .call(
                &serde_json::json!({"op": "hello", "device": options.device}),
                &[],
                0,
            )
            .map_err(|e| WarpError::CannotRun {
                python: python.clone(),
                reason: Box::new(e),
            })?;
        let info: HelloReply =
            serde_json::from_value(hello).map_err(|source| WarpError::Protocol {
                what: "hello",
                source,
            })?;
        worker.info.device = info.device;
        worker.info.device_name = info.device_name;
        worker.info.versions = info.versions;
        worker.check_pins()?;
        Ok(worker)
    }

    /// What the worker runs on.
    pub fn info(&self) -> &WorkerInfo {
        &self.info
    }

    /// Images per batch: as asked, else 2048 on a GPU and 16 on the CPU.
    pub fn batch_worlds(&self) -> usize {
        self.worlds
            .unwrap_or(if self.info.device == "cpu" { 16 } else { 2048 })
            .max(1)
    }

    fn check_pins(&self) -> Result<(), RenderError> {
        for (package, pin) in WARP_PINS {
            let have = self.info.versions.get(package).cloned().flatten();
            if have.as_deref() != Some(pin) {
                return Err(WarpError::Pin {
                    python: self.info.python.clone(),
                    package: package.to_string(),
                    found: have,
                    pin: pin.to_string(),
                }
                .into());
            }
        }
        Ok(())
    }

    /// One request and its reply: JSON header and payload each way; a reply whose
    /// payload would be larger than `expect` bytes (what was asked for) is refused before
    /// any of it is read.
    pub(super) fn call(
        &mut self,
        request: &serde_json::Value,
        payload: &[u8],
        expect: usize,
    ) -> Result<(serde_json::Value, Vec<u8>), RenderError> {
        let sent = self.send(request, payload);
        let reply = sent.and_then(|()| read_reply(&mut self.stdout, expect as u64));
        let (header, data) = reply.map_err(|e| self.died(&e))?;
        if header.get("ok") != Some(&serde_json::Value::Bool(true)) {
            let error = header
                .get("error")
                .and_then(|e| e.as_str())
                .unwrap_or("no message");
            tracing::debug!(
                trace = header.get("trace").and_then(|t| t.as_str()),
                "warp worker"
            );
            return Err(WarpError::Failed(error.to_string()).into());
        }
        Ok((header, data))
    }

    fn send(&mut self, request: &serde_json::Value, payload: &[u8]) -> std::io::Result<()> {
        let body = serde_json::to_vec(request).expect("json");
        self.stdin.write_all(&(body.len() as u32).to_le_bytes())?;
        self.stdin
            .write_all(&(payload.len() as u64).to_le_bytes())?;
        self.stdin.write_all(&body)?;
        self.stdin.write_all(payload)?;
        self.stdin.flush()
    }

    /// The error of a broken pipe: the worker's last words.
    fn died(&mut self, e: &std::io::Error) -> RenderError {
        let status = self.child.try_wait().ok().flatten();
        // Give the stderr reader a moment to collect what the worker printed last.
        std::thread::sleep(std::time::Duration::from_millis(100));
        let tail: Vec<String> = self.stderr.lock().expect("tail").iter().cloned().collect();
        WarpError::Stopped {
            python: self.info.python.clone(),
            source: std::io::Error::new(e.kind(), e.to_string()),
            exit: status.map_or_else(|| "running".into(), |s| s.to_string()),
            output: tail,
        }
        .into()
    }
}

impl Drop for WarpWorker {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Reads one framed reply (12-byte header: u32 JSON length, u64 payload length; the JSON
/// object; the payload) from `r`, refusing a header of more than 16 MiB, a payload of more
/// than `max_payload` bytes (both before reading them) and a JSON header that is not an
/// object: the worker is another program, its bytes are checked like a file's.
pub fn read_reply<R: Read>(
    r: &mut R,
    max_payload: u64,
) -> std::io::Result<(serde_json::Value, Vec<u8>)> {
    let mut head = [0u8; 12];
    r.read_exact(&mut head)?;
    let json_len = u32::from_le_bytes(head[..4].try_into().expect("4"));
    let payload_len = u64::from_le_bytes(head[4..].try_into().expect("8"));
    if json_len > MAX_HEADER {
        return Err(std::io::Error::other(format!(
            "the Warp worker's reply has a header of {json_len} bytes (at most {MAX_HEADER})"
        )));
    }
    if payload_len > max_payload {
        return Err(std::io::Error::other(format!(
            "the Warp worker's reply claims {payload_len} bytes of images where at most \
             {max_payload} were asked for"
        )));
    }
    let mut body = vec![0u8; json_len as usize];
    r.read_exact(&mut body)?;
    let header: serde_json::Value = serde_json::from_slice(&body).map_err(std::io::Error::other)?;
    if !header.is_object() {
        return Err(std::io::Error::other(
            "the Warp worker's reply header is not a JSON object",
        ));
    }
    let mut data = vec![0u8; payload_len as usize];
    r.read_exact(&mut data)?;
    Ok((header, data))
}

/// Makes the worker die with this process (Linux's parent-death signal, SIGKILL): a
/// worker left behind by a killed augment process would hold its GPU. The signal follows
/// the thread that starts the worker, which owns it until it ends (each render thread
/// keeps its own worker).
fn dies_with_parent(command: &mut Command) {
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::process::CommandExt;
        let parent = rustix::process::getpid();
        // SAFETY: only async-signal-safe system calls run between fork and exec.
        #[allow(unsafe_code)]
        unsafe {
            command.pre_exec(move || {
                rustix::process::set_parent_process_death_signal(Some(
                    rustix::process::Signal::KILL,
                ))?;
                // The parent may have died before the signal was asked for.
                if rustix::process::getppid() != Some(parent) {
                    return Err(std::io::Error::other("dexjoco-data ended"));
                }
                Ok(())
            });
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = command;
}

#[derive(Deserialize)]
struct HelloReply {
    device: String,
    device_name: String,
    versions: BTreeMap<String, Option<String>>,
}

/// Whether `python` imports `mujoco_warp` (a quick probe before starting the worker).
fn has_warp(python: &Path) -> bool {
    Command::new(python)
        .args(["-c", "import mujoco_warp"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A framed reply as the worker writes it.
    fn frame(header: &serde_json::Value, payload: &[u8]) -> Vec<u8> {
        let body = serde_json::to_vec(header).unwrap();
        let mut out = (body.len() as u32).to_le_bytes().to_vec();
        out.extend((payload.len() as u64).to_le_bytes());
        out.extend(body);
        out.extend(payload);
        out
    }

    /// The reply that once made augment read 2^60 bytes into memory: refused from its
    /// header, before any of the payload is read.
    #[test]
    fn a_reply_larger_than_asked_is_refused_before_it_is_read() {
        let mut bytes = frame(&serde_json::json!({"ok": true}), &[]);
        bytes[4..12].copy_from_slice(&(1u64 << 60).to_le_bytes());
        // An endless stream of zeros after it: reading it would never end.
        let mut r = std::io::Read::chain(&bytes[..], std::io::repeat(0));
        let e = read_reply(&mut r, 4096).unwrap_err().to_string();
        assert!(
            e.contains("Warp worker") && e.contains("1152921504606846976"),
            "{e}"
        );
        let (h, d) =
            read_reply(&mut &frame(&serde_json::json!({"ok": 1}), &[7; 16])[..], 16).unwrap();
        assert_eq!((h["ok"].as_i64(), d.len()), (Some(1), 16));
    }

    /// Replies of arbitrary bytes, and valid replies edited byte by byte: each is read or
    /// refused, never a panic, never more payload than asked for.
    #[test]
    fn hostile_replies_are_bounded_by_what_was_asked() {
        use dexjoco_testkit::hostile::{apply_bytes, byte_edits, run_cases};
        use proptest::prelude::*;
        let valid = [
            frame(
                &serde_json::json!({"ok": true, "worlds": 2, "times": {"render": 0.1}}),
                &[9; 64],
            ),
            frame(&serde_json::json!({"ok": false, "error": "boom"}), &[]),
        ];
        let strategy = (
            0..valid.len(),
            byte_edits(4),
            prop::collection::vec(any::<u8>(), 0..64),
            any::<bool>(),
        );
        run_cases(
            "warp replies",
            3000,
            strategy,
            move |(v, edits, raw, use_raw)| {
                let bytes = if use_raw {
                    raw
                } else {
                    apply_bytes(&valid[v], &edits)
                };
                match read_reply(&mut &bytes[..], 64) {
                    Ok((h, d)) if !h.is_object() || d.len() > 64 => {
                        Err(format!("read {} bytes, header {h}", d.len()))
                    }
                    _ => Ok(()),
                }
            },
        );
    }

    #[test]
    fn the_pins_are_those_setup_and_the_wheel_install() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let requirements =
            fs_err::read_to_string(root.join("scripts/warp-requirements.txt")).unwrap();
        let pyproject = fs_err::read_to_string(root.join("pyproject.toml")).unwrap();
        for (package, version) in WARP_PINS {
            let pin = format!("{package}=={version}");
            assert!(requirements.lines().any(|l| l.trim() == pin), "{pin}");
            assert!(
                pyproject.contains(&format!("\"{pin};")),
                "{pin} in pyproject"
            );
        }
    }
}
