//! GPU benchmark of the shadow-map core, with the adapter's ceilings measured in the same run so
//! every stage is reported as a fraction of the limit that bounds it, and the same stages on the
//! CPU backend beside a CPU tap ceiling, so the CPU/GPU ratio to each machine's limit is visible.
//!
//! Run (lavapipe, small): `SOFTSHADOW_BENCH_RES=512 cargo bench --bench gpu`; prints a markdown
//! table and writes JSON to `$OUT/gpu-bench.json` (or `target/gpu-bench.json`). Environment and
//! the meaning of each row: `benches/README.md`. A plain `fn main` (`harness = false`): GPU time
//! is taken from timestamp queries or from many iterations between one submit and one wait, which
//! criterion's per-iteration closure does not fit; readback, device creation and shader
//! compilation are never timed.
//!
//! Bench ids are `<algo>/<backend>/<stage>/<size>`.
use shadow_map_core::{
    gpu::{mssm::MinMaxRequest, GpuContext, GpuDepthMap, GpuScene, GpuShadowMapper},
    mssm::{DualMssm, MinMaxPyramid, Mssm},
    LightSpace, LightSpaceRequest, LightView, Receivers, Scene, SceneBvh,
};
use std::{fmt::Write as _, hint::black_box, time::Instant};
use wgpu::util::DeviceExt;

type BenchResult<T> = Result<T, Box<dyn std::error::Error>>;

/// The ceiling kernels (taps, triangles, atomic inserts).
const CEILINGS_WGSL: &str = include_str!("gpu_ceilings.wgsl");
/// Kernel side of the tap ceilings (`K` override of `taps_kernel`; the CPU twin uses it too).
const K: u32 = 15;
/// Workgroup side of `taps_kernel` (`WG` override).
const TAPS_WG: u32 = 8;
/// Workgroup size of `atomic_insert` (`WG_LINEAR` override).
const INSERT_WG: u32 = 256;
/// MSSM levels built (anchored and dual-grid): `0..=MSSM_LEVELS`.
const MSSM_LEVELS: u32 = 6;
/// Layers of the peeling stage.
const PEEL_LAYERS: u32 = 4;
/// Timed iterations per measurement: at least, at most.
const MIN_ITERS: u32 = 3;
const MAX_ITERS: u32 = 50;
/// Per-iteration GPU allocations (textures, MSSM planes) stay alive until the batch finishes:
/// the iteration count is capped so a batch holds at most this much.
const BYTES_IN_FLIGHT: u64 = 4 << 30;

// ---------------------------------------------------------------------------------------------
// Configuration

/// What to measure, from the environment (see `benches/README.md`).
struct Config {
    /// Scene file.
    fixture: String,
    /// Its file stem, for ids.
    name: String,
    /// Shadow-map resolution r.
    res: u32,
    /// Receiver grid (camera width x height).
    width: u32,
    height: u32,
    /// Triangles of the raster ceiling.
    triangles: u32,
    /// Inserts of the atomic ceiling.
    inserts: u32,
    /// Seconds each measurement aims at (iterations = budget / one probe iteration, clamped).
    budget_s: f64,
    /// Whether to run the CPU rows.
    cpu: bool,
}

fn env_u32(key: &str) -> BenchResult<Option<u32>> {
    match std::env::var(key) {
        Ok(v) => Ok(Some(
            v.trim().parse().map_err(|e| format!("{key}={v}: {e}"))?,
        )),
        Err(_) => Ok(None),
    }
}

impl Config {
    fn from_env(fixture: String, scene_camera: (u32, u32), res_default: u32) -> BenchResult<Self> {
        let name = std::path::Path::new(&fixture)
            .file_stem()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_default();
        let res = env_u32("SOFTSHADOW_BENCH_RES")?.unwrap_or(res_default);
        let (width, height) = match std::env::var("SOFTSHADOW_BENCH_RECEIVERS") {
            Ok(v) => {
                let (w, h) = v
                    .trim()
                    .split_once(['x', 'X'])
                    .ok_or_else(|| format!("SOFTSHADOW_BENCH_RECEIVERS={v}: expected WxH"))?;
                (
                    w.parse().map_err(|e| format!("receivers width {w}: {e}"))?,
                    h.parse()
                        .map_err(|e| format!("receivers height {h}: {e}"))?,
                )
            }
            Err(_) => scene_camera,
        };
        if res == 0 || width == 0 || height == 0 {
            return Err("resolution and receiver grid must be non-zero".into());
        }
        let triangles = env_u32("SOFTSHADOW_BENCH_TRIANGLES")?
            .unwrap_or(100_000)
            .max(1);
        let inserts = env_u32("SOFTSHADOW_BENCH_INSERTS")?
            .unwrap_or(res.saturating_mul(res))
            .max(1);
        let budget_s = match std::env::var("SOFTSHADOW_BENCH_BUDGET_S") {
            Ok(v) => v
                .trim()
                .parse::<f64>()
                .map_err(|e| format!("SOFTSHADOW_BENCH_BUDGET_S={v}: {e}"))?,
            Err(_) => 1.0,
        };
        let cpu = std::env::var("SOFTSHADOW_BENCH_CPU").map_or(true, |v| v != "0");
        Ok(Config {
            fixture,
            name,
            res,
            width,
            height,
            triangles,
            inserts,
            budget_s,
            cpu,
        })
    }
}

impl Config {
    /// Sizes of the smoke run (`cargo test --benches`): seconds on lavapipe.
    fn shrink_for_smoke(&mut self) {
        self.res = self.res.min(128);
        self.width = self.width.min(64);
        self.height = self.height.min(48);
        self.triangles = self.triangles.min(2_000);
        self.inserts = self.inserts.min(4_096);
        self.budget_s = 0.0;
    }
}

