//! deep-shadow's integration tests, linked as one binary (one module per topic).
mod common;

mod cpu;
mod frame;
mod gpu_estimator;
mod gpu_twin;
mod on_map;
mod random_sheets;
