//! The `softshadow` command line as the contract defines it: render, algos, score, and one-line
//! errors with nothing written on bad input.
use std::path::{Path, PathBuf};
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_softshadow"))
}

fn fixture(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures")
        .join(rel)
}

/// Runs, expects success, returns the process's output.
fn run_success(args: &[&str]) -> std::process::Output {
    let out = bin().args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Runs, expects success, returns stdout.
fn run_ok(args: &[&str]) -> String {
    String::from_utf8(run_success(args).stdout).unwrap()
}

/// The JSON `score <candidate> <reference> <rest...>` prints.
fn score(candidate: &Path, reference: &Path, rest: &[&str]) -> serde_json::Value {
    let mut args = vec![
        "score",
        candidate.to_str().unwrap(),
        reference.to_str().unwrap(),
    ];
    args.extend_from_slice(rest);
    serde_json::from_str(run_ok(&args).trim()).unwrap()
}

/// Runs, expects failure, returns stderr (which must be one line).
fn run_err(args: &[&str]) -> String {
    let out = bin().args(args).output().unwrap();
    assert!(!out.status.success(), "{args:?} should fail");
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
    err
}

#[test]
fn render_stats_and_score() {
    let dir = tempfile::tempdir().unwrap();
    let scene = fixture("parallel-squares/parallel-squares.toml");
    let pcss = dir.path().join("pcss.exr");
    let refr = dir.path().join("ref.exr");
    let png = dir.path().join("pcss.png");
    let sc = scene.to_str().unwrap();
    let stats = run_ok(&render(
        sc,
        "pcss",
        &["resolution=256"],
        &[
            "--out",
            pcss.to_str().unwrap(),
            "--png",
            png.to_str().unwrap(),
            "--stats",
        ],
    ));
    let j: serde_json::Value = serde_json::from_str(stats.trim()).unwrap();
    assert_eq!(j["algo"], "pcss");
    assert_eq!(j["backend"], "cpu");
    assert_eq!(j["params"]["resolution"], "256");
    assert!(j["stages_ms"]["build"].as_f64().unwrap() >= 0.0);
    assert!(j["stages_ms"]["estimate"].as_f64().unwrap() >= 0.0);
    assert!(png.exists());
    run_ok(&render(
        sc,
        "reference",
        &["spp=64"],
        &["--out", refr.to_str().unwrap()],
    ));
    let s = score(&pcss, &refr, &[]);
    assert_eq!(s["matched_fraction"], 1.0);
    assert!(s["rmse"].as_f64().unwrap() < 0.05, "{s}");
    assert_eq!(s["nonfinite_v"], 0);
    // Provenance (the contract's five header attributes), printed by score beside its JSON.
    let c = &s["candidate_provenance"];
    assert_eq!(c["algo"], "pcss", "{s}");
    assert_eq!(c["backend"], "cpu");
    assert_eq!(c["params"]["resolution"], "256");
    assert_eq!(c["params"]["max_taps"], "32");
    assert_eq!(c["version"], env!("CARGO_PKG_VERSION"));
    assert_eq!(c["scene"], sc);
    assert_eq!(s["reference_provenance"]["algo"], "reference");
    assert_eq!(s["reference_provenance"]["params"]["spp"], "64");
    // An image against itself scores zero, and the error image is written.
    let err_png = dir.path().join("err.png");
    let s = score(&pcss, &pcss, &["--err-png", err_png.to_str().unwrap()]);
    assert_eq!(s["rmse"], 0.0);
    assert!(err_png.exists());
}

/// A semi-transparent scene rendered by PCSS, which casts every mesh opaque: one warning line on
/// stderr, without `--stats`; an opaque scene gives none.
#[test]
fn render_warns_of_semi_transparent_casters() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.exr");
    let semi_transparent: &[&str] = &["warning: pcss: 1 semi-transparent meshes were treated as opaque (V too low behind them; backprojection, packet-hsm and deep-shadow model opacity)"];
    for (scene, warnings) in [
        ("strands/strands.toml", semi_transparent),
        ("parallel-squares/parallel-squares.toml", &[]),
    ] {
        let scene = fixture(scene);
        let run = run_success(&render(
            scene.to_str().unwrap(),
            "pcss",
            &["resolution=256"],
            &["--out", out.to_str().unwrap()],
        ));
        let err = String::from_utf8(run.stderr).unwrap();
        let lines: Vec<&str> = err.lines().filter(|l| l.contains("warning: ")).collect();
        assert_eq!(lines, warnings, "{err}");
        assert!(out.exists());
        std::fs::remove_file(&out).unwrap();
    }
}

