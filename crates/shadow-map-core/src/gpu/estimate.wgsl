// Mirrors crates/shadow-map-core/src/gpu/estimate.rs field for field (the layout test there
// checks offsets with naga). Shape codes and the workgroup size are set from Rust as overrides.

override WG: u32;
override LIGHT_RECT: u32;
override LIGHT_DISK: u32;
override LIGHT_SPHERE: u32;
override LIGHT_DIRECTIONAL: u32;
override PLANE_ROUNDING: f32;
override PLANE_SNAP: f32;
// The light's shape code (one of the four above), a switch of the pipeline: every pipeline of a
// module with this head sets it (EstimateUniform::shape_switch), so the light-geometry helpers
// compile to the light's own branch. light_shape in the uniform holds the same value.
override LIGHT_SHAPE: u32;

struct EstimateUniform {
    light_frame: Frame,
    light_shape: u32,
    light_size_x: f32,
    light_size_y: f32,
    light_one_sided: u32,
    light_half_extent: vec2<f32>,
    bias: f32,
    slope_bias: f32,
    kernel_half: i32,
    max_taps: u32,
    inv_samples: f32,
    depth_step: f32,
    probe: u32,
    receiver_plane: u32,
    _pad0: u32,
    _pad1: u32,
}
