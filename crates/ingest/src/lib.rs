//! Readers and writers of episode files (MCAP teleop logs, the DexJoCo raw layout) and their validation.
//!
//! Not built yet: the `ingest` stage is tracked as its own issue, and the CLI says so
//! rather than pretending.
