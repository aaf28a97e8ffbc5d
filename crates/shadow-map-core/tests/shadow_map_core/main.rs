//! shadow-map-core's integration tests, linked as one binary (one module per former test binary).
mod common;

mod depth_receivers;
mod fuzz;
mod gltf;
mod gpu_active;
mod gpu_casters;
mod gpu_context;
mod gpu_gbuffer;
mod gpu_maps;
mod gpu_opacity;
mod gpu_precision;
mod gpu_settle;
mod layouts;
mod raster;
mod scene_errors;
