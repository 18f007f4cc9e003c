//! The per-type evaluation (METHOD §4-9) on the per-image state shared by
//! every water type, and the chosen type's final restoration.

use super::work::{split_rows, Buffers, Kept, RowScratch, Work};
use super::Clock;
use crate::method::guided::{chart_fill, GuideStats};
use crate::method::hazelines::{fill_masked, haze_pass, t_tilde, HazeType, CHUNK_ROWS};
use crate::method::image::ImageRef;
use crate::method::params::Stage;
use crate::method::matting::{blend_row, Matting};
use crate::method::recover::{display_limits, recover_values, ArtifactClamp, Recovery, Stretch, DISPLAY_QS};
use crate::method::params::Params;
use crate::method::select::{choose, combine, counted_sums, row_stats, Choice, RowStats, TypeStats};
use crate::method::stretch::guide_image_into;
use crate::method::veiling::Veiling;
use crate::method::sphere::SphereIndex;
use crate::kernels::util::{channel_percentiles, reuse, reuse_zeroed, Normalize};
use crate::method::water::WaterType;
use crate::method::fallback::{blend_samples, noise_sigma, trust, Trust};
use crate::method::profile::{conditioned, gains_from, Fallback, PowerSums, TypeChoice, WhiteBalance, SOG_P, WHITE_PATCH_Q};
use rayon::prelude::*;

/// At most this many object pixels are compared by the central type
/// choice (METHOD §12.2): its median distances are then within about 1% of
/// those over every pixel.
pub const PROBE_PIXELS: usize = 4000;

/// Per-image state shared by every water type.
pub(crate) struct Shared<'a> {
    pub(crate) img: ImageRef<'a>,
    pub(crate) mask: Option<&'a [bool]>,
    pub(crate) vl: &'a [bool],
    pub(crate) a: [f32; 3],
    pub(crate) matting: Option<Matting>,
    pub(crate) guide: GuideStats,
    pub(crate) index: &'a SphereIndex,
    pub(crate) holes: bool,
    /// the type choice used (METHOD §9 or §12.2)
    pub(crate) choice: TypeChoice,
    /// the white balance used (METHOD §8 or §12.1)
    pub(crate) balance: WhiteBalance,
    /// the scale of t~ (METHOD §4.6)
    pub(crate) t_scale: f32,
    /// the haze-line floor's ratios (METHOD §12.3)
    pub(crate) floor: Option<[f64; 2]>,
    /// the fallback where the result cannot be trusted (METHOD §12.5)
    pub(crate) fallback: Fallback,
    /// the object pixels whose displayed colours the central type choice
    /// compares (METHOD §12.2); None when no such comparison is made here
    pub(crate) probe: Option<Probe>,
}

/// The pixels the central type choice compares (METHOD §12.2), and the
/// photo's noise that the trust step's blend there uses (METHOD §12.5).
pub(crate) struct Probe {
    pixels: Vec<usize>,
    noise: [f64; 3],
}

/// The displayed colours of one type at the probe's pixels (METHOD §12.2).
pub(crate) type Print = Vec<[f32; 3]>;

/// The selection statistics of the scored types, the choice among them,
/// and the filtered plane q of the type chosen so far when it was kept.
pub(crate) struct Scored {
    pub(crate) stats: Vec<TypeStats>,
    pub(crate) choice: Choice,
    pub(crate) kept: Option<Kept>,
    /// each type's displayed colours at the probe's pixels, where taken
    pub(crate) prints: Vec<Option<Print>>,
}

impl Scored {
    /// The statistics, the choice, and the kept plane q when it is the
    /// winner's (moved, not copied: the memory plan counts one such plane).
    pub(crate) fn into_parts(self) -> (Vec<TypeStats>, Choice, Option<Vec<f32>>) {
        let winner = self.choice.winner;
        let q = self.kept.filter(|k| k.index == winner).map(|k| k.q);
        (self.stats, self.choice, q)
    }
}

