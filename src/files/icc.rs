//! Inputs tagged with an ICC profile other than sRGB (Adobe RGB (1998),
//! Display P3, a camera's own): their codes are converted to the linear
//! working space the method works in (linear light, sRGB primaries, D65;
//! METHOD §2) with the `moxcms` colour-management engine, one
//! implementation for both commands. sRGB-tagged and untagged inputs keep
//! the sRGB decoding of `color` bit for bit.

use moxcms::{ColorProfile, DataColorSpace, Layout, ProfileText, RenderingIntent, ToneReprCurve, TransformOptions};

/// The distance of a profile's colorants from sRGB's under which it is
/// taken as sRGB (XYZ units; Adobe RGB's green is 0.07 away, P3's red 0.05).
const SRGB_TOLERANCE: f64 = 2e-3;

/// What the profile says it is: its description, else "unnamed".
fn description(p: &ColorProfile) -> String {
    match &p.description {
        Some(ProfileText::PlainString(s)) => s.clone(),
        Some(ProfileText::Localizable(v)) => v.first().map(|l| l.value.clone()).unwrap_or_default(),
        Some(ProfileText::Description(d)) => d.ascii_string.clone(),
        None => String::new(),
    }
    .trim_end_matches('\0')
    .trim()
    .to_string()
}

/// Whether `p` is sRGB: its colorants within [`SRGB_TOLERANCE`] of sRGB's
/// (a profile that says "sRGB" with other primaries is not). Its curves
/// are judged apart ([`srgb_curves`]).
fn is_srgb(p: &ColorProfile) -> bool {
    let s = ColorProfile::new_srgb();
    let near = |a: &moxcms::Xyzd, b: &moxcms::Xyzd| {
        (a.x - b.x).abs() < SRGB_TOLERANCE && (a.y - b.y).abs() < SRGB_TOLERANCE && (a.z - b.z).abs() < SRGB_TOLERANCE
    };
    near(&p.red_colorant, &s.red_colorant) && near(&p.green_colorant, &s.green_colorant) && near(&p.blue_colorant, &s.blue_colorant)
}

/// Whether the profile `icc` maps sRGB codes to themselves: a ramp of
/// grays and of each primary, converted to sRGB, within a code and a half
/// of 8-bit of where it started. sRGB's primaries with a gamma of 1 or 4
/// (a linear camera profile) are not sRGB, and decoding them as sRGB
/// would bend every tone without a word.
fn srgb_curves(icc: &[u8]) -> bool {
    let steps = 17;
    let mut ramp = Vec::with_capacity(steps * 12);
    for k in 0..steps {
        let v = k as f32 / (steps - 1) as f32;
        ramp.extend_from_slice(&[v, v, v, v, 0.0, 0.0, 0.0, v, 0.0, 0.0, 0.0, v]);
    }
    let mut out = ramp.clone();
    convert(icc, &mut out, false).is_ok() && out.iter().zip(&ramp).all(|(a, b)| (a - b).abs() <= 1.5 / 255.0)
}

/// The working space: sRGB primaries and white, linear (gamma 1) curves.
fn linear_srgb() -> ColorProfile {
    let mut p = ColorProfile::new_srgb();
    let linear = ToneReprCurve::Parametric(vec![1.0]);
    p.red_trc = Some(linear.clone());
    p.green_trc = Some(linear.clone());
    p.blue_trc = Some(linear);
    p.cicp = None;
    p
}

/// The result of looking at an input's profile.
#[derive(Debug, Clone, PartialEq)]
pub enum Profile {
    /// sRGB (or no profile): decode as sRGB
    Srgb(String),
    /// another profile: convert with [`convert`]
    Other(String),
    /// a profile that cannot be read: decoded as sRGB, with the reason
    Unreadable(String),
}

