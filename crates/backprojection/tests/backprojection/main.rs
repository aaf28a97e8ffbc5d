//! backprojection's integration tests, linked as one binary (one module per former test binary).
mod accuracy;
mod frame;
mod gpu_twin;
mod support;