impl<'a> Shared<'a> {
    /// The per-image terms of METHOD §5-6 for `img` with its estimation
    /// mask and the water region and A of `veil`: the matting model of
    /// the water's colors and the guide (built into `buf` when it has the
    /// right length) with its window statistics at radius `r`.
    pub(crate) fn new(
        img: ImageRef<'a>,
        mask: Option<&'a [bool]>,
        veil: &'a Veiling,
        index: &'a SphereIndex,
        r: usize,
        params: &Params,
        buf: Vec<f32>,
    ) -> Self {
        Self::with_region(img, mask, &veil.vl, veil.a, index, r, params, buf)
    }

    /// [`Shared::new`] with the water region and A given apart (the sampled
    /// copy of fast selection has its own region).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn with_region(
        img: ImageRef<'a>,
        mask: Option<&'a [bool]>,
        vl: &'a [bool],
        a: [f32; 3],
        index: &'a SphereIndex,
        r: usize,
        params: &Params,
        buf: Vec<f32>,
    ) -> Self {
        let s = params.subsample_at(r);
        Self {
            img,
            mask,
            vl,
            a,
            matting: Matting::fit(&img, vl),
            guide: GuideStats::subsampled(guide_image_into(img.data, mask, buf), img.height, img.width, r, params.guided_eps, s),
            index,
            holes: mask.is_some_and(|m| m.iter().any(|&b| !b)),
            choice: params.type_choice_used(),
            balance: params.white_balance_used(),
            t_scale: params.t_scale as f32,
            floor: params.haze_floor_ratios(),
            fallback: params.fallback_used(),
            probe: None,
        }
    }

    /// Takes the probe of the central type choice (METHOD §12.2): every
    /// k-th object pixel (masked-in, not VL) in raster order, k the
    /// smallest step that leaves at most [`PROBE_PIXELS`] of them, with
    /// the photo's noise `noise` (None: this image's, which is the photo).
    pub(crate) fn take_probe(&mut self, noise: Option<[f64; 3]>) {
        let n = self.img.len();
        let count = (0..n).into_par_iter().filter(|&i| self.is_object(i)).count();
        let step = count.div_ceil(PROBE_PIXELS).max(1);
        self.probe = Some(Probe {
            pixels: (0..n).filter(|&i| self.is_object(i)).step_by(step).collect(),
            noise: noise.unwrap_or_else(|| noise_sigma(&self.img)),
        });
    }

    /// Whether pixel i is an object pixel: masked-in and not in VL.
    pub(crate) fn is_object(&self, i: usize) -> bool {
        self.mask.is_none_or(|m| m.get(i).copied().unwrap_or(false)) && !self.vl.get(i).copied().unwrap_or(false)
    }

    /// Every type scored (METHOD §4-9) and the choice of METHOD §9.
    pub(crate) fn score_all(&self, types: &[&WaterType], work: &mut Work) -> Scored {
        let (stats, kept, prints) = self.score(types, work);
        let choice = choose(&stats);
        Scored { stats, choice, kept, prints }
    }

    /// METHOD §4-6 up to the guided filter's first pass: the refined
    /// transmission p = blend(max(t~, t_LB)) into `work.j[..n]`, then (a, b)
    /// into `work.aux`. Returns the bounds of (a, b) for the second pass.
    pub(crate) fn refine(&self, wt: &WaterType, work: &mut Work) -> [f64; 4] {
        let img = &self.img;
        let (n, w) = (img.len(), img.width);
        let Work { j, aux, .. } = work;
        let (p, _) = j.split_at_mut(n);
        // METHOD §12.3: the transmission with the floor's ratios where a type's are smaller
        let ht = HazeType::new(self.a, &conditioned(wt, self.floor));
        // (t_LB, cluster) in the first half of the (a, b) buffer
        let pairs = aux.as_flattened_mut().get_mut(..2 * n).unwrap_or(&mut []).as_chunks_mut::<2>().0;
        let rmax = haze_pass(img, &ht, self.index, self.mask, p, pairs);
        // r_max by cluster + 1 (0: no cluster, t~ = 1)
        let rm: Vec<f32> = std::iter::once(0.0).chain(rmax.iter().copied()).collect();
        let matting = self.matting.as_ref();
        let chunk = w * CHUNK_ROWS;
        if self.holes {
            p.par_iter_mut()
                .zip(pairs.par_iter())
                .for_each(|(v, x)| *v = t_tilde(*v, x[1], &rmax));
            if let Some(m) = self.mask {
                fill_masked(p, m, img.height, w);
            }
        }
        p.par_chunks_mut(chunk)
            .zip(pairs.par_chunks(chunk))
            .zip(img.data.par_chunks(3 * chunk))
            .for_each(|((pp, aa), px)| blend_row(pp, aa, px.as_chunks::<3>().0, &rm, matting, !self.holes, self.t_scale));
        self.guide.coefficients(p, aux)
    }

    /// METHOD §7 for one row: t_B (written to `tb` if given), t_R, t_G and J
    /// before the artifact clamp (to `j`), with the row's statistics.
    pub(crate) fn recover_row(&self, rec: &Recovery, y: usize, q: &[f32], j: &mut [f32], tb: Option<&mut [f32]>, sc: &mut RowScratch) -> RowStats {
        let w = self.img.width;
        let mut st = RowStats::default();
        let px = self.img.data.get(3 * y * w..3 * (y + 1) * w).unwrap_or(&[]);
        let jr = j.as_chunks_mut::<3>().0;
        let RowScratch { tr, tb: tb_own, yes, no } = sc;
        let tbr = match tb {
            Some(b) => b,
            None => &mut tb_own[..],
        };
        recover_values(rec, q, px.as_chunks::<3>().0, jr, tbr, tr);
        let (inside, vl) = self.row_masks(y, yes, no);
        row_stats(jr, tr, inside, vl, &mut st);
        st
    }

    /// Row y of the estimation mask (all true without one) and of the
    /// water region VL, with `yes` / `no` (w entries, all true / all false)
    /// standing in for what is absent.
    pub(crate) fn row_masks<'s>(&'s self, y: usize, yes: &'s [bool], no: &'s [bool]) -> (&'s [bool], &'s [bool]) {
        let w = self.img.width;
        let row = y * w..(y + 1) * w;
        let inside = match self.mask {
            Some(m) => m.get(row.clone()).unwrap_or(no),
            None => yes,
        };
        (inside, self.vl.get(row).unwrap_or(no))
    }

    /// The guided filter's second pass, the chart fill (METHOD §6) and the
    /// recovery (METHOD §7) into `work.j` (and t_B into `tb` if given);
    /// returns the statistics of all rows combined in row order.
    pub(crate) fn recover(&self, wt: &WaterType, bounds: [f64; 4], work: &mut Work, tb: Option<&mut [f32]>) -> RowStats {
        let (h, w) = (self.img.height, self.img.width);
        let mut tb_buf = tb;
        if !self.holes {
            let rec = Recovery::new(self.a, wt);
            let mut rows = vec![RowStats::default(); h];
            let Work { j, aux, q } = &mut *work;
            let ranges = self.guide.ranges();
            let tbs: Vec<Option<&mut [f32]>> = match tb_buf.as_deref_mut() {
                Some(b) => split_rows(b, w, &ranges).into_iter().map(Some).collect(),
                None => ranges.iter().map(|_| None).collect(),
            };
            let work: Vec<_> = ranges
                .iter()
                .cloned()
                .zip(split_rows(j, 3 * w, &ranges).into_iter().zip(tbs).zip(split_rows(&mut rows, 1, &ranges)))
                .zip(split_rows(q, w, &ranges))
                .map(|((r, ((jj, tt), rr)), qq)| (r.clone(), (r.start, jj, tt, rr, qq, RowScratch::new(w))))
                .collect();
            type State<'s> = (usize, &'s mut [f32], Option<&'s mut [f32]>, &'s mut [RowStats], &'s mut [f32], RowScratch);
            let sink = |o: &mut State<'_>, y: usize, qrow: &[f32]| {
                let k = y - o.0;
                let (Some(jr), Some(slot)) = (o.1.get_mut(3 * k * w..3 * (k + 1) * w), o.3.get_mut(k)) else {
                    return;
                };
                if let Some(d) = o.4.get_mut(k * w..(k + 1) * w) {
                    d.copy_from_slice(qrow);
                }
                let tr = o.2.as_deref_mut().and_then(|b| b.get_mut(k * w..(k + 1) * w));
                *slot = self.recover_row(&rec, y, qrow, jr, tr, &mut o.5);
            };
            self.guide.apply_rows(aux, bounds, work, &sink);
            combine(&rows)
        } else {
            let Work { aux, q, .. } = &mut *work;
            let ranges = self.guide.ranges();
            let bands: Vec<_> = ranges
                .iter()
                .cloned()
                .zip(split_rows(q, w, &ranges))
                .map(|(r, s)| (r.clone(), (r.start, s)))
                .collect();
            let sink = |o: &mut (usize, &mut [f32]), y: usize, qrow: &[f32]| {
                let k = y - o.0;
                if let Some(d) = o.1.get_mut(k * w..(k + 1) * w) {
                    d.copy_from_slice(qrow);
                }
            };
            self.guide.apply_rows(aux, bounds, bands, &sink);
            if let Some(m) = self.mask {
                chart_fill(q, m, h, w);
            }
            self.recover_from_q(wt, work, tb_buf)
        }
    }

    /// The recovery (METHOD §7) from the filtered plane in `work.q` into
    /// `work.j` (and t_B into `tb` if given), with the statistics of all
    /// rows combined in row order: what [`Shared::recover`] gives for the
    /// q it stored.
    pub(crate) fn recover_from_q(&self, wt: &WaterType, work: &mut Work, tb: Option<&mut [f32]>) -> RowStats {
        let (h, w) = (self.img.height, self.img.width);
        let rec = Recovery::new(self.a, wt);
        let Work { j, q, .. } = work;
        let mut rows = vec![RowStats::default(); h];
        let tbs: Vec<Option<&mut [f32]>> = match tb {
            Some(b) => b.chunks_mut(w).map(Some).collect(),
            None => (0..h).map(|_| None).collect(),
        };
        rows.par_iter_mut()
            .zip(j.par_chunks_mut(3 * w))
            .zip(q.par_chunks(w))
            .zip(tbs)
            .enumerate()
            .for_each_init(
                || RowScratch::new(w),
                |sc, (y, (((slot, jr), qr), tr))| *slot = self.recover_row(&rec, y, qr, jr, tr, sc),
            );
        combine(&rows)
    }

    /// The artifact clamp and display stretch of a recovered J (METHOD §7-8),
    /// from J's min and max and the order statistics of its channels.
    pub(crate) fn stretch(&self, j: &[f32], st: &RowStats) -> Stretch {
        let clamp = ArtifactClamp::new(st.lo, st.hi);
        let norm = Normalize::new(clamp.apply(st.lo), clamp.apply(st.hi));
        let pcts = channel_percentiles(j, self.mask, &DISPLAY_QS, |_, v| norm.apply(clamp.apply(v)));
        Stretch {
            clamp,
            norm,
            limits: display_limits(&pcts),
        }
    }

    /// Sums of the three displayed channels over counted pixels (METHOD §9),
    /// per row, combined in row order, of J mapped by `sp` (the values as
    /// they are without).
    pub(crate) fn channel_sums(&self, rgb: &[f32], sp: Option<&Stretch>) -> [f64; 3] {
        let w = self.img.width;
        let rows: Vec<[f64; 3]> = rgb
            .par_chunks(3 * w)
            .enumerate()
            .map_init(
                || (vec![false; w], RowScratch::new(w)),
                |(counted, sc), (y, row)| {
                    // counted: inside the mask and not in VL
                    let (inside, vl) = self.row_masks(y, &sc.yes, &sc.no);
                    counted.iter_mut().zip(inside).zip(vl).for_each(|((c, &i), &b)| *c = i & !b);
                    counted_sums(sp, row.as_chunks::<3>().0, counted)
                },
            )
            .collect();
        rows.iter().fold([0f64; 3], |a, r| [a[0] + r[0], a[1] + r[1], a[2] + r[2]])
    }

    /// The transmission output of a type below the haze-line floor
    /// (METHOD §12.3): the refined plane q clamped as the conditioned
    /// type's t_B, not to the type's own (higher) t_B floor 0.1^beta_BR,
    /// which serves only the recovery. Unchanged for other types.
    pub(crate) fn floor_transmission(&self, wt: &WaterType, q: &[f32], transmission: &mut [f32]) {
        let cond = conditioned(wt, self.floor);
        if cond.beta_br == wt.beta_br || q.len() != transmission.len() {
            return;
        }
        let rec = Recovery::new(self.a, &cond);
        transmission.par_iter_mut().zip(q.par_iter()).for_each(|(t, &v)| *t = rec.clamp_tb(v));
    }

    /// The power sums of METHOD §12 over the object pixels (masked-in, not
    /// VL) of J mapped by `clamp` (the values as they are without), per
    /// row, combined in row order.
    pub(crate) fn object_sums(&self, rgb: &[f32], clamp: Option<&ArtifactClamp>) -> PowerSums {
        let w = self.img.width;
        let rows: Vec<PowerSums> = rgb
            .par_chunks(3 * w)
            .enumerate()
            .map_init(
                || RowScratch::new(w),
                |sc, (y, row)| {
                    let (inside, vl) = self.row_masks(y, &sc.yes, &sc.no);
                    let mut s = PowerSums::default();
                    for ((px, &i), &b) in row.as_chunks::<3>().0.iter().zip(inside).zip(vl) {
                        if i && !b {
                            s.push(clamp.map_or(*px, |c| px.map(|v| c.apply(v))));
                        }
                    }
                    s
                },
            )
            .collect();
        rows.iter().fold(PowerSums::default(), |mut a, r| {
            a.add(r);
            a
        })
    }

    /// The selection statistics of a recovered J (before the artifact
    /// clamp) with row statistics `st`, by the type choice in use:
    /// METHOD §9 (gray world of the stretched image, t_R differences) or
    /// METHOD §12.2 (shades-of-gray spread of the clamped radiance, no
    /// exclusion), with the object pixels' power sums of the clamped
    /// radiance when they were summed for it (the central choice's display
    /// needs them too).
    pub(crate) fn type_stats(&self, j: &[f32], st: &RowStats) -> (TypeStats, Option<PowerSums>) {
        match self.choice {
            TypeChoice::GrayWorld => {
                let sp = self.stretch(j, st);
                let mut sums = st.sums;
                sums.channels = self.channel_sums(j, Some(&sp));
                (sums.stats(), None)
            }
            TypeChoice::ShadesOfGray | TypeChoice::Central => {
                let objects = self.object_sums(j, Some(&ArtifactClamp::new(st.lo, st.hi)));
                (TypeStats { score: objects.spread(), tr_diff: None }, Some(objects))
            }
        }
    }

    /// Selection statistics of one type (METHOD §4-9, §12.2) without keeping any of
    /// its images.
    /// With a probe, also the type's displayed colours at its pixels.
    pub(crate) fn evaluate(&self, wt: &WaterType, work: &mut Work) -> (TypeStats, Option<Print>) {
        let bounds = self.refine(wt, work);
        let st = self.recover(wt, bounds, work, None);
        let (stats, objects) = self.type_stats(&work.j, &st);
        (stats, self.print(wt, &work.j, &work.q, &st, objects))
    }

    /// The displayed colours (METHOD §12.1, and the trust step's blend of
    /// §12.5 when it is in use) at the probe's pixels of the recovered J
    /// (before the artifact clamp) with row statistics `st` and filtered
    /// plane `q`: what [`finish`] shows there for this type.
    /// `objects` are the object pixels' power sums of the clamped J when
    /// scoring summed them (else they are summed here).
    fn print(&self, wt: &WaterType, j: &[f32], q: &[f32], st: &RowStats, objects: Option<PowerSums>) -> Option<Print> {
        let Probe { pixels: probe, noise } = self.probe.as_ref()?;
        let clamp = ArtifactClamp::new(st.lo, st.hi);
        let sums = objects.unwrap_or_else(|| self.object_sums(j, Some(&clamp)));
        // each displayed value from the pixel's J: METHOD §8's stretch, or §12.1's gains
        let value: Box<dyn Fn(usize, f32) -> f32> = if self.balance == WhiteBalance::Stretch {
            let sp = self.stretch(j, st);
            Box::new(move |c, x| sp.apply(c, x))
        } else {
            let pct = channel_percentiles(j, self.mask, &[WHITE_PATCH_Q], |_, v| clamp.apply(v));
            let k = self.display_gains(&pct, &sums);
            Box::new(move |c, x| (clamp.apply(x) * k.get(c).copied().unwrap_or(1.0)).clamp(0.0, 1.0))
        };
        let mut shown: Print = probe
            .iter()
            .map(|&i| {
                let v = j.get(3 * i..3 * i + 3).unwrap_or(&[0.0; 3]);
                let mut px = [0f32; 3];
                for (c, (o, &x)) in px.iter_mut().zip(v).enumerate() {
                    *o = value(c, x);
                }
                px
            })
            .collect();
        if self.fallback == Fallback::InputBalance {
            // t_B as finish outputs it (METHOD §7, §12.3)
            let rec = Recovery::new(self.a, &conditioned(wt, self.floor));
            let w = self.img.width;
            let tb_row = |y: usize, row: &mut [f32]| {
                let qr = q.get(y * w..(y + 1) * w).unwrap_or(&[]);
                row.iter_mut().zip(qr).for_each(|(t, &v)| *t = rec.clamp_tb(v));
            };
            blend_samples(&self.img, &|i| self.is_object(i), (self.a, wt), *noise, &tb_row, &sums, probe, &mut shown);
        }
        Some(shown)
    }

    /// The gains of METHOD §12.1 with the exposure folded in, from the
    /// masked-in pixels' [`WHITE_PATCH_Q`] percentile per channel `pct`
    /// and the object pixels' power sums `sums` of the clamped radiance.
    fn display_gains(&self, pct: &[Vec<f64>; 3], sums: &PowerSums) -> [f32; 3] {
        let at = |c: usize| pct.get(c).and_then(|v| v.first()).copied().unwrap_or(1.0);
        let estimate = match self.balance {
            WhiteBalance::GrayWorld => sums.color(1.0),
            WhiteBalance::WhitePatch => [at(0), at(1), at(2)],
            WhiteBalance::ShadesOfGray | WhiteBalance::Stretch => sums.color(SOG_P),
        };
        let gains = gains_from(estimate);
        let top = gains.iter().enumerate().map(|(c, &g)| g * at(c)).fold(0.0f64, f64::max);
        let scale = if top > 0.0 { 1.0 / top } else { 1.0 };
        gains.map(|g| (g * scale) as f32)
    }

    /// The displayed image of METHOD §12.1 from the clamped radiance:
    /// per-channel gains that make the object pixels' color (gray world,
    /// shades of gray) or the masked-in pixels' [`WHITE_PATCH_Q`]
    /// percentile (white patch) gray, then one exposure that maps the
    /// largest balanced channel's [`WHITE_PATCH_Q`] percentile to 1, clipped to
    /// [0, 1]. `sums` are the object pixels' power sums of `radiance`.
    /// The exposure is the display mapping, kept apart from the color
    /// correction: the gains alone set the colors.
    pub(crate) fn balance_image(&self, radiance: &[f32], sums: &PowerSums, spare: Vec<f32>) -> Vec<f32> {
        let pct = channel_percentiles(radiance, self.mask, &[WHITE_PATCH_Q], |_, v| v);
        let k = self.display_gains(&pct, sums);
        // allocated at its size once (or the previous frame's, given back):
        // the memory plan counts one image; every value is written below
        let mut image = reuse(spare, radiance.len());
        image.par_chunks_mut(3).zip(radiance.par_chunks(3)).for_each(|(o, p)| {
            for ((o, &v), &g) in o.iter_mut().zip(p).zip(&k) {
                *o = (v * g).clamp(0.0, 1.0);
            }
        });
        image
    }

    /// The selection statistics of each type in `types` (in order), and the
    /// filtered plane q of the one that [`choose`] picks among them, when
    /// it is known: after each type, only the winner of the types scored
    /// so far can still win (a later type can only make the exclusion
    /// threshold stricter, or win itself; whether t_R differences exist
    /// does not depend on the type), so only its plane is kept.
    /// With a probe, also each type's displayed colours there.
    pub(crate) fn score(&self, types: &[&WaterType], work: &mut Work) -> (Vec<TypeStats>, Option<Kept>, Vec<Option<Print>>) {
        let mut stats = Vec::with_capacity(types.len());
        let mut prints = Vec::with_capacity(types.len());
        let mut kept: Option<Kept> = None;
        for (i, wt) in types.iter().enumerate() {
            let (st, print) = self.evaluate(wt, work);
            stats.push(st);
            prints.push(print);
            if choose(&stats).winner == i {
                let spare = kept.take().map_or_else(|| vec![0.0; work.q.len()], |k| k.q);
                kept = Some(Kept {
                    index: i,
                    q: std::mem::replace(&mut work.q, spare),
                });
            }
        }
        (stats, kept, prints)
    }
}

