//! Conversion of episodes to LeRobot v3.0 / v2.1 and Diffusion Policy Zarr, with normalization statistics.
//!
//! Not built yet: the `convert` stage is tracked as its own issue, and the CLI says so
//! rather than pretending.