/// Classifies the ICC profile `icc` of an input. A profile whose data are
/// not RGB (Lab, gray, CMYK) cannot describe the RGB codes decoded and is
/// unreadable for them: the codes are read as sRGB, with the reason.
pub fn classify(icc: &[u8]) -> Profile {
    match ColorProfile::new_from_slice(icc) {
        Ok(p) if p.color_space != DataColorSpace::Rgb => Profile::Unreadable(format!(
            "its colour space is {:?}, not RGB; ignored",
            p.color_space
        )),
        Ok(p) if is_srgb(&p) && srgb_curves(icc) => Profile::Srgb(description(&p)),
        Ok(p) => Profile::Other(description(&p)),
        Err(e) => Profile::Unreadable(format!("{e:?}")),
    }
}

/// Converts interleaved RGB codes (`values` in [0, 1]: codes / (2^bits - 1))
/// from the profile `icc` to the working space, in place: linear when
/// `linear`, else sRGB-encoded (`--preprocess reference`, which keeps the
/// sRGB values). Values outside the sRGB gamut are clipped to [0, 1].
///
/// A profile whose transform gives non-numbers, or maps an image that is
/// not constant to one colour, is broken: an error, and `values` are then
/// partly converted (the caller reads its codes as sRGB instead).
///
/// The values are converted a block of pixels at a time through a small
/// copy, not through a copy of the whole image: the decode phase of the
/// memory plan (`files::budget`) holds the codes and these values only.
pub fn convert(icc: &[u8], values: &mut [f32], linear: bool) -> Result<(), String> {
    let src = ColorProfile::new_from_slice(icc).map_err(|e| format!("the ICC profile cannot be read: {e:?}"))?;
    let dst = if linear { linear_srgb() } else { ColorProfile::new_srgb() };
    let options = TransformOptions {
        rendering_intent: RenderingIntent::RelativeColorimetric,
        prefer_fixed_point: false,
        ..TransformOptions::default()
    };
    let t = src
        .create_transform_f32(Layout::Rgb, &dst, Layout::Rgb, options)
        .map_err(|e| format!("no transform from the ICC profile {:?}: {e:?}", description(&src)))?;
    let clip = |p: &[f32]| {
        let mut c = [0f32; 3];
        c.iter_mut().zip(p).for_each(|(c, &v)| *c = v.clamp(0.0, 1.0));
        c
    };
    // the first pixel before and after, and whether any other differs from it
    let (mut first_in, mut first_out) = (None, None);
    let (mut input_varies, mut output_varies) = (false, false);
    let mut block = Vec::with_capacity(BLOCK_VALUES.min(values.len()));
    for chunk in values.chunks_mut(BLOCK_VALUES) {
        block.clear();
        block.extend_from_slice(chunk);
        for p in block.chunks_exact(3) {
            let c = clip(p);
            match first_in {
                None => first_in = Some(c),
                Some(f) => input_varies |= c != f,
            }
        }
        t.transform(&block, chunk).map_err(|e| format!("ICC transform: {e:?}"))?;
        if chunk.iter().any(|v| !v.is_finite()) {
            return Err("the ICC profile's transform gives non-numbers; ignored".into());
        }
        for p in chunk.chunks_exact(3) {
            let c = clip(p);
            match first_out {
                None => first_out = Some(c),
                Some(f) => output_varies |= c != f,
            }
        }
    }
    if input_varies && !output_varies {
        return Err("the ICC profile maps every pixel to one colour; ignored".into());
    }
    for v in values.iter_mut() {
        *v = v.clamp(0.0, 1.0);
    }
    Ok(())
}

/// Values (a multiple of 3: whole pixels) converted at a time by [`convert`].
const BLOCK_VALUES: usize = 3 * 16384;

#[cfg(test)]
mod tests {
    use super::*;

    fn encoded(p: ColorProfile) -> Vec<u8> {
        p.encode().unwrap()
    }

    #[test]
    fn srgb_is_recognised_and_others_are_not() {
        assert!(matches!(classify(&encoded(ColorProfile::new_srgb())), Profile::Srgb(_)));
        assert!(matches!(classify(&encoded(ColorProfile::new_adobe_rgb())), Profile::Other(_)));
        assert!(matches!(classify(&encoded(ColorProfile::new_display_p3())), Profile::Other(_)));
        assert!(matches!(classify(b"not a profile"), Profile::Unreadable(_)));
    }

