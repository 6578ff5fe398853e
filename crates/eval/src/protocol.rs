//! The openpi policy protocol, client side: a websocket to the policy server (openpi's
//! `WebsocketPolicyServer`, or any server speaking it), which first sends its metadata,
//! then answers each observation with a map holding `actions` (an array of shape
//! (horizon, action width)). A text frame is the server's error (its traceback), after
//! which it closes the connection.
//!
//! Every wait for the server is bounded by the deadline in wall-clock time, whatever the
//! server sends meanwhile: the TCP connection, the websocket handshake, the metadata and
//! each answer (sending the observation included). The stream under the websocket
//! ([`DeadlineStream`]) gives each read and write only the time left until the wait's
//! deadline, so pings, partial frames or one byte a second cannot stretch it. Messages
//! are at most [`MAX_MESSAGE_BYTES`] (refused by their header, before their bytes are
//! read), the handshake's response at most 64 KiB, and the bytes are decoded by
//! [`decode`](crate::decode) alone.

use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

use rmpv::Value;
use tungstenite::client::IntoClientRequest;
use tungstenite::handshake::HandshakeError;
use tungstenite::protocol::WebSocketConfig;
use tungstenite::{Message, WebSocket};

use crate::decode::{self, Limits};
use crate::error::EvalError;
use crate::wire;

/// The largest message a server may send (its metadata or an answer): 16 MiB, thousands
/// of times an answer's size ((50, 44) float64 is 17.6 KB).
pub const MAX_MESSAGE_BYTES: usize = 16 << 20;

/// The most bytes of the server's handshake response (HTTP headers).
const MAX_HANDSHAKE_BYTES: u64 = 64 << 10;

/// What a connection waits for, in words (`no <wait> within the deadline`).
#[derive(Debug, Clone, Copy)]
enum Wait {
    Connection,
    Handshake,
    Metadata,
    Answer,
}

impl Wait {
    fn words(self) -> &'static str {
        match self {
            Self::Connection => "connection",
            Self::Handshake => "websocket handshake",
            Self::Metadata => "metadata",
            Self::Answer => "answer",
        }
    }
}

/// A TCP stream whose reads and writes must all end before an instant: each gets only the
/// time left (and fails with `TimedOut` when none is), and reads may be limited to a
/// number of bytes.
struct DeadlineStream {
    tcp: TcpStream,
    until: Option<Instant>,
    read_budget: Option<u64>,
}

impl DeadlineStream {
    /// The time left, or `TimedOut`.
    fn left(&self) -> io::Result<Option<Duration>> {
        match self.until {
            None => Ok(None),
            Some(t) => {
                let left = t.saturating_duration_since(Instant::now());
                if left.is_zero() {
                    Err(io::ErrorKind::TimedOut.into())
                } else {
                    Ok(Some(left))
                }
            }
        }
    }
}

/// A socket timeout (reported as `WouldBlock` on Linux) as `TimedOut`, so that the
/// websocket layer does not take it for a non-blocking socket's "try again".
fn timed_out(e: io::Error) -> io::Error {
    if e.kind() == io::ErrorKind::WouldBlock {
        io::ErrorKind::TimedOut.into()
    } else {
        e
    }
}

impl Read for DeadlineStream {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let left = self.left()?;
        self.tcp.set_read_timeout(left)?;
        let cap = match self.read_budget {
            Some(0) => {
                return Err(io::Error::other(format!(
                    "the handshake's response is longer than {} KiB",
                    MAX_HANDSHAKE_BYTES >> 10
                )));
            }
            Some(b) => buf.len().min(b as usize),
            None => buf.len(),
        };
        let n = self.tcp.read(&mut buf[..cap]).map_err(timed_out)?;
        if let Some(b) = &mut self.read_budget {
            *b -= n as u64;
        }
        Ok(n)
    }
}

impl Write for DeadlineStream {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let left = self.left()?;
        self.tcp.set_write_timeout(left)?;
        self.tcp.write(buf).map_err(timed_out)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.tcp.flush()
    }
}

/// One connection to a policy server.
pub struct PolicyClient {
    socket: WebSocket<DeadlineStream>,
    uri: String,
    metadata: serde_json::Value,
    limits: Limits,
    deadline: Duration,
}

