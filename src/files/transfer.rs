//! Transfer curves of video and raw-frame samples (docs/OUTPUTS.md
//! "Videos and raw frames"): the code values of a video frame are the
//! camera's transfer curve (its OETF) applied to linear light, so they are
//! undone before the restoration (whose model, METHOD §0, holds on linear
//! light) and applied again to the restored frame, which then shows what
//! the camera would have recorded without the water.
//!
//! Decoding goes through a table of every code (256 or 65536 entries);
//! encoding through a table of the curve over sqrt(L) in 4096 steps,
//! linearly interpolated, within 0.1 of a 16-bit code of the exact curve
//! (a test), at a cost of one square root a sample. The pure powers, whose
//! slope is infinite at black, are computed exactly instead.

use rayon::prelude::*;

/// BT.2020's alpha and beta of the BT.709 curve (see [`Transfer::Bt709`]).
const ALPHA: f64 = 1.099_296_826_809_44;
const BETA: f64 = 0.018_053_968_510_807;

/// A transfer curve: linear light L in [0, 1] to a code value V in [0, 1].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Transfer {
    /// ITU-R BT.709 (the same curve as BT.601, SMPTE 170M and BT.2020 at
    /// 10 and 12 bits): V = 4.5 L below L = beta, else alpha L^0.45 - (alpha - 1),
    /// with BT.2020's exact alpha = 1.0992968 and beta = 0.0180540, which
    /// join the two pieces without a step (BT.709's rounded 1.099 and 0.018
    /// leave one of 2.4e-4, 16 codes at 16 bits)
    Bt709,
    /// IEC 61966-2-1 (sRGB): V = 12.92 L below L = 0.0031308, else 1.055 L^(1/2.4) - 0.055
    Srgb,
    /// a pure power 1/2.2 (BT.470 M)
    Gamma22,
    /// a pure power 1/2.8 (BT.470 BG)
    Gamma28,
    /// V = L
    Linear,
}

impl Transfer {
    /// The curve named as on the command line (`--transfer`).
    pub fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "bt709" => Transfer::Bt709,
            "srgb" => Transfer::Srgb,
            "gamma22" => Transfer::Gamma22,
            "gamma28" => Transfer::Gamma28,
            "linear" => Transfer::Linear,
            _ => return None,
        })
    }

    /// The curve a video stream's transfer tag names (FFmpeg's names of
    /// H.273's transfer characteristics): Ok(None) when the tag says
    /// nothing (unspecified, reserved), an error naming a curve that is
    /// not read (HDR: PQ, HLG; log curves).
    pub fn from_tag(tag: &str) -> Result<Option<Self>, String> {
        // FFmpeg spells them bt2020-10 and iec61966-2-1, PyAV BT2020_10 and IEC61966_2_1
        let norm = tag.trim().to_ascii_lowercase().replace('_', "-");
        Ok(Some(match norm.as_str() {
            "bt709" | "smpte170m" | "bt2020-10" | "bt2020-12" | "bt2020-10bit" | "bt2020-12bit" | "bt1361e"
            | "bt1361" | "bt1361-ecg" | "smpte240m" => Transfer::Bt709,
            "iec61966-2-1" | "iec61966-2-4" => Transfer::Srgb,
            "bt470m" | "gamma22" => Transfer::Gamma22,
            "bt470bg" | "gamma28" => Transfer::Gamma28,
            "linear" => Transfer::Linear,
            "" | "unknown" | "unspecified" | "reserved" | "reserved0" => return Ok(None),
            _ => {
                let other = tag.trim();
                return Err(format!(
                    "the stream's transfer curve {other} is not read (HDR and log curves are not): give \
                     --transfer to say how its samples are to be read"
                ))
            }
        }))
    }

    /// The name `--transfer` takes and the sidecar records.
    pub fn name(self) -> &'static str {
        match self {
            Transfer::Bt709 => "bt709",
            Transfer::Srgb => "srgb",
            Transfer::Gamma22 => "gamma22",
            Transfer::Gamma28 => "gamma28",
            Transfer::Linear => "linear",
        }
    }

    /// Linear light of a code value `v` in [0, 1] (the inverse OETF).
    pub fn to_linear(self, v: f64) -> f64 {
        let v = v.clamp(0.0, 1.0);
        match self {
            Transfer::Bt709 if v < 4.5 * BETA => v / 4.5,
            Transfer::Bt709 => ((v + ALPHA - 1.0) / ALPHA).powf(1.0 / 0.45),
            Transfer::Srgb if v <= 0.04045 => v / 12.92,
            Transfer::Srgb => ((v + 0.055) / 1.055).powf(2.4),
            Transfer::Gamma22 => v.powf(2.2),
            Transfer::Gamma28 => v.powf(2.8),
            Transfer::Linear => v,
        }
    }

    /// The code value of linear light `l` in [0, 1] (the OETF).
    pub fn from_linear(self, l: f64) -> f64 {
        let l = l.clamp(0.0, 1.0);
        match self {
            Transfer::Bt709 if l < BETA => 4.5 * l,
            Transfer::Bt709 => ALPHA * l.powf(0.45) - (ALPHA - 1.0),
            Transfer::Srgb if l <= 0.003_130_8 => 12.92 * l,
            Transfer::Srgb => 1.055 * l.powf(1.0 / 2.4) - 0.055,
            Transfer::Gamma22 => l.powf(1.0 / 2.2),
            Transfer::Gamma28 => l.powf(1.0 / 2.8),
            Transfer::Linear => l,
        }
    }
}

