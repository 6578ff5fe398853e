//! Randomized, validated replays of demonstrations in MuJoCo.
//!
//! Not built yet: the `augment` stage is tracked as its own issue, and the CLI says so
//! rather than pretending.
