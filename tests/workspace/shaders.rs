//! Every WGSL file of the root package (the GPU bench's ceiling kernels) parses and validates with
//! naga, so a shader error fails CPU-only CI too.
#[test]
fn bench_shaders_validate() {
    let src = include_str!("../../benches/gpu_ceilings.wgsl");
    let module =
        naga::front::wgsl::parse_str(src).unwrap_or_else(|e| panic!("{}", e.emit_to_string(src)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{}", e.emit_to_string(src)));
}
