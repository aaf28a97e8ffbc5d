//! A headless Bevy app (no window; the camera renders into an image) around a contract scene,
//! driven frame by frame: each method renders some frames through [`SoftShadowPlugin`] (the
//! light's [`SoftShadowSettings`] switched between methods), then its V texture is read back once
//! and compared with the CPU twin on the same receivers, those Bevy's prepass gave, in the same
//! light views. Not part of the crate: `tests/headless.rs` and `examples/headless.rs` include it
//! with `#[path]`, beside `fixture.rs` as `crate::fixture`.
#![allow(dead_code)] // each includer uses its own part

use crate::fixture;
use bevy::{
    app::PluginsState,
    camera::RenderTarget,
    core_pipeline::tonemapping::Tonemapping,
    prelude::*,
    render::{render_asset::RenderAssets, renderer::RenderDevice, texture::GpuImage, RenderApp},
    window::{ExitCondition, WindowPlugin},
};
use bevy_softshadow::{Method, SoftShadowPlugin, SoftShadowSettings, SoftShadowViews};
use shadow_map_core::{
    gpu::{depth_map::read_texture_words, GpuContext},
    Receivers, Scene, SceneBvh,
};
use std::time::Instant;

/// What one method's frames gave.
#[derive(Debug, Clone)]
pub struct MethodRun {
    /// The method.
    pub method: Method,
    /// Frames rendered.
    pub frames: u32,
    /// Wall time of one `App::update` plus the wait for the device to finish it, over the
    /// frames after the method's first (which prepares its pipelines).
    pub ms_per_frame: f64,
    /// The comparison, or why the view has no frame (a light the method does not model).
    pub result: Result<Comparison, String>,
}

/// The method's last V against the CPU twins.
#[derive(Debug, Clone)]
pub struct Comparison {
    /// RMSE against the CPU twin on the same receivers in the same views, over the receivers
    /// with a finite V.
    pub rmse_vs_cpu: f64,
    /// The largest difference among them.
    pub max_abs_vs_cpu: f64,
    /// Receivers (pixels Bevy's prepass covers).
    pub receivers: usize,
    /// Receivers the device left NaN (cut by its loop budget), counted apart.
    pub nan: usize,
    /// Light views the frame rendered.
    pub views: usize,
    /// Frames the view's prepared frame recorded since the method was switched to (the frame is
    /// prepared once per method and size, then kept).
    pub frames_recorded: u64,
    /// Mean V over the receivers.
    pub mean_v: f64,
    /// Share of receivers with V below 0.5.
    pub frac_below_half: f64,
    /// Pixels that Bevy's prepass and the ray-traced G-buffer disagree on covering.
    pub pixels_covered_by_one: usize,
    /// Pixels both cover whose positions differ by more than 1e-3 of the distance to the eye.
    pub pixels_apart: usize,
    /// The largest such relative difference.
    pub max_position_rel: f64,
    /// RMSE against `softshadow render --backend cpu` (the ray-traced G-buffer, the CPU's own
    /// view fit to the receivers) over the pixels both cover within 1e-3.
    pub rmse_vs_cpu_render: f64,
    /// Active receivers left NaN as the view's status (read back without waiting) counted them;
    /// `None` when no status had come back.
    pub status_left_nan: Option<u32>,
    /// Whether the method's frame keeps a status buffer (multi-sample keeps none).
    pub keeps_status: bool,
}

/// What [`run`] gives.
#[derive(Debug, Clone)]
pub struct Headless {
    /// One per method, in order.
    pub runs: Vec<MethodRun>,
    /// Bevy's own frame (prepass, main pass) without the plugin's work: the light's
    /// [`SoftShadowSettings`] removed, ms per frame measured as [`MethodRun::ms_per_frame`].
    pub bevy_alone_ms: f64,
    /// The last method's final image (RGBA8, the composite applied), when asked for.
    pub screenshot: Option<Vec<u8>>,
}

