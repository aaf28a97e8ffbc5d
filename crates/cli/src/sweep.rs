//! The parameter settings `softshadow report` runs for each method besides its defaults: the
//! axes its paper varies (layers, kernel size, packet size, sub-lights, filter) and the
//! shadow-map resolution. A report concern, so it lives here and not in the estimator trait.
use shadow_map_core::{light_view::RESOLUTION, Params};

/// One setting: `(key, value)` overrides of the defaults.
pub type Setting = Vec<(&'static str, String)>;

/// The settings of method `name` (whose parameter table is `params`); `quick` asks for the small
/// set CI runs.
pub fn settings(name: &str, params: &Params, quick: bool) -> Vec<Setting> {
    let kv = |p: &[(&'static str, &str)]| -> Setting {
        p.iter().map(|(k, v)| (*k, v.to_string())).collect()
    };
    let one = |k: &'static str, v: &str| kv(&[(k, v)]);
    match (name, quick) {
        ("backprojection", true) => vec![one("resolution", "256"), one("layers", "1")],
        ("backprojection", false) => {
            let mut s = resolutions(params, false);
            s.extend([
                one("layers", "1"),
                one("layers", "2"),
                one("gap_filling", "false"),
                one("occlusion", "additive"),
                one("self_shadow", "bias"),
                one("max_nspp", "25"),
                one("max_nspp", "49"),
            ]);
            s
        }
        ("accumulation", true) => vec![one("resolution", "256"), one("variant", "exact")],
        ("accumulation", false) => {
            let mut s: Vec<Setting> = ["3", "5", "15"].iter().map(|k| one("k", k)).collect();
            s.extend([
                one("variant", "exact"),
                one("kernel", "fixed"),
                one("resolution", "256"),
                one("resolution", "2048"),
            ]);
            s
        }
        // Sub-lights (Yang section 5), packet sizes (Algorithm 2) and resolution; hierarchy and
        // coherence change only the time, so the report runs their defaults.
        ("packet-hsm", true) => vec![one("resolution", "256"), one("sublights", "2")],
        ("packet-hsm", false) => vec![
            one("sublights", "2"),
            one("sublights", "4"),
            one("packet", "1x1"),
            one("packet", "4x4"),
            one("resolution", "256"),
            one("resolution", "512"),
        ],
        ("deep-shadow", true) => vec![one("resolution", "256"), one("sublights", "2")],
        ("deep-shadow", false) => vec![
            one("filter", "none"),
            one("max_taps", "16"),
            kv(&[("filter", "pcf"), ("kernel", "5")]),
            kv(&[("filter", "edsm"), ("kernel", "5")]),
            one("sublights", "2"),
            one("sublights", "3"),
            kv(&[("sublights", "2"), ("filter", "pcf"), ("kernel", "3")]),
            one("resolution", "256"),
            one("resolution", "512"),
        ],
        _ => resolutions(params, quick),
    }
}

/// Resolution 256 (quick), or 256, 512 and 2048 (full), when the table has `resolution`.
fn resolutions(params: &Params, quick: bool) -> Vec<Setting> {
    if params.specs().iter().all(|s| s.key != RESOLUTION.key) {
        return Vec::new();
    }
    let rs: &[u32] = if quick { &[256] } else { &[256, 512, 2048] };
    rs.iter()
        .map(|r| vec![("resolution", r.to_string())])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every key a setting names is in the method's table and its value parses, so a renamed
    /// parameter fails here and not halfway through a report.
    #[test]
    fn every_setting_is_a_valid_assignment() {
        for name in softshadow::ALGOS {
            let e = softshadow::estimator(name, shadow_map_core::Backend::Cpu).expect("estimator");
            for quick in [true, false] {
                for s in settings(name, e.params(), quick) {
                    let mut p = e.params().clone();
                    for (k, v) in &s {
                        if let Err(err) = p.set(k, v) {
                            panic!("{name}: {k}={v}: {err}");
                        }
                    }
                }
            }
        }
    }
}