/// `SOFTSHADOW_BENCH_FIXTURE`, else the bunny: by the absolute path of this checkout, or relative
/// to the working directory when the binary was carried to another machine.
fn fixture_path() -> String {
    if let Ok(p) = std::env::var("SOFTSHADOW_BENCH_FIXTURE") {
        return p;
    }
    let abs = concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/bunny/bunny.toml");
    if std::path::Path::new(abs).exists() {
        abs.to_string()
    } else {
        "fixtures/bunny/bunny.toml".to_string()
    }
}

// ---------------------------------------------------------------------------------------------
// Timing

/// How a row's time was taken.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Method {
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
    fn label(self) -> &'static str {
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
struct Timing {
    iters: u32,
    /// Wall clock per iteration (submit to wait, or first call to wait).
    wall_ms: f64,
    /// GPU timestamps per iteration, when taken.
    gpu_ms: Option<f64>,
    /// Host time per iteration spent recording (one-submit batches) or in the calls themselves.
    host_ms: f64,
    /// The time the row reports.
    method: Method,
    /// Why timestamps were not used, when they were taken but not trusted.
    note: Option<String>,
}

impl Timing {
    fn ms(&self) -> f64 {
        match (self.method, self.gpu_ms) {
            (Method::Timestamps, Some(g)) => g,
            _ => self.wall_ms,
        }
    }
}

/// Where the timestamp queries of one iteration go.
#[derive(Clone, Copy)]
struct Stamp<'a> {
    set: &'a wgpu::QuerySet,
    begin: u32,
    end: u32,
}

impl<'a> Stamp<'a> {
    fn compute(self) -> wgpu::ComputePassTimestampWrites<'a> {
        wgpu::ComputePassTimestampWrites {
            query_set: self.set,
            beginning_of_pass_write_index: Some(self.begin),
            end_of_pass_write_index: Some(self.end),
        }
    }
    fn render(self) -> wgpu::RenderPassTimestampWrites<'a> {
        wgpu::RenderPassTimestampWrites {
            query_set: self.set,
            beginning_of_pass_write_index: Some(self.begin),
            end_of_pass_write_index: Some(self.end),
        }
    }
}

/// Where a one-submit measurement can put timestamps.
#[derive(Clone, Copy, PartialEq)]
enum StampAt {
    /// The recorder writes them as its pass's `timestamp_writes` (`TIMESTAMP_QUERY`).
    Pass,
    /// The runner writes them on the encoder around the recorder's commands
    /// (`TIMESTAMP_QUERY_INSIDE_ENCODERS`): for public calls that record their own passes.
    Encoder,
}

/// The device under test and how to time it.
struct Gpu<'a> {
    ctx: &'a GpuContext,
    /// `TIMESTAMP_QUERY` enabled on the device.
    pass_stamps: bool,
    /// `TIMESTAMP_QUERY_INSIDE_ENCODERS` enabled on the device.
    encoder_stamps: bool,
    /// Nanoseconds per timestamp tick.
    period_ns: f64,
    /// A CPU adapter (lavapipe): wall clock is the truth there, and its timestamps were seen wrong
    /// for buffer-only passes (`gpu.md`), so they are reported but not used.
    cpu_adapter: bool,
    budget_ms: f64,
}

impl<'a> Gpu<'a> {
    fn new(ctx: &'a GpuContext, budget_s: f64) -> Self {
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
    fn time_encoded(
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
    fn time_calls(
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
fn time_cpu(budget_ms: f64, mut f: impl FnMut()) -> Timing {
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

// ---------------------------------------------------------------------------------------------
// Rows and ceilings

/// The ceilings each stage is measured against (per second).
#[derive(Debug, Clone, Copy, Default)]
struct Ceilings {
    gpu_taps: f64,
    gpu_triangles: f64,
    gpu_inserts: f64,
    cpu_taps: f64,
}

/// Which ceiling bounds a row.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Bound {
    GpuTaps,
    GpuTriangles,
    /// For A-buffer / deep-shadow stages (none in the core yet; estimate stages may use it).
    #[allow(dead_code)]
    GpuInserts,
    CpuTaps,
}

impl Bound {
    fn label(self) -> &'static str {
        match self {
            Bound::GpuTaps => "GPU taps/s",
            Bound::GpuTriangles => "GPU triangles/s",
            Bound::GpuInserts => "GPU inserts/s",
            Bound::CpuTaps => "CPU taps/s",
        }
    }
    fn rate(self, c: &Ceilings) -> f64 {
        match self {
            Bound::GpuTaps => c.gpu_taps,
            Bound::GpuTriangles => c.gpu_triangles,
            Bound::GpuInserts => c.gpu_inserts,
            Bound::CpuTaps => c.cpu_taps,
        }
    }
}

/// One measured row.
#[derive(Debug, Clone)]
struct Row {
    /// `<algo>/<backend>/<stage>/<size>`.
    id: String,
    timing: Timing,
    /// Units of work per iteration (the count `unit` names).
    work: f64,
    unit: &'static str,
    /// The ceiling that bounds it (None for the ceilings themselves and CPU raster stages).
    bound: Option<Bound>,
}

impl Row {
    fn rate(&self) -> f64 {
        self.work / (self.timing.ms() / 1e3)
    }
    fn fraction(&self, c: &Ceilings) -> Option<f64> {
        self.bound.map(|b| self.rate() / b.rate(c))
    }
}

/// Adapter and device facts printed with the table.
struct Facts {
    describe: String,
    driver: String,
    pass_stamps: bool,
    encoder_stamps: bool,
    max_binding: u64,
}

/// PCG hash, the twin of `pcg_hash` in `gpu_ceilings.wgsl`.
fn pcg_hash(v: u32) -> u32 {
    let state = v.wrapping_mul(747796405).wrapping_add(2891336453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277803737);
    (word >> 22) ^ word
}

/// `receiver_z` of `gpu_ceilings.wgsl`: exact in f32 on both sides.
fn receiver_z(k: u32) -> f32 {
    (pcg_hash(k) >> 8) as f32 / 16777216.0
}

/// A uniform float in [0, 1) from a hash stream.
fn unit(seed: u32, k: u32) -> f32 {
    receiver_z(pcg_hash(seed) ^ k.wrapping_mul(0x9e37_79b9))
}

/// Mirrors `TapsParams` in `gpu_ceilings.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct TapsParams {
    width: u32,
    height: u32,
    size: u32,
    _pad0: u32,
}

/// Mirrors `InsertParams` in `gpu_ceilings.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct InsertParams {
    count: u32,
    heads: u32,
    _pad0: u32,
    _pad1: u32,
}

fn ceilings_module(ctx: &GpuContext) -> BenchResult<wgpu::ShaderModule> {
    Ok(ctx.scoped("bench.ceilings", || {
        ctx.device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("bench.ceilings"),
                source: wgpu::ShaderSource::Wgsl(CEILINGS_WGSL.into()),
            })
    })?)
}

