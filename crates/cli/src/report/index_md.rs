//! The sections of `index.md`: intro, per-fixture Pareto tables and images, the time-budget
//! summary, the matched-time comparison and flicker.
use super::{pareto, FlickerRow, ReportArgs, Row, BASELINES};
use softshadow::ALGOS;
use std::fmt::Write as _;

/// The title and opening paragraph of `index.md`.
pub(super) fn index_intro(
    args: &ReportArgs,
    fixtures: &[String],
    rows: &[Row],
    seconds: f64,
) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "# softshadow report\n");
    let _ =
        writeln!(
        md,
        "{} runs, {} fixtures, {}, {:.0} s. Regenerate: `softshadow report{} --out {}`. Times: \
         build + estimate wall clock of one run (see `crates/cli/src/report.rs`); RMSE against \
         the ray-traced reference ({} spp). Baselines are drawn as crosses.\n",
        rows.len(),
        fixtures.len(),
        if args.quick { "quick (half-size images)" } else { "full" },
        seconds,
        if args.quick { " --quick" } else { "" },
        args.out.display(),
        if args.quick { 256 } else { 1024 }
    );
    md
}

/// The heading and table head of the summary: one column per time budget.
pub(super) fn summary_header(budgets: &[f64]) -> String {
    let mut summary = String::new();
    let _ = writeln!(
        summary,
        "## Summary: most accurate setting within each time budget\n"
    );
    let _ = write!(summary, "| fixture |");
    for &b in budgets {
        if b.is_finite() {
            let _ = write!(summary, " <= {b} ms |");
        } else {
            let _ = write!(summary, " any time |");
        }
    }
    let _ = writeln!(summary, "\n|---|{}", "---|".repeat(budgets.len()));
    summary
}

/// The heading and table head of the matched-time comparison.
pub(super) fn matched_header() -> String {
    let mut matched = String::new();
    let _ = writeln!(
        matched,
        "## Each seed algorithm against PCSS and multi-sample at matched time\n\n\
         Per fixture and backend: the seed algorithm's most accurate setting, and the most \
         accurate PCSS and multi-sample setting that is no slower.\n\n\
         | fixture | backend | algorithm (setting) | ms | RMSE | PCSS RMSE within that time | multi-sample RMSE within that time |\n|---|---|---|---|---|---|---|"
    );
    matched
}

/// A fixture's section of `index.md`: its plot, Pareto table, runs not made and best images.
pub(super) fn fixture_section(md: &mut String, fx: &str, svg: &str, mem: &str, fr: &[&Row]) {
    let _ = writeln!(md, "## {fx}\n\n![{fx}]({svg})\n\n![{fx}: memory]({mem})\n");
    let _ = writeln!(md, "Pareto-optimal settings:\n\n| algo | backend | setting | ms | RMSE | p99 |\n|---|---|---|---|---|---|");
    for i in pareto(fr) {
        let r = fr[i];
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.1} | {:.4} | {:.3} |",
            r.algo, r.backend, r.setting, r.frame_ms, r.rmse, r.p99
        );
    }
    let rejected: Vec<String> = fr
        .iter()
        .filter(|r| r.status != "ok")
        .map(|r| format!("{} {} ({})", r.algo, r.backend, r.status))
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect();
    if !rejected.is_empty() {
        let _ = writeln!(md, "\nNot run: {}", rejected.join("; "));
    }
    let warned: Vec<String> = fr
        .iter()
        .filter(|r| !r.warnings.is_empty())
        .map(|r| format!("{} {} `{}`: {}", r.algo, r.backend, r.setting, r.warnings))
        .collect();
    if !warned.is_empty() {
        let _ = writeln!(md, "\nWarnings (kind=count): {}", warned.join("; "));
    }
    let _ = writeln!(md, "\nMost accurate setting of each algorithm (V, then error: blue too dark, red too bright):\n");
    let _ = writeln!(
        md,
        "| reference | | |\n|---|---|---|\n| ![ref](images/{fx}-reference.png) | | |"
    );
    let mut algos: Vec<(String, String)> = fr
        .iter()
        .filter(|r| r.status == "ok")
        .map(|r| (r.algo.clone(), r.backend.clone()))
        .collect();
    algos.sort();
    algos.dedup();
    for (a, b) in &algos {
        let best = fr
            .iter()
            .filter(|r| &r.algo == a && &r.backend == b && r.rmse.is_finite())
            .min_by(|x, y| x.rmse.total_cmp(&y.rmse));
        if let Some(r) = best {
            let _ = writeln!(
                md,
                "| {a} {b} `{}` RMSE {:.4} | ![v](images/{fx}-{a}-{b}.png) | ![e](images/{fx}-{a}-{b}-error.png) |",
                r.setting, r.rmse
            );
        }
    }
    let _ = writeln!(md);
}

