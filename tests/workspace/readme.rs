//! README.md stays true and short: every command in its fenced `sh`, `bash` and `console` blocks
//! is either run verbatim by `.ci/run` (CI's entry point, which counts itself) or mapped in
//! [`MAPPED`] to the test that runs it; the README has fewer than 150 lines; and the crate map's
//! one-line examples compile (they are copied into [`crate_map_examples`]).
use std::path::Path;

/// The repository root (the root package's manifest directory).
const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// The command CI runs: `.ci/run` is CI's entry point, so README's `bash .ci/run` is run by CI.
const CI_ENTRY: &str = "bash .ci/run";

/// A README command that `.ci/run` does not run verbatim, and the test that runs it.
struct Mapped {
    /// The command as README writes it (whitespace normalised).
    command: &'static str,
    /// The test file, relative to the repository root.
    file: &'static str,
    /// The `#[test]` function in that file that runs the command.
    test: &'static str,
    /// Strings the test function's body must contain: what makes it the same command.
    evidence: &'static [&'static str],
}

/// README commands run by a test rather than verbatim by `.ci/run` (none today: `.ci/run` runs
/// the render command word for word). `cargo test --workspace` (in `.ci/run`) runs each test.
const MAPPED: &[Mapped] = &[];

fn read(rel: &str) -> String {
    std::fs::read_to_string(Path::new(ROOT).join(rel))
        .unwrap_or_else(|e| panic!("cannot read {rel}: {e}"))
}

fn normalise(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// The commands of a markdown text's fenced `sh`, `bash` and `console` blocks, each with the
/// 1-based line it starts on: comment and empty lines dropped, `\` continuations joined, a
/// console block's `$ ` prompts stripped (its other lines are output).
fn commands(markdown: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut block: Option<String> = None; // the open fence's language
    let mut pending: Option<(usize, String)> = None; // a command continued with `\`
    for (k, line) in markdown.lines().enumerate() {
        let trimmed = line.trim();
        if let Some(rest) = trimmed.strip_prefix("```") {
            if block.is_some() {
                if let Some(p) = pending.take() {
                    out.push(p);
                }
                block = None;
            } else {
                let lang = rest.split([' ', ',', '{']).next().unwrap_or("");
                block = Some(lang.to_ascii_lowercase());
            }
            continue;
        }
        let Some(lang) = block.as_deref() else {
            continue;
        };
        if !matches!(lang, "sh" | "bash" | "console" | "shell") {
            continue;
        }
        let text = if let Some((start, mut acc)) = pending.take() {
            acc.push(' ');
            acc.push_str(trimmed);
            (start, acc)
        } else {
            let text = if lang == "console" {
                match trimmed.strip_prefix('$') {
                    Some(cmd) => cmd.trim(),
                    None => continue,
                }
            } else {
                trimmed
            };
            if text.is_empty() || text.starts_with('#') {
                continue;
            }
            (k + 1, text.to_string())
        };
        match text.1.strip_suffix('\\') {
            Some(head) => pending = Some((text.0, head.trim_end().to_string())),
            None => out.push((text.0, normalise(&text.1))),
        }
    }
    if let Some((start, acc)) = pending {
        out.push((start, normalise(&acc)));
    }
    out
}

/// The body of `fn name(` in a Rust source: from its line to the first line that is just `}`.
fn fn_body<'a>(source: &'a str, name: &str) -> Option<&'a str> {
    let start = source.find(&format!("fn {name}("))?;
    let rest = &source[start..];
    let end = rest.find("\n}\n").map_or(rest.len(), |e| e + 3);
    Some(&rest[..end])
}

/// Why a mapping does not hold, if it does not.
fn mapping_broken(m: &Mapped) -> Option<String> {
    let path = Path::new(ROOT).join(m.file);
    let Ok(source) = std::fs::read_to_string(&path) else {
        return Some(format!("{} does not exist", m.file));
    };
    let Some(body) = fn_body(&source, m.test) else {
        return Some(format!("{} has no `fn {}(`", m.file, m.test));
    };
    let head = &source[..source.find(&format!("fn {}(", m.test)).unwrap()];
    let attrs = head.rsplit("\n\n").next().unwrap_or("");
    if !attrs.contains("#[test]") {
        return Some(format!("`{}` in {} is not a #[test]", m.test, m.file));
    }
    let missing: Vec<_> = m.evidence.iter().filter(|e| !body.contains(*e)).collect();
    if !missing.is_empty() {
        return Some(format!(
            "`{}` in {} no longer contains {missing:?}",
            m.test, m.file
        ));
    }
    None
}

/// Every README command no one runs, as one message each (empty when all are run).
fn unproven(readme: &str, ci_script: &str, mapped: &[Mapped]) -> Vec<String> {
    let ci_lines: Vec<String> = ci_script
        .lines()
        .map(normalise)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .collect();
    let mut problems = Vec::new();
    let found = commands(readme);
    for (line, cmd) in &found {
        if cmd == CI_ENTRY || ci_lines.iter().any(|l| l == cmd) {
            continue;
        }
        match mapped.iter().find(|m| normalise(m.command) == *cmd) {
            Some(m) => {
                if let Some(why) = mapping_broken(m) {
                    problems.push(format!("README.md:{line}: `{cmd}`: {why}"));
                }
            }
            None => problems.push(format!(
                "README.md:{line}: `{cmd}` is run neither verbatim by .ci/run nor by a test \
                 mapped in tests/workspace/readme.rs (MAPPED): add it to one of them or drop it"
            )),
        }
    }
    for m in mapped {
        if !found.iter().any(|(_, c)| *c == normalise(m.command)) {
            problems.push(format!(
                "tests/workspace/readme.rs maps `{}`, which README.md no longer has",
                m.command
            ));
        }
    }
    problems
}

