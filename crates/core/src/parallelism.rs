//! How much work runs at once by default: every core this process may use.

/// The cores this process may use (its CPU affinity and quota, as
/// `std::thread::available_parallelism` sees them; 1 when unknown): the default of
/// `--jobs`, and what worker shares are divided from.
pub fn available_cores() -> usize {
    std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get)
}
