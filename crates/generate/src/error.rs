//! Errors of the generate stage.

use std::path::PathBuf;

/// Why generation could not go on.
#[derive(Debug, thiserror::Error)]
pub enum GenerateError {
    /// A source episode cannot serve as a source.
    #[error("source episode '{episode}': {message}")]
    Source {
        /// The episode's id.
        episode: String,
        /// Why.
        message: String,
    },
    /// The task spec lacks what generation needs.
    #[error("task spec: {0}")]
    Spec(String),
    /// The output folder holds another run's episodes.
    #[error(
        "'{path}' was generated with other settings ({difference}): choose another --out, or give --overwrite to replace it"
    )]
    OtherRun {
        /// The output folder.
        path: PathBuf,
        /// The first difference.
        difference: String,
    },
    /// The output folder holds files generate did not write.
    #[error("'{path}' holds '{name}', which generate does not write: it is not written into")]
    Foreign {
        /// The output folder.
        path: PathBuf,
        /// The first foreign entry.
        name: String,
    },
    /// The pose figure could not be drawn.
    #[error("drawing '{path}': {message}")]
    Figure {
        /// The figure's file.
        path: PathBuf,
        /// Why.
        message: String,
    },
    /// The simulation failed.
    #[error(transparent)]
    Sim(#[from] dexjoco_sim::SimError),
    /// Recording an attempt failed (stepping, or making its episode).
    #[error(transparent)]
    Plan(#[from] dexjoco_scripted::PlanError),
    /// Rendering the contact sheet failed.
    #[error(transparent)]
    Render(#[from] dexjoco_render::RenderError),
    /// Reading or writing files failed.
    #[error(transparent)]
    Format(#[from] dexjoco_formats::FormatError),
    /// I/O.
    #[error(transparent)]
    Io(#[from] std::io::Error),
}