#[test]
fn every_readme_command_is_run_by_ci_or_a_test() {
    let ci_script = read(".ci/run");
    assert!(
        ci_script.contains("CI entry point"),
        ".ci/run no longer says it is CI's entry point"
    );
    let readme = read("README.md");
    let found = commands(&readme);
    assert!(
        found.iter().any(|(_, c)| c == CI_ENTRY),
        "README.md must give the test command `{CI_ENTRY}`"
    );
    let problems = unproven(&readme, &ci_script, MAPPED);
    assert!(problems.is_empty(), "\n{}", problems.join("\n"));
}

#[test]
fn readme_is_shorter_than_150_lines() {
    let n = read("README.md").lines().count();
    assert!(
        n < 150,
        "README.md has {n} lines: move detail into docs/ and link it"
    );
}

#[test]
fn an_unmapped_command_fails_by_name() {
    let readme = "# t\n\n```sh\n# a comment\nbash .ci/run\n```\n\n```bash\ncargo run --release \\\n  --example nowhere\n```\n\n```console\n$ softshadow frobnicate\noutput line\n```\n";
    assert_eq!(
        commands(readme),
        vec![
            (5, "bash .ci/run".to_string()),
            (9, "cargo run --release --example nowhere".to_string()),
            (14, "softshadow frobnicate".to_string()),
        ]
    );
    let problems = unproven(readme, "cargo test --workspace\n", &[]);
    assert_eq!(problems.len(), 2, "{problems:?}");
    assert!(problems[0].contains("README.md:9: `cargo run --release --example nowhere`"));
    assert!(problems[1].contains("`softshadow frobnicate`"));
    // Run verbatim by the CI script: proven.
    assert!(unproven(
        readme,
        "softshadow frobnicate\ncargo run --release --example nowhere\n",
        &[]
    )
    .is_empty());
    // A mapping to a test that does not exist is a failure too.
    let bad = [Mapped {
        command: "softshadow frobnicate",
        file: "crates/cli/tests/cli/commands.rs",
        test: "no_such_test",
        evidence: &[],
    }];
    let problems = unproven(readme, "cargo run --release --example nowhere\n", &bad);
    assert_eq!(problems.len(), 1, "{problems:?}");
    assert!(problems[0].contains("no_such_test"), "{problems:?}");
}

/// The crate map's one-line examples (README.md, "Crate map", third column), copied here so
/// they are compiled; [`crate_map_examples_are_compiled_here`] checks the copies match.
#[allow(dead_code, unused_variables)]
fn crate_map_examples() -> shadow_map_core::Result<()> {
    use shadow_map_core::{run, Backend, Receivers, Scene, SceneBvh};
    let scene = Scene::load("fixtures/bunny/bunny.toml")?;
    let rec = Receivers::from_camera(&scene, &SceneBvh::new(&scene));
    let mut est = softshadow::estimator("pcss", Backend::Cpu)?;
    est.set_param("resolution", "512")?;
    let (v_ref, _) = run(&mut reference::ReferenceEstimator::new()?, &scene, &rec)?;
    let (v, report) = run(&mut baselines::PcssShadow::new()?, &scene, &rec)?;
    run(&mut backprojection::CpuBackprojection::new()?, &scene, &rec)?;
    run(&mut accumulation::CpuAccumulation::new()?, &scene, &rec)?;
    run(&mut packet_hsm::CpuPacketHsm::new()?, &scene, &rec)?;
    run(&mut deep_shadow::CpuDeepShadow::new()?, &scene, &rec)?;
    Ok(())
}

#[test]
fn crate_map_examples_are_compiled_here() {
    let readme = read("README.md");
    let source = read("tests/workspace/readme.rs");
    let compiled: String = fn_body(&source, "crate_map_examples")
        .unwrap()
        .split_whitespace()
        .collect();
    let map = readme
        .split("## Crate map")
        .nth(1)
        .expect("README.md has a \"Crate map\" section");
    let map = map.split("\n## ").next().unwrap();
    let mut checked = 0;
    for row in map.lines().filter(|l| l.starts_with("| ")) {
        let Some(cell) = row.trim_end_matches('|').rsplit(" | ").next() else {
            continue;
        };
        // Code spans of Rust (a `let` or a call ending in `?`), not file names or prose.
        for span in cell.split('`').skip(1).step_by(2) {
            if !(span.starts_with("let ") || span.starts_with("run(")) {
                continue;
            }
            let squeezed: String = span.split_whitespace().collect();
            let squeezed = squeezed.trim_end_matches(';');
            assert!(
                compiled.contains(squeezed),
                "README crate map example `{span}` is not in tests/workspace/readme.rs crate_map_examples"
            );
            checked += 1;
        }
    }
    assert!(checked >= 8, "only {checked} crate map examples found");
}
