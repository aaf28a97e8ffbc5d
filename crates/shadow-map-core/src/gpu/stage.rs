//! Uniforms of several views recorded into one command encoder.
//!
//! `queue.write_buffer` takes effect at the next submit, before any command of it, so a uniform
//! written twice while one encoder is recorded holds only the last value for every pass. A
//! [`UniformStage`] keeps one region per slot (a view, a sub-light, an opacity level) in a buffer
//! of its own: [`UniformStage::stage`] writes the slot's value there and records a copy into the
//! uniform the passes bind, so the passes recorded after it read that slot's value.
use super::GpuContext;
use crate::{Error, Result};
use bytemuck::Pod;
use std::marker::PhantomData;

/// Staging for one uniform of type `T` in `slots` slots (see the module docs).
#[derive(Debug)]
pub struct UniformStage<T: Pod> {
    buffer: wgpu::Buffer,
    slots: u32,
    _t: PhantomData<T>,
}

impl<T: Pod> UniformStage<T> {
    /// Bytes per slot: `T`'s size, a multiple of the copy alignment (as every uniform is;
    /// checked when the stage is instantiated), so a value is written and copied as it is.
    const STRIDE: u64 = {
        let size = std::mem::size_of::<T>() as u64;
        assert!(size > 0 && size.is_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT));
        size
    };

    /// Room for `slots` values (at least 1).
    pub fn new(ctx: &GpuContext, label: &str, slots: u32) -> Self {
        let slots = slots.max(1);
        UniformStage {
            buffer: ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: Self::STRIDE * slots as u64,
                usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            slots,
            _t: PhantomData,
        }
    }

    /// Slots this stage holds.
    pub fn slots(&self) -> u32 {
        self.slots
    }

    /// Writes `value` into `slot` and records its copy into `dst` (a buffer with `COPY_DST`
    /// of at least `T`'s size): passes recorded after this read `value`. [`Error::LightView`]
    /// for a slot beyond [`slots`](Self::slots).
    pub fn stage(
        &self,
        queue: &wgpu::Queue,
        enc: &mut wgpu::CommandEncoder,
        slot: usize,
        value: &T,
        dst: &wgpu::Buffer,
    ) -> Result<()> {
        if slot >= self.slots as usize {
            return Err(Error::LightView(format!(
                "view slot {slot} of a frame prepared for {} views",
                self.slots
            )));
        }
        let at = Self::STRIDE * slot as u64;
        queue.write_buffer(&self.buffer, at, bytemuck::bytes_of(value));
        enc.copy_buffer_to_buffer(&self.buffer, at, dst, 0, Self::STRIDE);
        Ok(())
    }
}