/// Renders `scene` headless with each of `methods` for `frames` frames (at least 2) and
/// compares each method's last V with its CPU twins; first, as many frames without the plugin's
/// work. `max_distance`: [`SoftShadowSettings::max_distance`]. Errors: a scene or setting the app cannot render; panics only where Bevy itself does
/// (no GPU adapter: check one first).
pub fn run(
    scene: &Scene,
    methods: &[Method],
    frames: u32,
    screenshot: bool,
    max_distance: Option<f32>,
) -> Result<Headless, String> {
    if frames < 2 {
        return Err("frames: at least 2 (the first prepares the pipelines)".into());
    }
    let first = methods.first().copied().unwrap_or_default();
    let (mut app, light, target) = app(scene, first, max_distance);
    // Two frames for the meshes to reach the GPU.
    for _ in 0..2 {
        frame(&mut app);
    }
    let settings = app
        .world_mut()
        .entity_mut(light)
        .take::<SoftShadowSettings>()
        .ok_or("the light has no settings")?;
    let alone: Vec<f64> = (0..frames).map(|_| frame(&mut app)).collect();
    app.world_mut().entity_mut(light).insert(settings);
    let raytraced = Receivers::from_camera(scene, &SceneBvh::new(scene));
    let mut runs = Vec::new();
    for &method in methods {
        app.world_mut()
            .get_mut::<SoftShadowSettings>(light)
            .ok_or("the light lost its settings")?
            .method = method;
        let times: Vec<f64> = (0..frames).map(|_| frame(&mut app)).collect();
        runs.push(MethodRun {
            method,
            frames,
            ms_per_frame: times[1..].iter().sum::<f64>() / (times.len() - 1) as f64,
            result: compare(&app, scene, method, &raytraced),
        });
    }
    let shot = if screenshot {
        Some(read_image(&app, &target)?)
    } else {
        None
    };
    Ok(Headless {
        runs,
        bevy_alone_ms: alone[1..].iter().sum::<f64>() / (alone.len() - 1) as f64,
        screenshot: shot,
    })
}

/// The app: Bevy's default plugins without a window, the plugin, the scene with its light
/// carrying `method`, and its camera rendering into an image. Returns the light's entity and
/// the image.
fn app(scene: &Scene, method: Method, max_distance: Option<f32>) -> (App, Entity, Handle<Image>) {
    let (w, h) = (scene.camera().width, scene.camera().height);
    let mut app = App::new();
    app.add_plugins(DefaultPlugins.set(WindowPlugin {
        primary_window: None,
        exit_condition: ExitCondition::DontExit,
        ..default()
    }))
    .add_plugins(SoftShadowPlugin);
    let world = app.world_mut();
    let mut image = Image::new_target_texture(
        w,
        h,
        bevy::render::render_resource::TextureFormat::Rgba8UnormSrgb,
        None,
    );
    image.texture_descriptor.usage |= wgpu::TextureUsages::COPY_SRC;
    let target = world.resource_mut::<Assets<Image>>().add(image);
    world.spawn((
        fixture::camera_bundle(scene),
        RenderTarget::Image(target.clone().into()),
        Tonemapping::None,
    ));
    let light = world.resource_scope(|world, mut meshes: Mut<Assets<Mesh>>| {
        world.resource_scope(|world, mut materials: Mut<Assets<StandardMaterial>>| {
            let mut commands = world.commands();
            fixture::spawn(
                scene,
                SoftShadowSettings {
                    max_distance,
                    ..SoftShadowSettings::new(method)
                },
                &mut commands,
                &mut meshes,
                &mut materials,
            )
        })
    });
    world.flush();
    while app.plugins_state() == PluginsState::Adding {
        bevy::tasks::tick_global_task_pools_on_main_thread();
    }
    app.finish();
    app.cleanup();
    (app, light, target)
}

/// One frame, then the wait for the device to finish it: milliseconds.
fn frame(app: &mut App) -> f64 {
    let t = Instant::now();
    app.update();
    let device = app.sub_app(RenderApp).world().resource::<RenderDevice>();
    let _ = device
        .wgpu_device()
        .poll(wgpu::PollType::wait_indefinitely());
    t.elapsed().as_secs_f64() * 1e3
}

