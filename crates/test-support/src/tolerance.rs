//! The twin tolerance: how close a GPU twin's V must be to its CPU twin's.
//!
//! V is a fraction of the light's area in [0, 1]. A [`Tolerance`] bounds `|dV|` per receiver
//! ([`Tolerance::abs`]) on at least a fraction of the active receivers
//! ([`Tolerance::min_within`]), and optionally every receiver ([`Tolerance::max`]). On random
//! scenes each receiver beyond `abs` must also be explained as a tie ([`Tolerance::judge`]): a
//! depth comparison that a microscopic change of the depth threshold flips, or a sample that a
//! few ulps of receiver position move to the neighbouring texel; the method says which
//! ([`Verdict`]).

use shadow_map_core::{LightView, Receivers};
use std::fmt;

/// Per-receiver tolerance on V, the fraction of receivers that must meet it, and an optional
/// bound on all of them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerance {
    /// Per-receiver bound on `|V_cpu - V_gpu|`.
    pub abs: f32,
    /// Fraction of the active receivers that must lie within [`Tolerance::abs`]: over a whole
    /// random run, and per case at most `ceil((1 - min_within) n)` of its n active receivers
    /// beyond it ([`Tolerance::allowed_beyond`]).
    pub min_within: f64,
    /// A bound every active receiver must meet, if any.
    pub max: Option<f32>,
}

impl Tolerance {
    /// The twins' rule: `|dV| <= 1e-4` on 99.9% of the receivers.
    pub const TWIN: Tolerance = Tolerance {
        abs: 1e-4,
        min_within: 0.999,
        max: None,
    };

    /// This tolerance with every receiver also bound by `max`.
    pub const fn with_max(self, max: f32) -> Tolerance {
        Tolerance {
            max: Some(max),
            ..self
        }
    }

    /// How many of `n` active receivers one case may have beyond [`Tolerance::abs`].
    pub fn allowed_beyond(&self, n: usize) -> usize {
        ((1.0 - self.min_within) * n as f64).ceil() as usize
    }

    /// Compares the twins' outputs receiver by receiver. An error (naming `what`) when an
    /// inactive receiver is not NaN on both, an active GPU V is outside [0, 1], or an active
    /// receiver is beyond [`Tolerance::max`]; else the counts.
    pub fn compare(
        &self,
        what: &str,
        active: &[bool],
        cpu: &[f32],
        gpu: &[f32],
    ) -> Result<Comparison, String> {
        if cpu.len() != active.len() || gpu.len() != active.len() {
            return Err(format!(
                "{what}: {} receivers, cpu gave {} values, gpu {}",
                active.len(),
                cpu.len(),
                gpu.len()
            ));
        }
        let mut cmp = Comparison::default();
        for k in 0..active.len() {
            let (c, g) = (cpu[k], gpu[k]);
            if !active[k] {
                if !(c.is_nan() && g.is_nan()) {
                    return Err(format!(
                        "{what}: inactive receiver {k}: cpu {c}, gpu {g} (want NaN)"
                    ));
                }
                continue;
            }
            if !(0.0..=1.0).contains(&g) {
                return Err(format!(
                    "{what}: receiver {k}: gpu V = {g} outside [0, 1] (cpu {c})"
                ));
            }
            let d = (c - g).abs();
            if let Some(max) = self.max {
                if d.is_nan() || d > max {
                    return Err(format!(
                        "{what}: receiver {k}: cpu {c} gpu {g}, |dV| beyond {max}"
                    ));
                }
            }
            cmp.receivers += 1;
            cmp.classes[if c <= 0.0 {
                0
            } else if c < 1.0 {
                1
            } else {
                2
            }] += 1;
            cmp.max_dv = cmp.max_dv.max(d);
            if d > self.abs {
                cmp.beyond.push(k);
            } else if d <= self.abs {
                cmp.within += 1;
            }
        }
        Ok(cmp)
    }