/// The websocket address of `host` and `port` as the reference client forms it (`host`
/// may already be a `ws://` address).
pub fn uri(host: &str, port: Option<u16>) -> String {
    let mut uri = if host.starts_with("ws") {
        host.to_owned()
    } else {
        format!("ws://{host}")
    };
    if let Some(p) = port {
        uri.push_str(&format!(":{p}"));
    }
    uri
}

impl PolicyClient {
    /// Connects (retrying a refused connection until `wait` has passed, as servers take a
    /// moment to start), shakes hands and reads the server's metadata, each within
    /// `deadline`; answers must then fit `limits`.
    pub fn connect(
        uri: &str,
        wait: Duration,
        deadline: Duration,
        limits: Limits,
    ) -> Result<Self, EvalError> {
        let request = uri
            .into_client_request()
            .map_err(|e| usage_of(uri, format!("not a websocket address: {e}")))?;
        if request.uri().scheme_str() != Some("ws") {
            return Err(usage_of(
                uri,
                "only ws:// addresses are supported (openpi's server speaks plain websockets)"
                    .into(),
            ));
        }
        let host = request.uri().host().unwrap_or_default().to_owned();
        let port = request.uri().port_u16().unwrap_or(80);
        let tcp = open_tcp(uri, &host, port, wait, deadline)?;
        tcp.set_nodelay(true).ok();
        let stream = DeadlineStream {
            tcp,
            until: Some(Instant::now() + deadline),
            read_budget: Some(MAX_HANDSHAKE_BYTES),
        };
        let config = WebSocketConfig::default()
            .max_message_size(Some(MAX_MESSAGE_BYTES))
            .max_frame_size(Some(MAX_MESSAGE_BYTES));
        let started = Instant::now();
        let mut socket =
            match tungstenite::client::client_with_config(request, stream, Some(config)) {
                Ok((socket, _)) => socket,
                Err(HandshakeError::Failure(e)) => {
                    return Err(failure(uri, deadline, started, Wait::Handshake, e));
                }
                Err(HandshakeError::Interrupted(_)) => {
                    return Err(timeout(uri, deadline, started, Wait::Handshake));
                }
            };
        socket.get_mut().read_budget = None;
        let mut client = Self {
            socket,
            uri: uri.into(),
            metadata: serde_json::Value::Null,
            limits,
            deadline,
        };
        let bytes = client.receive(Wait::Metadata, Instant::now())?;
        client.metadata = decode::decode_metadata(&bytes)
            .map_err(|e| client.bad(format!("its metadata: {e}")))?;
        Ok(client)
    }

    /// The server's websocket address.
    pub fn uri(&self) -> &str {
        &self.uri
    }

    /// The metadata the server sent first, as JSON.
    pub fn metadata(&self) -> &serde_json::Value {
        &self.metadata
    }

    /// Sends the observation of step `step` (a MessagePack map) and waits for its answer:
    /// the chunk's rows, validated against the limits.
    pub fn infer(&mut self, observation: &Value, step: usize) -> Result<Vec<Vec<f64>>, EvalError> {
        let started = Instant::now();
        self.socket.get_mut().until = Some(started + self.deadline);
        let bytes = wire::encode(observation);
        if let Err(e) = self.socket.send(Message::binary(bytes)) {
            return Err(failure(&self.uri, self.deadline, started, Wait::Answer, e));
        }
        let answer = self.receive(Wait::Answer, started)?;
        decode::decode_answer(&answer, &self.limits).map_err(|e| {
            self.bad(format!(
                "the chunk answering the observation of step {step}: {e}"
            ))
        })
    }

    /// The next binary message, within the deadline of a wait that began at `started`.
    fn receive(&mut self, wait: Wait, started: Instant) -> Result<tungstenite::Bytes, EvalError> {
        self.socket.get_mut().until = Some(started + self.deadline);
        loop {
            let msg = self
                .socket
                .read()
                .map_err(|e| failure(&self.uri, self.deadline, started, wait, e))?;
            let what = wait.words();
            match msg {
                Message::Binary(b) => return Ok(b),
                Message::Text(t) => {
                    let text = t.as_str().trim_end();
                    return Err(self.broken(format!(
                        "the server reported an error instead of its {what}:\n{}",
                        &text[..text.floor_char_boundary(64 << 10)]
                    )));
                }
                Message::Close(c) => {
                    return Err(self.broken(format!(
                        "the server closed the connection while we waited for its {what}{}",
                        c.map(|c| format!(" ({}: {})", c.code, c.reason))
                            .unwrap_or_default()
                    )));
                }
                Message::Ping(_) | Message::Pong(_) | Message::Frame(_) => {}
            }
        }
    }

