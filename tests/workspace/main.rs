//! The workspace's integration tests, linked as one binary (each module was once a binary of its
//! own; one link instead of thirteen is most of what they cost CI). `gpu_faults` and
//! `gpu_shared_loss` stay binaries of their own: they destroy devices, the shared one included.
mod support;

mod cancel;
mod cascades;
mod contract;
mod culling_bias;
mod engine_inputs;
mod fit_modes;
mod readme;
mod self_shadow;
mod shaders;
mod stability;
mod sun;
mod threads;
mod toy_method;
mod twins;
