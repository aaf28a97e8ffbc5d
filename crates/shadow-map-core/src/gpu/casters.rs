//! Casters from the caller's own vertex and index buffers with per-instance transforms: a
//! renderer keeps its meshes where they are and, each frame, records
//! [`GpuCasterBuilder::encode`], which writes the world-space triangles of every instance into a
//! [`GpuScene`] (three `vec4` per triangle, the position and the mesh's
//! [`CasterMesh::opacity`]: the layout every raster pass of the frame API reads). One compute
//! dispatch per mesh, no readback; the CPU work is per mesh and per instance (a uniform and a
//! transform each), never per triangle. Uploading a [`crate::Scene`] with [`GpuScene::upload`]
//! is the other way to make casters.
//!
//! The caller's buffers need `STORAGE` usage (the pass reads them as `array<u32>`). Positions are
//! three `f32` at `position_offset` bytes into each `vertex_stride`-byte vertex; indices `u16` or
//! `u32` (or none: consecutive vertices); `base_vertex` is added to every index, as in wgpu's
//! `draw_indexed`. Transforms are affine (the last row is ignored). An index past the vertex
//! buffer reads whatever wgpu's bounds checks give (a vertex of the buffer, or zero): never a
//! fault, but a wrong triangle, as a draw call with that index would be.
use super::{
    kernel::{Kernel, SpecializedKernel},
    GpuContext, GpuScene,
};
use crate::{Error, Result};
use bytemuck::{Pod, Zeroable};
use glam::Mat4;

/// The pass's WGSL.
pub const CASTERS_WGSL: &str = include_str!("casters.wgsl");

/// Workgroup size of `build_casters`.
const WG: u32 = 64;

/// How a mesh's indices are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CasterIndices<'a> {
    /// Consecutive vertices, three per triangle.
    None,
    /// `u16` indices in a `STORAGE` buffer (two per 4-byte word, little end first).
    U16(&'a wgpu::Buffer),
    /// `u32` indices in a `STORAGE` buffer.
    U32(&'a wgpu::Buffer),
}

/// One of the caller's meshes.
#[derive(Debug, Clone, Copy)]
pub struct CasterMesh<'a> {
    /// The vertex buffer (`STORAGE` usage).
    pub vertices: &'a wgpu::Buffer,
    /// Bytes per vertex (a multiple of 4).
    pub vertex_stride: u32,
    /// Bytes from a vertex's start to its position (three `f32`; a multiple of 4).
    pub position_offset: u32,
    /// The index buffer, if any.
    pub indices: CasterIndices<'a>,
    /// First index (or first vertex when not indexed).
    pub first_index: u32,
    /// Indices (or vertices when not indexed) of the mesh: a multiple of 3.
    pub index_count: u32,
    /// Added to every index.
    pub base_vertex: i32,
    /// The mesh's opacity in [0, 1] (1: opaque), written into each of its triangles (the
    /// caster buffer's w) for the frames that model semi-transparent casters.
    pub opacity: f32,
}

/// One instance: a mesh (an index into the meshes passed with it) and its model-to-world
/// transform (affine).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CasterInstance {
    /// Index of the mesh.
    pub mesh: usize,
    /// Model to world.
    pub transform: Mat4,
}

/// One dispatch's uniform; mirrors `CasterParams` in `casters.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct CasterParams {
    /// Vertex stride in words.
    pub vertex_stride_words: u32,
    /// Position offset in words.
    pub position_offset_words: u32,
    /// First index.
    pub first_index: u32,
    /// Indices per instance.
    pub index_count: u32,
    /// Added to every index.
    pub base_vertex: i32,
    /// 0: none, 1: u16, 2: u32.
    pub index_kind: u32,
    /// First output triangle.
    pub out_first_triangle: u32,
    /// Instances of the dispatch.
    pub instances: u32,
    /// Invocations per row of the 2D dispatch.
    pub row: u32,
    /// The mesh's opacity, written as each output vertex's w.
    pub opacity: f32,
    /// Padding.
    pub _pad: [u32; 2],
}

/// The pass, prepared once for at most `max_meshes` meshes and `max_instances` instances per
/// frame ([`new`](Self::new)); [`encode`](Self::encode) per frame.
#[derive(Debug)]
pub struct GpuCasterBuilder {
    kernel: Kernel,
    params: wgpu::Buffer,
    transforms: wgpu::Buffer,
    /// A 4-byte placeholder bound as the index buffer of meshes without one.
    no_indices: wgpu::Buffer,
    max_meshes: u32,
    max_instances: u32,
    /// Bytes between two meshes' uniforms.
    params_stride: u64,
    /// Transforms of one mesh start at multiples of this many.
    transform_align: u64,
}

