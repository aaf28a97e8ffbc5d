//! Writing the report's files: `results.csv`, `results.json`, `flicker.csv` and `index.md`
//! (with its plots).
use super::index_md::{
    fixture_section, flicker_section, index_intro, matched_header, matched_rows, summary_header,
    summary_row,
};
use super::plot::{plot, PlotX};
use super::{FlickerRow, ReportArgs, Row};
use serde_json::json;
use std::fmt::Write as _;
use std::path::PathBuf;

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn num(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.6}")
    } else {
        String::new()
    }
}

pub(super) fn write_outputs(
    args: &ReportArgs,
    fixtures: &[String],
    rows: &[Row],
    flicker: &[FlickerRow],
    seconds: f64,
) -> Result<(), String> {
    // CSV and JSON.
    write_file(args.out.join("results.csv"), results_csv(rows))?;
    write_file(
        args.out.join("results.json"),
        results_json(args, rows, flicker, seconds)?,
    )?;
    write_file(args.out.join("flicker.csv"), flicker_csv(flicker))?;

    // index.md
    let mut md = index_intro(args, fixtures, rows, seconds);
    let budgets = [10.0, 30.0, 100.0, 300.0, 1000.0, f64::INFINITY];
    let mut summary = summary_header(&budgets);
    let mut matched = matched_header();
    for fx in fixtures {
        let fr: Vec<&Row> = rows.iter().filter(|r| &r.fixture == fx).collect();
        let svg = format!("plot-{fx}.svg");
        plot(&args.out.join(&svg), fx, &fr, PlotX::Time)?;
        let mem = format!("memory-{fx}.svg");
        plot(&args.out.join(&mem), fx, &fr, PlotX::Memory)?;
        fixture_section(&mut md, fx, &svg, &mem, &fr);
        summary_row(&mut summary, fx, &fr, &budgets);
        matched_rows(&mut matched, fx, &fr);
    }
    md.push_str(&summary);
    md.push('\n');
    md.push_str(&matched);
    md.push('\n');
    flicker_section(&mut md, flicker);
    write_file(args.out.join("index.md"), md)?;
    Ok(())
}

/// Writes `s` to `p`, naming the path in the error.
fn write_file(p: PathBuf, s: String) -> Result<(), String> {
    std::fs::write(&p, s).map_err(|e| format!("{}: {e}", p.display()))
}

/// `results.csv`: one line per run.
fn results_csv(rows: &[Row]) -> String {
    let mut csv = String::from("fixture,algo,backend,setting,params,status,build_ms,estimate_ms,frame_ms,rmse,mae,p99,frac_gt_0_1,nonfinite,light_space_bytes,texel_density_median,texel_density_p95,warnings\n");
    for r in rows {
        let params: Vec<String> = r.params.iter().map(|(k, v)| format!("{k}={v}")).collect();
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            csv_field(&r.fixture),
            csv_field(&r.algo),
            r.backend,
            csv_field(&r.setting),
            csv_field(&params.join(";")),
            csv_field(&r.status),
            num(r.build_ms),
            num(r.estimate_ms),
            num(r.frame_ms),
            num(r.rmse),
            num(r.mae),
            num(r.p99),
            num(r.frac_gt_0_1),
            r.nonfinite,
            r.light_space_bytes,
            num(r.texel_density.0),
            num(r.texel_density.1),
            csv_field(&r.warnings)
        );
    }
    csv
}

/// A JSON number, or `null` when not finite.
fn json_num(x: f64) -> serde_json::Value {
    if x.is_finite() {
        json!(x)
    } else {
        serde_json::Value::Null
    }
}

/// `results.json`: the runs and flicker rows, pretty-printed.
fn results_json(
    args: &ReportArgs,
    rows: &[Row],
    flicker: &[FlickerRow],
    seconds: f64,
) -> Result<String, String> {
    let jnum = json_num;
    let jrows: Vec<serde_json::Value> = rows
        .iter()
        .map(|r| {
            json!({
                "fixture": r.fixture, "algo": r.algo, "backend": r.backend,
                "setting": r.setting, "params": r.params, "status": r.status,
                "build_ms": jnum(r.build_ms), "estimate_ms": jnum(r.estimate_ms),
                "frame_ms": jnum(r.frame_ms), "rmse": jnum(r.rmse), "mae": jnum(r.mae),
                "p99": jnum(r.p99), "frac_gt_0_1": jnum(r.frac_gt_0_1),
                "nonfinite": r.nonfinite, "light_space_bytes": r.light_space_bytes,
                "texel_density_median": jnum(r.texel_density.0),
                "texel_density_p95": jnum(r.texel_density.1),
                "warnings": r.warnings,
            })
        })
        .collect();
    let jflicker: Vec<serde_json::Value> = flicker
        .iter()
        .map(|f| {
            json!({
                "fixture": f.fixture, "algo": f.algo, "backend": f.backend, "fit": f.fit,
                "mean_abs_dv": jnum(f.mean_abs_dv), "p99_abs_dv": jnum(f.p99_abs_dv),
                "pairs": f.pairs,
            })
        })
        .collect();
    serde_json::to_string_pretty(&json!({
        "quick": args.quick,
        "seconds": seconds,
        "runs": jrows,
        "flicker": jflicker,
    }))
    .map_err(|e| e.to_string())
}

/// `flicker.csv`: one line per flicker measurement.
fn flicker_csv(flicker: &[FlickerRow]) -> String {
    let mut fcsv = String::from("fixture,algo,backend,fit,mean_abs_dv,p99_abs_dv,pairs\n");
    for f in flicker {
        let _ = writeln!(
            fcsv,
            "{},{},{},{},{},{},{}",
            f.fixture,
            f.algo,
            f.backend,
            f.fit,
            num(f.mean_abs_dv),
            num(f.p99_abs_dv),
            f.pairs
        );
    }
    fcsv
}
