//! The rows the GPU bench measures, the ceilings that bound them, and how they are printed
//! (markdown tables) and written (JSON).
use crate::{
    ceilings::K,
    config::Config,
    stages::{MSSM_LEVELS, PEEL_LAYERS},
    timing::Timing,
};
use std::fmt::Write as _;

/// The ceilings each stage is measured against (per second).
#[derive(Debug, Clone, Copy, Default)]
pub struct Ceilings {
    pub gpu_taps: f64,
    pub gpu_triangles: f64,
    pub gpu_inserts: f64,
    pub cpu_taps: f64,
}

/// Which ceiling bounds a row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Bound {
    GpuTaps,
    GpuTriangles,
    /// For A-buffer / deep-shadow stages (none in the core yet; estimate stages may use it).
    #[allow(dead_code)]
    GpuInserts,
    CpuTaps,
}

impl Bound {
    fn label(self) -> &'static str {
        match self {
            Bound::GpuTaps => "GPU taps/s",
            Bound::GpuTriangles => "GPU triangles/s",
            Bound::GpuInserts => "GPU inserts/s",
            Bound::CpuTaps => "CPU taps/s",
        }
    }
    fn rate(self, c: &Ceilings) -> f64 {
        match self {
            Bound::GpuTaps => c.gpu_taps,
            Bound::GpuTriangles => c.gpu_triangles,
            Bound::GpuInserts => c.gpu_inserts,
            Bound::CpuTaps => c.cpu_taps,
        }
    }
}

/// One measured row.
#[derive(Debug, Clone)]
pub struct Row {
    /// `<algo>/<backend>/<stage>/<size>`.
    pub id: String,
    pub timing: Timing,
    /// Units of work per iteration (the count `unit` names).
    pub work: f64,
    pub unit: &'static str,
    /// The ceiling that bounds it (None for the ceilings themselves and CPU raster stages).
    pub bound: Option<Bound>,
}

impl Row {
    pub fn new(
        id: String,
        timing: Timing,
        work: f64,
        unit: &'static str,
        bound: Option<Bound>,
    ) -> Self {
        Row {
            id,
            timing,
            work,
            unit,
            bound,
        }
    }
    pub fn rate(&self) -> f64 {
        self.work / (self.timing.ms() / 1e3)
    }
    fn fraction(&self, c: &Ceilings) -> Option<f64> {
        self.bound.map(|b| self.rate() / b.rate(c))
    }
}

/// Adapter and device facts printed with the table.
pub struct Facts {
    pub describe: String,
    pub driver: String,
    pub pass_stamps: bool,
    pub encoder_stamps: bool,
    pub max_binding: u64,
}

fn fmt_rate(v: f64) -> String {
    if !v.is_finite() {
        return "-".into();
    }
    let (d, s) = if v >= 1e12 {
        (1e12, "T")
    } else if v >= 1e9 {
        (1e9, "G")
    } else if v >= 1e6 {
        (1e6, "M")
    } else if v >= 1e3 {
        (1e3, "k")
    } else {
        (1.0, "")
    };
    format!("{:.3} {s}", v / d)
}

fn fmt_ms(v: f64) -> String {
    if v >= 100.0 {
        format!("{v:.1}")
    } else if v >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.4}")
    }
}

pub fn table(rows: &[Row], c: &Ceilings) -> String {
    let mut s = String::new();
    s.push_str("| id | method | iters | ms/iter | wall ms | ts ms | host ms | work/iter | rate/s | bound | % of ceiling |\n");
    s.push_str("|---|---|---|---|---|---|---|---|---|---|---|\n");
    for r in rows {
        let t = &r.timing;
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} {} | {} | {} | {} |",
            r.id,
            t.method.label(),
            t.iters,
            fmt_ms(t.ms()),
            fmt_ms(t.wall_ms),
            t.gpu_ms.map_or("-".into(), fmt_ms),
            fmt_ms(t.host_ms),
            fmt_rate(r.work),
            r.unit,
            fmt_rate(r.rate()),
            r.bound.map_or("-", Bound::label),
            r.fraction(c)
                .map_or("-".into(), |f| format!("{:.1}%", 100.0 * f)),
        );
    }
    s
}

/// GPU beside CPU per stage: times, speed-up, and each as a fraction of its own machine's limit.
pub fn comparison(rows: &[Row], c: &Ceilings) -> String {
    let mut s = String::new();
    s.push_str("| stage | CPU ms | GPU ms | GPU speed-up | CPU % of CPU ceiling | GPU % of GPU ceiling |\n");
    s.push_str("|---|---|---|---|---|---|\n");
    for gpu in rows
        .iter()
        .filter(|r| r.id.contains("/gpu/") && r.bound.is_some())
    {
        let key = gpu.id.replacen("/gpu/", "/cpu/", 1);
        let Some(cpu) = rows.iter().find(|r| r.id == key) else {
            continue;
        };
        let pct = |f: Option<f64>| f.map_or("-".into(), |f| format!("{:.1}%", 100.0 * f));
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.1}x | {} | {} |",
            gpu.id.replacen("/gpu", "", 1),
            fmt_ms(cpu.timing.ms()),
            fmt_ms(gpu.timing.ms()),
            cpu.timing.ms() / gpu.timing.ms(),
            pct(cpu.fraction(c)),
            pct(gpu.fraction(c)),
        );
    }
    s
}