/// Steps of the encoding table over sqrt(L).
const STEPS: usize = 4096;

/// Code values to linear light and back for one curve and sample depth:
/// the tables are made once and reused frame after frame.
#[derive(Debug, Clone)]
pub struct Codec {
    transfer: Transfer,
    /// 8 or 16
    bits: u32,
    /// linear light of every code
    decode: Vec<f32>,
    /// the code value (scaled to the largest code) at sqrt(L) = i / STEPS
    encode: Vec<f32>,
}

impl Codec {
    /// The tables of `transfer` for `bits` (8 or 16) a sample.
    pub fn new(transfer: Transfer, bits: u32) -> Self {
        let top = if bits <= 8 { 255.0 } else { 65535.0 };
        let codes = if bits <= 8 { 256 } else { 65536 };
        Self {
            transfer,
            bits: if bits <= 8 { 8 } else { 16 },
            decode: (0..codes).map(|c| transfer.to_linear(f64::from(c as u32) / top) as f32).collect(),
            encode: (0..=STEPS)
                .map(|i| {
                    let s = i as f64 / STEPS as f64;
                    (transfer.from_linear(s * s) * top) as f32
                })
                .collect(),
        }
    }

    /// The curve.
    pub fn transfer(&self) -> Transfer {
        self.transfer
    }

    /// Bits a sample: 8 or 16.
    pub fn bits(&self) -> u32 {
        self.bits
    }

    /// Linear light of 8-bit codes, into `out` (same length).
    pub fn decode_u8(&self, codes: &[u8], out: &mut [f32]) {
        out.par_chunks_mut(1 << 14).zip(codes.par_chunks(1 << 14)).for_each(|(o, c)| {
            for (o, &c) in o.iter_mut().zip(c) {
                *o = self.decode.get(usize::from(c)).copied().unwrap_or(0.0);
            }
        });
    }

    /// Linear light of 16-bit codes, into `out` (same length); with an
    /// 8-bit codec the codes' top byte is used.
    pub fn decode_u16(&self, codes: &[u16], out: &mut [f32]) {
        let shift = if self.bits == 8 { 8 } else { 0 };
        out.par_chunks_mut(1 << 14).zip(codes.par_chunks(1 << 14)).for_each(|(o, c)| {
            for (o, &c) in o.iter_mut().zip(c) {
                *o = self.decode.get(usize::from(c >> shift)).copied().unwrap_or(0.0);
            }
        });
    }

    /// The code value of linear light `l`, scaled to the largest code, not rounded.
    #[inline]
    fn code(&self, l: f32) -> f32 {
        let l = if l.is_nan() { 0.0 } else { l.clamp(0.0, 1.0) };
        if matches!(self.transfer, Transfer::Gamma22 | Transfer::Gamma28) {
            return (self.transfer.from_linear(f64::from(l)) * if self.bits == 8 { 255.0 } else { 65535.0 }) as f32;
        }
        let x = l.sqrt() * STEPS as f32;
        let i = (x as usize).min(STEPS - 1);
        let f = x - i as f32;
        // the table has STEPS + 1 entries
        match self.encode.get(i..i + 2) {
            Some(&[lo, hi]) => lo + f * (hi - lo),
            _ => 0.0,
        }
    }

    /// 8-bit codes of linear light (rounded to nearest), into `out`.
    pub fn encode_u8(&self, linear: &[f32], out: &mut [u8]) {
        let k = if self.bits == 8 { 1.0 } else { 255.0 / 65535.0 };
        out.par_chunks_mut(1 << 14).zip(linear.par_chunks(1 << 14)).for_each(|(o, l)| {
            for (o, &l) in o.iter_mut().zip(l) {
                *o = (self.code(l) * k + 0.5) as u8;
            }
        });
    }

