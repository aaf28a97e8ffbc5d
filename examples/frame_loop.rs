//! A headless renderer of its own driving the engine path: every frame it renders a
//! G-buffer of a camera orbiting a fixture on the GPU, then records each estimator that has the
//! frame API ([`softshadow::FRAME_ALGOS`]: hard, PCF, PCSS, multi-sample, backprojection,
//! accumulation, deep-shadow, packet-hsm; [`softshadow::frame_estimator`] makes them) into its own command encoder
//! from that G-buffer's receiver buffer, V into a buffer of its own. Nothing is read back until the last
//! frame; then V and the receivers are read once and compared with the CPU twin in the same
//! light view(s).
//!
//! The scene is run twice: as loaded ("small") and with its triangles split into 4^k (at least
//! 50 times as many, "large"); host ms is the CPU time spent in `encode` per frame after the
//! first (whose encode compiles the frame's specialised pipelines, a one-time cost reported as
//! `host_ms_first_frame*`): the calling thread's CPU clock (`CLOCK_THREAD_CPUTIME_ID` through the `cpu-time` crate), which the
//! device's own threads do not inflate when a CPU adapter (lavapipe) shares the cores with it;
//! the wall time of the same calls is `host_wall_ms_per_frame_*`. After the
//! readback, `--timed-frames` more frames (10 unless told) on the last receivers are submitted back to back and
//! waited for once (`gpu_ms_per_frame_*`: the frame's wall time on the device), then
//! [`IDLE_ENCODES`] encodes each with the device idle and the host's caches swept by a [`SWEEP_BYTES`] write
//! (`host_ms_idle_*`, thread CPU time: on a CPU adapter the device's own work runs on the host's
//! cores and evicts `encode`'s working set, more for the large scene; after the sweep both
//! scenes start equally cold), then 2000 encodes in a tight loop, dropped
//! unsubmitted (`host_ms_warm_*`: the API's own host cost, caches warm), and the CPU twin's build
//! and estimate on the same receivers are timed (`cpu_twin_ms_*`), and one more frame is
//! recorded with timestamps between its passes (`gpu_stage_ms_*`: GPU ms per stage, from
//! [`FrameTimestamps`], where the adapter has timestamp queries). The light
//! views are fitted once, on the CPU, to every vertex of the scene (a view that holds any
//! receiver the orbit can see), so no per-frame CPU work grows with the triangles.
//!
//! ```text
//! WGPU_BACKEND=vulkan cargo run --release --example frame_loop -- [--json] [--frames N]
//!     [--timed-frames N] [--size WxH] [--resolution R] [--param NAME=VALUE]... [--algo NAME]
//!     [--small-only] [SCENE.toml]
//!
//! `--size` sets the camera's image (the receivers), `--resolution` every estimator's shadow-map
//! resolution, `--param` one of the estimator's parameters (with `--algo`), `--algo` runs one estimator only, `--small-only` the scene as loaded only (one
//! JSON line per estimator: a 3840 x 2160 view in minutes on lavapipe).
//! ```
use cpu_time::ThreadTime;
use glam::Vec3;
use shadow_map_core::{
    gpu::{
        frame::{FrameEstimator, FrameInputs, FrameTimestamps, Views},
        receivers::GpuReceivers,
        GpuContext, GpuGBuffer, GpuScene,
    },
    Camera, LightView, Receivers, Result, Scene,
};
use softshadow::FRAME_ALGOS;
use std::{sync::Arc, time::Instant};

/// Every vertex of the scene as a receiver facing its triangle's normal: what the views are
/// fitted to.
fn vertex_receivers(scene: &Scene) -> Result<Receivers> {
    let (mut p, mut n) = (Vec::new(), Vec::new());
    for t in scene.triangles() {
        let nrm = (t[1] - t[0]).cross(t[2] - t[0]).normalize_or(Vec3::Y);
        for v in t {
            p.push(*v);
            n.push(nrm);
        }
    }
    Receivers::from_points(p, n)
}

/// `scene` with every triangle split into `4^levels` by its edge midpoints (one opaque mesh).
fn tessellated(scene: &Scene, levels: u32) -> Result<Scene> {
    let mut tris = scene.triangles().to_vec();
    for _ in 0..levels {
        tris = tris
            .iter()
            .flat_map(|[a, b, c]| {
                let (ab, bc, ca) = ((*a + *b) * 0.5, (*b + *c) * 0.5, (*c + *a) * 0.5);
                [[*a, ab, ca], [ab, *b, bc], [ca, bc, *c], [ab, bc, ca]]
            })
            .collect();
    }
    Scene::from_meshes("large", *scene.camera(), *scene.light(), vec![(tris, 1.0)])
}