fn json_str(s: &str) -> String {
    let mut o = String::from("\"");
    for ch in s.chars() {
        match ch {
            '"' => o.push_str("\\\""),
            '\\' => o.push_str("\\\\"),
            c if (c as u32) < 0x20 => {
                let _ = write!(o, "\\u{:04x}", c as u32);
            }
            c => o.push(c),
        }
    }
    o.push('"');
    o
}

fn json_num(v: f64) -> String {
    if v.is_finite() {
        format!("{v}")
    } else {
        "null".into()
    }
}

/// `{"k": v, ...}` from fields whose values are already JSON.
fn json_obj(fields: &[(&str, String)]) -> String {
    let body: Vec<String> = fields
        .iter()
        .map(|(k, v)| format!("\"{k}\": {v}"))
        .collect();
    format!("{{{}}}", body.join(", "))
}

fn json_config(cfg: &Config) -> String {
    json_obj(&[
        ("fixture", json_str(&cfg.fixture)),
        ("resolution", cfg.res.to_string()),
        ("receivers", format!("[{}, {}]", cfg.width, cfg.height)),
        ("ceiling_triangles", cfg.triangles.to_string()),
        ("ceiling_inserts", cfg.inserts.to_string()),
        ("kernel", K.to_string()),
        ("mssm_levels", MSSM_LEVELS.to_string()),
        ("peel_layers", PEEL_LAYERS.to_string()),
        ("budget_s", json_num(cfg.budget_s)),
    ])
}

fn json_ceilings(c: &Ceilings) -> String {
    json_obj(&[
        ("gpu_taps", json_num(c.gpu_taps)),
        ("gpu_triangles", json_num(c.gpu_triangles)),
        ("gpu_inserts", json_num(c.gpu_inserts)),
        ("cpu_taps", json_num(c.cpu_taps)),
    ])
}

fn json_row(r: &Row, c: &Ceilings) -> String {
    let t = &r.timing;
    json_obj(&[
        ("id", json_str(&r.id)),
        ("method", json_str(t.method.label())),
        ("iters", t.iters.to_string()),
        ("ms_per_iter", json_num(t.ms())),
        ("wall_ms_per_iter", json_num(t.wall_ms)),
        (
            "timestamp_ms_per_iter",
            t.gpu_ms.map_or("null".into(), json_num),
        ),
        ("host_ms_per_iter", json_num(t.host_ms)),
        ("work_per_iter", json_num(r.work)),
        ("unit", json_str(r.unit)),
        ("rate_per_s", json_num(r.rate())),
        (
            "bound",
            r.bound.map_or("null".into(), |b| json_str(b.label())),
        ),
        (
            "fraction_of_ceiling",
            r.fraction(c).map_or("null".into(), json_num),
        ),
        ("note", t.note.as_deref().map_or("null".into(), json_str)),
    ])
}

pub fn json(
    facts: &Facts,
    cfg: &Config,
    c: &Ceilings,
    rows: &[Row],
    checks: &[(String, bool)],
) -> String {
    let mut s = String::from("{\n");
    let _ = writeln!(s, "  \"adapter\": {},", json_str(&facts.describe));
    let _ = writeln!(s, "  \"driver\": {},", json_str(&facts.driver));
    let _ = writeln!(
        s,
        "  \"timestamp_query\": {}, \"timestamp_query_inside_encoders\": {},",
        facts.pass_stamps, facts.encoder_stamps
    );
    let _ = writeln!(s, "  \"config\": {},", json_config(cfg));
    let _ = writeln!(s, "  \"ceilings_per_s\": {},", json_ceilings(c));
    let checks: Vec<String> = checks
        .iter()
        .map(|(what, ok)| json_obj(&[("check", json_str(what)), ("ok", ok.to_string())]))
        .collect();
    let mut rows: String = rows
        .iter()
        .map(|r| format!("    {}", json_row(r, c)))
        .collect::<Vec<_>>()
        .join(",\n");
    if !rows.is_empty() {
        rows.push('\n');
    }
    let _ = write!(
        s,
        "  \"checks\": [{}],\n  \"rows\": [\n{rows}  ]\n}}\n",
        checks.join(", ")
    );
    s
}

pub fn out_path() -> std::path::PathBuf {
    match std::env::var_os("OUT") {
        Some(dir) => std::path::PathBuf::from(dir).join("gpu-bench.json"),
        None => std::path::PathBuf::from("target").join("gpu-bench.json"),
    }
}
