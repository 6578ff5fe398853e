//! When a chunk the policy answered reaches the action buffer. Deterministic by default:
//! the chunk asked for at step `t` is merged at step `t + latency` (the latency modelled
//! in control steps), whatever the machine's and the server's speed, so the same seed and
//! policy give the same rollouts everywhere. In real time (`--real-time`), as the
//! reference client: the server is asked on a thread of its own while the loop runs at
//! 30 Hz, and a chunk is merged at the first step after it arrives.

use std::sync::mpsc::{Receiver, Sender, TryRecvError};
use std::time::Instant;

use rmpv::Value;

use crate::error::EvalError;
use crate::protocol::PolicyClient;

/// A chunk ready to merge: its rows and the step of the observation it answers.
pub(crate) struct Chunk {
    pub(crate) actions: Vec<Vec<f64>>,
    pub(crate) obs_step: usize,
}

/// How answers reach the loop.
pub(crate) enum Inference {
    /// Asked and answered at once, merged `latency` steps later.
    Modelled {
        client: Box<PolicyClient>,
        latency: usize,
        pending: Option<(Chunk, usize)>,
        seconds: Vec<f64>,
    },
    /// Asked on a thread; merged when it arrives.
    RealTime {
        ask: Sender<(Value, usize)>,
        answers: Receiver<Result<(Chunk, f64), EvalError>>,
        in_flight: bool,
        seconds: Vec<f64>,
        uri: String,
    },
}

impl Inference {
    /// Deterministic inference over `client`.
    pub(crate) fn modelled(client: PolicyClient, latency: usize) -> Self {
        Self::Modelled {
            client: Box::new(client),
            latency,
            pending: None,
            seconds: Vec::new(),
        }
    }

    /// Real-time inference: `client` moves to a thread of its own.
    pub(crate) fn real_time(client: PolicyClient, uri: &str) -> Self {
        let (ask, asked) = std::sync::mpsc::channel::<(Value, usize)>();
        let (tell, answers) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut client = client;
            for (obs, step) in asked {
                let started = Instant::now();
                let r = client.infer(&obs, step).map(|actions| {
                    let chunk = Chunk {
                        actions,
                        obs_step: step,
                    };
                    (chunk, started.elapsed().as_secs_f64())
                });
                let failed = r.is_err();
                if tell.send(r).is_err() || failed {
                    break;
                }
            }
            client.close();
        });
        Self::RealTime {
            ask,
            answers,
            in_flight: false,
            seconds: Vec::new(),
            uri: uri.to_owned(),
        }
    }

    /// Whether an observation is out and its chunk not merged yet.
    pub(crate) fn in_flight(&self) -> bool {
        match self {
            Self::Modelled { pending, .. } => pending.is_some(),
            Self::RealTime { in_flight, .. } => *in_flight,
        }
    }

    /// Sends the observation of step `step`.
    pub(crate) fn ask(&mut self, obs: Value, step: usize) -> Result<(), EvalError> {
        match self {
            Self::Modelled {
                client,
                latency,
                pending,
                seconds,
            } => {
                let started = Instant::now();
                let actions = client.infer(&obs, step)?;
                seconds.push(started.elapsed().as_secs_f64());
                *pending = Some((
                    Chunk {
                        actions,
                        obs_step: step,
                    },
                    step + *latency,
                ));
                Ok(())
            }
            Self::RealTime {
                ask,
                in_flight,
                uri,
                ..
            } => {
                ask.send((obs, step)).map_err(|_| EvalError::Server {
                    uri: uri.clone(),
                    message: "the inference thread ended".into(),
                    hint: None,
                })?;
                *in_flight = true;
                Ok(())
            }
        }
    }

    /// The chunk to merge at step `now`, if one is due.
    pub(crate) fn due(&mut self, now: usize) -> Result<Option<Chunk>, EvalError> {
        match self {
            Self::Modelled { pending, .. } => {
                if pending.as_ref().is_some_and(|(_, due)| *due <= now) {
                    Ok(pending.take().map(|(c, _)| c))
                } else {
                    Ok(None)
                }
            }
            Self::RealTime {
                answers,
                in_flight,
                seconds,
                uri,
                ..
            } => match answers.try_recv() {
                Ok(r) => {
                    let (chunk, s) = r?;
                    *in_flight = false;
                    seconds.push(s);
                    Ok(Some(chunk))
                }
                Err(TryRecvError::Empty) => Ok(None),
                Err(TryRecvError::Disconnected) => Err(EvalError::Server {
                    uri: uri.clone(),
                    message: "the inference thread ended".into(),
                    hint: None,
                }),
            },
        }
    }

    /// Waits for a chunk in flight to arrive and drops it (between episodes).
    pub(crate) fn drain(&mut self) -> Result<(), EvalError> {
        match self {
            Self::Modelled { pending, .. } => {
                *pending = None;
                Ok(())
            }
            Self::RealTime {
                answers, in_flight, ..
            } => {
                if *in_flight {
                    answers
                        .recv()
                        .map_err(|_| EvalError::Worker("the inference thread ended".into()))??;
                    *in_flight = false;
                }
                Ok(())
            }
        }
    }

    /// Closes the connection (in real time, the thread closes it once its channel ends).
    pub(crate) fn close(self) {
        if let Self::Modelled { client, .. } = self {
            client.close();
        }
    }

    /// The seconds each answer took since the last call.
    pub(crate) fn take_seconds(&mut self) -> Vec<f64> {
        match self {
            Self::Modelled { seconds, .. } | Self::RealTime { seconds, .. } => {
                std::mem::take(seconds)
            }
        }
    }
}