#[test]
fn algos_lists_every_estimator_with_parameters() {
    let text = run_ok(&["algos"]);
    for name in ["reference", "hard", "pcf", "pcss", "multi-sample"] {
        assert!(
            text.contains(&format!("{name}:")),
            "{name} missing from {text}"
        );
    }
    let j: serde_json::Value = serde_json::from_str(run_ok(&["algos", "--json"]).trim()).unwrap();
    let pcss = j
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["name"] == "pcss")
        .unwrap();
    assert!(pcss["params"]
        .as_array()
        .unwrap()
        .iter()
        .any(|p| p["key"] == "resolution" && p["default"] == "1024"));
    let help = run_ok(&["render", "--help"]);
    assert!(
        help.contains("max_taps"),
        "render --help must list parameters"
    );
}

/// The arguments `render <scene> --algo <algo>`, `--param <p>` for each of `params`, `rest...`.
fn render<'a>(scene: &'a str, algo: &'a str, params: &[&'a str], rest: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec!["render", scene, "--algo", algo];
    for p in params {
        args.extend(["--param", p]);
    }
    args.extend_from_slice(rest);
    args
}

/// The error line of `render <scene> --algo pcss <extra...> --out <out>`.
fn render_pcss_err(scene: &str, extra: &[&str], out: &str) -> String {
    let mut rest = extra.to_vec();
    rest.extend(["--out", out]);
    run_err(&render(scene, "pcss", &[], &rest))
}

#[test]
fn bad_input_is_one_line_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.exr");
    let o = out.to_str().unwrap();
    let scene = fixture("parallel-squares/parallel-squares.toml");
    let s = scene.to_str().unwrap();
    let e = render_pcss_err("/no/such/scene.toml", &[], o);
    assert!(e.contains("/no/such/scene.toml"), "{e}");
    let e = render_pcss_err(s, &["--param", "resolution=0"], o);
    assert!(
        e.contains("resolution") && e.contains("out of range"),
        "{e}"
    );
    let e = render_pcss_err(s, &["--param", "resolution"], o);
    assert!(e.contains("KEY=VALUE"), "{e}");
    let e = run_err(&["render", s, "--algo", "nope", "--out", o]);
    assert!(e.contains("nope"), "{e}");
    let e = render_pcss_err(s, &[], "/no/such/dir/out.exr");
    assert!(e.contains("/no/such/dir/out.exr"), "{e}");
    let bad = dir.path().join("bad.toml");
    std::fs::write(
        &bad,
        std::fs::read_to_string(&scene)
            .unwrap()
            .replace("fov_y_deg", "fov"),
    )
    .unwrap();
    let e = render_pcss_err(bad.to_str().unwrap(), &[], o);
    assert!(e.contains("bad.toml"), "{e}");
    let e = run_err(&["score", "/no/such/a.exr", "/no/such/b.exr"]);
    assert!(e.contains("/no/such/a.exr"), "{e}");
    assert!(!out.exists(), "nothing may be written on bad input");
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "no temporary files left behind"
    );
}

#[test]
fn camera_path_writes_numbered_frames_and_flicker() {
    let dir = tempfile::tempdir().unwrap();
    let scene = fixture("parallel-squares/parallel-squares.toml");
    let out = dir.path().join("pan.exr");
    let mut flicker = Vec::new();
    for fit in ["receivers", "stable"] {
        let fit_kv = format!("fit={fit}");
        let stdout = run_ok(&render(
            scene.to_str().unwrap(),
            "pcf",
            &["resolution=128", &fit_kv],
            &[
                "--frames",
                "3",
                "--pan",
                "0.1,0,-0.05",
                "--out",
                out.to_str().unwrap(),
                "--stats",
            ],
        ));
        let lines: Vec<serde_json::Value> = stdout
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(
            lines.len(),
            4,
            "3 stats lines and the flicker line: {stdout}"
        );
        for (k, l) in lines[..3].iter().enumerate() {
            assert_eq!(l["frame"], k);
        }
        let f = &lines[3]["flicker"];
        assert_eq!(f["frames"], 3);
        assert!(f["pairs"].as_u64().unwrap() > 1000, "{f}");
        let mean = f["mean_abs_dv"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&mean));
        flicker.push(mean);
    }
    for k in 0..3 {
        assert!(dir.path().join(format!("pan.{k:04}.exr")).exists());
    }
    assert!(!dir.path().join("pan.exr").exists());
    // Path flags need each other.
    let s = scene.to_str().unwrap();
    let o = out.to_str().unwrap();
    let err = run_err(&["render", s, "--algo", "hard", "--frames", "3", "--out", o]);
    assert!(err.contains("--orbit"), "{err}");
    let err = run_err(&["render", s, "--algo", "hard", "--orbit", "30", "--out", o]);
    assert!(err.contains("--frames"), "{err}");
    let err = run_err(&[
        "render", s, "--algo", "hard", "--frames", "2", "--pan", "1,x,2", "--out", o,
    ]);
    assert!(err.contains("--pan"), "{err}");
}

