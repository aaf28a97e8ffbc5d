// V per receiver (the frame API's buffer, row by row from the top) into the view-sized R32Float
// texture the composite pass or the app's material samples. NaN stays NaN: a background pixel,
// or a receiver cut by the device's loop budget (the frame's status counts those).
struct Size {
    width: u32,
    height: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<storage, read> v: array<f32>;
@group(0) @binding(1) var out: texture_storage_2d<r32float, write>;
@group(0) @binding(2) var<uniform> size: Size;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= size.width || id.y >= size.height {
        return;
    }
    textureStore(out, vec2<i32>(id.xy), vec4<f32>(v[id.y * size.width + id.x], 0.0, 0.0, 1.0));
}
