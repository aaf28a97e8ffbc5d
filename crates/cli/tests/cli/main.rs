//! softshadow-cli's integration tests, linked as one binary (one module per former test binary).
mod commands;
mod fuzz;