    /// [`Tolerance::compare`], then at least one active receiver compared and the fraction within
    /// [`Tolerance::abs`] at least [`Tolerance::min_within`] on this output alone; panics naming
    /// `what` otherwise. Returns
    /// that fraction and the largest `|dV|`.
    pub fn assert_twins(
        &self,
        what: &str,
        active: &[bool],
        cpu: &[f32],
        gpu: &[f32],
    ) -> (f64, f32) {
        let cmp = match self.compare(what, active, cpu, gpu) {
            Ok(c) => c,
            Err(e) => panic!("{e}"),
        };
        assert!(cmp.receivers > 0, "{what}: no active receiver compared");
        let f = cmp.fraction_within();
        assert!(f >= self.min_within, "{what}: only {f} within {}", self.abs);
        (f, cmp.max_dv)
    }

    /// Whether an alternative CPU value `alt` of a receiver (the CPU twin rerun with its depth
    /// test or samples nudged) shows a tie between the CPU's `cpu` and the GPU's `gpu`: the
    /// nudge moves the CPU's V beyond [`Tolerance::abs`], or reproduces the GPU's within it.
    pub fn nudge_explains(&self, alt: f32, cpu: f32, gpu: f32) -> bool {
        (alt - cpu).abs() > self.abs || (alt - gpu).abs() <= self.abs
    }

    /// The rule of a random case: every receiver beyond [`Tolerance::abs`] must be a tie, and
    /// at most [`Tolerance::allowed_beyond`] of them. `explain` is called (once, only when some
    /// receiver is beyond) with those receivers, worst first, and gives a [`Verdict`] for each.
    pub fn judge(
        &self,
        what: &str,
        cmp: &Comparison,
        rec: &Receivers,
        cpu: &[f32],
        gpu: &[f32],
        explain: impl FnOnce(&[usize]) -> Result<Vec<Verdict>, String>,
    ) -> Result<CaseStats, String> {
        let mut st = CaseStats {
            receivers: cmp.receivers,
            beyond: cmp.beyond.len(),
            ties: 0,
            max_dv: cmp.max_dv,
            classes: cmp.classes,
        };
        if cmp.beyond.is_empty() {
            return Ok(st);
        }
        let mut beyond = cmp.beyond.clone();
        let dv = |k: usize| (cpu[k] - gpu[k]).abs();
        beyond.sort_by(|&a, &b| dv(b).total_cmp(&dv(a)));
        let verdicts = explain(&beyond)?;
        if verdicts.len() != beyond.len() {
            return Err(format!(
                "{what}: {} verdicts for {} receivers beyond {}",
                verdicts.len(),
                beyond.len(),
                self.abs
            ));
        }
        let mut unexplained = 0;
        let mut lines = Vec::new();
        for (&k, v) in beyond.iter().zip(&verdicts) {
            if v.tie == Tie::Unexplained {
                unexplained += 1;
            } else {
                st.ties += 1;
            }
            if lines.len() < 12 {
                lines.push(format!(
                    "  #{k}: p {:?} n {:?} cpu {} gpu {} |dV| {:.3e}{}{} -> {}",
                    rec.position()[k],
                    rec.normal()[k],
                    cpu[k],
                    gpu[k],
                    dv(k),
                    if v.note.is_empty() { "" } else { " " },
                    v.note,
                    v.tie
                ));
            }
        }
        let n = cmp.receivers;
        let allowed = self.allowed_beyond(n);
        if unexplained > 0 || beyond.len() > allowed {
            return Err(format!(
                "{what}: {} of {n} receivers beyond |dV| {} ({:.4}% within, {allowed} allowed), \
                 {unexplained} not ties; worst:\n{}",
                beyond.len(),
                self.abs,
                100.0 * (1.0 - beyond.len() as f64 / n.max(1) as f64),
                lines.join("\n")
            ));
        }
        Ok(st)
    }
}

/// The change of the receiver bias (in texel footprints) that moves a depth test's `z - eps` by
/// `rel z` in `view`: the nudge of the CPU reruns that expose depth ties.
pub fn bias_nudge(view: &LightView, rel: f32) -> f32 {
    rel * view.n * view.r as f32 / view.w
}

/// One output compared with its twin's ([`Tolerance::compare`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Comparison {
    /// Active receivers.
    pub receivers: usize,
    /// Active receivers within [`Tolerance::abs`].
    pub within: usize,
    /// Active receivers beyond [`Tolerance::abs`], in receiver order.
    pub beyond: Vec<usize>,
    /// The largest `|dV|`.
    pub max_dv: f32,
    /// Active receivers with CPU V = 0, 0 < V < 1, V = 1 (umbra, penumbra, lit).
    pub classes: [usize; 3],
}

