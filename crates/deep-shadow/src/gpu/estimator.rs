//! [`GpuDeepShadow`] as a [`SoftShadowEstimator`]: the parameters, and `estimate` over the
//! sub-light points with the chunked queries of the parent module.
use super::*;

impl SoftShadowEstimator for GpuDeepShadow {
    shadow_map_core::estimator_identity!(params::NAME, params::DESCRIPTION, Gpu, params);
    fn set_param(&mut self, key: &str, value: &str) -> Result<()> {
        self.settings = params::set(&mut self.params, key, value)?;
        Ok(())
    }
    fn set_cancel(&mut self, cancel: Cancel) {
        self.cancel = cancel;
    }
    fn build(&mut self, _scene: &Scene, _receivers: &Receivers) -> Result<()> {
        self.report = Report::default();
        Ok(())
    }
    fn estimate(&mut self, scene: &Scene, receivers: &Receivers, v: &mut [f32]) -> Result<()> {
        receivers.check_output(v)?;
        self.report = Report::default();
        let s = self.settings();
        let opaque = scene.is_opaque();
        let points = sublight_points(scene, s.sublights);
        let mut acc = vec![0.0f32; receivers.len()];
        let (mut t_build, mut t_est) = (0.0, 0.0);
        let mut tally = Tally::default();
        let (mut fallbacks, mut cut_texels) = (0usize, 0u64);
        let mut outside = vec![false; receivers.len()];
        for y in &points {
            self.cancel.check()?;
            let t = Instant::now();
            let (view, _) = tally.fit_view(scene, receivers, *y, &s)?;
            let map = self.build_map(scene, &view, &s)?;
            tally.fragments += map.stats.fragments;
            tally.kept += if opaque {
                map.stats.fragments
            } else {
                map.stats.kept
            };
            tally.max_len = tally.max_len.max(map.stats.max_len);
            tally.capacity = tally.capacity.max(map.stats.capacity);
            tally.passes += map.stats.passes;
            tally.peak = tally
                .peak
                .max((map.head.size() + map.nodes.size()) as usize);
            t_build += t.elapsed().as_secs_f64() * 1e3;
            let t = Instant::now();
            let queries: Vec<PackedQuery> = (0..receivers.len())
                .map(|k| {
                    if receivers.active()[k] {
                        pack_query(query(
                            &view,
                            scene.light(),
                            receivers.position()[k],
                            receivers.normal()[k],
                            &s,
                        ))
                    } else {
                        [0.0; 8]
                    }
                })
                .collect();
            let ls = lookup_settings(&view, scene.light(), &s);
            crate::cpu::mark_outside(&view, scene.light(), receivers, &s, &mut outside);
            let (tv, steps, redone) = self.lookup(&map, &ls, &queries)?;
            fallbacks += redone;
            cut_texels += map.cut_texels;
            tally.lookups += queries.iter().filter(|q| q[3] < 0.0).count() as u64;
            tally.steps += steps;
            for (a, x) in acc.iter_mut().zip(&tv) {
                *a += x;
            }
            t_est += t.elapsed().as_secs_f64() * 1e3;
        }
        let bad = finish(scene, receivers, &acc, points.len(), v);
        let settled = crate::cpu::settle_outside(scene, receivers, &outside, v)?;
        if settled > 0 {
            self.report.note("settled_outside", settled);
        }
        self.report.stages.push(("build".into(), t_build));
        self.report.stages.push(("estimate".into(), t_est));
        tally.note(&mut self.report, scene, opaque, points.len());
        self.report.note("non_finite", bad);
        self.report
            .warn(shadow_map_core::Warning::NonFiniteV { receivers: bad });
        if fallbacks > 0 || cut_texels > 0 {
            self.report.note("loop_limit_cpu_fallbacks", fallbacks);
            self.report.note("loop_limit_cpu_lists", cut_texels);
        }
        self.report.note("device", self.ctx.describe());
        Ok(())
    }
    fn report(&self) -> Report {
        self.report.clone()
    }
}
