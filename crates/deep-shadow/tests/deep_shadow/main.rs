//! deep-shadow's integration tests, linked as one binary (one module per former test binary).
mod common;

mod cpu;
mod frame;
mod gpu_twin;
