//! Method profiles (METHOD §12): named sets of steps. `paper` is the method
//! of METHOD §2-10 as the paper and its reference code define it;
//! `revised` (the default) replaces the display stretch of METHOD §8 by a
//! white balance of the restored radiance on the object pixels
//! (METHOD §12.1) and the gray-world choice of METHOD §9 by the
//! shades-of-gray spread of that radiance (METHOD §12.2). Each step is
//! also a keyword of its own, so steps combine freely.

use crate::error::{Error, Result};
use crate::method::params::Selection;
use crate::method::water::WaterType;

/// A named profile: the default of each step not given explicitly.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// METHOD §2-10 exactly: display stretch, gray world with the t_R rule
    Paper,
    /// METHOD §12: white balance of the radiance, shades-of-gray type choice
    #[default]
    Revised,
}

/// How the restored radiance becomes the displayed image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WhiteBalance {
    /// METHOD §8: global min-max, then per-channel percentile stretch
    Stretch,
    /// METHOD §12.1 with p = 1: channel means over the object pixels
    GrayWorld,
    /// METHOD §12.1 with p = [`SOG_P`]: channel p-norm means over the object pixels
    ShadesOfGray,
    /// METHOD §12.1: the channels' [`WHITE_PATCH_Q`] percentiles over the object pixels
    WhitePatch,
}

/// What is done where the restoration cannot be trusted (METHOD §12.5).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fallback {
    /// nothing: the displayed image is the white balance's (or the stretch's) alone
    None,
    /// the displayed colours blended toward a shades-of-gray balance of the
    /// input where confidence is low, with a confidence map and the
    /// `unreliable` flag (METHOD §12.5)
    InputBalance,
}

impl Fallback {
    /// Every name.
    pub const NAMES: [&'static str; 2] = ["none", "input_balance"];

    /// The name used by both commands, the Python keyword and the sidecar.
    pub fn name(self) -> &'static str {
        match self {
            Fallback::None => "none",
            Fallback::InputBalance => "input_balance",
        }
    }

    /// The fallback called `name`; a parameter error naming the choices.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "none" => Ok(Fallback::None),
            "input_balance" => Ok(Fallback::InputBalance),
            other => Err(unknown("fallback", &Self::NAMES, other)),
        }
    }
}

/// How the water type is chosen among the candidates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TypeChoice {
    /// METHOD §9: gray world of the stretched image, with the t_R exclusion rule
    GrayWorld,
    /// METHOD §12.2: the least chromatic shades-of-gray color of the radiance, no exclusion
    ShadesOfGray,
    /// METHOD §12.2: of the [`CENTRAL_OF`] types that [`TypeChoice::ShadesOfGray`]
    /// scores best, the one whose displayed colours are nearest the others'
    Central,
}

/// How many of the best-scored types the central type choice compares (METHOD §12.2).
pub const CENTRAL_OF: usize = 3;

/// Exponent of the shades-of-gray norm (METHOD §12.1-12.2).
pub const SOG_P: f64 = 4.0;
/// Percentile of the white-patch balance, and of the balanced channels
/// that the display maps to 1 (METHOD §12.1).
pub const WHITE_PATCH_Q: f64 = 0.99;

fn unknown(key: &'static str, names: &[&str], got: &str) -> Error {
    let list: Vec<String> = names.iter().map(|n| format!("{n:?}")).collect();
    Error::Param {
        name: key,
        msg: format!("must be one of {}; got {got:?}", list.join(", ")),
    }
}

impl Method {
    /// Every profile's name, the default first.
    pub const NAMES: [&'static str; 2] = ["revised", "paper"];

    /// The name used by both commands, the Python keyword and the sidecar.
    pub fn name(self) -> &'static str {
        match self {
            Method::Paper => "paper",
            Method::Revised => "revised",
        }
    }

