//! The openpi policy protocol, client side: a websocket to the policy server (openpi's
//! `WebsocketPolicyServer`, or any server speaking it), which first sends its metadata,
//! then answers each observation with a map holding `actions` (an array of shape
//! (horizon, action width)). A text frame is the server's error (its traceback), after
//! which it closes the connection.

use std::net::TcpStream;
use std::time::{Duration, Instant};

use rmpv::Value;
use tungstenite::stream::MaybeTlsStream;
use tungstenite::{Message, WebSocket};

use crate::error::EvalError;
use crate::wire::{self, NdArray};

/// One connection to a policy server.
pub struct PolicyClient {
    socket: WebSocket<MaybeTlsStream<TcpStream>>,
    uri: String,
    metadata: Value,
}

/// An answer: the action chunk (rows of the policy's action layout) and the rest of the
/// response as JSON (timings the server adds).
#[derive(Debug, Clone)]
pub struct Answer {
    /// The actions, one row per step.
    pub actions: Vec<Vec<f64>>,
    /// `server_timing` and any other keys, readable.
    pub extra: serde_json::Value,
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
    /// moment to start) and reads the server's metadata. `deadline` bounds every answer.
    pub fn connect(uri: &str, wait: Duration, deadline: Duration) -> Result<Self, EvalError> {
        let start = Instant::now();
        let (mut socket, _) = loop {
            match tungstenite::connect(uri) {
                Ok(ok) => break ok,
                Err(e) if start.elapsed() < wait && refused(&e) => {
                    std::thread::sleep(Duration::from_millis(250));
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
        };
        if let MaybeTlsStream::Plain(tcp) = socket.get_mut() {
            tcp.set_read_timeout(Some(deadline)).ok();
            tcp.set_nodelay(true).ok();
        }
        let mut client = Self {
            socket,
            uri: uri.into(),
            metadata: Value::Nil,
        };
        client.metadata = client.receive("its metadata")?;
        Ok(client)
    }

    /// The server's websocket address.
    pub fn uri(&self) -> &str {
        &self.uri
    }

    /// The metadata the server sent first.
    pub fn metadata(&self) -> &Value {
        &self.metadata
    }

    /// Sends one observation (a MessagePack map) and waits for its answer.
    pub fn infer(&mut self, observation: &Value) -> Result<Answer, EvalError> {
        let bytes = wire::encode(observation);
        self.socket
            .send(Message::binary(bytes))
            .map_err(|e| self.broken(format!("sending an observation failed: {e}")))?;
        let v = self.receive("an answer")?;
        let actions = wire::get(&v, "actions").ok_or_else(|| {
            self.bad(format!(
                "the answer has no 'actions' (it has: {})",
                keys(&v).join(", ")
            ))
        })?;
        let array = NdArray::from_value(actions)
            .ok_or_else(|| self.bad("'actions' is not a numpy array".into()))?;
        let values = array.to_f64().ok_or_else(|| {
            self.bad(format!(
                "'actions' of dtype {} and shape {:?} is not an array of numbers",
                array.dtype, array.shape
            ))
        })?;
        let (rows, width) = match array.shape.as_slice() {
            [h, w] => (*h, *w),
            s => return Err(self.bad(format!("'actions' has shape {s:?}, not (horizon, width)"))),
        };
        let actions = (0..rows)
            .map(|r| values[r * width..(r + 1) * width].to_vec())
            .collect();
        let mut extra = wire::to_json(&v);
        if let Some(o) = extra.as_object_mut() {
            o.remove("actions");
        }
        Ok(Answer { actions, extra })
    }

    fn receive(&mut self, what: &str) -> Result<Value, EvalError> {
        loop {
            let msg = self.socket.read().map_err(|e| match e {
                tungstenite::Error::Io(io)
                    if matches!(
                        io.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    self.broken(format!(
                        "no answer within the deadline while waiting for {what}"
                    ))
                }
                e => self.broken(format!(
                    "the connection ended while waiting for {what}: {e}"
                )),
            })?;
            match msg {
                Message::Binary(b) => {
                    return wire::decode(&b).map_err(|e| self.bad(format!("{what}: {e}")));
                }
                Message::Text(t) => {
                    return Err(self.broken(format!(
                        "the server reported an error instead of {what}:\n{}",
                        t.as_str().trim_end()
                    )));
                }
                Message::Close(c) => {
                    return Err(self.broken(format!(
                        "the server closed the connection while we waited for {what}{}",
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

    /// Closes the connection politely.
    pub fn close(mut self) {
        let _ = self.socket.close(None);
        let _ = self.socket.flush();
    }
}

fn keys(v: &Value) -> Vec<String> {
    v.as_map()
        .map(|m| {
            m.iter()
                .map(|(k, _)| match k {
                    Value::String(s) => s.as_str().unwrap_or("?").to_owned(),
                    Value::Binary(b) => String::from_utf8_lossy(b).into_owned(),
                    o => o.to_string(),
                })
                .collect()
        })
        .unwrap_or_default()
}

fn refused(e: &tungstenite::Error) -> bool {
    match e {
        tungstenite::Error::Io(io) => io.kind() == std::io::ErrorKind::ConnectionRefused,
        tungstenite::Error::Url(tungstenite::error::UrlError::UnableToConnect(_)) => true,
        _ => false,
    }
}
