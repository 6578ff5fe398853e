//! Progress bars on stderr (hidden with --quiet or when stderr is not a terminal): the one
//! drawing of every stage's [`Progress`] callbacks.

use dexjoco_core::Progress;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// A bar of `len` steps labelled `what`.
pub fn bar(len: u64, what: &str, quiet: bool) -> ProgressBar {
    let pb = ProgressBar::new(len);
    if quiet {
        pb.set_draw_target(ProgressDrawTarget::hidden());
    }
    pb.set_style(
        ProgressStyle::with_template(
            "{prefix:>10.bold} [{bar:30}] {pos}/{len} {msg} ({per_sec}, {elapsed}, eta {eta})",
        )
        .expect("static template")
        .progress_chars("=> "),
    );
    pb.set_prefix(what.to_owned());
    pb
}

/// A stage's progress drawn as a bar: totals set its length, steps advance it (the last
/// item named as its message), notes print above it.
#[derive(Debug, Clone)]
pub struct Bar(pub ProgressBar);

impl Bar {
    /// A bar labelled `what`, its length set by the stage.
    pub fn new(what: &str, quiet: bool) -> Self {
        Self(bar(0, what, quiet))
    }

    /// Removes the bar.
    pub fn finish(&self) {
        self.0.finish_and_clear();
    }
}

impl Progress for Bar {
    fn start(&self, total: u64) {
        self.0.set_length(total);
    }

    fn phase(&self, name: &str, total: u64) {
        self.0.set_prefix(name.to_owned());
        self.0.set_message("");
        self.0.reset();
        self.0.set_length(total);
    }

    fn advance(&self, n: u64, item: &str) {
        let name = std::path::Path::new(item)
            .file_name()
            .map_or_else(|| item.to_owned(), |n| n.to_string_lossy().into_owned());
        self.0.set_message(name);
        self.0.inc(n);
    }

    fn note(&self, line: &str) {
        self.0.println(line);
    }
}