impl GpuCasterBuilder {
    /// Compiles the pass and allocates room for `max_meshes` meshes and `max_instances`
    /// instances per frame.
    pub fn new(ctx: &GpuContext, max_meshes: u32, max_instances: u32) -> Result<Self> {
        let kernel = SpecializedKernel::new(ctx, "casters", &[CASTERS_WGSL], "build_casters", &[])?
            .fixed(ctx)?;
        let limits = ctx.limits();
        let align = (limits.min_uniform_buffer_offset_alignment as u64).max(1);
        let params_stride = (std::mem::size_of::<CasterParams>() as u64).div_ceil(align) * align;
        let transform_align = (limits.min_storage_buffer_offset_alignment as u64 / 64).max(1);
        let (max_meshes, max_instances) = (max_meshes.max(1), max_instances.max(1));
        // Each mesh's transforms may start up to transform_align - 1 slots later.
        let transform_slots = max_instances as u64 + max_meshes as u64 * (transform_align - 1);
        let buffer = |label, size, usage| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: usage | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let (params, transforms, no_indices) = ctx.scoped("casters", || {
            (
                buffer(
                    "casters.params",
                    params_stride * max_meshes as u64,
                    wgpu::BufferUsages::UNIFORM,
                ),
                buffer(
                    "casters.transforms",
                    64 * transform_slots,
                    wgpu::BufferUsages::STORAGE,
                ),
                buffer("casters.no_indices", 4, wgpu::BufferUsages::STORAGE),
            )
        })?;
        Ok(GpuCasterBuilder {
            kernel,
            params,
            transforms,
            no_indices,
            max_meshes,
            max_instances,
            params_stride,
            transform_align,
        })
    }