    /// 16-bit codes of linear light (rounded to nearest), into `out`.
    pub fn encode_u16(&self, linear: &[f32], out: &mut [u16]) {
        let k = if self.bits == 8 { 65535.0 / 255.0 } else { 1.0 };
        out.par_chunks_mut(1 << 14).zip(linear.par_chunks(1 << 14)).for_each(|(o, l)| {
            for (o, &l) in o.iter_mut().zip(l) {
                *o = (self.code(l) * k + 0.5) as u16;
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: [Transfer; 5] = [Transfer::Bt709, Transfer::Srgb, Transfer::Gamma22, Transfer::Gamma28, Transfer::Linear];

    #[test]
    fn curves_against_their_published_values() {
        // BT.709: the two pieces meet without a step; 18% gray is
        // V = 1.0992968 * 0.18^0.45 - 0.0992968 = 0.408848 (with 1.099 and 0.099: 0.409005)
        let b = Transfer::Bt709;
        assert!((4.5 * BETA - (ALPHA * BETA.powf(0.45) - (ALPHA - 1.0))).abs() < 1e-9);
        assert!((b.from_linear(0.18) - 0.408_848).abs() < 1e-6);
        assert!((b.to_linear(0.408_848) - 0.18).abs() < 1e-5);
        // sRGB: code 128 of 255 is L = 0.21586
        assert!((Transfer::Srgb.to_linear(128.0 / 255.0) - 0.215_861).abs() < 1e-5);
        assert!((Transfer::Gamma22.to_linear(0.5) - 0.5f64.powf(2.2)).abs() < 1e-12);
        for t in ALL {
            assert_eq!(t.to_linear(0.0), 0.0, "{t:?}");
            assert!((t.to_linear(1.0) - 1.0).abs() < 1e-12 && (t.from_linear(1.0) - 1.0).abs() < 1e-12, "{t:?}");
            for i in 0..=100 {
                let v = f64::from(i) / 100.0;
                assert!((t.from_linear(t.to_linear(v)) - v).abs() < 1e-9, "{t:?} {v}");
            }
        }
    }

    #[test]
    fn tags_name_curves_and_refuse_hdr() {
        assert_eq!(Transfer::from_tag("smpte170m"), Ok(Some(Transfer::Bt709)));
        assert_eq!(Transfer::from_tag("iec61966-2-1"), Ok(Some(Transfer::Srgb)));
        assert_eq!(Transfer::from_tag("IEC61966_2_1"), Ok(Some(Transfer::Srgb)));
        assert_eq!(Transfer::from_tag("BT2020_10"), Ok(Some(Transfer::Bt709)));
        assert_eq!(Transfer::from_tag("unknown"), Ok(None));
        let e = Transfer::from_tag("smpte2084").unwrap_err();
        assert!(e.contains("smpte2084") && e.contains("--transfer"), "{e}");
        for t in ALL {
            assert_eq!(Transfer::parse(t.name()), Some(t));
        }
    }

    #[test]
    fn every_code_survives_decoding_and_encoding() {
        for t in ALL {
            let c16 = Codec::new(t, 16);
            let codes: Vec<u16> = (0..=65535u16).collect();
            let mut lin = vec![0f32; codes.len()];
            c16.decode_u16(&codes, &mut lin);
            let mut back = vec![0u16; codes.len()];
            c16.encode_u16(&lin, &mut back);
            // f32 linear light holds a 16-bit code within one step near the top
            let worst = codes.iter().zip(&back).map(|(a, b)| (i32::from(*a) - i32::from(*b)).abs()).max();
            assert!(worst <= Some(1), "{t:?}: {worst:?}");
            let c8 = Codec::new(t, 8);
            let codes: Vec<u8> = (0..=255u8).collect();
            let mut lin = vec![0f32; 256];
            c8.decode_u8(&codes, &mut lin);
            let mut back = vec![0u8; 256];
            c8.encode_u8(&lin, &mut back);
            assert_eq!(back, codes, "{t:?}");
        }
    }

    #[test]
    fn the_encoding_table_is_within_a_tenth_of_a_code() {
        for t in ALL {
            let c = Codec::new(t, 16);
            let worst = (0..200_000)
                .map(|i| {
                    let l = (f64::from(i) / 200_000.0).powi(3);
                    (f64::from(c.code(l as f32)) - t.from_linear(f64::from(l as f32)) * 65535.0).abs()
                })
                .fold(0.0, f64::max);
            assert!(worst < 0.1, "{t:?}: {worst}");
        }
        // out-of-range light is clipped, NaN is black
        let c = Codec::new(Transfer::Bt709, 8);
        let mut out = [0u8; 3];
        c.encode_u8(&[-1.0, 2.0, f32::NAN], &mut out);
        assert_eq!(out, [0, 255, 0]);
    }
}
