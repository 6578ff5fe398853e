//! Arguments of `generate`: new demonstrations at new object poses from a few sources.

use std::path::PathBuf;

use clap::{Args, ValueEnum};

use super::TasksDirArgs;

/// How `generate` picks a source segment for each subtask.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ChoiceArg {
    /// Uniformly among the sources, from the seed (MimicGen's default).
    Random,
    /// The source whose reference object was nearest to where it is now.
    Nearest,
}

/// `generate` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Examples:
  dexjoco-data generate --task click_mouse --count 20          # from the sample demo
  dexjoco-data generate demos/hammer_nail --task hammer_nail --count 100 -j 8
  dexjoco-data scripted --task pick_bucket --episodes 3 --seed 1000 --out src/
  dexjoco-data generate src/pick_bucket --task pick_bucket --count 50
  dexjoco-data generate --task fold_glasses --count 500 --dry-run   # how many attempts?
  dexjoco-data generate --task hammer_nail --count 1000 --out /shared/gen --shard auto
  dexjoco-data augment dexjoco-work/generate/click_mouse        # then render them

For each attempt, a reset is drawn from the task spec's placement ranges (attempt k uses
reset k of --seed's draws, as `scripted --seed` draws them); then, subtask by subtask in
the spec's order (each arm on its own, both together for a `both` subtask, waiting where
`after` says), a source's segment of that subtask is chosen, its end-effector targets are
carried from the source's reference-object pose to the object's pose now, bridged from
where the arm is, run through the DexJoCo controller, and the subtask's end checked. An
attempt is kept when the task succeeds.

Sources: raw episode folders, episode stores or MCAP files of the task (default: the
sample demonstration, datasets/demos/<task>). Each is replayed first; one that does not
replay to success, or in which a subtask never ends, is left out and named.

Writes <out>/<task>/episode_NNNNNN (the raw layout, as `scripted` writes it; NNNNNN is the
attempt) with generate.json (reset, source segment and transform per subtask), the
attempts' records in .attempts/, failed attempts' episodes in .failed/ with
--keep-failed, and generate_report.md/.json (success per subtask). The same seed, sources
and scene give the same bytes whatever -j; a killed run continues where it stopped; a
rerun with a larger --count or --max-attempts goes on from there (attempts past the
--count-th success wait in .surplus/ for a later run that needs them).

Shards: --shard I/N makes every N-th attempt into a shared --out and stops once the
attempts of all shards hold --count successes; the same command without --shard afterwards
makes the attempts still missing and writes the report: the folder holds what one
unsharded run writes. scripts/slurm/submit.sh --stage generate N ARGS... submits both.

Exit code 3: fewer than --count episodes succeeded within --max-attempts, or some sources
were left out; 1: nothing succeeded.")]
pub struct GenerateArgs {
    /// Source episodes: raw episode folders, episode stores or MCAP files (default: the
    /// sample demonstration of the task).
    pub inputs: Vec<PathBuf>,
    /// Task id, e.g. click_mouse.
    #[arg(long)]
    pub task: String,
    /// Successful episodes wanted.
    #[arg(long, default_value_t = 10,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=1_000_000))]
    pub count: usize,
    /// Attempts at most (default: 10 x --count).
    #[arg(long, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=10_000_000))]
    pub max_attempts: Option<usize>,
    /// Output folder; episodes go to OUT/<task> (default: <work-dir>/generate).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Scene pack folder (e.g. the DexJoCo reference xmls/); default: built-in scenes.
    #[arg(long)]
    pub scene_dir: Option<PathBuf>,
    /// How a source segment is chosen per subtask.
    #[arg(long, value_enum, default_value = "random")]
    pub choice: ChoiceArg,
    /// Choose a source anew for every subtask (default: each arm keeps the source of its
    /// first subtask, MimicGen's default).
    #[arg(long)]
    pub per_subtask: bool,
    /// Steps a subtask may take to end after its segment ran out, before the attempt fails
    /// there.
    #[arg(long, default_value_t = dexjoco_generate::AttemptOptions::default().grace_steps,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(0..=10_000))]
    pub grace_steps: usize,
    /// Steps a source's replay may go on past its recording, its last action repeated,
    /// to reach its success (a recording made with another MuJoCo may succeed a few steps
    /// late; as augment --extend-steps). Sources that needed it are named in the report;
    /// 0: the strict replay.
    #[arg(long, default_value_t = dexjoco_core::DEFAULT_EXTEND_STEPS, value_name = "N",
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(0..=100_000))]
    pub extend_steps: usize,
    /// Keep failed attempts' episodes (OUT/<task>/.failed/attempt_NNNNNN, with where
    /// they failed).
    #[arg(long)]
    pub keep_failed: bool,
    /// Make a pilot of --pilot attempts, write nothing, and say how many attempts
    /// --count needs and how long they take.
    #[arg(long)]
    pub dry_run: bool,
    /// Attempts of the --dry-run pilot.
    #[arg(long, default_value_t = 10,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=10_000))]
    pub pilot: usize,
    /// Make only this share of the attempts: I/N (0-based; attempts k with k % N == I), or
    /// `auto` from the cluster's environment (Slurm job array, Kubernetes Indexed Job);
    /// then the same command without --shard finishes the run.
    #[arg(long, value_name = "I/N|auto")]
    pub shard: Option<String>,
    /// Replace OUT/<task> written by an earlier generate run with other settings.
    #[arg(long)]
    pub overwrite: bool,
    /// The known tasks.
    #[command(flatten)]
    pub tasks: TasksDirArgs,
}