fn compute_pipeline(
    ctx: &GpuContext,
    module: &wgpu::ShaderModule,
    entry: &str,
    constants: &[(&str, f64)],
) -> BenchResult<wgpu::ComputePipeline> {
    Ok(ctx.scoped(entry, || {
        ctx.device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: None,
                module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants,
                    ..Default::default()
                },
                cache: None,
            })
    })?)
}

/// The random `r x r` map of the tap ceilings (depths in [0, 1)).
fn random_map(r: u32) -> Vec<f32> {
    (0..r * r).map(|k| unit(1, k)).collect()
}

/// Ceiling (a): `K x K` `textureLoad` taps per receiver over a `width x height` receiver grid
/// from a random `r x r` R32Float map. Returns the row and the total lit-tap count (read back
/// after timing, for the check against the CPU twin).
fn ceiling_taps(
    g: &Gpu,
    cfg: &Config,
    map: &[f32],
    module: &wgpu::ShaderModule,
) -> BenchResult<(Row, u64)> {
    let ctx = g.ctx;
    let (w, h, r) = (cfg.width, cfg.height, cfg.res);
    let pipeline = compute_pipeline(
        ctx,
        module,
        "taps_kernel",
        &[("K", K as f64), ("WG", TAPS_WG as f64)],
    )?;
    let (group, out) = ctx.scoped("taps_kernel", || {
        let texture = ctx.device.create_texture_with_data(
            &ctx.queue,
            &wgpu::TextureDescriptor {
                label: Some("bench.taps.map"),
                size: wgpu::Extent3d {
                    width: r,
                    height: r,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::R32Float,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            },
            wgpu::util::TextureDataOrder::LayerMajor,
            bytemuck::cast_slice(map),
        );
        let params = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("bench.taps.params"),
                contents: bytemuck::bytes_of(&TapsParams {
                    width: w,
                    height: h,
                    size: r,
                    _pad0: 0,
                }),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let out = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bench.taps.out"),
            size: w as u64 * h as u64 * 4,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let view = texture.create_view(&Default::default());
        let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("bench.taps"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: params.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&view),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: out.as_entire_binding(),
                },
            ],
        });
        (group, out)
    })?;
    let timing = g.time_encoded(StampAt::Pass, 0, |enc, stamp| {
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("taps_kernel"),
            timestamp_writes: stamp.map(Stamp::compute),
        });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(w.div_ceil(TAPS_WG), h.div_ceil(TAPS_WG), 1);
        Ok(())
    })?;
    let lit: Vec<u32> = ctx.read_buffer(&out, out.size())?;
    let total = lit.iter().map(|&v| v as u64).sum();
    Ok((
        Row {
            id: format!("ceiling/gpu/taps-{K}x{K}/{w}x{h}@{r}"),
            timing,
            work: w as f64 * h as f64 * (K * K) as f64,
            unit: "taps",
            bound: None,
        },
        total,
    ))
}

/// The CPU twin of `taps_kernel` (the CPU ceiling): the same receivers, map and kernel, rows in
/// parallel (rayon). Returns the total lit-tap count.
fn cpu_taps(map: &[f32], r: u32, w: u32, h: u32) -> u64 {
    use rayon::prelude::*;
    let half = (K / 2) as i32;
    let hi = r as i32 - 1;
    (0..h)
        .into_par_iter()
        .map(|y| {
            let mut lit = 0u64;
            for x in 0..w {
                let k = y * w + x;
                let cx = (x as u64 * r as u64 / w as u64) as i32;
                let cy = (y as u64 * r as u64 / h as u64) as i32;
                let z = receiver_z(k);
                let mut n = 0u32;
                for dj in -half..=half {
                    let row = (cy + dj).clamp(0, hi) as usize * r as usize;
                    for di in -half..=half {
                        let t = row + (cx + di).clamp(0, hi) as usize;
                        n += (map[t] >= z) as u32;
                    }
                }
                lit += n as u64;
            }
            lit
        })
        .sum()
}

