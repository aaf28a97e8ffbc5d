//! Unit tests of the report: the reference cache key.
use super::cache_key;
use shadow_map_core::Scene;
use std::path::Path;

/// The reference cache's key follows the parsed scene, the mesh files and the sample count:
/// a comment or spacing in the TOML keeps it, a value, a mesh byte or the sample count moves
/// it.
#[test]
fn cache_key_follows_the_scene_the_meshes_and_the_samples() {
    let dir = tempfile::tempdir().unwrap();
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures");
    let toml =
        std::fs::read_to_string(fixtures.join("parallel-squares/parallel-squares.toml")).unwrap();
    let plane = fixtures.join("common/plane.obj");
    let occ = std::fs::read_to_string(fixtures.join("parallel-squares/occluder.obj")).unwrap();
    std::fs::write(dir.path().join("occluder.obj"), &occ).unwrap();
    let toml = toml.replace("../common/plane.obj", &plane.display().to_string());
    let key = |text: &str, spp: u32| {
        let p = dir.path().join("scene.toml");
        std::fs::write(&p, text).unwrap();
        cache_key(&Scene::load(&p).unwrap(), spp).unwrap()
    };
    let base = key(&toml, 256);
    assert_eq!(base.len(), 32);
    assert_eq!(key(&toml, 256), base, "not deterministic");
    let commented = format!("# a comment\n{}", toml.replace(" = ", "   =   "));
    assert_eq!(key(&commented, 256), base, "a comment moved the key");
    assert_ne!(key(&toml, 1024), base, "the sample count");
    assert_ne!(
        key(&toml.replace("fov_y_deg = 40.0", "fov_y_deg = 41.0"), 256),
        base,
        "a camera value"
    );
    // A mesh byte that moves no vertex (a comment) still moves the key: its bytes are hashed.
    std::fs::write(dir.path().join("occluder.obj"), format!("# edited\n{occ}")).unwrap();
    assert_ne!(key(&toml, 256), base, "the mesh file's bytes");
}