    fn broken(&self, message: String) -> EvalError {
        EvalError::Server {
            uri: self.uri.clone(),
            message,
            hint: None,
        }
    }

    fn bad(&self, message: String) -> EvalError {
        EvalError::Answer {
            uri: self.uri.clone(),
            message,
        }
    }

    /// Closes the connection politely (within a second).
    pub fn close(mut self) {
        self.socket.get_mut().until = Some(Instant::now() + Duration::from_secs(1));
        let _ = self.socket.close(None);
        let _ = self.socket.flush();
    }
}

/// Opens the TCP connection, each attempt within `deadline`, retrying a refused one until
/// `wait` has passed.
fn open_tcp(
    uri: &str,
    host: &str,
    port: u16,
    wait: Duration,
    deadline: Duration,
) -> Result<TcpStream, EvalError> {
    let start = Instant::now();
    loop {
        let started = Instant::now();
        let attempt = (host, port).to_socket_addrs().and_then(|addrs| {
            let mut last =
                io::Error::new(io::ErrorKind::NotFound, format!("'{host}' has no address"));
            for addr in addrs {
                match TcpStream::connect_timeout(&addr, deadline) {
                    Ok(tcp) => return Ok(tcp),
                    Err(e) => last = e,
                }
            }
            Err(last)
        });
        match attempt {
            Ok(tcp) => return Ok(tcp),
            Err(e) if e.kind() == io::ErrorKind::ConnectionRefused && start.elapsed() < wait => {
                std::thread::sleep(Duration::from_millis(250));
            }
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock
                ) =>
            {
                return Err(timeout(uri, deadline, started, Wait::Connection));
            }
            Err(e) => {
                return Err(EvalError::Server {
                    uri: uri.into(),
                    message: format!("cannot connect: {e}"),
                    hint: Some(
                        "start a policy server first (openpi's `scripts/serve_policy.py`, or \
                         examples/serve_lerobot_policy.py), and give its --host and --port"
                            .into(),
                    ),
                });
            }
        }
    }
}

/// A wait past its deadline, named with how long it lasted.
fn timeout(uri: &str, deadline: Duration, started: Instant, wait: Wait) -> EvalError {
    EvalError::Server {
        uri: uri.into(),
        message: format!(
            "no {} within the deadline: waited {:.1} s (--deadline {} s)",
            wait.words(),
            started.elapsed().as_secs_f64(),
            deadline.as_secs_f64()
        ),
        hint: Some(
            "a policy that needs longer (a first inference compiling, a slow GPU) needs a \
             larger --deadline; otherwise check that the server at this address is an openpi \
             policy server and that it is alive"
                .into(),
        ),
    }
}

/// A websocket error during a wait: the deadline, a message too large, or the connection
/// ending.
fn failure(
    uri: &str,
    deadline: Duration,
    started: Instant,
    wait: Wait,
    e: tungstenite::Error,
) -> EvalError {
    match e {
        tungstenite::Error::Io(io) if io.kind() == io::ErrorKind::TimedOut => {
            timeout(uri, deadline, started, wait)
        }
        tungstenite::Error::Capacity(c) => EvalError::Answer {
            uri: uri.into(),
            message: format!(
                "its {}: {c} (a server may send at most {} MiB)",
                wait.words(),
                MAX_MESSAGE_BYTES >> 20
            ),
        },
        e => EvalError::Server {
            uri: uri.into(),
            message: format!(
                "the connection ended while waiting for its {}: {e}",
                wait.words()
            ),
            hint: None,
        },
    }
}

fn usage_of(uri: &str, message: String) -> EvalError {
    EvalError::Usage(format!("--host/--port '{uri}': {message}"))
}
