//! The error each setting was measured at: `docs/report/results.csv` (the CPU twins against the
//! ray-traced reference on the repository's fixtures, `softshadow report`), compiled in so an app
//! can show it beside the setting (the windowed example puts it in the title bar).
use crate::{Method, SoftShadowSettings};

/// The report the figures come from.
const RESULTS_CSV: &str = include_str!("../../../docs/report/results.csv");

/// One measured run of the report.
#[derive(Debug, Clone, PartialEq)]
pub struct Measured {
    /// The fixture (`fixtures/NAME/NAME.toml`).
    pub fixture: String,
    /// RMSE of V against the 1024-spp ray-traced reference.
    pub rmse: f64,
    /// CPU frame time in ms (build + estimate) on the machine the report ran on.
    pub frame_ms: f64,
}

/// The report's runs of `settings` (its method at its resolution, every other parameter at its
/// default; CPU backend), one per fixture, in the report's order. Empty for a resolution the
/// report did not sweep.
pub fn measured(settings: &SoftShadowSettings) -> Vec<Measured> {
    let resolution = settings.params.resolution;
    rows(settings.method)
        .filter(|(setting, _)| match resolution {
            None => *setting == "defaults",
            // The defaults row holds the default resolution; swept ones are rows of their own.
            Some(r) => {
                *setting == format!("resolution={r}")
                    || (*setting == "defaults" && default_resolution(settings.method) == Some(r))
            }
        })
        .map(|(_, m)| m)
        .collect()
}

/// The mean RMSE of [`measured`] over `fixtures` (every fixture when empty), with the count of
/// runs; `None` when the report has none.
pub fn mean_rmse(settings: &SoftShadowSettings, fixtures: &[&str]) -> Option<(f64, usize)> {
    let m: Vec<f64> = measured(settings)
        .into_iter()
        .filter(|m| fixtures.is_empty() || fixtures.contains(&m.fixture.as_str()))
        .map(|m| m.rmse)
        .collect();
    (!m.is_empty()).then(|| (m.iter().sum::<f64>() / m.len() as f64, m.len()))
}

fn default_resolution(method: Method) -> Option<u32> {
    let p = SoftShadowSettings::new(method).params_table().ok()?;
    p.get(softshadow::core::light_view::RESOLUTION.key)?
        .to_string()
        .parse()
        .ok()
}

/// `(setting, run)` of every CPU row of `method` with status `ok`.
fn rows(method: Method) -> impl Iterator<Item = (&'static str, Measured)> {
    let mut lines = RESULTS_CSV.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name);
    let cols = (
        col("fixture"),
        col("algo"),
        col("backend"),
        col("setting"),
        col("status"),
        col("rmse"),
        col("frame_ms"),
    );
    lines.filter_map(move |line| {
        let f: Vec<&'static str> = line.split(',').collect();
        let get = |c: Option<usize>| c.and_then(|c| f.get(c).copied());
        if get(cols.1)? != method.name() || get(cols.2)? != "cpu" || get(cols.4)? != "ok" {
            return None;
        }
        Some((
            get(cols.3)?,
            Measured {
                fixture: get(cols.0)?.to_string(),
                rmse: get(cols.5)?.parse().ok()?,
                frame_ms: get(cols.6)?.parse().ok()?,
            },
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_method_has_its_defaults_measured_on_every_fixture() {
        for &m in Method::ALL {
            let runs = measured(&SoftShadowSettings::new(m));
            assert!(runs.len() >= 25, "{}: {} runs", m.name(), runs.len());
            assert!(runs.iter().all(|r| r.rmse.is_finite() && r.rmse >= 0.0));
        }
        // The figure docs/measurements.md gives for PCSS on the bunny.
        let pcss = measured(&SoftShadowSettings::new(Method::Pcss));
        let bunny = pcss.iter().find(|r| r.fixture == "bunny").unwrap();
        assert!((bunny.rmse - 0.0403).abs() < 5e-5, "{}", bunny.rmse);
    }

    #[test]
    fn resolutions_pick_their_rows() {
        let mut s = SoftShadowSettings::new(Method::Hard);
        s.params.resolution = Some(256);
        let low = mean_rmse(&s, &[]).unwrap();
        s.params.resolution = Some(1024);
        let default = mean_rmse(&s, &[]).unwrap();
        assert_eq!(
            default,
            mean_rmse(&SoftShadowSettings::new(Method::Hard), &[]).unwrap()
        );
        assert!(low.1 >= 25 && default.1 >= 25);
        assert_ne!(low.0, default.0);
        s.params.resolution = Some(777);
        assert!(measured(&s).is_empty());
    }
}