/// Ceiling (b): `cfg.triangles` random small triangles (each within about 4 x 4 texels, random
/// depth) rendered depth-only into an `r x r` Depth32Float target, one render pass (clear,
/// draw, store) per iteration.
fn ceiling_triangles(g: &Gpu, cfg: &Config, module: &wgpu::ShaderModule) -> BenchResult<Row> {
    let ctx = g.ctx;
    let (m, r) = (cfg.triangles, cfg.res);
    let texel = 2.0 / r as f32;
    let mut verts: Vec<[f32; 4]> = Vec::with_capacity(3 * m as usize);
    for t in 0..m {
        let c = [unit(2, t) * 2.0 - 1.0, unit(3, t) * 2.0 - 1.0];
        let z = 0.05 + 0.9 * unit(4, t);
        for v in 0..3 {
            let s = 3 * t + v;
            verts.push([
                c[0] + (unit(5, s) * 4.0 - 2.0) * texel,
                c[1] + (unit(6, s) * 4.0 - 2.0) * texel,
                z,
                1.0,
            ]);
        }
    }
    let (pipeline, vertices, depth) = ctx.scoped("tri_vs", || {
        let pipeline = ctx
            .device
            .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("bench.triangles"),
                layout: None,
                vertex: wgpu::VertexState {
                    module,
                    entry_point: Some("tri_vs"),
                    compilation_options: Default::default(),
                    buffers: &[Some(wgpu::VertexBufferLayout {
                        array_stride: 16,
                        step_mode: wgpu::VertexStepMode::Vertex,
                        attributes: &[wgpu::VertexAttribute {
                            format: wgpu::VertexFormat::Float32x4,
                            offset: 0,
                            shader_location: 0,
                        }],
                    })],
                },
                primitive: wgpu::PrimitiveState {
                    topology: wgpu::PrimitiveTopology::TriangleList,
                    cull_mode: None,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: wgpu::TextureFormat::Depth32Float,
                    depth_write_enabled: Some(true),
                    depth_compare: Some(wgpu::CompareFunction::Less),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: None,
                multiview_mask: None,
                cache: None,
            });
        let vertices = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("bench.triangles.vertices"),
                contents: bytemuck::cast_slice(&verts),
                usage: wgpu::BufferUsages::VERTEX,
            });
        let depth = ctx
            .device
            .create_texture(&wgpu::TextureDescriptor {
                label: Some("bench.triangles.depth"),
                size: wgpu::Extent3d {
                    width: r,
                    height: r,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Depth32Float,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                view_formats: &[],
            })
            .create_view(&Default::default());
        (pipeline, vertices, depth)
    })?;
    let timing = g.time_encoded(StampAt::Pass, 0, |enc, stamp| {
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("bench.triangles"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: stamp.map(Stamp::render),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&pipeline);
        pass.set_vertex_buffer(0, vertices.slice(..));
        pass.draw(0..3 * m, 0..1);
        Ok(())
    })?;
    Ok(Row {
        id: format!("ceiling/gpu/triangles/{m}@{r}"),
        timing,
        work: m as f64,
        unit: "triangles",
        bound: None,
    })
}

/// Ceiling (c): `cfg.inserts` linked-list inserts (one per thread: atomicAdd on a node counter,
/// atomicExchange on a list head, one node written) into `inserts / 4` lists. Counter and heads
/// are cleared before each pass (outside the timestamps, inside the wall clock). Returns the row
/// and the final counter (read back after timing; must equal the insert count).
fn ceiling_inserts(g: &Gpu, cfg: &Config, module: &wgpu::ShaderModule) -> BenchResult<(Row, u32)> {
    let ctx = g.ctx;
    let max_nodes = ctx.limits().max_storage_buffer_binding_size / 8;
    let count = (cfg.inserts as u64).min(max_nodes) as u32;
    let heads = (count / 4).max(1);
    let pipeline = compute_pipeline(
        ctx,
        module,
        "atomic_insert",
        &[("WG_LINEAR", INSERT_WG as f64)],
    )?;
    let (group, counter, head_buf) = ctx.scoped("atomic_insert", || {
        let params = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("bench.inserts.params"),
                contents: bytemuck::bytes_of(&InsertParams {
                    count,
                    heads,
                    _pad0: 0,
                    _pad1: 0,
                }),
                usage: wgpu::BufferUsages::UNIFORM,
            });
        let buffer = |label, size: u64| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_DST
                    | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let counter = buffer("bench.inserts.counter", 4);
        let head_buf = buffer("bench.inserts.heads", heads as u64 * 4);
        let nodes = buffer("bench.inserts.nodes", count as u64 * 8);
        let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("bench.inserts"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: params.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: counter.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: head_buf.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 6,
                    resource: nodes.as_entire_binding(),
                },
            ],
        });
        (group, counter, head_buf)
    })?;
    let groups = count.div_ceil(INSERT_WG);
    let gx = groups.min(ctx.limits().max_compute_workgroups_per_dimension);
    let gy = groups.div_ceil(gx);
    let timing = g.time_encoded(StampAt::Pass, 0, |enc, stamp| {
        enc.clear_buffer(&counter, 0, None);
        enc.clear_buffer(&head_buf, 0, None);
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("atomic_insert"),
            timestamp_writes: stamp.map(Stamp::compute),
        });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(gx, gy, 1);
        Ok(())
    })?;
    let c: Vec<u32> = ctx.read_buffer(&counter, 4)?;
    Ok((
        Row {
            id: format!("ceiling/gpu/atomic-insert/{count}"),
            timing,
            work: count as f64,
            unit: "inserts",
            bound: None,
        },
        c.first().copied().unwrap_or(0),
    ))
}

// ---------------------------------------------------------------------------------------------
// Stages

/// Texel reads of one anchored step with window offset h over an s x s level: each output texel
/// fetches (x, y), (x+h, y), (x, y+h), (x+h, y+h) where inside the map, from the min and the max
/// plane: `2 (2s - h)^2`.
fn step_reads(s: u64, h: u64) -> f64 {
    let e = 2 * s - h.min(s);
    2.0 * (e * e) as f64
}

/// `floor(log2(n))`.
fn floor_log2(n: u32) -> u32 {
    31 - n.max(1).leading_zeros()
}