impl Comparison {
    /// The fraction of the active receivers within the tolerance (0 with none active).
    pub fn fraction_within(&self) -> f64 {
        self.within as f64 / self.receivers.max(1) as f64
    }
}

/// What explains a receiver beyond the tolerance.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Tie {
    /// A depth-comparison tie: moving the CPU twin's depth threshold by a microscopic fraction
    /// of the depth changes its V by more than the tolerance, or brings it within the
    /// tolerance of the GPU's.
    Depth,
    /// A sampling tie: moving the receiver by a few f32 ulps does the same (a sample position
    /// an ulp from a texel edge).
    Sampling,
    /// Nothing: a real difference between the twins.
    Unexplained,
}

impl fmt::Display for Tie {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Tie::Depth => "tie",
            Tie::Sampling => "sampling tie",
            Tie::Unexplained => "NOT A TIE",
        })
    }
}

/// The explanation of one receiver beyond the tolerance, with a note for the failure message.
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    /// The kind of tie, or none.
    pub tie: Tie,
    /// What the explainer saw (the nudged CPU values, say); may be empty.
    pub note: String,
}

impl Verdict {
    /// A verdict without a note.
    pub fn new(tie: Tie) -> Verdict {
        Verdict {
            tie,
            note: String::new(),
        }
    }

    /// A depth tie when `depth`, else a sampling tie when `sampling`, else unexplained.
    pub fn of(depth: bool, sampling: bool) -> Verdict {
        Verdict::new(if depth {
            Tie::Depth
        } else if sampling {
            Tie::Sampling
        } else {
            Tie::Unexplained
        })
    }

    /// This verdict with the note `note`.
    pub fn note(self, note: impl Into<String>) -> Verdict {
        Verdict {
            note: note.into(),
            ..self
        }
    }
}

/// One random case's counts ([`Tolerance::judge`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CaseStats {
    /// Active receivers compared.
    pub receivers: usize,
    /// Receivers beyond the tolerance.
    pub beyond: usize,
    /// Receivers beyond it explained as ties.
    pub ties: usize,
    /// The largest `|dV|`.
    pub max_dv: f32,
    /// Receivers with CPU V = 0, 0 < V < 1, V = 1.
    pub classes: [usize; 3],
}

/// The counts over a random run, with its whole-run checks.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RunStats {
    /// Cases compared.
    pub cases: usize,
    /// Cases that both twins refused alike (nothing compared).
    pub refused: usize,
    /// Active receivers compared.
    pub receivers: usize,
    /// Receivers beyond the tolerance.
    pub beyond: usize,
    /// Receivers beyond it explained as ties.
    pub ties: usize,
    /// The largest `|dV|`.
    pub max_dv: f32,
    /// Receivers with CPU V = 0, 0 < V < 1, V = 1 (umbra, penumbra, lit).
    pub classes: [usize; 3],
}

impl RunStats {
    /// Adds one case's counts.
    pub fn add(&mut self, st: &CaseStats) {
        self.cases += 1;
        self.receivers += st.receivers;
        self.beyond += st.beyond;
        self.ties += st.ties;
        self.max_dv = self.max_dv.max(st.max_dv);
        for (a, b) in self.classes.iter_mut().zip(st.classes) {
            *a += b;
        }
    }

    /// The fraction of the compared receivers beyond the tolerance (0 with none compared).
    pub fn fraction_beyond(&self) -> f64 {
        self.beyond as f64 / self.receivers.max(1) as f64
    }

    /// One line for the test's output.
    pub fn summary(&self, label: &str, tol: &Tolerance) -> String {
        format!(
            "{label}: {} cases ({} refused alike), {} receivers (V = 0: {}, 0 < V < 1: {}, V = 1: \
             {}), max |dV| {:.3e}, beyond {}: {} ({:.5}%, {} ties)",
            self.cases,
            self.refused,
            self.receivers,
            self.classes[0],
            self.classes[1],
            self.classes[2],
            self.max_dv,
            tol.abs,
            self.beyond,
            100.0 * self.fraction_beyond(),
            self.ties
        )
    }

