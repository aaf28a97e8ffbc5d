//! What the GPU bench measures, from the environment (`SOFTSHADOW_BENCH_*`, see
//! `benches/README.md`), and the fixture it loads.
use crate::BenchResult;

/// What to measure, from the environment (see `benches/README.md`).
pub struct Config {
    /// Scene file.
    pub fixture: String,
    /// Its file stem, for ids.
    pub name: String,
    /// Shadow-map resolution r.
    pub res: u32,
    /// Receiver grid (camera width x height).
    pub width: u32,
    pub height: u32,
    /// Triangles of the raster ceiling.
    pub triangles: u32,
    /// Inserts of the atomic ceiling.
    pub inserts: u32,
    /// Seconds each measurement aims at (iterations = budget / one probe iteration, clamped).
    pub budget_s: f64,
    /// Whether to run the CPU rows.
    pub cpu: bool,
}

fn env_u32(key: &str) -> BenchResult<Option<u32>> {
    match std::env::var(key) {
        Ok(v) => Ok(Some(
            v.trim().parse().map_err(|e| format!("{key}={v}: {e}"))?,
        )),
        Err(_) => Ok(None),
    }
}

impl Config {
    pub fn from_env(
        fixture: String,
        scene_camera: (u32, u32),
        res_default: u32,
    ) -> BenchResult<Self> {
        let name = std::path::Path::new(&fixture)
            .file_stem()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_default();
        let res = env_u32("SOFTSHADOW_BENCH_RES")?.unwrap_or(res_default);
        let (width, height) = match std::env::var("SOFTSHADOW_BENCH_RECEIVERS") {
            Ok(v) => {
                let (w, h) = v
                    .trim()
                    .split_once(['x', 'X'])
                    .ok_or_else(|| format!("SOFTSHADOW_BENCH_RECEIVERS={v}: expected WxH"))?;
                (
                    w.parse().map_err(|e| format!("receivers width {w}: {e}"))?,
                    h.parse()
                        .map_err(|e| format!("receivers height {h}: {e}"))?,
                )
            }
            Err(_) => scene_camera,
        };
        if res == 0 || width == 0 || height == 0 {
            return Err("resolution and receiver grid must be non-zero".into());
        }
        let triangles = env_u32("SOFTSHADOW_BENCH_TRIANGLES")?
            .unwrap_or(100_000)
            .max(1);
        let inserts = env_u32("SOFTSHADOW_BENCH_INSERTS")?
            .unwrap_or(res.saturating_mul(res))
            .max(1);
        let budget_s = match std::env::var("SOFTSHADOW_BENCH_BUDGET_S") {
            Ok(v) => v
                .trim()
                .parse::<f64>()
                .map_err(|e| format!("SOFTSHADOW_BENCH_BUDGET_S={v}: {e}"))?,
            Err(_) => 1.0,
        };
        let cpu = std::env::var("SOFTSHADOW_BENCH_CPU").map_or(true, |v| v != "0");
        Ok(Config {
            fixture,
            name,
            res,
            width,
            height,
            triangles,
            inserts,
            budget_s,
            cpu,
        })
    }

    /// Sizes of the smoke run (`cargo test --benches`): seconds on lavapipe.
    pub fn shrink_for_smoke(&mut self) {
        self.res = self.res.min(128);
        self.width = self.width.min(64);
        self.height = self.height.min(48);
        self.triangles = self.triangles.min(2_000);
        self.inserts = self.inserts.min(4_096);
        self.budget_s = 0.0;
    }
}

/// `SOFTSHADOW_BENCH_FIXTURE`, else the bunny: by the absolute path of this checkout, or relative
/// to the working directory when the binary was carried to another machine.
pub fn fixture_path() -> String {
    if let Ok(p) = std::env::var("SOFTSHADOW_BENCH_FIXTURE") {
        return p;
    }
    let abs = concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/bunny/bunny.toml");
    if std::path::Path::new(abs).exists() {
        abs.to_string()
    } else {
        "fixtures/bunny/bunny.toml".to_string()
    }
}
