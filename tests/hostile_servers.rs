//! `eval` against policy servers no one here wrote (issue #44): each speaks openpi's
//! websocket protocol up to a point, then sends exactly the bytes of a buggy or hostile
//! server. Every case ends with exit 1 naming what was wrong (no panic, no abort, no
//! half episode), the eval process tree's peak memory at most 1.5 times that of the same
//! run against a well-behaved server (openpi's own), and every stalling server's wait
//! bounded by `--deadline` plus a small margin, measured on the server's side.

mod common;

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::Output;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use common::{PolicyServer, dexjoco, processes_marked, said, without_behaviour_env};
use dexjoco_eval::wire::{self, NdArray, encode};
use rmpv::Value;
use tungstenite::Message;

/// What a hostile server does.
#[derive(Clone)]
enum Behaviour {
    /// Handshake, metadata, then these bytes as the answer to every observation.
    Answer(Vec<u8>),
    /// Handshake, then these bytes as its metadata.
    Metadata(Vec<u8>),
    /// Accepts the TCP connection and never completes the websocket handshake.
    NoHandshake,
    /// Handshake, then never sends its metadata.
    NoMetadata,
    /// Handshake, metadata, then a ping every second instead of an answer.
    Pings,
    /// Handshake, metadata, then an answer's frame header and one byte a second.
    Trickle,
}

/// A server on 127.0.0.1 behaving as told, for every connection; records how long each
/// stall lasted until the client closed the connection.
struct HostileServer {
    port: u16,
    stalls: Arc<Mutex<Vec<Duration>>>,
}

impl HostileServer {
    fn start(how: Behaviour) -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        let stalls = Arc::new(Mutex::new(Vec::new()));
        let log = Arc::clone(&stalls);
        std::thread::spawn(move || {
            for tcp in listener.incoming().flatten() {
                let (how, log) = (how.clone(), Arc::clone(&log));
                std::thread::spawn(move || {
                    if let Some(stall) = serve(tcp, &how) {
                        log.lock().unwrap().push(stall);
                    }
                });
            }
        });
        Self { port, stalls }
    }

    fn stalls(&self) -> Vec<Duration> {
        self.stalls.lock().unwrap().clone()
    }
}

/// The metadata a server sends first: `{"policy": "hostile"}`.
fn metadata() -> Vec<u8> {
    encode(&Value::Map(vec![(
        Value::from("policy"),
        Value::from("hostile"),
    )]))
}

/// Serves one connection; for a stalling behaviour, returns how long the stall lasted
/// until the client closed the connection.
fn serve(tcp: TcpStream, how: &Behaviour) -> Option<Duration> {
    if let Behaviour::NoHandshake = how {
        return Some(stall_until_closed(tcp, Instant::now(), false));
    }
    let mut ws = tungstenite::accept(tcp).ok()?;
    if let Behaviour::NoMetadata = how {
        let started = Instant::now();
        return Some(stall_until_closed(
            ws.get_mut().try_clone().ok()?,
            started,
            false,
        ));
    }
    let first = match how {
        Behaviour::Metadata(bytes) => bytes.clone(),
        _ => metadata(),
    };
    ws.send(Message::binary(first)).ok()?;
    loop {
        match ws.read().ok()? {
            Message::Binary(_) => {}
            Message::Close(_) => return None,
            _ => continue,
        }
        let started = Instant::now();
        match how {
            Behaviour::Answer(bytes) => ws.send(Message::binary(bytes.clone())).ok()?,
            Behaviour::Pings => return Some(ping_until_closed(ws, started)),
            Behaviour::Trickle => {
                let tcp = ws.get_mut();
                // A final binary frame of 4096 bytes (unmasked, from a server) ...
                tcp.write_all(&[0x82, 0x7e, 0x10, 0x00]).ok()?;
                return Some(stall_until_closed(tcp.try_clone().ok()?, started, true));
            }
            _ => unreachable!("handled above"),
        }
    }
}

/// Waits until the client closes `tcp`, writing a byte a second when `trickle`.
fn stall_until_closed(mut tcp: TcpStream, started: Instant, trickle: bool) -> Duration {
    tcp.set_read_timeout(Some(Duration::from_millis(100)))
        .unwrap();
    let mut last = Instant::now();
    let mut buf = [0u8; 4096];
    loop {
        match tcp.read(&mut buf) {
            Ok(0) => return started.elapsed(),
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
            Err(_) => return started.elapsed(),
        }
        if trickle && last.elapsed() >= Duration::from_secs(1) {
            last = Instant::now();
            if tcp.write_all(&[0]).is_err() {
                return started.elapsed();
            }
        }
        if started.elapsed() > Duration::from_secs(120) {
            return started.elapsed();
        }
    }
}

