//! Shared helpers of the nerflex benchmarks.
