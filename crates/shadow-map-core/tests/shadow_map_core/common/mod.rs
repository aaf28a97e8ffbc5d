//! Helpers shared by the shadow-map core's integration tests: the unit light view and light of
//! the raster tests, the scene text of the loader tests and, with feature `gpu`, the GPU gate
//! (one shared object per test binary) and naga's view of the WGSL struct layouts.
#![allow(dead_code)] // each test binary uses its own part

use glam::{Vec2, Vec3};
use shadow_map_core::{light_view::LightView, Light, LightFrame, LightShape};

/// A view from the origin down +z with n = 1 and the window [0, r] x [0, r]: at z = 1, texel
/// coordinates equal x and y.
pub fn unit_view(r: u32) -> LightView {
    LightView {
        frame: LightFrame {
            origin: Vec3::ZERO,
            ex: Vec3::X,
            ey: Vec3::Y,
            ez: Vec3::Z,
        },
        n: 1.0,
        far: 100.0,
        window_min: Vec2::ZERO,
        w: r as f32,
        r,
        projection: Default::default(),
    }
}

/// A 1 x 1 rect light at the origin looking down +z (light space = world space).
pub fn unit_light() -> Light {
    Light {
        shape: LightShape::Rect { size: [1.0, 1.0] },
        center: Vec3::ZERO,
        normal: Vec3::Z,
        tangent: Vec3::X,
    }
}

/// Two triangles covering texels [u0, u1] x [v0, v1] of [`unit_view`] at depth z, facing the
/// light at the origin (normal -z).
pub fn quad_uv(u0: f32, v0: f32, u1: f32, v1: f32, z: f32) -> Vec<[Vec3; 3]> {
    let p = |u: f32, v: f32| Vec3::new(u * z, v * z, z);
    let (a, b, c, d) = (p(u0, v0), p(u1, v0), p(u1, v1), p(u0, v1));
    vec![[a, c, b], [a, d, c]]
}

/// The fixture scene `fixtures/<name>/<name>.toml` at `w` x `h` pixels; panics naming the file
/// it could not load (a test's bug).
pub fn fixture(name: &str, w: u32, h: u32) -> shadow_map_core::Scene {
    let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join(format!("../../fixtures/{name}/{name}.toml"));
    let mut s =
        shadow_map_core::Scene::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    s.set_resolution(w, h).unwrap();
    s
}

/// An OBJ quad of two triangles in the y = 0 plane.
pub const QUAD: &str = "v -1 0 -1\nv -1 0 1\nv 1 0 1\nv 1 0 -1\nf 1 2 3\nf 1 3 4\n";