    /// Triangles `instances` of `meshes` make.
    pub fn triangles(meshes: &[CasterMesh<'_>], instances: &[CasterInstance]) -> u64 {
        instances
            .iter()
            .filter_map(|i| meshes.get(i.mesh))
            .map(|m| m.index_count as u64 / 3)
            .sum()
    }

    /// Writes the meshes' uniforms and the instances' transforms in the encoder's order
    /// ([`GpuContext::write_in`]) and records one dispatch per mesh with instances, writing every
    /// instance's triangles into `out` (mesh by mesh in the order of `meshes`, instances in
    /// their order) and setting `out.triangles`. Errors before anything is recorded
    /// ([`Error::Receivers`] names the mesh or instance, [`Error::Limit`] the capacity): an
    /// instance naming no mesh or with a non-finite transform, a stride, offset or count the
    /// layout cannot take, a vertex or index range beyond its buffer, a buffer without `STORAGE`
    /// usage, more meshes or instances than prepared, more triangles than `out` holds.
    pub fn encode(
        &self,
        ctx: &GpuContext,
        enc: &mut wgpu::CommandEncoder,
        meshes: &[CasterMesh<'_>],
        instances: &[CasterInstance],
        out: &mut GpuScene,
    ) -> Result<()> {
        ctx.check_lost()?;
        let bad = |what: String| Err(Error::Receivers(format!("casters: {what}")));
        for (k, inst) in instances.iter().enumerate() {
            if inst.mesh >= meshes.len() {
                return bad(format!(
                    "instance {k} names mesh {} of {}",
                    inst.mesh,
                    meshes.len()
                ));
            }
            if !inst.transform.is_finite() {
                return bad(format!("instance {k} has a non-finite transform"));
            }
        }
        let max_bind = ctx.limits().max_storage_buffer_binding_size;
        for (k, m) in meshes.iter().enumerate() {
            check_mesh(k, m)?;
            let index_bytes = match m.indices {
                CasterIndices::None => 0,
                CasterIndices::U16(b) | CasterIndices::U32(b) => b.size(),
            };
            if m.vertices.size().max(index_bytes) > max_bind {
                return Err(Error::Limit {
                    what: "caster mesh buffer bytes in one storage binding",
                    requested: m.vertices.size().max(index_bytes),
                    max: max_bind,
                });
            }
        }
        if meshes.len() > self.max_meshes as usize || instances.len() > self.max_instances as usize
        {
            return Err(Error::Limit {
                what: "caster meshes / instances per frame (GpuCasterBuilder::new)",
                requested: meshes.len().max(instances.len()) as u64,
                max: self.max_meshes.min(self.max_instances) as u64,
            });
        }
        let total = Self::triangles(meshes, instances);
        if total > out.capacity() as u64 {
            return Err(Error::Limit {
                what: "caster triangles (GpuScene::with_capacity)",
                requested: total,
                max: out.capacity() as u64,
            });
        }
        if 48 * total > max_bind {
            return Err(Error::Limit {
                what: "caster bytes in one storage binding",
                requested: 48 * total,
                max: max_bind,
            });
        }
        let max_groups = ctx.limits().max_compute_workgroups_per_dimension;
        // Each mesh's transforms, in the instances' order (one pass over the instances).
        let mut by_mesh: Vec<Vec<[f32; 16]>> = vec![Vec::new(); meshes.len()];
        for inst in instances {
            by_mesh[inst.mesh].push(inst.transform.to_cols_array());
        }
        let cast = || {
            meshes
                .iter()
                .zip(&by_mesh)
                .filter(|(m, mats)| !mats.is_empty() && m.index_count >= 3)
        };
        out.semi_transparent = cast().any(|(m, _)| m.opacity < 1.0);
        out.levels = if out.semi_transparent {
            crate::OpacityLevel::of(cast().map(|(m, _)| m.opacity))
        } else {
            Vec::new()
        };
        let mut slot = 0u64; // next transform slot
        let mut first = 0u32; // next output triangle
        for (k, (m, mats)) in meshes.iter().zip(&by_mesh).enumerate() {
            let per = m.index_count / 3;
            if mats.is_empty() || per == 0 {
                continue;
            }
            slot = slot.div_ceil(self.transform_align) * self.transform_align;
            let n = per as u64 * mats.len() as u64;
            let groups = n.div_ceil(WG as u64);
            let gx = groups.min(max_groups as u64) as u32;
            let gy = groups.div_ceil(gx as u64) as u32;
            let params = CasterParams {
                vertex_stride_words: m.vertex_stride / 4,
                position_offset_words: m.position_offset / 4,
                first_index: m.first_index,
                index_count: m.index_count,
                base_vertex: m.base_vertex,
                index_kind: match m.indices {
                    CasterIndices::None => 0,
                    CasterIndices::U16(_) => 1,
                    CasterIndices::U32(_) => 2,
                },
                out_first_triangle: first,
                instances: mats.len() as u32,
                row: gx * WG,
                opacity: m.opacity,
                _pad: [0; 2],
            };
            let p_off = self.params_stride * k as u64;
            ctx.write_in(enc, &self.params, p_off, bytemuck::bytes_of(&params));
            ctx.write_in(enc, &self.transforms, 64 * slot, bytemuck::cast_slice(mats));
            let index_buf = match m.indices {
                CasterIndices::None => &self.no_indices,
                CasterIndices::U16(b) | CasterIndices::U32(b) => b,
            };
            let range = |buffer, offset, size| {
                wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer,
                    offset,
                    size: std::num::NonZeroU64::new(size),
                })
            };
            let group = self.kernel.bind_group(
                ctx,
                "casters",
                &[
                    range(
                        &self.params,
                        p_off,
                        std::mem::size_of::<CasterParams>() as u64,
                    ),
                    m.vertices.as_entire_binding(),
                    index_buf.as_entire_binding(),
                    range(&self.transforms, 64 * slot, 64 * mats.len() as u64),
                    range(&out.vertices, 0, 48 * total),
                ],
            );
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("casters"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.kernel.pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
            drop(pass);
            slot += mats.len() as u64;
            first += n as u32;
        }
        out.triangles = first;
        Ok(())
    }
}

/// The checks [`GpuCasterBuilder::encode`] makes on mesh `k` before recording.
fn check_mesh(k: usize, m: &CasterMesh<'_>) -> Result<()> {
    let bad = |what: String| Err(Error::Receivers(format!("casters: mesh {k}: {what}")));
    if m.vertex_stride == 0
        || !m.vertex_stride.is_multiple_of(4)
        || !m.position_offset.is_multiple_of(4)
    {
        return bad(format!(
            "vertex stride {} and position offset {} must be multiples of 4 (stride > 0)",
            m.vertex_stride, m.position_offset
        ));
    }
    if m.position_offset + 12 > m.vertex_stride {
        return bad(format!(
            "a position at byte {} does not fit a {}-byte vertex",
            m.position_offset, m.vertex_stride
        ));
    }
    if !(0.0..=1.0).contains(&m.opacity) {
        return bad(format!("opacity {} is not in [0, 1]", m.opacity));
    }
    if !m.index_count.is_multiple_of(3) {
        return bad(format!("{} indices are not whole triangles", m.index_count));
    }
    let storage = |b: &wgpu::Buffer| b.usage().contains(wgpu::BufferUsages::STORAGE);
    if !storage(m.vertices) {
        return bad("the vertex buffer needs STORAGE usage".into());
    }
    let end = m.first_index as u64 + m.index_count as u64;
    match m.indices {
        CasterIndices::None => {
            let verts = m.vertices.size() / m.vertex_stride as u64;
            let last = m.base_vertex as i64 + end as i64;
            if m.base_vertex < 0 && m.index_count > 0 || last > verts as i64 {
                return bad(format!(
                    "vertices {}..{last} beyond the buffer's {verts}",
                    m.base_vertex as i64 + m.first_index as i64
                ));
            }
        }
        CasterIndices::U16(b) | CasterIndices::U32(b) => {
            let bytes = if matches!(m.indices, CasterIndices::U16(_)) {
                2
            } else {
                4
            };
            if !storage(b) {
                return bad("the index buffer needs STORAGE usage".into());
            }
            if end * bytes > b.size() {
                return bad(format!(
                    "indices {}..{end} beyond the buffer's {}",
                    m.first_index,
                    b.size() / bytes
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn params_layout_matches_wgsl() {
        test_support::assert_wgsl_layout!(
            CASTERS_WGSL,
            CasterParams {
                vertex_stride_words,
                position_offset_words,
                first_index,
                index_count,
                base_vertex,
                index_kind,
                out_first_triangle,
                instances,
                row,
                opacity
            },
            pad _pad: 2
        );
    }
}
