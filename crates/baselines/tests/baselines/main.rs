//! baselines' integration tests, linked as one binary (one module per former test binary).
mod accuracy;
mod frame;
mod frame_maps;
mod gpu_twins;