    /// The profile called `name`; a parameter error naming the choices.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "paper" => Ok(Method::Paper),
            "revised" => Ok(Method::Revised),
            other => Err(unknown("method", &Self::NAMES, other)),
        }
    }

    /// The profile's white balance.
    pub fn white_balance(self) -> WhiteBalance {
        match self {
            Method::Paper => WhiteBalance::Stretch,
            Method::Revised => WhiteBalance::ShadesOfGray,
        }
    }

    /// The profile's type choice.
    pub fn type_choice(self) -> TypeChoice {
        match self {
            Method::Paper => TypeChoice::GrayWorld,
            Method::Revised => TypeChoice::Central,
        }
    }

    /// The profile's selection: fast selection agrees with the exhaustive
    /// one under the revised choice on every shared photo and render
    /// measured (benches/profiles.py) and is 2-3x faster at 12 MP.
    pub fn selection(self) -> Selection {
        match self {
            Method::Paper => Selection::Exhaustive,
            Method::Revised => Selection::Fast,
        }
    }

    /// The profile's fallback where the result cannot be trusted (METHOD §12.5).
    pub fn fallback(self) -> Fallback {
        match self {
            Method::Paper => Fallback::None,
            Method::Revised => Fallback::InputBalance,
        }
    }

    /// The profile's haze-line floor: the Jerlov type whose ratios bound
    /// from below those the transmission is estimated with (METHOD §12.3),
    /// None for none.
    pub fn haze_floor(self) -> Option<&'static str> {
        match self {
            Method::Paper => None,
            Method::Revised => Some(REVISED_HAZE_FLOOR),
        }
    }
}

/// The revised profile's haze-line floor (METHOD §12.3).
pub const REVISED_HAZE_FLOOR: &str = "3C";

/// The ratios (beta_BR, beta_BG) the transmission of `wt` is estimated with
/// under the floor `floor` (METHOD §12.3): each at least the floor's. The
/// recovery (METHOD §7) keeps `wt`'s own.
pub fn conditioned(wt: &WaterType, floor: Option<[f64; 2]>) -> WaterType {
    match floor {
        Some([br, bg]) if wt.beta_br < br || wt.beta_bg < bg => WaterType {
            name: wt.name.clone(),
            beta_br: wt.beta_br.max(br),
            beta_bg: wt.beta_bg.max(bg),
        },
        _ => wt.clone(),
    }
}

impl WhiteBalance {
    /// Every name.
    pub const NAMES: [&'static str; 4] = ["stretch", "gray_world", "shades_of_gray", "white_patch"];

    /// The name used by both commands, the Python keyword and the sidecar.
    pub fn name(self) -> &'static str {
        match self {
            WhiteBalance::Stretch => "stretch",
            WhiteBalance::GrayWorld => "gray_world",
            WhiteBalance::ShadesOfGray => "shades_of_gray",
            WhiteBalance::WhitePatch => "white_patch",
        }
    }

    /// The white balance called `name`; a parameter error naming the choices.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "stretch" => Ok(WhiteBalance::Stretch),
            "gray_world" => Ok(WhiteBalance::GrayWorld),
            "shades_of_gray" => Ok(WhiteBalance::ShadesOfGray),
            "white_patch" => Ok(WhiteBalance::WhitePatch),
            other => Err(unknown("white_balance", &Self::NAMES, other)),
        }
    }
}

impl TypeChoice {
    /// Every name.
    pub const NAMES: [&'static str; 3] = ["gray_world", "shades_of_gray", "central"];

    /// The name used by both commands, the Python keyword and the sidecar.
    pub fn name(self) -> &'static str {
        match self {
            TypeChoice::GrayWorld => "gray_world",
            TypeChoice::ShadesOfGray => "shades_of_gray",
            TypeChoice::Central => "central",
        }
    }

    /// The type choice called `name`; a parameter error naming the choices.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "gray_world" => Ok(TypeChoice::GrayWorld),
            "shades_of_gray" => Ok(TypeChoice::ShadesOfGray),
            "central" => Ok(TypeChoice::Central),
            other => Err(unknown("type_choice", &Self::NAMES, other)),
        }
    }
}

/// Power sums over the object pixels (masked-in, not in the water region)
/// that the white balance and the type choice of METHOD §12 need:
/// per channel the sums of v and v^p, and their number. Combined in a
/// fixed order, so the result does not depend on the thread count.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PowerSums {
    /// sum of each channel
    pub s1: [f64; 3],
    /// sum of each channel to the power [`SOG_P`]
    pub sp: [f64; 3],
    /// number of pixels
    pub n: f64,
}

impl PowerSums {
    /// Adds one pixel.
    #[inline]
    pub fn push(&mut self, v: [f32; 3]) {
        for ((s1, sp), v) in self.s1.iter_mut().zip(&mut self.sp).zip(v) {
            let x = f64::from(v.max(0.0));
            *s1 += x;
            let x2 = x * x;
            *sp += x2 * x2;
        }
        self.n += 1.0;
    }

