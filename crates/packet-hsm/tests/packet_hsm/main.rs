//! packet-hsm's integration tests, linked as one binary (one module per former test binary).
mod common;

mod accuracy;
mod exactness;
mod frame;
mod gpu_twin;
