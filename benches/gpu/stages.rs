//! The shadow-map stages (raster, peeling, MSSM, dual MSSM, pyramid) and the PCSS estimate, on
//! the fixture, on both backends, with the work each counts (`benches/README.md`, "The rows").
use crate::{
    config::Config,
    report::{Bound, Row},
    timing::{time_cpu, try_time_cpu, Gpu, Method, StampAt},
    BenchResult,
};
use shadow_map_core::{
    gpu::{mssm::MinMaxRequest, GpuDepthMap, GpuScene, GpuShadowMapper},
    mssm::{DualMssm, MinMaxPyramid, Mssm},
    LightSpace, LightSpaceRequest, LightView, Receivers, Scene,
};
use std::hint::black_box;

/// MSSM levels built (anchored and dual-grid): `0..=MSSM_LEVELS`.
pub const MSSM_LEVELS: u32 = 6;
/// Layers of the peeling stage.
pub const PEEL_LAYERS: u32 = 4;

/// Texel reads of one anchored step with window offset h over an s x s level: each output texel
/// fetches (x, y), (x+h, y), (x, y+h), (x+h, y+h) where inside the map, from the min and the max
/// plane: `2 (2s - h)^2`.
fn step_reads(s: u64, h: u64) -> f64 {
    let e = 2 * s - h.min(s);
    2.0 * (e * e) as f64
}

/// `floor(log2(n))`.
pub fn floor_log2(n: u32) -> u32 {
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
pub struct StageEnv<'a> {
    pub g: &'a Gpu<'a>,
    pub cfg: &'a Config,
    pub scene: &'a Scene,
    pub receivers: &'a Receivers,
    pub view: LightView,
    pub gpu_scene: GpuScene,
    pub mapper: GpuShadowMapper,
    /// Layer 0 rendered on the GPU in `view` (the MSSM stages' input).
    pub layer0: GpuDepthMap,
}

fn peel_request(r: u32) -> LightSpaceRequest {
    LightSpaceRequest {
        layers: PEEL_LAYERS,
        ..LightSpaceRequest::single(r)
    }
}

/// The raster stages on `backend`: their ids and requests (one layer, then the peeled layers).
fn raster_stages(backend: &str, r: u32, name: &str) -> [(String, LightSpaceRequest); 2] {
    [
        (
            format!("shadow-map/{backend}/render-1/{r}@{name}"),
            LightSpaceRequest::single(r),
        ),
        (
            format!("peeling/{backend}/peel-{PEEL_LAYERS}/{r}@{name}"),
            peel_request(r),
        ),
    ]
}