    #[test]
    fn srgb_primaries_with_another_curve_are_not_srgb() {
        // sRGB's colorants with gamma 1 or 4: converted, not decoded as sRGB
        for gamma in [1.0f32, 4.0] {
            let mut p = ColorProfile::new_srgb();
            let curve = ToneReprCurve::Parametric(vec![gamma]);
            p.red_trc = Some(curve.clone());
            p.green_trc = Some(curve.clone());
            p.blue_trc = Some(curve);
            p.cicp = None;
            let icc = encoded(p);
            assert!(matches!(classify(&icc), Profile::Other(_)), "gamma {gamma}");
            // its mid gray is linear 0.5^gamma, not sRGB's 0.214
            let mut v = vec![0.5, 0.5, 0.5];
            convert(&icc, &mut v, true).unwrap();
            assert!(v.iter().all(|x| (x - 0.5f32.powf(gamma)).abs() < 2e-3), "{v:?}");
        }
        // sRGB's parametric curve written out is still sRGB
        let mut p = ColorProfile::new_srgb();
        p.cicp = None;
        assert!(matches!(classify(&encoded(p)), Profile::Srgb(_)));
    }

    #[test]
    fn adobe_rgb_primaries_land_where_the_matrices_put_them() {
        // Adobe RGB (1998) pure green is outside sRGB: clipped to (0, 1, 0);
        // its white is white; its mid gray (gamma 563/256) is linear 0.5^2.199
        let icc = encoded(ColorProfile::new_adobe_rgb());
        let mut v = vec![0.0, 1.0, 0.0, 1.0, 1.0, 1.0, 0.5, 0.5, 0.5];
        convert(&icc, &mut v, true).unwrap();
        assert!(v[0] < 1e-3 && (v[1] - 1.0).abs() < 1e-3 && v[2] < 1e-3, "{v:?}");
        assert!(v[3..6].iter().all(|x| (x - 1.0).abs() < 2e-3), "{v:?}");
        let gray = 0.5f32.powf(563.0 / 256.0);
        assert!(v[6..9].iter().all(|x| (x - gray).abs() < 2e-3), "{v:?} vs {gray}");
        // Adobe red (R=1) in linear sRGB: X,Y,Z of Adobe red through sRGB's inverse matrix
        let mut r = vec![1.0, 0.0, 0.0];
        convert(&icc, &mut r, true).unwrap();
        assert!(r[0] > 0.99 && r[1] < 1e-3 && r[2] < 1e-3, "{r:?}");
    }

    #[test]
    fn block_by_block_is_the_whole_image_at_once() {
        // a few blocks and a part block: the values of one transform of the whole, bit for bit
        let icc = encoded(ColorProfile::new_display_p3());
        let n = 3 * (2 * BLOCK_VALUES / 3 + 1001);
        let v0: Vec<f32> = (0..n).map(|i| ((i * 7919) % 1000) as f32 / 999.0).collect();
        let mut v = v0.clone();
        convert(&icc, &mut v, true).unwrap();
        let src = ColorProfile::new_from_slice(&icc).unwrap();
        let options = TransformOptions {
            rendering_intent: RenderingIntent::RelativeColorimetric,
            prefer_fixed_point: false,
            ..TransformOptions::default()
        };
        let t = src.create_transform_f32(Layout::Rgb, &linear_srgb(), Layout::Rgb, options).unwrap();
        let mut whole = vec![0.0f32; n];
        t.transform(&v0, &mut whole).unwrap();
        let whole: Vec<f32> = whole.iter().map(|x| x.clamp(0.0, 1.0)).collect();
        assert!(v.iter().zip(&whole).all(|(a, b)| a.to_bits() == b.to_bits()));
        // a constant image stays a valid conversion (not "every pixel to one colour")
        let mut gray = vec![0.5f32; n];
        assert!(convert(&icc, &mut gray, true).is_ok());
    }
}