/// A fixture's summary row: its most accurate run within each time budget.
pub(super) fn summary_row(summary: &mut String, fx: &str, fr: &[&Row], budgets: &[f64]) {
    let _ = write!(summary, "| {fx} |");
    for &b in budgets {
        let best = fr
            .iter()
            .filter(|r| r.rmse.is_finite() && r.frame_ms <= b)
            .min_by(|x, y| x.rmse.total_cmp(&y.rmse));
        match best {
            Some(r) => {
                let _ = write!(
                    summary,
                    " {} {} `{}` {:.4} |",
                    r.algo, r.backend, r.setting, r.rmse
                );
            }
            None => {
                let _ = write!(summary, " none |");
            }
        }
    }
    let _ = writeln!(summary);
}

/// A fixture's matched-time rows: each seed algorithm's best run per backend against the best
/// PCSS and multi-sample runs that are no slower.
pub(super) fn matched_rows(matched: &mut String, fx: &str, fr: &[&Row]) {
    for backend in ["cpu", "gpu"] {
        for seed in ALGOS
            .iter()
            .filter(|a| **a != "reference" && !BASELINES.contains(a))
        {
            let best = fr
                .iter()
                .filter(|r| r.algo == *seed && r.backend == backend && r.rmse.is_finite())
                .min_by(|x, y| x.rmse.total_cmp(&y.rmse));
            let Some(s) = best else { continue };
            let within = |algo: &str| {
                fr.iter()
                    .filter(|r| {
                        r.algo == algo
                            && r.backend == backend
                            && r.rmse.is_finite()
                            && r.frame_ms <= s.frame_ms
                    })
                    .map(|r| r.rmse)
                    .fold(f64::INFINITY, f64::min)
            };
            let f = |x: f64| {
                if x.is_finite() {
                    format!("{x:.4}")
                } else {
                    "none that fast".into()
                }
            };
            let _ = writeln!(
                matched,
                "| {fx} | {backend} | {seed} (`{}`) | {:.1} | {:.4} | {} | {} |",
                s.setting,
                s.frame_ms,
                s.rmse,
                f(within("pcss")),
                f(within("multi-sample"))
            );
        }
    }
}

/// The flicker section of `index.md`: one table row per fit-mode measurement.
pub(super) fn flicker_section(md: &mut String, flicker: &[FlickerRow]) {
    let _ = writeln!(
        md,
        "## Flicker per fit mode\n\nMean and 99th percentile of |dV| between consecutive frames \
         of a sideways camera pan, at the same world points (`crates/cli/src/path.rs`).\n\n\
         | fixture | algo | backend | fit | mean abs dV | p99 abs dV | pairs |\n|---|---|---|---|---|---|---|"
    );
    for f in flicker {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {:.5} | {:.4} | {} |",
            f.fixture, f.algo, f.backend, f.fit, f.mean_abs_dv, f.p99_abs_dv, f.pairs
        );
    }
}