/// `render --backend gpu` of an estimator with an engine path renders on the frame API (one
/// encode, one submit, V read back; the `engine_path` note), never leaves an active pixel
/// without a finite V (receivers the device's loop budget cuts are redone by the CPU twin: the
/// exact variant of accumulation on lavapipe), and matches the CPU backend's image but for the
/// G-buffer's pixels (rasterised on the GPU, ray cast on the CPU); with `cascades=3` or a
/// semi-transparent scene the registry's GPU estimator runs: the frame twin for the baselines
/// (`engine_path` "frame twin"), a method's own twin otherwise (no `engine_path` note).
#[cfg(feature = "gpu")]
#[test]
fn render_gpu_takes_the_frame_api() {
    if test_support::gate::context_for_tests("render_gpu_takes_the_frame_api")
        .unwrap()
        .is_none()
    {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let squares = fixture("parallel-squares/parallel-squares.toml");
    // Semi-transparent strands: backprojection's and deep-shadow's frames model the casters'
    // opacity (opacity planes, lists); hard's frame twin casts them opaque and warns.
    let strands = fixture("strands/strands.toml");
    // A sphere light: packet-hsm's engine path sets its silhouette up on the device.
    let sphere = fixture("sphere-light/sphere-light.toml");
    // Sub-pixel strands over a ground (and hair, the same kind): a rasterised G-buffer saw
    // background where the ray-cast one sees ground; both backends must render the same pixels.
    let hair = fixture("hair/hair.toml");
    // The path `--backend gpu` takes: the CLI's own frame (the G-buffer's receivers on the
    // device), the registry's GPU estimator when that is the frame twin (hard, PCF, PCSS and
    // multi-sample: cascades, semi-transparent scenes), or a method's own GPU twin.
    #[derive(Debug, Clone, Copy, PartialEq)]
    enum Path {
        Frame,
        FrameTwin,
        Twin,
    }
    // Every case at resolution=256, with these parameters besides.
    let cases: [(&str, &[&str], Path, &std::path::Path); 16] = [
        ("pcss", &[], Path::Frame, &squares),
        // 16-bit maps: encoded within the frame (the engine path used to refuse them).
        ("hard", &["depth=unorm16"], Path::Frame, &squares),
        ("backprojection", &[], Path::Frame, &squares),
        ("accumulation", &["variant=exact"], Path::Frame, &squares),
        ("deep-shadow", &[], Path::Frame, &squares),
        ("pcss", &["cascades=3"], Path::FrameTwin, &squares),
        ("backprojection", &[], Path::Frame, &strands),
        ("backprojection", &[], Path::Frame, &hair),
        ("deep-shadow", &[], Path::Frame, &strands),
        ("deep-shadow", &[], Path::Frame, &hair),
        ("hard", &[], Path::FrameTwin, &strands),
        ("hard", &[], Path::FrameTwin, &hair),
        ("packet-hsm", &[], Path::Frame, &squares),
        ("packet-hsm", &[], Path::Frame, &sphere),
        // Sub-lights and opacity levels: one view each within the frame.
        ("packet-hsm", &["sublights=2"], Path::Frame, &squares),
        ("packet-hsm", &[], Path::Frame, &hair),
    ];
    for (algo, extra, engine, scene) in cases {
        let params = [&["resolution=256"][..], extra].concat();
        let sc = scene.to_str().unwrap();
        let mut imgs = Vec::new();
        for backend in ["cpu", "gpu"] {
            let out = dir.path().join(format!("{algo}-{engine:?}-{backend}.exr"));
            let stats = run_ok(&render(
                sc,
                algo,
                &params,
                &[
                    "--backend",
                    backend,
                    "--out",
                    out.to_str().unwrap(),
                    "--stats",
                ],
            ));
            let j: serde_json::Value = serde_json::from_str(stats.trim()).unwrap();
            if backend == "gpu" {
                let path = match j["notes"].get("engine_path").and_then(|p| p.as_str()) {
                    Some("frame twin") => Path::FrameTwin,
                    Some(_) => Path::Frame,
                    None => Path::Twin,
                };
                assert_eq!(path, engine, "{algo} {params:?}: {j}");
            }
            imgs.push(out);
        }
        let s = score(&imgs[1], &imgs[0], &[]);
        assert_eq!(s["nonfinite_v"], 0, "{algo} {params:?}: {s}");
        // The same receivers on both backends: every pixel matched.
        assert_eq!(s["matched_fraction"], 1.0, "{algo} {params:?}: {s}");
        assert!(
            s["frac_abs_error_gt_0_1"].as_f64().unwrap() < 0.002,
            "{algo} {params:?}: GPU vs CPU {s}"
        );
    }
}

/// V and Z of an EXR the CLI wrote.
fn read_vz(path: &Path) -> (Vec<f32>, Vec<f32>) {
    let image = crate::first_layer::read_first_layer(path).unwrap();
    let get = |name: &str| -> Vec<f32> {
        image
            .layer_data
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == name)
            .unwrap()
            .sample_data
            .values_as_f32()
            .collect()
    };
    (get("V"), get("Z"))
}