/// Sends a ping every second until the client closes the connection.
fn ping_until_closed(mut ws: tungstenite::WebSocket<TcpStream>, started: Instant) -> Duration {
    ws.get_mut()
        .set_read_timeout(Some(Duration::from_secs(1)))
        .unwrap();
    loop {
        if ws.send(Message::Ping(Vec::new().into())).is_err() {
            return started.elapsed();
        }
        match ws.read() {
            Ok(_) => {}
            Err(tungstenite::Error::Io(e)) if e.kind() == std::io::ErrorKind::WouldBlock => {}
            Err(_) => return started.elapsed(),
        }
        if started.elapsed() > Duration::from_secs(120) {
            return started.elapsed();
        }
    }
}

/// An answer `{"actions": <ndarray>}` with the array's parts given raw.
fn answer(dtype: &str, shape: &[usize], data: Vec<u8>) -> Vec<u8> {
    let shape = shape.to_vec();
    encode(&wire::answer(&NdArray {
        dtype: dtype.into(),
        shape,
        data,
    }))
}

/// `{key: [nil x n]}`: a message of about `n` bytes that builds nothing when walked.
fn nils_under(key: &str, n: u32) -> Vec<u8> {
    let mut m = vec![0x81, 0xa0 | key.len() as u8];
    m.extend(key.as_bytes());
    m.push(0xdd);
    m.extend(n.to_be_bytes());
    m.extend(std::iter::repeat_n(0xc0, n as usize));
    m
}

/// `eval` of hammer_nail on 127.0.0.1, small renders, no videos, short episodes.
const EVAL: &[&str] = &[
    "-q",
    "eval",
    "--task",
    "hammer_nail",
    "--host",
    "127.0.0.1",
    "--server-wait",
    "0",
    "--render-size",
    "224x224",
    "--no-videos",
    "--step-cap",
    "60",
];

/// `eval` of hammer_nail, one episode, small renders, no videos, against `port`, with its
/// process tree's peak memory (KiB).
fn eval(port: u16, out: &Path, extra: &[&str]) -> (Output, u64) {
    let rss = out.with_extension("rss");
    let mut cmd = std::process::Command::new(dexjoco_testkit::python());
    let o = without_behaviour_env(&mut cmd)
        .arg(dexjoco_testkit::workspace_root().join("tests/python/peak_rss.py"))
        .arg(&rss)
        .arg(env!("CARGO_BIN_EXE_dexjoco-data"))
        .args(EVAL)
        .args(["--episodes", "1", "--port", &port.to_string()])
        .args(extra)
        .arg("--output")
        .arg(out)
        .output()
        .unwrap();
    let kib = fs_err::read_to_string(&rss)
        .unwrap()
        .trim()
        .parse()
        .unwrap();
    (o, kib)
}

/// No episode folder and no staging left in `out`.
fn nothing_half_written(out: &Path) -> bool {
    fs_err::read_dir(out).map_or(true, |rd| {
        rd.flatten().all(|e| {
            let n = e.file_name().to_string_lossy().into_owned();
            !n.starts_with("episode_") && n != ".staging"
        })
    })
}