/// Texel reads of an anchored MSSM build up to `levels`: s^2 (the depth map, once) plus one
/// anchored step per level with h = 1, 2, 4, ...
fn mssm_reads(s: u32, levels: u32) -> f64 {
    let top = levels.min(floor_log2(s));
    (s as f64).powi(2) + (0..top).map(|l| step_reads(s as u64, 1 << l)).sum::<f64>()
}

/// Texel reads of a dual-grid MSSM build: s^2, a step with h = 1 (level 0), then the anchored
/// steps of levels 1..=levels.
fn dual_mssm_reads(s: u32, levels: u32) -> f64 {
    mssm_reads(s, levels) + step_reads(s as u64, 1)
}

/// Texel reads of a min/max pyramid build: s^2, then each 2 x 2 reduction of an sp x sp level
/// reads every source texel of both planes once: `2 sp^2`.
fn pyramid_reads(s: u32) -> f64 {
    let mut reads = (s as f64).powi(2);
    let mut sp = s;
    while sp > 1 {
        reads += 2.0 * (sp as f64).powi(2);
        sp = sp.div_ceil(2);
    }
    reads
}

/// The fixture and everything the stages share (built outside every timed region).
struct StageEnv<'a> {
    g: &'a Gpu<'a>,
    cfg: &'a Config,
    scene: &'a Scene,
    receivers: &'a Receivers,
    view: LightView,
    gpu_scene: GpuScene,
    mapper: GpuShadowMapper,
    /// Layer 0 rendered on the GPU in `view` (the MSSM stages' input).
    layer0: GpuDepthMap,
}

fn peel_request(r: u32) -> LightSpaceRequest {
    LightSpaceRequest {
        layers: PEEL_LAYERS,
        ..LightSpaceRequest::single(r)
    }
}

/// The shadow-map stages on the GPU through the public API.
fn gpu_stages(env: &StageEnv) -> BenchResult<Vec<Row>> {
    let (g, ctx, r) = (env.g, env.g.ctx, env.cfg.res);
    let name = &env.cfg.name;
    let tris = env.gpu_scene.triangles as f64;
    let plane = r as u64 * r as u64 * 4;
    let mut rows = Vec::new();
    // Raster: `render_layers` records and submits by itself, with no timestamp hook: wall clock
    // over T calls and one wait.
    let single = LightSpaceRequest::single(r);
    let t = g.time_calls(2 * plane, || {
        env.mapper
            .render_layers(ctx, &env.gpu_scene, &env.view, &single)?;
        Ok(())
    })?;
    rows.push(Row {
        id: format!("shadow-map/gpu/render-1/{r}@{name}"),
        timing: t,
        work: tris,
        unit: "triangles",
        bound: Some(Bound::GpuTriangles),
    });
    let peel = peel_request(r);
    let t = g.time_calls((PEEL_LAYERS as u64 + 1) * plane, || {
        env.mapper
            .render_layers(ctx, &env.gpu_scene, &env.view, &peel)?;
        Ok(())
    })?;
    rows.push(Row {
        id: format!("peeling/gpu/peel-{PEEL_LAYERS}/{r}@{name}"),
        timing: t,
        work: tris * PEEL_LAYERS as f64,
        unit: "triangles",
        bound: Some(Bound::GpuTriangles),
    });
    // MSSM family: `GpuMssmBuilder::encode` records into our encoder, so T builds go in one
    // submit, with encoder-level timestamps around each.
    let builder = env.mapper.mssm_builder();
    let levels = MSSM_LEVELS.min(floor_log2(r));
    let stages: [(&str, MinMaxRequest, f64, u64); 3] = [
        (
            "mssm/gpu/build-6",
            MinMaxRequest {
                mssm_levels: Some(MSSM_LEVELS),
                ..Default::default()
            },
            mssm_reads(r, MSSM_LEVELS),
            (1 + 2 * levels as u64) * plane,
        ),
        (
            "dual-mssm/gpu/build-6",
            MinMaxRequest {
                dual_mssm_levels: Some(MSSM_LEVELS),
                ..Default::default()
            },
            dual_mssm_reads(r, MSSM_LEVELS),
            (3 + 2 * levels as u64) * plane,
        ),
        (
            "pyramid/gpu/build",
            MinMaxRequest {
                pyramid: true,
                ..Default::default()
            },
            pyramid_reads(r),
            4 * plane,
        ),
    ];
    for (id, req, reads, bytes) in stages {
        let t = g.time_encoded(StampAt::Encoder, bytes, |enc, _| {
            builder.encode(ctx, enc, &env.layer0, req)?;
            Ok(())
        })?;
        rows.push(Row {
            id: format!("{id}/{r}@{name}"),
            timing: t,
            work: reads,
            unit: "texel reads",
            bound: Some(Bound::GpuTaps),
        });
    }
    Ok(rows)
}

