//! The plugin in a window, for people: a fixture scene with an orbiting camera, the method
//! switched on a key, and the measured RMSE of the current setting (from `docs/report/`, the
//! CPU twin against the ray-traced reference on this fixture) in the window's title.
//!
//! ```text
//! cargo run --release --example windowed --features window -- ../../fixtures/sun-bunny/sun-bunny.toml
//! cargo run --release --example windowed --features window -- ../../fixtures/sun-street/sun-street.toml 30
//! ```
//!
//! The optional second argument is `SoftShadowSettings::max_distance` (large grounds).
//!
//! Keys: 1-8 pick a method (hard, pcf, pcss, multi-sample, backprojection, accumulation,
//! deep-shadow, packet-hsm), Space cycles, Left/Right orbit, O stops or starts the orbit,
//! C turns the composite off and on (Bevy's own lighting without the plugin's shadow).
use bevy::{prelude::*, window::PrimaryWindow};
use bevy_softshadow::{measured, Method, SoftShadowPlugin, SoftShadowSettings};
use shadow_map_core::Scene;

/// The contract scene as Bevy entities (shared with the tests).
#[path = "../tests/common/fixture.rs"]
mod fixture;

#[derive(Resource)]
struct Demo {
    scene: Scene,
    max_distance: Option<f32>,
    fixture: String,
    light: Option<Entity>,
    angle: f32,
    orbit: bool,
}

fn main() {
    let path = std::env::args().nth(1).unwrap_or_else(|| {
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../fixtures/bunny/bunny.toml"
        )
        .into()
    });
    let scene = match Scene::load(&path) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("windowed: {e}");
            std::process::exit(1);
        }
    };
    let max_distance = std::env::args().nth(2).and_then(|d| d.parse().ok());
    let fixture = std::path::Path::new(&path)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let (w, h) = (
        scene.camera().width.max(640),
        scene.camera().height.max(480),
    );
    App::new()
        .add_plugins(DefaultPlugins.set(WindowPlugin {
            primary_window: Some(Window {
                resolution: (w, h).into(),
                title: "softshadow".into(),
                ..default()
            }),
            ..default()
        }))
        .add_plugins(SoftShadowPlugin)
        .insert_resource(Demo {
            scene,
            max_distance,
            fixture,
            light: None,
            angle: 0.0,
            orbit: true,
        })
        .add_systems(Startup, setup)
        .add_systems(Update, (keys, orbit, title))
        .run();
}

fn setup(
    mut commands: Commands,
    mut demo: ResMut<Demo>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    commands.spawn(fixture::camera_bundle(&demo.scene));
    let light = fixture::spawn(
        &demo.scene,
        SoftShadowSettings {
            max_distance: demo.max_distance,
            ..SoftShadowSettings::new(Method::Pcss)
        },
        &mut commands,
        &mut meshes,
        &mut materials,
    );
    demo.light = Some(light);
}

fn keys(
    input: Res<ButtonInput<KeyCode>>,
    time: Res<Time>,
    mut demo: ResMut<Demo>,
    mut settings: Query<&mut SoftShadowSettings>,
) {
    let Some(mut s) = demo.light.and_then(|l| settings.get_mut(l).ok()) else {
        return;
    };
    let digits = [
        KeyCode::Digit1,
        KeyCode::Digit2,
        KeyCode::Digit3,
        KeyCode::Digit4,
        KeyCode::Digit5,
        KeyCode::Digit6,
        KeyCode::Digit7,
        KeyCode::Digit8,
    ];
    for (k, key) in digits.iter().enumerate() {
        if input.just_pressed(*key) {
            s.method = Method::ALL[k];
        }
    }
    if input.just_pressed(KeyCode::Space) {
        let k = Method::ALL.iter().position(|m| *m == s.method).unwrap_or(0);
        s.method = Method::ALL[(k + 1) % Method::ALL.len()];
    }
    if input.just_pressed(KeyCode::KeyC) {
        s.composite = if s.composite > 0.0 { 0.0 } else { 1.0 };
    }
    if input.just_pressed(KeyCode::KeyO) {
        demo.orbit = !demo.orbit;
    }
    let dt = time.delta_secs();
    if input.pressed(KeyCode::ArrowLeft) {
        demo.angle -= dt;
    }
    if input.pressed(KeyCode::ArrowRight) {
        demo.angle += dt;
    }
}

/// The camera on a circle around the contract camera's target, at its height and distance.
fn orbit(time: Res<Time>, mut demo: ResMut<Demo>, mut cams: Query<&mut Transform, With<Camera3d>>) {
    if demo.orbit {
        demo.angle += 0.2 * time.delta_secs();
    }
    let c = demo.scene.camera();
    let offset = Quat::from_axis_angle(c.up.normalize(), demo.angle) * (c.eye - c.target);
    for mut t in &mut cams {
        *t = Transform::from_translation(c.target + offset).looking_at(c.target, c.up);
    }
}

fn title(
    demo: Res<Demo>,
    settings: Query<&SoftShadowSettings>,
    mut window: Query<&mut Window, With<PrimaryWindow>>,
) {
    let (Some(s), Ok(mut w)) = (
        demo.light.and_then(|l| settings.get(l).ok()),
        window.single_mut(),
    ) else {
        return;
    };
    let runs = measured(s);
    let here = runs.iter().find(|r| r.fixture == demo.fixture);
    let rmse = match here {
        Some(r) => format!(
            "RMSE {:.4} on {} (CPU {:.0} ms)",
            r.rmse, r.fixture, r.frame_ms
        ),
        None => match bevy_softshadow::mean_rmse(s, &[]) {
            Some((m, n)) => format!("mean RMSE {m:.4} over {n} fixtures"),
            None => "not measured".into(),
        },
    };
    let t = format!(
        "softshadow: {} (keys 1-8, Space) - {rmse}, docs/report{}",
        s.method.name(),
        if s.composite > 0.0 {
            ""
        } else {
            " - composite off"
        }
    );
    if w.title != t {
        w.title = t;
    }
}
