//! Orchestration (METHOD §2-10): per-image work once (validation, veiling
//! light and water region, the Mahalanobis matting model, guide
//! statistics), then the water types one after another, each with every
//! pass parallel over rows, and the chosen type computed once more to
//! produce the outputs. Per type only three buffers exist (the refined
//! transmission / J, the guided filter's (a, b), and with an estimation
//! mask the filtered plane); no per-type full-resolution image is kept.
//!
//! Selection needs from each type only sums over pixels (METHOD §9) and the
//! display stretch's limits, which come from order statistics of J before
//! the artifact clamp: the clamp and the normalisation are non-decreasing
//! maps, so they commute with ranking ([`crate::kernels::rank`]).

mod evaluate;
pub(crate) mod fast;
pub(crate) mod given;
pub(crate) mod work;

use crate::error::{Error, Result};
use crate::method::params::{check_params, default_radius, Flag, Input, Params, Restoration, Selection, Stage};
use crate::method::profile::{TypeChoice, CENTRAL_OF};
use crate::method::select::{self, choose};
use crate::method::sphere::SphereIndex;
use crate::kernels::util::with_threads;
use crate::method::veiling::{estimate, Veiling};
use crate::method::water::WaterType;
use evaluate::{finish, Scored, Shared};
pub use work::Buffers;
use work::Work;



/// Wall-clock laps of the stages of one [`restore`] call.
struct Clock {
    last: std::time::Instant,
    laps: Vec<(Stage, f64)>,
}

impl Clock {
    fn new() -> Self {
        Self {
            last: std::time::Instant::now(),
            laps: Vec::new(),
        }
    }

    /// Ends the stage `name` when `ran` (else the time goes to the next lap).
    fn lap_if(&mut self, ran: bool, name: Stage) {
        if ran {
            self.lap(name);
        }
    }

    /// Ends the stage `name` (adds to an earlier lap of that name).
    fn lap(&mut self, name: Stage) {
        let now = std::time::Instant::now();
        let dt = (now - self.last).as_secs_f64();
        self.last = now;
        match self.laps.iter_mut().find(|(n, _)| *n == name) {
            Some((_, t)) => *t += dt,
            None => self.laps.push((name, dt)),
        }
    }
}

/// The whole method (METHOD §2-10) on one image.
pub fn restore(input: &Input, params: &Params) -> Result<Restoration> {
    restore_with(input, params, &mut Buffers::default())
}

/// [`restore`] with work buffers taken from, and (when they are kept)
/// returned to, `pool`; the results are the same bits.
pub fn restore_with(input: &Input, params: &Params, pool: &mut Buffers) -> Result<Restoration> {
    with_threads(params.threads, || restore_inner(input, params, pool))?
}

