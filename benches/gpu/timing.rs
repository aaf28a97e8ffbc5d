//! How the GPU bench takes time: one-submit batches with pass- or encoder-level timestamps,
//! public calls that submit by themselves, and CPU stages (`benches/README.md`, "How time is
//! taken").
use crate::BenchResult;
use shadow_map_core::gpu::GpuContext;
use std::time::Instant;

/// Timed iterations per measurement: at least, at most.
const MIN_ITERS: u32 = 3;
const MAX_ITERS: u32 = 50;
/// Per-iteration GPU allocations (textures, MSSM planes) stay alive until the batch finishes:
/// the iteration count is capped so a batch holds at most this much.
const BYTES_IN_FLIGHT: u64 = 4 << 30;

/// How a row's time was taken.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Method {
    /// GPU timestamp queries around each iteration's pass (or its commands, encoder-level),
    /// averaged over the iterations.
    Timestamps,
    /// All iterations recorded into one encoder, then wall clock from one submit to one wait.
    WallOneSubmit,
    /// Iterations issued through a public call that submits by itself (T submits), wall clock
    /// from the first call to one wait: includes the calls' host-side recording.
    WallCalls,
    /// CPU backend: wall clock of T calls.
    Cpu,
}

impl Method {
    pub fn label(self) -> &'static str {
        match self {
            Method::Timestamps => "timestamps",
            Method::WallOneSubmit => "wall, 1 submit",
            Method::WallCalls => "wall, T calls",
            Method::Cpu => "wall (CPU)",
        }
    }
}

/// Per-iteration times of one measurement.
#[derive(Debug, Clone)]
pub struct Timing {
    pub iters: u32,
    /// Wall clock per iteration (submit to wait, or first call to wait).
    pub wall_ms: f64,
    /// GPU timestamps per iteration, when taken.
    pub gpu_ms: Option<f64>,
    /// Host time per iteration spent recording (one-submit batches) or in the calls themselves.
    pub host_ms: f64,
    /// The time the row reports.
    pub method: Method,
    /// Why timestamps were not used, when they were taken but not trusted.
    pub note: Option<String>,
}

impl Timing {
    pub fn ms(&self) -> f64 {
        match (self.method, self.gpu_ms) {
            (Method::Timestamps, Some(g)) => g,
            _ => self.wall_ms,
        }
    }
}

/// Where the timestamp queries of one iteration go.
#[derive(Clone, Copy)]
pub struct Stamp<'a> {
    set: &'a wgpu::QuerySet,
    begin: u32,
    end: u32,
}

impl<'a> Stamp<'a> {
    pub fn compute(self) -> wgpu::ComputePassTimestampWrites<'a> {
        wgpu::ComputePassTimestampWrites {
            query_set: self.set,
            beginning_of_pass_write_index: Some(self.begin),
            end_of_pass_write_index: Some(self.end),
        }
    }
    pub fn render(self) -> wgpu::RenderPassTimestampWrites<'a> {
        wgpu::RenderPassTimestampWrites {
            query_set: self.set,
            beginning_of_pass_write_index: Some(self.begin),
            end_of_pass_write_index: Some(self.end),
        }
    }
}

/// Where a one-submit measurement can put timestamps.
#[derive(Clone, Copy, PartialEq)]
pub enum StampAt {
    /// The recorder writes them as its pass's `timestamp_writes` (`TIMESTAMP_QUERY`).
    Pass,
    /// The runner writes them on the encoder around the recorder's commands
    /// (`TIMESTAMP_QUERY_INSIDE_ENCODERS`): for public calls that record their own passes.
    Encoder,
}

/// The device under test and how to time it.
pub struct Gpu<'a> {
    pub ctx: &'a GpuContext,
    /// `TIMESTAMP_QUERY` enabled on the device.
    pub pass_stamps: bool,
    /// `TIMESTAMP_QUERY_INSIDE_ENCODERS` enabled on the device.
    pub encoder_stamps: bool,
    /// Nanoseconds per timestamp tick.
    pub period_ns: f64,
    /// A CPU adapter (lavapipe): wall clock is the truth there, and its timestamps were seen wrong
    /// for buffer-only passes (docs/methods.md §12), so they are reported but not used.
    pub cpu_adapter: bool,
    pub budget_ms: f64,
}