/// The same stages on the CPU backend, in the same view.
fn cpu_stages(env: &StageEnv) -> Vec<Row> {
    let (r, name, budget) = (env.cfg.res, &env.cfg.name, env.g.budget_ms);
    let tris = env.gpu_scene.triangles as f64;
    let fit = Default::default();
    let single = LightSpaceRequest::single(r);
    let mut rows = vec![Row {
        id: format!("shadow-map/cpu/render-1/{r}@{name}"),
        timing: time_cpu(budget, || {
            black_box(LightSpace::build_in_view(env.scene, env.view, fit, &single));
        }),
        work: tris,
        unit: "triangles",
        bound: None,
    }];
    let peel = peel_request(r);
    rows.push(Row {
        id: format!("peeling/cpu/peel-{PEEL_LAYERS}/{r}@{name}"),
        timing: time_cpu(budget, || {
            black_box(LightSpace::build_in_view(env.scene, env.view, fit, &peel));
        }),
        work: tris * PEEL_LAYERS as f64,
        unit: "triangles",
        bound: None,
    });
    let ls = LightSpace::build_in_view(env.scene, env.view, fit, &single);
    let l0 = &ls.layers[0];
    let (d, s) = (&l0.depth, l0.size);
    rows.push(Row {
        id: format!("mssm/cpu/build-6/{r}@{name}"),
        timing: time_cpu(budget, || {
            black_box(Mssm::build(black_box(d), s, MSSM_LEVELS));
        }),
        work: mssm_reads(s, MSSM_LEVELS),
        unit: "texel reads",
        bound: Some(Bound::CpuTaps),
    });
    rows.push(Row {
        id: format!("dual-mssm/cpu/build-6/{r}@{name}"),
        timing: time_cpu(budget, || {
            black_box(DualMssm::build(black_box(d), s, MSSM_LEVELS));
        }),
        work: dual_mssm_reads(s, MSSM_LEVELS),
        unit: "texel reads",
        bound: Some(Bound::CpuTaps),
    });
    rows.push(Row {
        id: format!("pyramid/cpu/build/{r}@{name}"),
        timing: time_cpu(budget, || {
            black_box(MinMaxPyramid::build(black_box(d), s));
        }),
        work: pyramid_reads(s),
        unit: "texel reads",
        bound: Some(Bound::CpuTaps),
    });
    rows
}

/// HOOK for the GPU estimate stages (the lead adds the GPU PCSS of `crates/baselines` here once
/// it lands; see `benches/README.md`, "Adding the estimate stage").
///
/// Everything an estimator needs is in `env`, built outside the timed regions: the scene, the
/// receivers (`env.receivers`, upload them once with `GpuReceivers::upload`), the view, the GPU
/// scene and mapper, and layer 0. Time with `env.g.time_encoded(StampAt::Pass, bytes, ..)` when
/// the estimator can record into a caller's encoder (preferred: one submit, timestamps), or with
/// `env.g.time_calls(bytes, ..)` when it only offers a call that submits by itself. Return one
/// [`Row`] per stage with id `pcss/gpu/<stage>/<r>@<fixture>`, unit `"taps"` and
/// `bound: Some(Bound::GpuTaps)`, counting per active receiver the taps actually issued (PCSS:
/// blocker search `w_s^2` plus filter `w_f^2`, from the kernel widths the estimator computed; or a
/// fixed upper bound, named in the README), so the row reads as a fraction of the tap ceiling.
/// The CPU twin goes in the same place with `Bound::CpuTaps`.
fn estimate_stages(env: &StageEnv) -> BenchResult<Vec<Row>> {
    use baselines::{gpu::GpuPcssShadow, PcssShadow};
    use shadow_map_core::SoftShadowEstimator;
    let r = env.cfg.res;
    let name = &env.cfg.name;
    let n = env.receivers.active_count() as f64;
    let mut rows = Vec::new();
    // Identical light-space data for both twins: the CPU map in the bench's view.
    let ls = LightSpace::build_in_view(
        env.scene,
        env.view,
        Default::default(),
        &LightSpaceRequest::single(r),
    );
    let mut v = vec![0.0f32; env.receivers.len()];
    let mut gpu = GpuPcssShadow::new(std::sync::Arc::new(env.g.ctx.clone()))?;
    gpu.set_param("resolution", &r.to_string())?;
    let mut failed = None;
    let mut t = time_cpu(2000.0, || {
        if let Err(e) = gpu.estimate_with(&ls, &env.scene.light, env.receivers, &mut v) {
            failed = Some(e);
        }
    });
    if let Some(e) = failed {
        return Err(e.into());
    }
    t.method = Method::WallCalls;
    t.note = Some("whole estimate call: receiver upload, dispatch and V readback".into());
    rows.push(Row {
        id: format!("pcss/gpu/estimate/{r}@{name}"),
        timing: t,
        work: n,
        unit: "receivers",
        bound: None,
    });
    let mut cpu = PcssShadow::new()?;
    cpu.set_param("resolution", &r.to_string())?;
    cpu.build(env.scene, env.receivers)?;
    let t = time_cpu(2000.0, || {
        if let Err(e) = cpu.estimate(env.scene, env.receivers, &mut v) {
            failed = Some(e);
        }
    });
    if let Some(e) = failed {
        return Err(e.into());
    }
    rows.push(Row {
        id: format!("pcss/cpu/estimate/{r}@{name}"),
        timing: t,
        work: n,
        unit: "receivers",
        bound: None,
    });
    Ok(rows)
}

// ---------------------------------------------------------------------------------------------
// Output

fn fmt_rate(v: f64) -> String {
    if !v.is_finite() {
        return "-".into();
    }
    let (d, s) = if v >= 1e12 {
        (1e12, "T")
    } else if v >= 1e9 {
        (1e9, "G")
    } else if v >= 1e6 {
        (1e6, "M")
    } else if v >= 1e3 {
        (1e3, "k")
    } else {
        (1.0, "")
    };
    format!("{:.3} {s}", v / d)
}

fn fmt_ms(v: f64) -> String {
    if v >= 100.0 {
        format!("{v:.1}")
    } else if v >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.4}")
    }
}

fn table(rows: &[Row], c: &Ceilings) -> String {
    let mut s = String::new();
    s.push_str("| id | method | iters | ms/iter | wall ms | ts ms | host ms | work/iter | rate/s | bound | % of ceiling |\n");
    s.push_str("|---|---|---|---|---|---|---|---|---|---|---|\n");
    for r in rows {
        let t = &r.timing;
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} {} | {} | {} | {} |",
            r.id,
            t.method.label(),
            t.iters,
            fmt_ms(t.ms()),
            fmt_ms(t.wall_ms),
            t.gpu_ms.map_or("-".into(), fmt_ms),
            fmt_ms(t.host_ms),
            fmt_rate(r.work),
            r.unit,
            fmt_rate(r.rate()),
            r.bound.map_or("-", Bound::label),
            r.fraction(c)
                .map_or("-".into(), |f| format!("{:.1}%", 100.0 * f)),
        );
    }
    s
}