#[test]
fn hostile_answers_are_named_with_bounded_memory() {
    let tmp = tempfile::tempdir().unwrap();
    // The same run against openpi's own server answering well: the memory baseline.
    let good = PolicyServer::start(&["hold"]);
    let (o, baseline) = eval(good.port, &tmp.path().join("good"), &[]);
    assert_eq!(o.status.code(), Some(0), "{}", said(&o));
    let cases: Vec<(&str, Behaviour, &str)> = vec![
        (
            "u1 data shorter than its shape",
            Behaviour::Answer(answer("|u1", &[30, 22], vec![7; 10])),
            "needs 660 bytes of data, it has 10",
        ),
        (
            "an empty dtype",
            Behaviour::Answer(answer("", &[30, 22], vec![])),
            "dtype ''",
        ),
        (
            "shape (10^12, 0) and no data",
            Behaviour::Answer(answer("<f8", &[1_000_000_000_000, 0], vec![])),
            "shape (1000000000000, 0)",
        ),
        (
            "shape (2^32, 2^32), whose product wraps to 0",
            Behaviour::Answer(answer("<f8", &[1 << 32, 1 << 32], vec![])),
            "shape (4294967296, 4294967296)",
        ),
        (
            "64 MiB of nils",
            Behaviour::Answer(vec![0xc0; 64 << 20]),
            "a server may send at most 16 MiB",
        ),
        (
            "15 MiB of nils in an array, no actions",
            Behaviour::Answer(nils_under("pad", 15 << 20)),
            "no 'actions' (it has: pad)",
        ),
        (
            "15 MiB of nested arrays",
            Behaviour::Answer({
                let mut m = vec![0x81, 0xa1, b'x'];
                m.extend(std::iter::repeat_n(0x91, 15 << 20));
                m.push(0xc0);
                m
            }),
            "no 'actions' (it has: x)",
        ),
        (
            "metadata of 15 MiB of nils",
            Behaviour::Metadata(nils_under("m", 15 << 20)),
            "its metadata: more than 65536 values",
        ),
    ];
    for (what, how, expect) in cases {
        let server = HostileServer::start(how);
        let out = tmp.path().join(what.replace(' ', "_"));
        let (o, peak) = eval(server.port, &out, &[]);
        let s = said(&o);
        assert_eq!(o.status.code(), Some(1), "{what}: {s}");
        assert!(s.contains(expect), "{what}: expected '{expect}' in {s}");
        assert!(!s.contains("panicked"), "{what}: {s}");
        assert!(
            nothing_half_written(&out),
            "{what}: something left in {out:?}"
        );
        assert!(
            peak as f64 <= 1.5 * baseline as f64,
            "{what}: peak memory {peak} KiB, against {baseline} KiB with a server that answers well"
        );
        eprintln!("{what}: exit 1, peak {peak} KiB (well-behaved: {baseline} KiB)");
    }
}

#[test]
fn every_wait_for_a_stalling_server_ends_at_the_deadline() {
    let tmp = tempfile::tempdir().unwrap();
    let deadline = 3.0;
    for (how, expect) in [
        (
            Behaviour::NoHandshake,
            "no websocket handshake within the deadline",
        ),
        (Behaviour::NoMetadata, "no metadata within the deadline"),
        (Behaviour::Pings, "no answer within the deadline"),
        (Behaviour::Trickle, "no answer within the deadline"),
    ] {
        let server = HostileServer::start(how);
        let out = tmp.path().join(expect.replace(' ', "_"));
        let (o, _) = eval(server.port, &out, &["--deadline", "3"]);
        let s = said(&o);
        assert_eq!(o.status.code(), Some(1), "{expect}: {s}");
        assert!(s.contains(expect) && s.contains("--deadline 3 s"), "{s}");
        let stalls = server.stalls();
        assert_eq!(stalls.len(), 1, "{expect}: {stalls:?}");
        let waited = stalls[0].as_secs_f64();
        assert!(
            waited >= deadline - 0.2 && waited <= deadline + 1.5,
            "{expect}: the server was kept waiting {waited:.2} s with --deadline {deadline}"
        );
        assert!(nothing_half_written(&out), "{expect}");
        eprintln!("{expect}: the server waited {waited:.2} s (--deadline {deadline})");
    }
}

#[test]
fn a_run_with_worker_processes_that_fails_leaves_no_process_behind() {
    let tmp = tempfile::tempdir().unwrap();
    let server = HostileServer::start(Behaviour::Answer(answer("", &[30, 22], vec![])));
    let mark = format!("hostile-{}", std::process::id());
    let out = tmp.path().join("run");
    let o = dexjoco()
        .env("DEXJOCO_TEST_MARK", &mark)
        .args(EVAL)
        .args([
            "--episodes",
            "4",
            "-j",
            "2",
            "--port",
            &server.port.to_string(),
        ])
        .arg("--output")
        .arg(&out)
        .output()
        .unwrap();
    let s = said(&o);
    assert_eq!(o.status.code(), Some(1), "{s}");
    assert!(s.contains("dtype ''"), "{s}");
    assert!(nothing_half_written(&out), "{:?}", names(&out));
    assert_eq!(
        processes_marked(&mark, ""),
        Vec::<u32>::new(),
        "workers left behind"
    );
}

fn names(dir: &Path) -> Vec<PathBuf> {
    fs_err::read_dir(dir)
        .map(|rd| rd.flatten().map(|e| e.path()).collect())
        .unwrap_or_default()
}
