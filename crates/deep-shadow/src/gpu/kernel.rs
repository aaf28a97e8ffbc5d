//! What the frame's list and lookup passes share with `deep_shadow.wgsl`: its WGSL, the
//! constants it takes as pipeline overrides, the counters' size, the element capacity, the
//! per-view uniform ([`DsUniform`]) and the dispatch grid.
use crate::math::{LookupSettings, Node};
use crate::settings::{Filter, Settings, Traversal};
use shadow_map_core::gpu::{estimate::WORKGROUP_SIZE, shared::LOOP_PROBE, GpuContext};

/// The stages of the lists (`clear`, `process`, `link`) and the per-query transmittance of the
/// lists and of the opaque path's depths.
pub const DEEP_SHADOW_WGSL: &str = include_str!("../deep_shadow.wgsl");

/// The list element `Node` and the empty index `NIL`, the part before [`DEEP_SHADOW_WGSL`] and
/// before the insert pass's WGSL.
pub const NODE_WGSL: &str = include_str!("../node.wgsl");

/// The constants the WGSL shares with the CPU twin, passed as pipeline overrides (never copied
/// into the WGSL by hand); the workgroup size and the light codes come from the core's
/// estimate overrides.
pub(crate) const OWN_OVERRIDES: &[(&str, f64)] = &[
    ("NIL", crate::math::NIL as f64),
    ("EDSM_CUTOFF", crate::math::EDSM_CUTOFF as f64),
];

/// The settings `deep_shadow.wgsl`'s stages read (`DsUniform`), one per view. 64 bytes.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct DsUniform {
    /// Resolution r.
    pub r: u32,
    /// Element-buffer capacity (`process` reads it; 0 on the opaque path).
    pub capacity: u32,
    /// Truncation epsilon.
    pub epsilon: f32,
    /// 0 first, 1 none, 2 pcf, 3 edsm, 4 pcss.
    pub filter_mode: u32,
    /// Kernel side N.
    pub kernel: u32,
    /// 0 linked, 1 naive.
    pub traversal: u32,
    /// EDSM c' in world units.
    pub c_world: f32,
    /// pcss: the view's near plane n ([`crate::math::SoftLookup::near`]).
    pub near: f32,
    /// pcss: `r / w` ([`crate::math::SoftLookup::to_texels`]).
    pub to_texels: f32,
    /// pcss: most cells per side ([`crate::math::SoftLookup::max_taps`]).
    pub max_taps: u32,
    /// pcss: light extent l along x ([`crate::math::SoftLookup::light`]).
    pub light_x: f32,
    /// pcss: light extent l along y.
    pub light_y: f32,
    /// pcss: 1 for a disk kernel, 0 for a box ([`crate::math::SoftLookup::disk`]).
    pub disk: u32,
    /// 1 for an orthographic view (the sun): the caster test varies its height, not its slope,
    /// and pcss's widths are world units ([`crate::math::SoftLookup::ortho`]).
    pub ortho: u32,
    /// The loop-budget probe's trip count, always `shadow_map_core::gpu::shared::LOOP_PROBE`
    /// (2) on every stage that loops over lists (process, link, lookups): some devices end a
    /// shader invocation's loops after a budget (llvmpipe: 65535 iterations), and the probe
    /// finds the invocations cut short.
    pub probe: u32,
    /// `process`: the depth window kept behind the truncation point
    /// ([`crate::math::truncation_window`]; 0: truncate right after it).
    pub trunc_window: f32,
}

/// Bytes of the counter buffer: the element counter, the lookup steps, the element counter's
/// wraps, the texels cut short by the loop budget, the elements kept after truncation and the
/// longest list (`Counters` in `deep_shadow.wgsl`).
pub const COUNTER_BYTES: u64 = 24;

/// The most list elements a map may take under `s`: `max_capacity`, the device's binding and the
/// u32 element index (below `NIL`), whichever is least.
pub(crate) fn capacity_cap(ctx: &GpuContext, s: &Settings) -> u64 {
    let l = ctx.limits();
    let device = l.max_storage_buffer_binding_size.min(l.max_buffer_size)
        / std::mem::size_of::<Node>() as u64;
    s.max_capacity.min(device).min(u32::MAX as u64 - 1)
}

/// The element capacity of an `r x r` map (`texels`): the setting (0: four per texel, at least
/// 1024), within `1..=max_cap`.
pub(crate) fn initial_capacity(s: &Settings, texels: u64, max_cap: u64) -> u64 {
    if s.capacity == 0 {
        (4 * texels).max(1024)
    } else {
        s.capacity
    }
    .min(max_cap)
    .max(1)
}

/// `frame_lookup`'s switches for a view whose uniform is `u` (`DS_*` in `deep_shadow.wgsl` and
/// `frame.wgsl`): the filter, the list walk, a disk light, whether the casters are in lists,
/// beside the light's `shape` switch. The uniform keeps the same fields.
pub(crate) fn lookup_switches(
    u: &DsUniform,
    lists: bool,
    shape: (&'static str, f64),
) -> [(&'static str, f64); 5] {
    [
        ("DS_FILTER", u.filter_mode as f64),
        ("DS_TRAVERSAL", u.traversal as f64),
        ("DS_DISK", u.disk as f64),
        ("DS_LISTS", f64::from(u8::from(lists))),
        shape,
    ]
}

/// The uniform of the lookups in an `r x r` map with element capacity `capacity` under `ls`
/// (what `process` reads besides, the truncation, the caller sets).
pub(crate) fn lookup_uniform(r: u32, capacity: u32, ls: &LookupSettings) -> DsUniform {
    DsUniform {
        r,
        capacity,
        epsilon: 0.0,
        filter_mode: match ls.filter {
            Filter::First => 0,
            Filter::None => 1,
            Filter::Pcf => 2,
            Filter::Edsm => 3,
            Filter::Pcss => 4,
        },
        kernel: ls.kernel,
        traversal: match ls.traversal {
            Traversal::Linked => 0,
            Traversal::Naive => 1,
        },
        c_world: ls.c_world,
        near: ls.soft.near,
        to_texels: ls.soft.to_texels,
        max_taps: ls.soft.max_taps,
        light_x: ls.soft.light.x,
        light_y: ls.soft.light.y,
        disk: ls.soft.disk as u32,
        ortho: ls.soft.ortho as u32,
        probe: LOOP_PROBE,
        trunc_window: 0.0,
    }
}

/// Workgroups covering `threads` invocations: one row up to 65535 workgroups, then rows of 65535
/// (the grid `linear_id` in `deep_shadow.wgsl` reads).
pub(crate) fn workgroups(threads: u64) -> [u32; 3] {
    let groups = threads.div_ceil(WORKGROUP_SIZE as u64).max(1);
    let x = groups.min(65535);
    let y = groups.div_ceil(x);
    [x as u32, y as u32, 1]
}