/// The MSSM-family requests of `GpuMssmBuilder::encode`, with the id stem, the texel reads
/// counted at side `r`, and the bytes of GPU memory one build holds (`plane` bytes a level plane).
fn mssm_stages(r: u32, plane: u64) -> [(&'static str, MinMaxRequest, f64, u64); 3] {
    let levels = MSSM_LEVELS.min(floor_log2(r));
    [
        (
            "mssm/gpu/build-6",
            MinMaxRequest::mssm(MSSM_LEVELS),
            mssm_reads(r, MSSM_LEVELS),
            (1 + 2 * levels as u64) * plane,
        ),
        (
            "dual-mssm/gpu/build-6",
            MinMaxRequest::dual_mssm(MSSM_LEVELS),
            dual_mssm_reads(r, MSSM_LEVELS),
            (3 + 2 * levels as u64) * plane,
        ),
        (
            "pyramid/gpu/build",
            MinMaxRequest::pyramid(),
            pyramid_reads(r),
            4 * plane,
        ),
    ]
}

/// The shadow-map stages on the GPU through the public API.
pub fn gpu_stages(env: &StageEnv) -> BenchResult<Vec<Row>> {
    let (g, ctx, r) = (env.g, env.g.ctx, env.cfg.res);
    let name = &env.cfg.name;
    let tris = env.gpu_scene.triangles as f64;
    let plane = r as u64 * r as u64 * 4;
    let mut rows = Vec::new();
    // Raster: `render_layers` records and submits by itself, with no timestamp hook: wall clock
    // over T calls and one wait.
    for (id, req) in raster_stages("gpu", r, name) {
        let t = g.time_calls((req.layers as u64 + 1) * plane, || {
            env.mapper
                .render_layers(ctx, &env.gpu_scene, &env.view, &req)?;
            Ok(())
        })?;
        let work = tris * req.layers as f64;
        rows.push(Row::new(
            id,
            t,
            work,
            "triangles",
            Some(Bound::GpuTriangles),
        ));
    }
    // MSSM family: `GpuMssmBuilder::encode` records into our encoder, so T builds go in one
    // submit, with encoder-level timestamps around each.
    let builder = env.mapper.mssm_builder();
    for (id, req, reads, bytes) in mssm_stages(r, plane) {
        let t = g.time_encoded(StampAt::Encoder, bytes, |enc, _| {
            builder.encode(ctx, enc, &env.layer0, req)?;
            Ok(())
        })?;
        let id = format!("{id}/{r}@{name}");
        rows.push(Row::new(id, t, reads, "texel reads", Some(Bound::GpuTaps)));
    }
    Ok(rows)
}

/// The same stages on the CPU backend, in the same view.
pub fn cpu_stages(env: &StageEnv) -> Vec<Row> {
    let (r, name, budget) = (env.cfg.res, &env.cfg.name, env.g.budget_ms);
    let tris = env.gpu_scene.triangles as f64;
    let fit = Default::default();
    let mut rows = Vec::new();
    for (id, req) in raster_stages("cpu", r, name) {
        let t = time_cpu(budget, || {
            black_box(LightSpace::build_in_view(env.scene, env.view, fit, &req));
        });
        rows.push(Row::new(id, t, tris * req.layers as f64, "triangles", None));
    }
    let ls = LightSpace::build_in_view(env.scene, env.view, fit, &LightSpaceRequest::single(r));
    let l0 = &ls.layers[0];
    let (d, s) = (&l0.depth, l0.size);
    let builds: [(String, f64, &dyn Fn()); 3] = [
        (
            format!("mssm/cpu/build-6/{r}@{name}"),
            mssm_reads(s, MSSM_LEVELS),
            &|| {
                black_box(Mssm::build(black_box(d), s, MSSM_LEVELS));
            },
        ),
        (
            format!("dual-mssm/cpu/build-6/{r}@{name}"),
            dual_mssm_reads(s, MSSM_LEVELS),
            &|| {
                black_box(DualMssm::build(black_box(d), s, MSSM_LEVELS));
            },
        ),
        (
            format!("pyramid/cpu/build/{r}@{name}"),
            pyramid_reads(s),
            &|| {
                black_box(MinMaxPyramid::build(black_box(d), s));
            },
        ),
    ];
    for (id, work, build) in builds {
        let t = time_cpu(budget, build);
        rows.push(Row::new(id, t, work, "texel reads", Some(Bound::CpuTaps)));
    }
    rows
}

/// The PCSS estimate of `crates/baselines` on both backends through the estimator trait, in the
/// bench's scene and receivers: `pcss/gpu/estimate` is the registry's GPU estimator (its frame
/// run by `FrameTwin`: receiver upload, the frame's raster and kernel, V readback) after one
/// `build`, `pcss/cpu/estimate` the CPU twin's estimate after its `build`. Unit: receivers.
pub fn estimate_stages(env: &StageEnv) -> BenchResult<Vec<Row>> {
    use baselines::PcssShadow;
    use shadow_map_core::SoftShadowEstimator;
    let r = env.cfg.res;
    let name = &env.cfg.name;
    let n = env.receivers.active_count() as f64;
    let mut v = vec![0.0f32; env.receivers.len()];
    let mut gpu = baselines::PCSS
        .gpu(std::sync::Arc::new(env.g.ctx.clone()))
        .expect("PCSS has a frame")?;
    gpu.set_param("resolution", &r.to_string())?;
    gpu.build(env.scene, env.receivers)?;
    let mut t = try_time_cpu(2000.0, || gpu.estimate(env.scene, env.receivers, &mut v))?;
    t.method = Method::WallCalls;
    t.note = Some("whole estimate call: receiver upload, raster, kernel and V readback".into());
    let mut rows = vec![Row::new(
        format!("pcss/gpu/estimate/{r}@{name}"),
        t,
        n,
        "receivers",
        None,
    )];
    let mut cpu = PcssShadow::new()?;
    cpu.set_param("resolution", &r.to_string())?;
    cpu.build(env.scene, env.receivers)?;
    let t = try_time_cpu(2000.0, || cpu.estimate(env.scene, env.receivers, &mut v))?;
    rows.push(Row::new(
        format!("pcss/cpu/estimate/{r}@{name}"),
        t,
        n,
        "receivers",
        None,
    ));
    Ok(rows)
}

/// The engine path of every estimator that has one (`FrameEstimator`): a frame recorded into
/// the bench's encoder (views fitted once, receivers uploaded once, V into a buffer of the
/// bench's), timed with every iteration in one encoder and one submit, timestamps around each
/// where the device has them; beside it the CPU twin's build and estimate in the same views. Work:
/// the casters' triangles times the frame's passes over them, so the GPU row reads as a fraction
/// of the triangle ceiling (the frame's kernels come on top: the fraction is what raster alone
/// would allow).
pub fn frame_stages(env: &StageEnv, cpu: bool) -> BenchResult<Vec<Row>> {
    use shadow_map_core::gpu::{frame::FrameInputs, receivers::GpuReceivers};
    let (g, r, name) = (env.g, env.cfg.res, &env.cfg.name);
    let ctx = std::sync::Arc::new(g.ctx.clone());
    let receivers = GpuReceivers::upload(g.ctx, env.receivers)?;
    let n = env.receivers.len() as u64;
    let v = g.ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("bench V"),
        size: 4 * n.max(1),
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    let mut frames = Vec::new();
    for algo in softshadow::FRAME_ALGOS {
        let mut p = softshadow::method(algo)?.cpu()?.params().clone();
        p.set("resolution", &r.to_string())?;
        if let Some(f) = softshadow::frame_estimator(algo, ctx.clone(), &p, n as u32)? {
            frames.push((algo, f));
        }
    }
    let tris = env.gpu_scene.triangles as f64;
    let mut rows = Vec::new();
    for (algo, frame) in &frames {
        let views = frame.fit_views(env.scene, env.receivers)?;
        let work = tris * frame.caster_passes(&views) as f64;
        let inputs = FrameInputs {
            casters: &env.gpu_scene,
            views: &views,
            light: env.scene.light(),
            receivers: &receivers.buffer,
            count: receivers.count,
            v: &v,
            timestamps: None,
        };
        let t = g.time_encoded(StampAt::Encoder, (r as u64).pow(2) * 16, |enc, _| {
            Ok(frame.encode(enc, &inputs)?)
        })?;
        rows.push(Row::new(
            format!("frame/gpu/{algo}/{r}@{name}"),
            t,
            work,
            "triangles",
            Some(Bound::GpuTriangles),
        ));
        if cpu {
            let mut t = try_time_cpu(g.budget_ms, || {
                frame
                    .cpu_twin(env.scene, env.receivers, &views)
                    .map(|v| drop(black_box(v)))
            })?;
            t.note = Some("the CPU twin's build and estimate in the frame's views".into());
            rows.push(Row::new(
                format!("frame/cpu/{algo}/{r}@{name}"),
                t,
                work,
                "triangles",
                None,
            ));
        }
    }
    Ok(rows)
}