/// The method, step by step (METHOD §2-10).
fn restore_inner(input: &Input, params: &Params, pool: &mut Buffers) -> Result<Restoration> {
    let mut clock = Clock::new();
    // §2: the input and the parameters
    check_params(input, params)?;
    let img = &input.image;
    img.validate_values()?;
    let index = SphereIndex::shared(params.sphere_points)?;
    clock.lap(Stage::Validation);
    // §3: veiling light A and water region VL
    let veil = estimate(img, input.mask, input.water_mask, params.veiling_light);
    objects_left(input, veil.vl_count)?;
    clock.lap(Stage::VeilingLight);
    // §9, fast selection: every type scored on a sampled copy first
    let types: Vec<&WaterType> = params.water_types.iter().collect();
    let copy = match params.selection_used() {
        Selection::Fast if types.len() >= 2 => fast::copy_stats(img, input.mask, &veil, &index, params, &types)?,
        _ => None,
    };
    clock.lap_if(copy.is_some(), Stage::FastCopyScoring);
    // §5-6: the per-image terms (matting model, guide and its statistics)
    let radius = params.guided_radius.unwrap_or_else(|| default_radius(img.height, img.width));
    let mut shared = Shared::new(*img, input.mask, &veil, &index, radius, params, std::mem::take(&mut pool.guide));
    let central = params.type_choice_used() == TypeChoice::Central;
    if central && copy.is_none() && types.len() >= 2 {
        shared.take_probe(None);
    }
    let matting_skipped = veil.vl_count > 0 && shared.matting.is_none();
    clock.lap(Stage::Guide);
    let mut work = Work::from_pool(img.len(), pool);
    clock.lap(Stage::WorkBuffers);
    // §4-9: the candidate types evaluated and scored, and the choice
    let scored = match copy {
        Some((copy, prints)) => Some(fast::rescore(&shared, &types, copy, prints, &mut work)),
        None if types.len() >= 2 => Some(shared.score_all(&types, &mut work)),
        None => None,
    };
    // METHOD §12.2: the central one of the best-scored types
    let scored = scored.map(|mut s| {
        if let Some(c) = central
            .then(|| select::central(&s.stats, &s.choice.excluded, &s.prints, CENTRAL_OF, s.choice.winner))
            .flatten()
        {
            s.choice.winner = c;
        }
        s
    });
    clock.lap(Stage::Scoring);
    // §4-8 once more for the chosen type: the outputs
    let winner = scored.as_ref().map_or(0, |s| s.choice.winner);
    let wt = (*types.get(winner).ok_or_else(|| Error::Internal("winner out of range".into()))?).clone();
    let (scored, q) = match scored.map(Scored::into_parts) {
        Some((stats, choice, q)) => (Some((stats, choice)), q),
        None => (None, None),
    };
    let out = finish(shared, &wt, work, q, pool, &mut clock);
    // §10: the result, with the chosen type's full-resolution statistics
    let (stats, choice) = match scored {
        Some((mut stats, choice)) => {
            if let Some(d) = stats.get_mut(winner) {
                *d = out.stats;
            }
            (stats, choice)
        }
        None => (vec![out.stats], choose(&[out.stats])),
    };
    let Veiling { a, vl, mut flags, .. } = veil;
    if choice.relaxed {
        flags.push(Flag::ExclusionRelaxed);
    }
    if matting_skipped {
        flags.push(Flag::MattingSkipped);
    }
    flags.extend(out.trust.iter().flat_map(|t| t.flags()));
    let named = |keep: &dyn Fn(usize) -> bool| -> Vec<String> {
        types.iter().enumerate().filter(|(i, _)| keep(*i)).map(|(_, t)| t.name.clone()).collect()
    };
    Ok(Restoration {
        height: img.height,
        width: img.width,
        image: out.image,
        radiance: out.radiance,
        transmission: out.transmission,
        scores: types.iter().zip(&stats).map(|(t, s)| (t.name.clone(), s.score)).collect(),
        excluded: named(&|i| choice.excluded.get(i).copied().unwrap_or(false)),
        water_type: wt,
        veiling_light: a,
        veiling_mask: vl,
        flags,
        veil_excess: out.trust.as_ref().map(|t| t.veil_excess),
        fallback_share: out.trust.as_ref().and_then(|t| t.fallback_share),
        distance: None,
        confidence: out.trust.map(|t| t.confidence),
        guided_radius: radius,
        guided_subsample: params.subsample_at(radius),
        timings: clock.laps,
    })
}

/// A water region of `water` pixels that covers every pixel used for
/// estimation leaves no object pixels to choose the water type with
/// (METHOD §9).
/// The error names what the caller gave: the water mask, or, when the
/// water region was found (§3), the mask that left only water.
fn objects_left(input: &Input, water: usize) -> Result<()> {
    let usable = input.mask.map_or(input.image.len(), |m| m.iter().filter(|&&b| b).count());
    if water < usable {
        return Ok(());
    }
    Err(if input.water_mask.is_some() {
        Error::Mask {
            name: "water_mask",
            msg: "covers every pixel used for estimation: no object pixels are left to choose the water type".into(),
        }
    } else {
        Error::Mask {
            name: "mask",
            msg: "leaves only pixels of the water region found (METHOD §3): no object pixels are left to choose \
                  the water type; mask in some of the scene, or give water_mask"
                .into(),
        }
    })
}

#[cfg(test)]
mod tests {
    use crate::method::hazelines::{t_tilde, T_SCALE};
    use crate::method::matting::blend_row;
    use crate::method::recover::{ArtifactClamp, Stretch};
    use crate::method::select::{counted_sums, row_stats, RowStats};
    use crate::method::stretch::guide_row;
    use crate::kernels::util::{ChannelStretch, Normalize};

