//! softshadow-cli's integration tests, linked as one binary (one module per former test binary).
mod commands;
mod fuzz;

// The CLI's own EXR reading (it has no library to link): what the tests read back.
#[path = "../../src/exr_io/first_layer.rs"]
mod first_layer;