/// Frame `k` of `n`: the camera orbited about the vertical axis through its target, 40 degrees
/// over the path.
fn orbit(c: &Camera, k: u32, n: u32) -> Camera {
    let a = (40.0f32 * k as f32 / n.max(1) as f32).to_radians();
    let d = c.eye - c.target;
    let (s, co) = a.sin_cos();
    let eye = c.target + Vec3::new(co * d.x + s * d.z, d.y, -s * d.x + co * d.z);
    Camera { eye, ..*c }
}

/// An estimator's frame path and the views it renders.
type Path = (Box<dyn FrameEstimator>, Vec<Option<LightView>>);

/// The frame path of `algo` for `scene` at default parameters, and its views fitted to every
/// vertex.
fn frame_path(
    ctx: &Arc<GpuContext>,
    algo: &str,
    scene: &Scene,
    settings: &[(String, String)],
) -> Result<Path> {
    let mut params = softshadow::method(algo)?.cpu()?.params().clone();
    for (k, v) in settings {
        params.set(k, v)?;
    }
    let pixels = scene.camera().width * scene.camera().height;
    let path =
        softshadow::frame_estimator(algo, ctx.clone(), &params, pixels)?.ok_or_else(|| {
            shadow_map_core::Error::param("algo", format!("{algo} has no engine path"))
        })?;
    let views = path.fit_views(scene, &vertex_receivers(scene)?)?;
    Ok((path, views))
}

