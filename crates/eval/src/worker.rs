//! An `eval` worker process's side: it reads the run (the `hello`), opens its renderer
//! (saying on which EGL device, then that it drew its first frame, as `dexjoco-workers`'
//! deadlines expect), connects to the policy server, then runs each episode it is given,
//! telling the parent after every step (a parent that has gone ends the worker before it
//! commits anything) and when the episode is committed. Every failure is run-wide: a
//! server that answers badly answers every worker badly.

use std::io::{BufRead, Write};

use dexjoco_workers::serve::{FromParent, tell};
use dexjoco_workers::{Failure, FromWorker};

use crate::error::{EvalError, one_line};
use crate::inference::Inference;
use crate::run::{EpisodeDone, EpisodeJob, WorkerHello, connect, inference_over, run_one};
use crate::stage::{Stage, run_spec};

type Message = FromWorker<EpisodeDone>;

/// What a ready worker holds between episodes.
struct Ready {
    stage: Stage,
    inference: Inference,
    metadata: serde_json::Value,
}

/// The worker side: reads the `hello` and the episodes to run from `input`, answers on
/// `output`. Returns when `input` ends.
pub fn serve_worker(input: impl BufRead, mut output: impl Write) -> Result<(), EvalError> {
    let mut parent = FromParent::new(input);
    let Some(hello) = parent.hello::<WorkerHello>().map_err(EvalError::Worker)? else {
        return Ok(());
    };
    let mut ready = prepare(hello, &mut output).map_err(|e| one_line(&e));
    while let Some((_attempt, job)) = parent.job::<EpisodeJob>().map_err(EvalError::Worker)? {
        let msg = match &mut ready {
            Err(why) => Message::Failed(Failure::run_wide(why.clone())),
            Ok(r) => episode(r, &job, &mut output),
        };
        tell(&mut output, &msg);
    }
    if let Ok(r) = ready {
        r.inference.close();
    }
    Ok(())
}

/// Opens the renderer (drawing a first frame) and connects to the server.
fn prepare(hello: WorkerHello, output: &mut dyn Write) -> Result<Ready, EvalError> {
    let WorkerHello { config } = hello;
    tell(output, &Message::Opening);
    let mut stage = match Stage::new(&config) {
        Ok(s) => s,
        Err(e) if cannot_render(&e) => {
            tell(output, &Message::CannotRender(one_line(&e)));
            return Err(e);
        }
        Err(e) => return Err(e),
    };
    tell(output, &Message::Device(stage.device_words()));
    if let Err(e) = stage.warm_up() {
        tell(output, &Message::CannotRender(one_line(&e)));
        return Err(e);
    }
    tell(output, &Message::Ready);
    let spec = run_spec(&config)?;
    let client = connect(&config, &spec)?;
    let metadata = client.metadata().clone();
    Ok(Ready {
        inference: inference_over(&config, client),
        stage,
        metadata,
    })
}

/// Whether an error says that this machine cannot render here.
fn cannot_render(e: &EvalError) -> bool {
    matches!(
        e,
        EvalError::Sim {
            source: dexjoco_render::RenderError::Egl(_),
            ..
        }
    )
}

/// Runs and commits an episode, telling the parent after every step.
fn episode(r: &mut Ready, job: &EpisodeJob, output: &mut dyn Write) -> Message {
    let (k, state0) = (job.episode, &job.state);
    let mut tick = || tell(output, &Message::Progress(1));
    match run_one(
        &mut r.stage,
        &mut r.inference,
        k,
        state0,
        &r.metadata,
        &mut tick,
    ) {
        Ok(record) => Message::Done(EpisodeDone {
            episode: k,
            success: record.success,
        }),
        Err(e) => Message::Failed(Failure::run_wide(one_line(&e))),
    }
}
