//! Bad input, fuzzed: the scene TOML and OBJ loaders and the `--param` parser under proptest with
//! arbitrary and mutated inputs. Every outcome must be `Ok` or a one-line error that names the
//! file (and, for the loaders, the key or the line); nothing may panic (a panic fails the case).
//! Loaded scenes must hold only finite geometry and a valid light.
//!
//! Cases per property: 10^4 by default (what CI runs); `SOFTSHADOW_FUZZ_CASES=1000000` for the
//! long run.
use crate::common;

use common::{good_scene_toml, QUAD};
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use shadow_map_core::{params::parse_assignment, Error, ParamSpec, Params, Scene};
use std::path::Path;

const GOOD: &str = concat!(good_scene_toml!(), "opacity = 0.5\n");

fn cases() -> u32 {
    std::env::var("SOFTSHADOW_FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10_000)
}

fn runner() -> TestRunner {
    TestRunner::new(Config {
        cases: cases(),
        failure_persistence: None,
        ..Config::default()
    })
}

/// A mutation of a valid text: delete, duplicate or replace a span, or insert bytes from a
/// vocabulary of syntax the format uses (and some it must reject).
fn mutated(base: &'static str) -> impl Strategy<Value = String> {
    let vocab = prop::sample::select(vec![
        "",
        "=",
        "[",
        "]",
        "[[",
        "]]",
        ",",
        "\"",
        "\n",
        "#",
        ".",
        "-",
        "e",
        "1e39",
        "-0",
        "nan",
        "inf",
        "0",
        "1",
        "-1",
        "0.0",
        "[]",
        "[1,2]",
        "true",
        "f 1 2 3",
        "v 1 2",
        "f 0 0 0",
        "f -1 -2 -3",
        "f 1/1/1 2//2 3/3",
        "vn 0 1 0",
        "o x",
        "mtllib a.mtl",
        "\u{feff}",
        "\u{0}",
        "size",
        "radius",
        "shape = \"disk\"",
        "shape = \"sphere\"",
        "opacity = 2",
        "width = 0",
        "path = \"missing.obj\"",
        "scale = -1",
        "[[mesh]]\npath = \"quad.obj\"",
    ]);
    let ops = prop::collection::vec(
        (0usize..4, any::<prop::sample::Index>(), 0usize..12, vocab),
        1..6,
    );
    ops.prop_map(move |ops| {
        let mut s: Vec<char> = base.chars().collect();
        for (op, at, len, ins) in ops {
            let i = at.index(s.len() + 1);
            let j = (i + len).min(s.len());
            match op {
                0 => {
                    s.drain(i..j);
                }
                1 => {
                    let dup: Vec<char> = s[i..j].to_vec();
                    s.splice(i..i, dup);
                }
                2 => {
                    s.splice(i..j, ins.chars());
                }
                _ => {
                    s.splice(i..i, ins.chars());
                }
            }
        }
        s.into_iter().collect()
    })
}

fn check_load(dir: &Path, toml: &str, obj: &str) -> Result<(), TestCaseError> {
    std::fs::write(dir.join("quad.obj"), obj).unwrap();
    let p = dir.join("scene.toml");
    std::fs::write(&p, toml).unwrap();
    match Scene::load(&p) {
        Ok(scene) => {
            for t in scene.triangles() {
                prop_assert!(t.iter().all(|v| v.is_finite()), "non-finite vertex loaded");
            }
            prop_assert!(scene.light().center.is_finite() && scene.light().normal.is_normalized());
            prop_assert!(scene.camera().width > 0 && scene.camera().height > 0);
        }
        Err(e) => {
            let msg = e.to_string();
            prop_assert!(!msg.trim().is_empty());
            prop_assert!(!msg.trim_end().contains('\n'), "not one line: {msg}");
            // The scene file, or the OBJ path the (mutated) scene names, which lies in `dir`.
            let names_file = msg.contains("scene.toml") || msg.contains(&*dir.to_string_lossy());
            prop_assert!(names_file, "error names no file: {msg}");
            if let Error::Obj {
                line: Some(line), ..
            } = &e
            {
                prop_assert!(*line >= 1, "OBJ error at line 0: {msg}");
            }
        }
    }
    Ok(())
}

#[test]
fn mutated_scene_files_load_or_fail_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let (ok, failed) = (std::cell::Cell::new(0u32), std::cell::Cell::new(0u32));
    runner()
        .run(&mutated(GOOD), |toml| {
            check_load(dir.path(), &toml, QUAD)?;
            if Scene::load(dir.path().join("scene.toml")).is_ok() {
                ok.set(ok.get() + 1);
            } else {
                failed.set(failed.get() + 1);
            }
            Ok(())
        })
        .unwrap();
    println!(
        "mutated scenes: {} loaded, {} rejected",
        ok.get(),
        failed.get()
    );
    // The mutations must exercise both outcomes, or the property says nothing.
    assert!(ok.get() > 0 && failed.get() > 0);
}

