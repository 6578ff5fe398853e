//! Progress of long work, as every stage reports it: libraries call a [`Progress`], the
//! command line draws it (a bar on stderr), tests and benchmarks pass [`NoProgress`].

/// Callbacks of a long stage (called from worker threads).
pub trait Progress: Sync {
    /// The work has `total` steps (called again when the total is known better).
    fn start(&self, _total: u64) {}
    /// A new phase of the work, named `name`, of `total` steps (counted from zero).
    fn phase(&self, _name: &str, total: u64) {
        self.start(total);
    }
    /// `n` more steps are done; `item` names the last one (a file, an episode).
    fn advance(&self, _n: u64, _item: &str) {}
    /// A line worth showing above the bar (an episode left out, and why).
    fn note(&self, _line: &str) {}
}

/// Reports nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoProgress;

impl Progress for NoProgress {}