impl<'a> Gpu<'a> {
    pub fn new(ctx: &'a GpuContext, budget_s: f64) -> Self {
        let f = ctx.device.features();
        Gpu {
            ctx,
            pass_stamps: f.contains(wgpu::Features::TIMESTAMP_QUERY),
            encoder_stamps: f.contains(wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS),
            period_ns: ctx.queue.get_timestamp_period() as f64,
            cpu_adapter: ctx
                .adapter
                .as_ref()
                .is_some_and(|a| a.device_type == wgpu::DeviceType::Cpu),
            budget_ms: budget_s * 1e3,
        }
    }

    /// Iterations for a measurement whose single iteration took `probe_ms` and holds
    /// `bytes_per_iter` of GPU memory until the batch ends.
    fn iters(&self, probe_ms: f64, bytes_per_iter: u64) -> u32 {
        let by_time = (self.budget_ms / probe_ms.max(1e-3)).floor() as u64;
        let by_memory = BYTES_IN_FLIGHT / bytes_per_iter.max(1);
        by_time
            .min(by_memory)
            .clamp(MIN_ITERS as u64, MAX_ITERS as u64) as u32
    }

    fn wait(&self) -> BenchResult<()> {
        Ok(self.ctx.wait()?)
    }

    /// Times `record` (one iteration's commands) with every iteration in one encoder, one submit
    /// and one wait; timestamps at `stamp_at` when the device has them. Warm-up and a probe
    /// iteration (untimed, for the iteration count) come first.
    pub fn time_encoded(
        &self,
        stamp_at: StampAt,
        bytes_per_iter: u64,
        mut record: impl FnMut(&mut wgpu::CommandEncoder, Option<Stamp<'_>>) -> BenchResult<()>,
    ) -> BenchResult<Timing> {
        let device = &self.ctx.device;
        let batch = |n: u32,
                     set: Option<&wgpu::QuerySet>,
                     record: &mut dyn FnMut(
            &mut wgpu::CommandEncoder,
            Option<Stamp<'_>>,
        ) -> BenchResult<()>|
         -> BenchResult<(f64, f64)> {
            let t_rec = Instant::now();
            let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("bench"),
            });
            for i in 0..n {
                let stamp = set.map(|set| Stamp {
                    set,
                    begin: 2 * i,
                    end: 2 * i + 1,
                });
                match (stamp_at, stamp) {
                    (StampAt::Encoder, Some(s)) => {
                        enc.write_timestamp(s.set, s.begin);
                        record(&mut enc, None)?;
                        enc.write_timestamp(s.set, s.end);
                    }
                    _ => record(&mut enc, stamp)?,
                }
            }
            let cmd = enc.finish();
            let host = t_rec.elapsed().as_secs_f64() * 1e3;
            let t0 = Instant::now();
            self.ctx.queue.submit([cmd]);
            self.wait()?;
            Ok((t0.elapsed().as_secs_f64() * 1e3, host))
        };
        batch(1, None, &mut record)?;
        let (probe, _) = batch(1, None, &mut record)?;
        let iters = self.iters(probe, bytes_per_iter);
        let stamps = match stamp_at {
            StampAt::Pass => self.pass_stamps,
            StampAt::Encoder => self.encoder_stamps,
        };
        let set = stamps.then(|| {
            device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("bench.timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2 * iters,
            })
        });
        let (wall, host) = batch(iters, set.as_ref(), &mut record)?;
        let gpu_ms = match &set {
            Some(set) => Some(self.read_stamps(set, iters)?),
            None => None,
        };
        let n = iters as f64;
        Ok(self.timing(iters, wall / n, gpu_ms, host / n, Method::WallOneSubmit))
    }

    /// Times a public call that records and submits by itself: T calls, then one wait.
    pub fn time_calls(
        &self,
        bytes_per_iter: u64,
        mut call: impl FnMut() -> BenchResult<()>,
    ) -> BenchResult<Timing> {
        let mut run = |n: u32| -> BenchResult<(f64, f64)> {
            let t0 = Instant::now();
            for _ in 0..n {
                call()?;
            }
            let host = t0.elapsed().as_secs_f64() * 1e3;
            self.wait()?;
            Ok((t0.elapsed().as_secs_f64() * 1e3, host))
        };
        run(1)?;
        let (probe, _) = run(1)?;
        let iters = self.iters(probe, bytes_per_iter);
        let (wall, host) = run(iters)?;
        let n = iters as f64;
        let mut t = self.timing(iters, wall / n, None, host / n, Method::WallCalls);
        if self.cpu_adapter {
            t.note = Some(
                "CPU adapter: submits may run the work before returning, so host and wall time overlap"
                    .to_string(),
            );
        } else if host > 0.9 * wall {
            t.note = Some(format!(
                "host-bound: the calls took {:.0}% of the wall time, so this is an upper bound on GPU time",
                100.0 * host / wall
            ));
        }
        Ok(t)
    }

    /// Picks timestamps over wall clock when they exist, the adapter is a real GPU, and they are
    /// plausible (positive, and no more than the wall clock of the same batch).
    fn timing(
        &self,
        iters: u32,
        wall_ms: f64,
        gpu_ms: Option<f64>,
        host_ms: f64,
        wall: Method,
    ) -> Timing {
        let (method, note) = match gpu_ms {
            None => (wall, None),
            Some(_) if self.cpu_adapter => (
                wall,
                Some("CPU adapter: wall clock used, timestamps only reported".to_string()),
            ),
            Some(g) if g > 0.0 && g <= 1.05 * wall_ms => (Method::Timestamps, None),
            Some(g) => (
                wall,
                Some(format!(
                    "timestamps implausible ({g:.3} ms vs {wall_ms:.3} ms wall): wall clock used"
                )),
            ),
        };
        Timing {
            iters,
            wall_ms,
            gpu_ms,
            host_ms,
            method,
            note,
        }
    }

    /// Mean `end - begin` over the iterations, in ms (resolved and read after the timed batch).
    fn read_stamps(&self, set: &wgpu::QuerySet, iters: u32) -> BenchResult<f64> {
        let count = 2 * iters;
        let bytes = count as u64 * 8;
        let buf = self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bench.timestamps"),
            size: bytes,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        enc.resolve_query_set(set, 0..count, &buf, 0);
        self.ctx.queue.submit([enc.finish()]);
        let ticks: Vec<u64> = self.ctx.read_buffer(&buf, bytes)?;
        let total: u64 = ticks.chunks_exact(2).map(|p| p[1].wrapping_sub(p[0])).sum();
        Ok(total as f64 * self.period_ns / 1e6 / iters as f64)
    }
}

/// Times a CPU stage: one warm-up, one probe, then `budget / probe` iterations (clamped).
pub fn time_cpu(budget_ms: f64, mut f: impl FnMut()) -> Timing {
    f();
    let t0 = Instant::now();
    f();
    let probe = t0.elapsed().as_secs_f64() * 1e3;
    let iters = ((budget_ms / probe.max(1e-3)).floor() as u64)
        .clamp(MIN_ITERS as u64, MAX_ITERS as u64) as u32;
    let t0 = Instant::now();
    for _ in 0..iters {
        f();
    }
    let ms = t0.elapsed().as_secs_f64() * 1e3 / iters as f64;
    Timing {
        iters,
        wall_ms: ms,
        gpu_ms: None,
        host_ms: ms,
        method: Method::Cpu,
        note: None,
    }
}

/// [`time_cpu`] of a call that can fail: the last error any iteration returned, if one did.
pub fn try_time_cpu<E>(budget_ms: f64, mut f: impl FnMut() -> Result<(), E>) -> Result<Timing, E> {
    let mut failed = None;
    let t = time_cpu(budget_ms, || {
        if let Err(e) = f() {
            failed = Some(e);
        }
    });
    match failed {
        Some(e) => Err(e),
        None => Ok(t),
    }
}