    /// Adds a partial sum.
    pub fn add(&mut self, o: &Self) {
        for ((s1, sp), (o1, op)) in self.s1.iter_mut().zip(&mut self.sp).zip(o.s1.iter().zip(&o.sp)) {
            *s1 += o1;
            *sp += op;
        }
        self.n += o.n;
    }

    /// The per-channel illuminant estimate of METHOD §12.1: means (p = 1)
    /// or p-norm means (p = [`SOG_P`]).
    pub fn color(&self, p: f64) -> [f64; 3] {
        let n = self.n.max(1.0);
        if p == 1.0 {
            self.s1.map(|s| s / n)
        } else {
            self.sp.map(|s| (s / n).powf(1.0 / p))
        }
    }

    /// The type-choice score of METHOD §12.2: the sample standard deviation
    /// of the three shades-of-gray channel values divided by their mean (0
    /// for a gray scene, the same for any exposure); infinite when the
    /// radiance is black.
    pub fn spread(&self) -> f64 {
        let m = self.color(SOG_P);
        let mu = (m[0] + m[1] + m[2]) / 3.0;
        if mu.is_nan() || mu <= 0.0 {
            return f64::INFINITY;
        }
        let var = m.iter().map(|v| (v - mu).powi(2)).sum::<f64>() / 2.0;
        var.sqrt() / mu
    }
}

/// Per-channel gains of METHOD §12.1 from the illuminant estimate `e`:
/// each channel scaled so its estimate becomes the mean of the three
/// (an empty channel keeps gain 1).
pub fn gains_from(e: [f64; 3]) -> [f64; 3] {
    let mu = (e[0] + e[1] + e[2]) / 3.0;
    e.map(|v| if v > 0.0 && mu > 0.0 { mu / v } else { 1.0 })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_bad_names_list_the_choices() {
        for n in Method::NAMES {
            assert_eq!(Method::from_name(n).unwrap().name(), n);
        }
        for n in WhiteBalance::NAMES {
            assert_eq!(WhiteBalance::from_name(n).unwrap().name(), n);
        }
        for n in TypeChoice::NAMES {
            assert_eq!(TypeChoice::from_name(n).unwrap().name(), n);
        }
        let e = Method::from_name("best").unwrap_err().to_string();
        assert!(e.contains("method") && e.contains("\"paper\"") && e.contains("\"best\""), "{e}");
        assert!(WhiteBalance::from_name("auto").is_err() && TypeChoice::from_name("").is_err());
        assert_eq!(Method::default(), Method::Revised);
        assert_eq!(Method::Paper.white_balance(), WhiteBalance::Stretch);
        assert_eq!(Method::Paper.type_choice(), TypeChoice::GrayWorld);
    }

    /// Hand-computed: pixels (1, 2, 0) and (3, 2, 4).
    #[test]
    fn power_sums_give_means_norms_and_spread() {
        let mut s = PowerSums::default();
        s.push([1.0, 2.0, 0.0]);
        s.push([3.0, 2.0, 4.0]);
        assert_eq!(s.color(1.0), [2.0, 2.0, 2.0]);
        let m4 = s.color(SOG_P);
        let want = [((1.0f64 + 81.0) / 2.0).powf(0.25), 2.0, (256.0f64 / 2.0).powf(0.25)];
        for c in 0..3 {
            assert!((m4[c] - want[c]).abs() < 1e-12);
        }
        // a gray scene has no spread, at any exposure
        let mut g = PowerSums::default();
        g.push([0.2, 0.2, 0.2]);
        g.push([0.7, 0.7, 0.7]);
        assert!(g.spread().abs() < 1e-12);
        let mu = want.iter().sum::<f64>() / 3.0;
        let sd = (want.iter().map(|v| (v - mu).powi(2)).sum::<f64>() / 2.0).sqrt();
        assert!((s.spread() - sd / mu).abs() < 1e-12);
        assert_eq!(PowerSums::default().spread(), f64::INFINITY);
        // gains make the estimate gray
        let gn = gains_from([0.1, 0.4, 0.7]);
        let balanced: Vec<f64> = [0.1, 0.4, 0.7].iter().zip(gn).map(|(e, g)| e * g).collect();
        assert!(balanced.iter().all(|v| (v - 0.4).abs() < 1e-12));
        assert_eq!(gains_from([0.0, 0.5, 0.5])[0], 1.0);
    }
}