/// A valid scene file (as a literal, for `concat!`) with one mesh `quad.obj` and the mesh table
/// left open for more keys: camera 32 x 24, a 2 x 2 rect light above the origin.
#[allow(unused_macros)]
macro_rules! good_scene_toml {
    () => {
        r#"[camera]
eye = [0.0, 3.0, 6.0]
target = [0.0, 0.5, 0.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = 40.0
width = 32
height = 24

[light]
shape = "rect"
center = [0.0, 6.0, 0.0]
normal = [0.0, -1.0, 0.0]
tangent = [1.0, 0.0, 0.0]
size = [2.0, 2.0]

[[mesh]]
path = "quad.obj"
"#
    };
}
#[allow(unused_imports)]
pub(crate) use good_scene_toml;

#[cfg(feature = "gpu")]
#[allow(unused_imports)] // not every binary uses the GPU part
pub use gpu::*;

// test-support's GPU gate (`context_for_tests`), compiled here by path: this crate's
// dev-dependency leaves test-support's `gpu` feature off, so that CPU-only test builds of this
// crate stay CPU-only. Its other items are unused here; it reads `super::REQUIRE_GPU_ENV`.
#[cfg(feature = "gpu")]
#[path = "../../../../test-support/src/gate.rs"]
#[allow(dead_code)]
mod gate;
#[cfg(feature = "gpu")]
use test_support::REQUIRE_GPU_ENV;

#[cfg(feature = "gpu")]
mod gpu {
    use shadow_map_core::{
        gpu::{GpuContext, SHADERS},
        Error,
    };
    use std::sync::{Arc, OnceLock};

    pub use super::gate::context_for_tests;

    /// The shared context and one object of the whole test binary.
    pub type Shared<T> = (Arc<GpuContext>, Arc<T>);

    /// The shared context and one `T` made by `make` for the whole binary (cached in `cell`; a
    /// failure to make it is an [`Error::Gpu`] at `stage`), or `None` after a loud skip.
    pub fn gpu_with<T>(
        test: &str,
        cell: &OnceLock<Result<Arc<T>, String>>,
        stage: &str,
        make: impl FnOnce(&GpuContext) -> Result<T, Error>,
    ) -> Result<Option<Shared<T>>, Error> {
        let Some(ctx) = context_for_tests(test)? else {
            return Ok(None);
        };
        let made = cell
            .get_or_init(|| make(&ctx).map(Arc::new).map_err(|e| e.to_string()))
            .clone()
            .map_err(|reason| Error::Gpu {
                stage: stage.into(),
                reason,
            })?;
        Ok(Some((ctx, made)))
    }

    /// naga's view of one struct: span, alignment and (member, offset, size) in order.
    pub struct WgslStruct {
        pub span: u32,
        pub align: u32,
        pub members: Vec<(String, u32, u32)>,
    }

    /// The layout of struct `name` of shader `shader` (by its name in [`SHADERS`]), from naga's
    /// layouter; asserts that the layouter's size is the struct's span.
    pub fn wgsl_struct(shader: &str, name: &str) -> WgslStruct {
        let src = SHADERS
            .iter()
            .find(|(n, _)| *n == shader)
            .unwrap_or_else(|| panic!("no shader {shader}"))
            .1;
        let module = naga::front::wgsl::parse_str(src)
            .unwrap_or_else(|e| panic!("{shader}: {}", e.emit_to_string(src)));
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).expect("layouter");
        let (handle, ty) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("{shader}: no struct {name}"));
        let naga::TypeInner::Struct { members, span } = &ty.inner else {
            panic!("{name} is not a struct");
        };
        let layout = layouter[handle];
        assert_eq!(layout.size, *span);
        let members = members
            .iter()
            .map(|m| {
                (
                    m.name.clone().unwrap_or_default(),
                    m.offset,
                    layouter[m.ty].size,
                )
            })
            .collect();
        WgslStruct {
            span: *span,
            // Alignment as a number: the smallest multiple of it that is >= 1.
            align: layout.alignment.round_up(1),
            members,
        }
    }

    /// Asserts that a Rust struct of `size` and `align` with `(name, offset, size)` members
    /// mirrors `wgsl`.
    pub fn assert_mirrors(
        wgsl: &str,
        w: &WgslStruct,
        size: usize,
        align: usize,
        rust: &[(&str, usize, usize)],
    ) {
        assert_eq!(w.span as usize, size, "{}: span", wgsl);
        assert_eq!(w.align as usize, align, "{}: alignment", wgsl);
        assert_eq!(w.members.len(), rust.len(), "{}: member count", wgsl);
        for ((wname, woff, wsize), (rname, roff, rsize)) in w.members.iter().zip(rust) {
            assert_eq!(wname, rname, "{}: member order", wgsl);
            assert_eq!(*woff as usize, *roff, "{}.{}: offset", wgsl, wname);
            assert_eq!(*wsize as usize, *rsize, "{}.{}: size", wgsl, wname);
        }
    }
}

/// Asserts that `$rust` mirrors WGSL struct `$wgsl` of shader `$shader`, member by member in
/// declaration order: `[wgsl_name => rust_field, ..]`, or `[field, ..]` where the names agree.
#[cfg(feature = "gpu")]
#[allow(unused_macros)]
macro_rules! check_layout {
    ($shader:literal, $wgsl:literal, $rust:ty, [$($field:ident),* $(,)?]) => {
        $crate::common::check_layout!($shader, $wgsl, $rust, [$(stringify!($field) => $field),*])
    };
    ($shader:literal, $wgsl:literal, $rust:ty, [$($wname:expr => $field:ident),* $(,)?]) => {{
        let w = $crate::common::wgsl_struct($shader, $wgsl);
        let zero: $rust = bytemuck::Zeroable::zeroed();
        let rust: Vec<(&str, usize, usize)> = vec![
            $((
                $wname,
                std::mem::offset_of!($rust, $field),
                std::mem::size_of_val(&zero.$field),
            )),*
        ];
        $crate::common::assert_mirrors(
            $wgsl,
            &w,
            std::mem::size_of::<$rust>(),
            std::mem::align_of::<$rust>(),
            &rust,
        );
    }};
}
#[cfg(feature = "gpu")]
#[allow(unused_imports)]
pub(crate) use check_layout;