/// The outputs of the chosen type.
pub(crate) struct Final {
    pub(crate) radiance: Vec<f32>,
    pub(crate) transmission: Vec<f32>,
    pub(crate) image: Vec<f32>,
    pub(crate) stats: TypeStats,
    /// the trust step's confidence and veil excess (METHOD §12.5), with a fallback
    pub(crate) trust: Option<Trust>,
}

/// Restores the image with one water type (METHOD §4-8): the outputs and the
/// type's selection statistics, identical to what the evaluation gave.
/// With `q`, the type's filtered plane kept from its scoring, only the
/// recovery is run again.
pub(crate) fn finish(
    mut shared: Shared<'_>,
    wt: &WaterType,
    mut work: Work,
    q: Option<Vec<f32>>,
    pool: &mut Buffers,
    clock: &mut Clock,
) -> Final {
    let n = shared.img.len();
    let (st, mut transmission) = match q {
        Some(q) if q.len() == n => {
            shared.guide.release_stats();
            if !pool.keep {
                // not read from here on: freed early unless kept
                work.aux = Vec::new();
            }
            work.q = q;
            let mut transmission = reuse_zeroed(std::mem::take(&mut pool.spare.transmission), n);
            let st = shared.recover_from_q(wt, &mut work, Some(&mut transmission));
            clock.lap(Stage::ChosenFromKept);
            (st, transmission)
        }
        _ => {
            let bounds = shared.refine(wt, &mut work);
            clock.lap(Stage::ChosenFirstPass);
            // the guide statistics serve only the first pass
            shared.guide.release_stats();
            let mut transmission = reuse_zeroed(std::mem::take(&mut pool.spare.transmission), n);
            let st = shared.recover(wt, bounds, &mut work, Some(&mut transmission));
            clock.lap(Stage::ChosenSecondPass);
            (st, transmission)
        }
    };
    shared.floor_transmission(wt, &work.q, &mut transmission);
    // METHOD §8's stretch is the display, or only scores the gray-world choice (METHOD §9)
    let display = (shared.balance == WhiteBalance::Stretch).then(|| shared.stretch(&work.j, &st));
    let gray_world = (display.is_none() && shared.choice == TypeChoice::GrayWorld).then(|| shared.type_stats(&work.j, &st).0);
    clock.lap(Stage::ChosenStretch);
    pool.put(std::mem::take(&mut work.aux), std::mem::take(&mut work.q));
    let mut radiance = std::mem::take(&mut work.j);
    let clamp = ArtifactClamp::new(st.lo, st.hi);
    radiance.par_iter_mut().for_each(|v| *v = clamp.apply(*v));
    let (mut image, stats) = match display {
        Some(sp) => {
            let image = sp.limits.map_rgb(&radiance, |v| sp.norm.apply(v));
            let stats = match shared.choice {
                TypeChoice::GrayWorld => {
                    let mut sums = st.sums;
                    sums.channels = shared.channel_sums(&image, None);
                    sums.stats()
                }
                TypeChoice::ShadesOfGray | TypeChoice::Central => TypeStats { score: shared.object_sums(&radiance, None).spread(), tr_diff: None },
            };
            (image, stats)
        }
        None => {
            // METHOD §12.1-12.2: one pass of power sums serves the balance and the choice
            let objects = shared.object_sums(&radiance, None);
            let stats = gray_world.unwrap_or(TypeStats { score: objects.spread(), tr_diff: None });
            (shared.balance_image(&radiance, &objects, std::mem::take(&mut pool.spare.image)), stats)
        }
    };
    // METHOD §12.5: confidence, veil excess and the blend toward the input's balance
    let trust = (shared.fallback == Fallback::InputBalance).then(|| {
        trust(&shared.img, &|i| shared.is_object(i), shared.a, wt, &transmission, &radiance, &mut image, true)
    });
    if pool.keep {
        pool.guide = shared.guide.into_guide();
    }
    clock.lap(Stage::ChosenOutputs);
    Final {
        radiance,
        transmission,
        image,
        stats,
        trust,
    }
}