/// Reads the view's V texture and receivers back (once) and compares V with the CPU twins.
fn compare(
    app: &App,
    scene: &Scene,
    method: Method,
    raytraced: &Receivers,
) -> Result<Comparison, String> {
    let world = app.sub_app(RenderApp).world();
    let state = world.resource::<SoftShadowViews>();
    let vf = state.views.values().next().ok_or("no view was rendered")?;
    if let Some(e) = &vf.error {
        return Err(e.clone());
    }
    if vf.method() != method || vf.frames == 0 {
        return Err(format!("{}: the view did not switch", method.name()));
    }
    let ctx = &state.shared.as_ref().ok_or("no device state")?.ctx;
    let (w, h) = vf.size();
    let n = (w * h) as usize;
    let v = read_texture(ctx, &vf.v_texture)?;
    let rec: Vec<shadow_map_core::gpu::shared::ReceiverGpu> = ctx
        .read_buffer(&vf.receivers, 32 * n as u64)
        .map_err(|e| e.to_string())?;
    let active: Vec<usize> = (0..n).filter(|&k| rec[k].active == 1).collect();
    let receivers = Receivers::from_points(
        active
            .iter()
            .map(|&k| Vec3::from(rec[k].position))
            .collect(),
        active.iter().map(|&k| Vec3::from(rec[k].normal)).collect(),
    )
    .map_err(|e| e.to_string())?;
    // The twins on the plugin's own light (a disk is a RectLight in Bevy).
    let mut twin_scene = scene.clone();
    twin_scene
        .set_light(vf.light.ok_or("no light recorded")?)
        .map_err(|e| e.to_string())?;
    let cpu = vf
        .frame
        .cpu_twin(&twin_scene, &receivers, &vf.views)
        .map_err(|e| e.to_string())?;
    let (mut se, mut count, mut nan, mut max) = (0.0f64, 0usize, 0usize, 0.0f64);
    for (i, &k) in active.iter().enumerate() {
        if !v[k].is_finite() {
            nan += 1;
            continue;
        }
        let d = (v[k] - cpu[i]) as f64;
        se += d * d;
        max = max.max(d.abs());
        count += 1;
    }
    // Bevy's prepass against the ray-traced G-buffer, and V against `softshadow render` on
    // the CPU (its own receivers and view fit) where the two G-buffers agree.
    let mut est = softshadow::estimator(method.name(), softshadow::Backend::Cpu)
        .map_err(|e| e.to_string())?;
    let (v_render, _) =
        shadow_map_core::run(est.as_mut(), &twin_scene, raytraced).map_err(|e| e.to_string())?;
    let (mut only_one, mut worst, mut apart) = (0usize, 0.0f32, 0usize);
    let (mut se_r, mut count_r) = (0.0f64, 0usize);
    for k in 0..n.min(raytraced.len()) {
        let a = rec[k].active == 1;
        if a != raytraced.active()[k] {
            only_one += 1;
        } else if a {
            let q = raytraced.position()[k];
            let rel =
                (Vec3::from(rec[k].position) - q).length() / (q - scene.camera().eye).length();
            worst = worst.max(rel);
            if rel > 1e-3 {
                apart += 1;
            } else if v[k].is_finite() && v_render[k].is_finite() {
                let d = (v[k] - v_render[k]) as f64;
                se_r += d * d;
                count_r += 1;
            }
        }
    }
    let finite: Vec<f64> = active
        .iter()
        .map(|&k| v[k] as f64)
        .filter(|x| x.is_finite())
        .collect();
    let per = |x: f64, c: usize| if c > 0 { x / c as f64 } else { f64::NAN };
    Ok(Comparison {
        rmse_vs_cpu: per(se, count).sqrt(),
        max_abs_vs_cpu: max,
        receivers: active.len(),
        nan,
        views: vf.views.iter().flatten().count(),
        frames_recorded: vf.frames,
        mean_v: per(finite.iter().sum(), finite.len()),
        frac_below_half: per(
            finite.iter().filter(|&&x| x < 0.5).count() as f64,
            finite.len(),
        ),
        pixels_covered_by_one: only_one,
        pixels_apart: apart,
        max_position_rel: worst as f64,
        rmse_vs_cpu_render: per(se_r, count_r).sqrt(),
        status_left_nan: vf.status.map(|s| s.left_nan),
        keeps_status: vf.frame.status().is_some(),
    })
}

/// An `R32Float` texture's texels, row by row from the top.
fn read_texture(ctx: &GpuContext, tex: &wgpu::Texture) -> Result<Vec<f32>, String> {
    Ok(read_texture_words(ctx, tex)
        .map_err(|e| e.to_string())?
        .into_iter()
        .map(f32::from_bits)
        .collect())
}

/// The camera's image (RGBA8, the composite applied).
fn read_image(app: &App, target: &Handle<Image>) -> Result<Vec<u8>, String> {
    let world = app.sub_app(RenderApp).world();
    let gpu = world
        .resource::<RenderAssets<GpuImage>>()
        .get(target)
        .ok_or("the target image is not on the GPU")?;
    let state = world.resource::<SoftShadowViews>();
    let ctx = &state.shared.as_ref().ok_or("no device state")?.ctx;
    let words = read_texture_words(ctx, &gpu.texture).map_err(|e| e.to_string())?;
    Ok(bytemuck::cast_slice(&words).to_vec())
}