#[test]
fn mutated_obj_files_load_or_fail_in_one_line() {
    let dir = tempfile::tempdir().unwrap();
    runner()
        .run(&mutated(QUAD), |obj| check_load(dir.path(), GOOD, &obj))
        .unwrap();
}

#[test]
fn arbitrary_bytes_as_scene_and_obj() {
    let dir = tempfile::tempdir().unwrap();
    runner()
        .run(
            &(
                prop::collection::vec(any::<u8>(), 0..200),
                prop::collection::vec(any::<u8>(), 0..200),
            ),
            |(t, o)| {
                std::fs::write(dir.path().join("quad.obj"), &o).unwrap();
                let p = dir.path().join("scene.toml");
                std::fs::write(&p, &t).unwrap();
                if let Err(e) = Scene::load(&p) {
                    let msg = e.to_string();
                    prop_assert!(!msg.trim_end().contains('\n'), "not one line: {msg}");
                    let dir = dir.path().to_string_lossy();
                    prop_assert!(msg.contains("scene.toml") || msg.contains(&*dir), "{msg}");
                }
                Ok(())
            },
        )
        .unwrap();
}

const SPECS: &[ParamSpec] = &[
    ParamSpec::int(1, 16384, "1024").named("resolution", "r"),
    ParamSpec::float(0.0, 1e4, "80").named("c", "c"),
    ParamSpec::choice(&["additive", "exact"], "additive").named("variant", "v"),
    ParamSpec::flag(true).named("hierarchy", "h"),
];

#[test]
fn param_assignments_parse_or_name_the_key() {
    let value = prop_oneof![
        any::<String>(),
        prop::sample::select(vec![
            "0", "1", "-1", "16384", "16385", "1e3", "1.5", "nan", "inf", "-inf", "1e400", "true",
            "false", "TRUE", "exact", "additive", "", " 3", "0x10", "4x4",
        ])
        .prop_map(String::from),
    ];
    let key = prop_oneof![
        any::<String>(),
        prop::sample::select(vec![
            "resolution",
            "c",
            "variant",
            "hierarchy",
            "",
            "=",
            "k"
        ])
        .prop_map(String::from),
    ];
    let sep = prop::sample::select(vec!["=", "", "==", " = "]);
    runner()
        .run(&(key, sep, value), |(k, s, v)| {
            let kv = format!("{k}{s}{v}");
            let mut p = Params::new(SPECS).unwrap();
            match parse_assignment(&kv).and_then(|(k, v)| p.set(k, v).map(|_| (k, v))) {
                Ok((k, _)) => {
                    let spec = SPECS.iter().find(|s| s.key == k);
                    prop_assert!(spec.is_some(), "unknown key {k:?} accepted");
                    let val = p.get(k).unwrap().to_string();
                    prop_assert!(
                        spec.unwrap().parse(&val).is_ok(),
                        "stored value does not re-parse"
                    );
                    if let Some(x) = p.get("c") {
                        prop_assert!(x.to_string().parse::<f64>().is_ok_and(f64::is_finite));
                    }
                }
                Err(e) => {
                    let msg = e.to_string();
                    prop_assert!(!msg.trim_end().contains('\n'), "not one line: {msg}");
                    prop_assert!(!msg.is_empty());
                }
            }
            Ok(())
        })
        .unwrap();
}