/// GPU beside CPU per stage: times, speed-up, and each as a fraction of its own machine's limit.
fn comparison(rows: &[Row], c: &Ceilings) -> String {
    let mut s = String::new();
    s.push_str("| stage | CPU ms | GPU ms | GPU speed-up | CPU % of CPU ceiling | GPU % of GPU ceiling |\n");
    s.push_str("|---|---|---|---|---|---|\n");
    for gpu in rows
        .iter()
        .filter(|r| r.id.contains("/gpu/") && r.bound.is_some())
    {
        let key = gpu.id.replacen("/gpu/", "/cpu/", 1);
        let Some(cpu) = rows.iter().find(|r| r.id == key) else {
            continue;
        };
        let pct = |f: Option<f64>| f.map_or("-".into(), |f| format!("{:.1}%", 100.0 * f));
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.1}x | {} | {} |",
            gpu.id.replacen("/gpu", "", 1),
            fmt_ms(cpu.timing.ms()),
            fmt_ms(gpu.timing.ms()),
            cpu.timing.ms() / gpu.timing.ms(),
            pct(cpu.fraction(c)),
            pct(gpu.fraction(c)),
        );
    }
    s
}

fn json_str(s: &str) -> String {
    let mut o = String::from("\"");
    for ch in s.chars() {
        match ch {
            '"' => o.push_str("\\\""),
            '\\' => o.push_str("\\\\"),
            c if (c as u32) < 0x20 => {
                let _ = write!(o, "\\u{:04x}", c as u32);
            }
            c => o.push(c),
        }
    }
    o.push('"');
    o
}

fn json_num(v: f64) -> String {
    if v.is_finite() {
        format!("{v}")
    } else {
        "null".into()
    }
}

fn json(
    facts: &Facts,
    cfg: &Config,
    c: &Ceilings,
    rows: &[Row],
    checks: &[(String, bool)],
) -> String {
    let mut s = String::from("{\n");
    let _ = writeln!(s, "  \"adapter\": {},", json_str(&facts.describe));
    let _ = writeln!(s, "  \"driver\": {},", json_str(&facts.driver));
    let _ = writeln!(
        s,
        "  \"timestamp_query\": {}, \"timestamp_query_inside_encoders\": {},",
        facts.pass_stamps, facts.encoder_stamps
    );
    let _ = writeln!(
        s,
        "  \"config\": {{\"fixture\": {}, \"resolution\": {}, \"receivers\": [{}, {}], \"ceiling_triangles\": {}, \"ceiling_inserts\": {}, \"kernel\": {K}, \"mssm_levels\": {MSSM_LEVELS}, \"peel_layers\": {PEEL_LAYERS}, \"budget_s\": {}}},",
        json_str(&cfg.fixture),
        cfg.res,
        cfg.width,
        cfg.height,
        cfg.triangles,
        cfg.inserts,
        json_num(cfg.budget_s)
    );
    let _ = writeln!(
        s,
        "  \"ceilings_per_s\": {{\"gpu_taps\": {}, \"gpu_triangles\": {}, \"gpu_inserts\": {}, \"cpu_taps\": {}}},",
        json_num(c.gpu_taps),
        json_num(c.gpu_triangles),
        json_num(c.gpu_inserts),
        json_num(c.cpu_taps)
    );
    s.push_str("  \"checks\": [");
    for (k, (what, ok)) in checks.iter().enumerate() {
        let _ = write!(
            s,
            "{}{{\"check\": {}, \"ok\": {ok}}}",
            if k > 0 { ", " } else { "" },
            json_str(what)
        );
    }
    s.push_str("],\n  \"rows\": [\n");
    for (k, r) in rows.iter().enumerate() {
        let t = &r.timing;
        let _ = write!(
            s,
            "    {{\"id\": {}, \"method\": {}, \"iters\": {}, \"ms_per_iter\": {}, \"wall_ms_per_iter\": {}, \"timestamp_ms_per_iter\": {}, \"host_ms_per_iter\": {}, \"work_per_iter\": {}, \"unit\": {}, \"rate_per_s\": {}, \"bound\": {}, \"fraction_of_ceiling\": {}, \"note\": {}}}",
            json_str(&r.id),
            json_str(t.method.label()),
            t.iters,
            json_num(t.ms()),
            json_num(t.wall_ms),
            t.gpu_ms.map_or("null".into(), json_num),
            json_num(t.host_ms),
            json_num(r.work),
            json_str(r.unit),
            json_num(r.rate()),
            r.bound.map_or("null".into(), |b| json_str(b.label())),
            r.fraction(c).map_or("null".into(), json_num),
            t.note.as_deref().map_or("null".into(), json_str),
        );
        s.push_str(if k + 1 < rows.len() { ",\n" } else { "\n" });
    }
    s.push_str("  ]\n}\n");
    s
}

fn out_path() -> std::path::PathBuf {
    match std::env::var_os("OUT") {
        Some(dir) => std::path::PathBuf::from(dir).join("gpu-bench.json"),
        None => std::path::PathBuf::from("target").join("gpu-bench.json"),
    }
}

// ---------------------------------------------------------------------------------------------