    /// The row kernels (AVX2 builds where the CPU has AVX2) against the
    /// per-pixel functions (baseline builds here): the same bits
    /// (METHOD appendix, same bits on every CPU), and row_stats against a plain loop.
    #[test]
    fn row_kernels_match_per_pixel_values() {
        let n = 1037;
        let noise = crate::kernels::util::test_noise(8 * n, 3);
        let j: Vec<[f32; 3]> = noise.chunks_exact(3).take(n).map(|c| [c[0] * 1.4 - 0.2, c[1], c[2] * 2.0]).collect();
        let clamp = ArtifactClamp::new(-0.2, 2.0);
        let norm = Normalize::new(clamp.apply(-0.2), clamp.apply(2.0));
        for limits in [
            [Some((0.1, 0.9)), None, Some((0.0, 0.5))],
            [None, None, None],
            [Some((0.2, 0.3)), Some((0.0, 1.0)), Some((0.4, 0.8))],
        ] {
            let sp = Stretch { clamp, norm, limits: ChannelStretch::new(limits) };
            let shown: Vec<[f32; 3]> = j.iter().map(|v| std::array::from_fn(|c| sp.apply(c, v[c]))).collect();
            let counted: Vec<bool> = (0..n).map(|i| i % 5 != 2 && i % 11 != 0).collect();
            for len in [0, 5, 8, 13, n] {
                let (jr, sr, cr) = (&j[..len], &shown[..len], &counted[..len]);
                // summed from J with the stretch, or from the shown values:
                // the same bits (scoring and final output agree)
                let from_j = counted_sums(Some(&sp), jr, cr);
                let from_shown = counted_sums(None, sr, cr);
                assert_eq!(from_j.map(f64::to_bits), from_shown.map(f64::to_bits), "len {len}");
                // and the plain sums, up to the order of the additions
                for c in 0..3 {
                    let plain: f64 = sr.iter().zip(cr).filter(|(_, &k)| k).map(|(v, _)| f64::from(v[c])).sum();
                    assert!((from_j[c] - plain).abs() <= 1e-12 * plain.abs().max(1.0), "len {len} c {c}");
                }
            }
        }
        // the guide (METHOD §6): stretched input to the power 1/2.2, 0 where masked out
        let st = ChannelStretch::new([Some((0.1, 0.9)), None, Some((0.05, 0.7))]);
        let gn = Normalize::new(0.0, 1.4);
        let src: Vec<[f32; 3]> = j.iter().map(|v| v.map(|x| x.max(0.0))).collect();
        let gmask: Vec<bool> = (0..n).map(|i| i % 7 != 3).collect();
        for m in [None, Some(&gmask[..])] {
            let mut g = vec![[9f32; 3]; n];
            guide_row(&gn, &st, &src, &mut g, m);
            for i in 0..n {
                for c in 0..3 {
                    let want = if m.is_some_and(|m| !m[i]) {
                        0.0
                    } else {
                        crate::kernels::fastmath::pow_pos(st.apply(c, gn.apply(src[i][c])), 1.0 / 2.2)
                    };
                    assert_eq!(g[i][c].to_bits(), want.to_bits(), "{i} {c}");
                }
            }
        }
        // row statistics
        let tr: Vec<f32> = noise.iter().skip(3 * n).take(n).copied().collect();
        let inside: Vec<bool> = noise.iter().skip(4 * n).take(n).map(|v| *v > 0.2).collect();
        let vl: Vec<bool> = noise.iter().skip(5 * n).take(n).map(|v| *v > 0.6).collect();
        let mut st = RowStats::default();
        row_stats(&j, &tr, &inside, &vl, &mut st);
        let (mut lo, mut hi, mut s) = (f32::INFINITY, f32::NEG_INFINITY, [0f64; 4]);
        for i in 0..n {
            if inside[i] {
                lo = lo.min(j[i][0]).min(j[i][1]).min(j[i][2]);
                hi = hi.max(j[i][0]).max(j[i][1]).max(j[i][2]);
                let k = if vl[i] { 0 } else { 2 };
                s[k] += tr[i] as f64;
                s[k + 1] += 1.0;
            }
        }
        assert_eq!((st.lo, st.hi), (lo, hi));
        assert_eq!((st.sums.vl, st.sums.counted), (s[1], s[3]));
        assert!((st.sums.tr_vl - s[0]).abs() < 1e-9 && (st.sums.tr_counted - s[2]).abs() < 1e-9);
        // blend: t~ from r / r_max, the bound and the matting weight
        let rm = [0.0f32, 0.5, 0.0, 2.0];
        let aux: Vec<[f32; 2]> = (0..n).map(|i| [noise[6 * n + i] * 0.5, (i % 4) as f32 - 1.0]).collect();
        let r: Vec<f32> = noise.iter().skip(7 * n).take(n).map(|v| v * 2.0).collect();
        let mut p = r.clone();
        blend_row(&mut p, &aux, &j, &rm, None, true, T_SCALE);
        for i in 0..n {
            let t = t_tilde(r[i], aux[i][1], &rm[1..]);
            assert_eq!(p[i].to_bits(), (t * T_SCALE).max(aux[i][0]).to_bits(), "{i}");
        }
    }
}