    /// Panics unless the run compared at least one receiver and at least
    /// [`Tolerance::min_within`] of them are within the tolerance (a run that compared nothing
    /// proves nothing). Returns how many it compared, for the caller's own minimum.
    pub fn assert_within(&self, label: &str, tol: &Tolerance) -> usize {
        assert!(
            self.receivers > 0,
            "{label}: no receiver compared ({} cases, {} refused alike)",
            self.cases,
            self.refused
        );
        let frac = self.fraction_beyond();
        assert!(
            1.0 - frac >= tol.min_within,
            "{label}: {:.5}% beyond",
            100.0 * frac
        );
        self.receivers
    }

    /// Panics unless the run compared umbra (CPU V = 0), penumbra (0 < V < 1) and lit (V = 1)
    /// receivers, each where asked: a run that met none of a kind proves nothing about it.
    pub fn assert_met(&self, label: &str, umbra: bool, penumbra: bool, lit: bool) {
        let c = self.classes;
        assert!(
            (c[0] > 0 || !umbra) && (c[1] > 0 || !penumbra) && (c[2] > 0 || !lit),
            "{label}: a vacuous run (umbra, penumbra, lit): {c:?}"
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn receivers(n: usize) -> Receivers {
        Receivers::from_points(vec![Vec3::ZERO; n], vec![Vec3::Y; n]).unwrap()
    }

    #[test]
    fn allowed_beyond_rounds_up() {
        let t = Tolerance::TWIN;
        assert_eq!(t.allowed_beyond(0), 0);
        assert_eq!(t.allowed_beyond(1), 1);
        assert_eq!(t.allowed_beyond(500), 1);
        assert_eq!(t.allowed_beyond(1500), 2);
    }

    #[test]
    fn compare_counts_and_refuses() {
        let t = Tolerance::TWIN;
        let active = [true, true, true, false];
        let cmp = t
            .compare(
                "x",
                &active,
                &[0.0, 0.5, 1.0, f32::NAN],
                &[0.0, 0.5002, 1.0, f32::NAN],
            )
            .unwrap();
        assert_eq!(
            (cmp.receivers, cmp.within, cmp.beyond.clone()),
            (3, 2, vec![1])
        );
        assert_eq!(cmp.classes, [1, 1, 1]);
        // Inactive must be NaN on both; GPU V in [0, 1]; the bound when set.
        assert!(t.compare("x", &[false], &[f32::NAN], &[0.5]).is_err());
        assert!(t.compare("x", &[true], &[0.5], &[1.5]).is_err());
        assert!(t
            .with_max(0.05)
            .compare("x", &[true], &[0.5], &[0.6])
            .is_err());
        assert!(t
            .with_max(0.05)
            .compare("x", &[true], &[f32::NAN], &[0.6])
            .is_err());
        assert!(t.compare("x", &[true], &[f32::NAN], &[0.6]).is_ok());
    }

    #[test]
    #[should_panic(expected = "no receiver compared")]
    fn an_empty_run_fails() {
        RunStats::default().assert_within("empty", &Tolerance::TWIN);
    }

    #[test]
    #[should_panic(expected = "no active receiver compared")]
    fn an_empty_comparison_fails() {
        Tolerance::TWIN.assert_twins("empty", &[false], &[f32::NAN], &[f32::NAN]);
    }

    #[test]
    fn a_run_reports_how_many_it_compared() {
        let mut st = RunStats::default();
        st.add(&CaseStats {
            receivers: 5,
            ..CaseStats::default()
        });
        assert_eq!(st.assert_within("five", &Tolerance::TWIN), 5);
    }

    #[test]
    fn judge_needs_ties_and_the_allowance() {
        let t = Tolerance::TWIN;
        let rec = receivers(2);
        let (c, g) = ([0.0, 0.5], [0.0, 0.6]);
        let cmp = t.compare("x", rec.active(), &c, &g).unwrap();
        // One of two beyond: allowed (ceil(0.001 * 2) = 1), when it is a tie.
        let st = t
            .judge("x", &cmp, &rec, &c, &g, |b| {
                Ok(vec![Verdict::new(Tie::Depth); b.len()])
            })
            .unwrap();
        assert_eq!((st.beyond, st.ties), (1, 1));
        let e = t
            .judge("x", &cmp, &rec, &c, &g, |b| {
                Ok(vec![Verdict::of(false, false); b.len()])
            })
            .unwrap_err();
        assert!(e.contains("NOT A TIE"), "{e}");
    }
}
