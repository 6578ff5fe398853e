//! Language-generalization statistics, success-rate tables and dataset summaries.
//!
//! Not built yet: the `stats` stage is tracked as its own issue, and the CLI says so
//! rather than pretending.