fn main() -> BenchResult<()> {
    let t_start = Instant::now();
    // `cargo bench` passes `--bench`; `cargo test --benches` does not. Without it this is a smoke
    // run (as criterion's test mode): tiny sizes, every kernel run and checked, no JSON written,
    // and a missing adapter is a loud skip (a failure under SOFTSHADOW_REQUIRE_GPU=1).
    let smoke = !std::env::args().any(|a| a == "--bench");
    let ctx = if smoke {
        match shadow_map_core::gpu::context_for_tests("benches/gpu")? {
            Some(ctx) => ctx,
            None => return Ok(()),
        }
    } else {
        std::sync::Arc::new(GpuContext::new()?)
    };
    let adapter = ctx.adapter.clone();
    let g = Gpu::new(&ctx, 1.0);
    let facts = Facts {
        describe: ctx.describe(),
        driver: adapter
            .as_ref()
            .map(|a| format!("{} {}", a.driver, a.driver_info))
            .unwrap_or_default(),
        pass_stamps: g.pass_stamps,
        encoder_stamps: g.encoder_stamps,
        max_binding: ctx.limits().max_storage_buffer_binding_size,
    };
    println!("adapter: {} [{}]", facts.describe, facts.driver.trim());
    println!(
        "timestamps: pass {} / inside encoders {} (period {} ns); max storage binding {} MiB",
        facts.pass_stamps,
        facts.encoder_stamps,
        g.period_ns,
        facts.max_binding >> 20
    );

    // Fixture, receivers and view: outside every timed region.
    let fixture = fixture_path();
    let mut scene = Scene::load(&fixture)?;
    let mut cfg = Config::from_env(
        fixture,
        (scene.camera.width, scene.camera.height),
        if g.cpu_adapter { 1024 } else { 2048 },
    )?;
    if smoke {
        println!("smoke run (no --bench argument): tiny sizes, no JSON; `cargo bench --bench gpu` measures");
        cfg.shrink_for_smoke();
    }
    let g = Gpu::new(&ctx, cfg.budget_s);
    scene.camera.width = cfg.width;
    scene.camera.height = cfg.height;
    let bvh = SceneBvh::new(&scene);
    let receivers = Receivers::from_camera(&scene, &bvh);
    let light = &scene.light;
    let (view, _fit) = LightView::fit(
        &scene,
        &receivers,
        light.frame(),
        light.half_extent(),
        cfg.res,
    )?;
    println!(
        "fixture: {} ({} triangles), shadow map {r}x{r}, receivers {}x{} ({} active), kernel {K}x{K}",
        cfg.fixture,
        scene.triangles.len(),
        cfg.width,
        cfg.height,
        receivers.active_count(),
        r = cfg.res,
    );

    // Ceilings.
    let module = ceilings_module(&ctx)?;
    let map = random_map(cfg.res);
    let mut rows = Vec::new();
    let mut checks = Vec::new();
    let (taps, gpu_lit) = ceiling_taps(&g, &cfg, &map, &module)?;
    let tris = ceiling_triangles(&g, &cfg, &module)?;
    let (inserts, counter) = ceiling_inserts(&g, &cfg, &module)?;
    checks.push((
        format!(
            "atomic-insert counter {counter} == {} inserts",
            inserts.work
        ),
        counter as f64 == inserts.work,
    ));
    let mut c = Ceilings {
        gpu_taps: taps.rate(),
        gpu_triangles: tris.rate(),
        gpu_inserts: inserts.rate(),
        cpu_taps: f64::NAN,
    };
    rows.extend([taps, tris, inserts]);

    // Stages on the GPU.
    let gpu_scene = GpuScene::upload(&ctx, &scene)?;
    let mapper = GpuShadowMapper::new(&ctx)?;
    let base =
        mapper.render_layers(&ctx, &gpu_scene, &view, &LightSpaceRequest::single(cfg.res))?;
    ctx.wait()?;
    let layer0 = base.layers[0].clone();
    let env = StageEnv {
        g: &g,
        cfg: &cfg,
        scene: &scene,
        receivers: &receivers,
        view,
        gpu_scene,
        mapper,
        layer0,
    };
    rows.extend(gpu_stages(&env)?);
    rows.extend(estimate_stages(&env)?);

    // CPU: the tap ceiling (the twin of taps_kernel, checked against it) and the same stages.
    if cfg.cpu {
        let (w, h, r) = (cfg.width, cfg.height, cfg.res);
        let mut cpu_lit = 0;
        let timing = time_cpu(g.budget_ms, || {
            cpu_lit = black_box(cpu_taps(black_box(&map), r, w, h));
        });
        checks.push((
            format!("taps_kernel lit taps: GPU {gpu_lit} == CPU {cpu_lit}"),
            gpu_lit == cpu_lit,
        ));
        let row = Row {
            id: format!("ceiling/cpu/taps-{K}x{K}/{w}x{h}@{r}"),
            timing,
            work: w as f64 * h as f64 * (K * K) as f64,
            unit: "taps",
            bound: None,
        };
        c.cpu_taps = row.rate();
        rows.push(row);
        rows.extend(cpu_stages(&env));
    }

    println!();
    print!("{}", table(&rows, &c));
    if cfg.cpu {
        println!();
        print!("{}", comparison(&rows, &c));
    }
    println!();
    for r in &rows {
        if let Some(n) = &r.timing.note {
            println!("note: {}: {n}", r.id);
        }
    }
    for (what, ok) in &checks {
        println!("check: {what}: {}", if *ok { "ok" } else { "FAILED" });
    }
    if !smoke {
        let path = out_path();
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir)?;
        }
        std::fs::write(&path, json(&facts, &cfg, &c, &rows, &checks))?;
        println!("wrote {}", path.display());
    }
    println!("{:.1} s in all", t_start.elapsed().as_secs_f64());
    if checks.iter().any(|(_, ok)| !ok) {
        return Err("a ceiling check failed".into());
    }
    Ok(())
}