/// What [`run`] measured for one estimator on one scene.
#[derive(Default)]
struct Measured {
    /// CPU ms spent in `encode` per frame after the first: the calling thread's CPU clock.
    host_ms: f64,
    /// CPU ms spent in the first frame's `encode`, which compiles the frame's specialised
    /// pipelines (`SpecializedKernel`).
    host_first_ms: f64,
    /// Wall ms spent in `encode` per frame (on a CPU adapter, also the device threads'
    /// contention for the cores).
    host_wall_ms: f64,
    /// RMSE of the last frame's V against the CPU twin over the active receivers the frame
    /// computed (those left NaN are counted in [`left_nan`](Self::left_nan)).
    rmse: f64,
    /// Active receivers the last frame left NaN for the caller to redo (cut short by the
    /// device's loop budget, counted in the estimator's status).
    left_nan: usize,
    /// Active receivers of the last frame.
    active: usize,
    /// Buffers the library mapped back to the CPU during the frames ([`GpuContext::readbacks`]).
    readbacks: u64,
    /// Wall ms per frame of `--timed-frames` frames on the last frame's receivers, submitted
    /// back to back and waited for once: encode, submit and the device's work (on lavapipe the
    /// device is this machine's CPU cores).
    gpu_ms: f64,
    /// CPU ms (thread clock) in `encode` per frame with the device idle and the caches swept:
    /// the median of [`IDLE_ENCODES`] encodes, each after a wait and a [`SWEEP_BYTES`] write: on a CPU
    /// adapter the device's work runs on the host's cores and evicts `encode`'s working set,
    /// which [`host_ms`](Self::host_ms) also counts.
    host_idle_ms: f64,
    /// CPU ms per `encode` in a tight loop of [`WARM_ENCODES`] recordings that are dropped, not
    /// submitted: the API's own host cost with warm caches, which no device work disturbs.
    host_warm_ms: f64,
    /// Wall ms of the CPU twin's build and estimate on the same receivers in the same views.
    cpu_ms: f64,
    /// GPU ms per stage of one more frame, from timestamps written between its passes
    /// ([`FrameTimestamps`]); empty where the adapter has no timestamp queries.
    stages: Vec<(&'static str, f64)>,
}

/// A JSON object of stage names to milliseconds.
fn stages_json(stages: &[(&'static str, f64)]) -> String {
    let body: Vec<String> = stages
        .iter()
        .map(|(s, ms)| format!("\"{s}\":{ms:.4}"))
        .collect();
    format!("{{{}}}", body.join(","))
}

/// Frames the loop lets the device queue before it waits for the oldest (the pacing a
/// swapchain gives a renderer); nothing is read back.
const FRAMES_IN_FLIGHT: usize = 2;

/// Frames timed after the readback-free run unless `--timed-frames` says (the wait that ends
/// them is the only stall).
const TIMED_FRAMES: u32 = 10;

/// Encodes of the idle, cold-cache measurement ([`Measured::host_idle_ms`]).
const IDLE_ENCODES: usize = 31;

/// The median of `x` (0 when empty).
fn median(x: &mut [f64]) -> f64 {
    x.sort_by(f64::total_cmp);
    x.get(x.len() / 2).copied().unwrap_or(0.0)
}

/// Bytes written before each idle encode ([`Measured::host_idle_ms`]): more than the host's
/// caches, so small and large scenes start equally cold.
const SWEEP_BYTES: usize = 64 << 20;

/// Recordings of the warm-encode measurement ([`Measured::host_warm_ms`]).
const WARM_ENCODES: u32 = 2000;

/// A frame's inputs: `casters` under `scene`'s light in `views`, the G-buffer's `receivers`, V
/// into `v`, no timestamps.
fn frame_inputs<'a>(
    casters: &'a GpuScene,
    views: &'a Views,
    scene: &'a Scene,
    receivers: &'a GpuReceivers,
    v: &'a wgpu::Buffer,
) -> FrameInputs<'a> {
    FrameInputs {
        casters,
        views,
        light: scene.light(),
        receivers: &receivers.buffer,
        count: receivers.count,
        v,
        timestamps: None,
    }
}

/// Runs `frames` frames of `path` over `scene`, reads V and the receivers back once after the
/// last, compares with the CPU twin, then times `timed` more frames.
fn run(
    ctx: &Arc<GpuContext>,
    (path, views): Path,
    scene: &Scene,
    frames: u32,
    timed: u32,
) -> Result<Measured> {
    let casters = GpuScene::upload(ctx, scene)?;
    let gbuffer = GpuGBuffer::new(ctx)?;
    let pixels = (scene.camera().width * scene.camera().height) as u64;
    let v = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("frame_loop V"),
        size: 4 * pixels,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let (mut host, mut host_wall, mut host_first) = (0.0, 0.0, 0.0);
    let mut in_flight = std::collections::VecDeque::new();
    let mut last = None;
    let readbacks_before = ctx.readbacks();
    for k in 0..frames {
        let camera = orbit(scene.camera(), k, frames);
        let img = gbuffer.render(ctx, &casters, &camera)?;
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        let (t, cpu) = (Instant::now(), ThreadTime::now());
        path.encode(
            &mut enc,
            &frame_inputs(&casters, &views, scene, &img.receivers, &v),
        )?;
        let (ms, wall_ms) = (
            cpu.elapsed().as_secs_f64() * 1e3,
            t.elapsed().as_secs_f64() * 1e3,
        );
        // The first encode compiles the specialised pipelines: reported apart (with one frame,
        // it is all there is).
        if k == 0 {
            host_first = ms;
        }
        if k > 0 || frames == 1 {
            host += ms;
            host_wall += wall_ms;
        }
        in_flight.push_back(ctx.queue.submit([enc.finish()]));
        // A renderer's pacing: at most FRAMES_IN_FLIGHT frames queued on the device (what a
        // swapchain's present gives), so the host does not run ahead of the device unboundedly.
        if in_flight.len() > FRAMES_IN_FLIGHT {
            if let Some(idx) = in_flight.pop_front() {
                ctx.device
                    .poll(wgpu::PollType::Wait {
                        submission_index: Some(idx),
                        timeout: None,
                    })
                    .map_err(|e| shadow_map_core::Error::Gpu {
                        stage: "frame pacing".into(),
                        reason: e.to_string(),
                    })?;
            }
        }
        last = Some((img, camera));
    }
    let readbacks = ctx.readbacks() - readbacks_before;
    // The one readback, after the last frame.
    let Some((img, camera)) = last else {
        return Ok(Measured::default());
    };
    let receivers = img.read_back(ctx)?;
    let bits: Vec<u32> = ctx.read_buffer(&v, 4 * pixels)?;
    let mut s = scene.clone();
    s.set_camera(camera)?;
    let t = Instant::now();
    let cpu = path.cpu_twin(&s, &receivers, &views)?;
    let cpu_ms = t.elapsed().as_secs_f64() * 1e3;
    let (mut se, mut n, mut left_nan) = (0.0f64, 0usize, 0usize);
    for (k, c) in cpu.iter().enumerate() {
        if receivers.active()[k] {
            let g = f32::from_bits(bits[k]);
            if g.is_nan() {
                left_nan += 1;
                continue;
            }
            let d = g as f64 - *c as f64;
            se += d * d;
            n += 1;
        }
    }
    // After the comparison: frames timed on the last receivers, waited for once.
    let inputs = frame_inputs(&casters, &views, scene, &img.receivers, &v);
    ctx.wait()?;
    let t = Instant::now();
    for _ in 0..timed {
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        path.encode(&mut enc, &inputs)?;
        ctx.queue.submit([enc.finish()]);
    }
    ctx.wait()?;
    let gpu_ms = t.elapsed().as_secs_f64() * 1e3 / timed as f64;
    ctx.wait()?;
    let t = Instant::now();
    for _ in 0..WARM_ENCODES {
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        path.encode(&mut enc, &inputs)?;
        drop(enc);
    }
    let host_warm_ms = t.elapsed().as_secs_f64() * 1e3 / WARM_ENCODES as f64;
    let mut host_idle = Vec::with_capacity(IDLE_ENCODES);
    let mut sweep = vec![0u8; SWEEP_BYTES];
    for k in 0..IDLE_ENCODES {
        ctx.wait()?;
        sweep
            .iter_mut()
            .step_by(64)
            .for_each(|b| *b = b.wrapping_add(k as u8 | 1));
        std::hint::black_box(&sweep);
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        let t = ThreadTime::now();
        path.encode(&mut enc, &inputs)?;
        host_idle.push(t.elapsed().as_secs_f64() * 1e3);
        // Recorded, not submitted: the device stays idle and the next sweep starts cold.
        drop(enc);
    }
    ctx.wait()?;
    // One more frame with timestamps between its passes: GPU ms per stage.
    let mut stages = Vec::new();
    if let Some(ts) = FrameTimestamps::new(ctx, FrameTimestamps::FRAME_CAPACITY)? {
        ts.reset();
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        path.encode(
            &mut enc,
            &FrameInputs {
                timestamps: Some(&ts),
                ..inputs
            },
        )?;
        ts.resolve(&mut enc);
        ctx.queue.submit([enc.finish()]);
        stages = ts.read(ctx)?;
        if ts.dropped() > 0 {
            // The stage times would be short: say so rather than print them.
            return Err(shadow_map_core::Error::Limit {
                what: "timestamps per frame (marks dropped for want of room)",
                requested: u64::from(FrameTimestamps::FRAME_CAPACITY + ts.dropped()),
                max: u64::from(FrameTimestamps::FRAME_CAPACITY),
            });
        }
    }
    Ok(Measured {
        host_ms: host / frames.saturating_sub(1).max(1) as f64,
        host_first_ms: host_first,
        host_wall_ms: host_wall / frames.saturating_sub(1).max(1) as f64,
        rmse: if n > 0 {
            (se / n as f64).sqrt()
        } else {
            f64::NAN
        },
        left_nan,
        active: n + left_nan,
        readbacks,
        gpu_ms,
        host_idle_ms: median(&mut host_idle),
        host_warm_ms,
        cpu_ms,
        stages,
    })
}

fn main() -> std::result::Result<(), Box<dyn std::error::Error>> {
    let mut json = false;
    let mut frames = 60u32;
    let mut timed = TIMED_FRAMES;
    let mut path = concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/bunny/bunny.toml").to_string();
    let (mut size, mut only) = (None, None);
    let mut settings: Vec<(String, String)> = Vec::new();
    let mut small_only = false;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--json" => json = true,
            "--frames" => frames = value()?.parse()?,
            "--timed-frames" => {
                timed = value()?.parse()?;
                if timed == 0 {
                    return Err("--timed-frames: at least 1".into());
                }
            }
            "--resolution" => settings.push(("resolution".into(), value()?)),
            "--param" => {
                let v = value()?;
                let (k, x) = v.split_once('=').ok_or("--param takes NAME=VALUE")?;
                settings.push((k.into(), x.into()));
            }
            "--algo" => only = Some(value()?),
            "--small-only" => small_only = true,
            "--size" => {
                let v = value()?;
                let (w, h) = v
                    .split_once('x')
                    .ok_or("--size takes WxH, e.g. 1920x1080")?;
                size = Some((w.parse::<u32>()?, h.parse::<u32>()?));
            }
            _ => path = a,
        }
    }
    if let Some(o) = only.as_deref().filter(|o| !FRAME_ALGOS.contains(o)) {
        return Err(format!(
            "--algo {o}: no engine path (one of {})",
            FRAME_ALGOS.join(", ")
        )
        .into());
    }
    let ctx = GpuContext::shared()?;
    let mut small = Scene::load(&path)?;
    if let Some((w, h)) = size {
        small.set_resolution(w, h)?;
    }
    let levels = (1..8)
        .find(|l| 4usize.pow(*l) >= 50)
        .ok_or("no tessellation level")?;
    let large = tessellated(&small, levels)?;
    for algo in FRAME_ALGOS
        .iter()
        .copied()
        .filter(|a| only.as_deref().is_none_or(|o| o == *a))
    {
        let measure = |scene: &Scene| {
            run(
                &ctx,
                frame_path(&ctx, algo, scene, &settings)?,
                scene,
                frames,
                timed,
            )
        };
        if small_only {
            let sm = measure(&small)?;
            let (w, h) = (small.camera().width, small.camera().height);
            println!(
                "{{\"algo\":\"{algo}\",\"size\":\"{w}x{h}\",\"frames\":{frames},\"host_ms_per_frame\":{:.4},\"host_ms_first_frame\":{:.4},\"gpu_ms_per_frame\":{:.3},\"cpu_twin_ms\":{:.3},\"rmse_vs_cpu\":{:.3e},\"left_nan\":{},\"active\":{},\"gpu_stage_ms\":{}}}",
                sm.host_ms, sm.host_first_ms, sm.gpu_ms, sm.cpu_ms, sm.rmse, sm.left_nan, sm.active, stages_json(&sm.stages)
            );
            continue;
        }
        let (sm, lg) = (measure(&small)?, measure(&large)?);
        let (ts, tl) = (small.triangles().len(), large.triangles().len());
        if json {
            println!(
                "{{\"algo\":\"{algo}\",\"frames\":{frames},\"readbacks_during_frames\":{},\"triangles_small\":{ts},\"triangles_large\":{tl},\"host_ms_per_frame_small\":{:.4},\"host_ms_per_frame_large\":{:.4},\"host_ms_first_frame_small\":{:.4},\"host_ms_first_frame_large\":{:.4},\"host_wall_ms_per_frame_small\":{:.4},\"host_wall_ms_per_frame_large\":{:.4},\"rmse_vs_cpu_small\":{:.3e},\"rmse_vs_cpu_large\":{:.3e},\"gpu_ms_per_frame_small\":{:.3},\"gpu_ms_per_frame_large\":{:.3},\"cpu_twin_ms_small\":{:.3},\"cpu_twin_ms_large\":{:.3},\"host_ms_idle_small\":{:.4},\"host_ms_idle_large\":{:.4},\"host_ms_warm_small\":{:.4},\"host_ms_warm_large\":{:.4},\"left_nan_small\":{},\"left_nan_large\":{},\"active_small\":{},\"active_large\":{},\"gpu_stage_ms_small\":{},\"gpu_stage_ms_large\":{}}}",
                sm.readbacks + lg.readbacks,
                sm.host_ms,
                lg.host_ms,
                sm.host_first_ms,
                lg.host_first_ms,
                sm.host_wall_ms,
                lg.host_wall_ms,
                sm.rmse,
                lg.rmse,
                sm.gpu_ms,
                lg.gpu_ms,
                sm.cpu_ms,
                lg.cpu_ms,
                sm.host_idle_ms,
                lg.host_idle_ms,
                sm.host_warm_ms,
                lg.host_warm_ms,
                sm.left_nan,
                lg.left_nan,
                sm.active,
                lg.active,
                stages_json(&sm.stages),
                stages_json(&lg.stages)
            );
        } else {
            println!(
                "{algo:>14}: {frames} frames; host ms/frame in encode {:.3} ({ts} triangles) / {:.3} ({tl} triangles); frame ms {:.2} / {:.2} against the CPU twin's {:.2} / {:.2}; last frame RMSE vs CPU twin {:.2e} / {:.2e}, left NaN {} / {}, readbacks during frames {}",
                sm.host_ms, lg.host_ms, sm.gpu_ms, lg.gpu_ms, sm.cpu_ms, lg.cpu_ms, sm.rmse, lg.rmse,
                sm.left_nan, lg.left_nan, sm.readbacks + lg.readbacks
            );
            if !lg.stages.is_empty() {
                println!(
                    "{:>14}  GPU ms per stage (timestamps), small {} / large {}",
                    "",
                    stages_json(&sm.stages),
                    stages_json(&lg.stages)
                );
            }
        }
    }
    Ok(())
}