/// The `.glb` bunny renders the V of the OBJ bunny (max |dV| <= 1e-5) on both
/// backends, through the engine path (backprojection on the GPU) and the twin path alike.
#[test]
fn glb_bunny_renders_the_obj_bunny() {
    let dir = tempfile::tempdir().unwrap();
    let toml = std::fs::read_to_string(fixture("bunny/bunny.toml")).unwrap();
    let abs = |s: &str| fixture(s).display().to_string();
    let scene = |mesh: &str| {
        let t = toml
            .replace("../common/plane.obj", &abs("common/plane.obj"))
            .replace(
                "\"bunny.obj\"",
                &format!("\"{}\"", abs(&format!("bunny/{mesh}"))),
            )
            .replace("width = 320", "width = 96")
            .replace("height = 240", "height = 72");
        let p = dir.path().join(format!("{mesh}.toml"));
        std::fs::write(&p, t).unwrap();
        p
    };
    let (obj, glb) = (scene("bunny.obj"), scene("bunny.glb"));
    let gpu = test_support::gate::context_for_tests("glb_bunny_renders_the_obj_bunny")
        .unwrap()
        .is_some();
    for backend in ["cpu", "gpu"] {
        if backend == "gpu" && !gpu {
            continue;
        }
        for algo in ["pcss", "backprojection"] {
            let out = |s: &Path, tag: &str| {
                let o = dir.path().join(format!("{algo}-{backend}-{tag}.exr"));
                run_ok(&[
                    "render",
                    s.to_str().unwrap(),
                    "--algo",
                    algo,
                    "--backend",
                    backend,
                    "--param",
                    "resolution=512",
                    "--out",
                    o.to_str().unwrap(),
                ]);
                read_vz(&o)
            };
            let ((va, za), (vb, zb)) = (out(&obj, "obj"), out(&glb, "glb"));
            assert_eq!(za.len(), zb.len());
            let mut max = 0.0f32;
            for k in 0..va.len() {
                assert_eq!(
                    za[k].is_finite(),
                    zb[k].is_finite(),
                    "{algo} {backend} pixel {k}"
                );
                if za[k].is_finite() {
                    max = max.max((va[k] - vb[k]).abs());
                }
            }
            println!("{algo} on {backend}: glb against obj, max |dV| {max:.2e}");
            assert!(max <= 1e-5, "{algo} on {backend}: max |dV| {max}");
        }
    }
}

/// Ctrl-C (SIGINT) during a long render stops it at the estimator's next cancellation check:
/// exit status 130, one line on standard error, no output file. Without the handler the
/// process would die by the signal (no status 130, no message).
#[test]
fn ctrl_c_stops_a_render_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ref.exr");
    let scene = fixture("bunny/bunny.toml");
    let mut child = bin()
        .args([
            "render",
            scene.to_str().unwrap(),
            "--algo",
            "reference",
            "--param",
            "spp=65536",
            "--out",
            out.to_str().unwrap(),
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Long enough for the scene to load and the handler to be installed; the render itself
    // takes minutes at this sample count.
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let sent = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(sent.success(), "kill -INT failed");
    let t = std::time::Instant::now();
    let output = loop {
        if child.try_wait().unwrap().is_some() {
            break child.wait_with_output().unwrap();
        }
        if t.elapsed().as_secs() > 60 {
            let _ = child.kill();
            panic!("render still running 60 s after SIGINT");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    let err = String::from_utf8_lossy(&output.stderr);
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(output.status.code(), Some(130), "stderr: {err}");
    assert_eq!(lines.len(), 1, "stderr: {err}");
    assert!(lines[0].contains("interrupted"), "{err}");
    assert!(!out.exists(), "a partial output was written");
}
