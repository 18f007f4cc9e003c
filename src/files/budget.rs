//! The memory plan of one input through a command, computed from the
//! image header before anything large is allocated (`--max-memory`); what
//! the machine can give is `crate::kernels::memory`.
//!
//! Phases and what is alive in each (n = input pixels after orientation,
//! m = pixels after `--max-side`, b = decoded bytes per pixel):
//!
//! | phase | bytes |
//! |---|---|
//! | decode | `b n` decoded + `b n` rotated copy (EXIF orientation) or RGB conversion + `12 n` f32 (while the RGB buffer is alive) |
//! | reference stretch | `12 n` in + `12 n` out + `4 n` one channel's percentile copy |
//! | downscale | `12 n` + `12 m` |
//! | restore | `12 m` input + `params::memory_estimate(h, w, k)` + the sphere index (`64` bytes a point) |
//! | write | `12 m` input + the restoration (`33 m`) + the four outputs' codes and encoded files, encoded at once (`22 m`) + the photo's metadata carried (`18 m`: three copies of its encoding; `b n`: the input file read again, `crate::files::metadata`) + the allocator's slack (`8 m`) |
//!
//! plus `n` bytes per mask given (`--mask`, `--water-mask`; read once per run)
//! and `2 m` for their downscaled copies. The plan is the largest phase.
//!
//! The batch and stream loops decode and restore an input while the
//! previous one's outputs are written (`crate::cli::run`); that one holds
//! `69 m'` bytes (its restoration, encoders and metadata, `m'` its pixels) until it
//! is written. An input whose plan does not fit in `--max-memory` beside
//! them waits until they are written, so the two together stay within the
//! budget and an input is refused only if its own plan exceeds it.
//!
//! `--max-memory` bounds the process's peak resident memory: the plan is
//! added to [`process_base`](crate::kernels::memory::process_base), what the process holds before its first
//! input (code, libraries, the Python interpreter) plus [`SLACK`](crate::kernels::memory::SLACK).

use crate::method::params::memory_estimate;

/// Bytes per processed pixel an input holds while its outputs are written:
/// the restoration (33: the image and the radiance, t_B, the confidence
/// map, the water mask), the four outputs' codes and encoded files, all
/// four encoded at once (22: 6, 4, 6 and 4, and PNG's slack),
/// and carrying the metadata ([`METADATA_PER_PIXEL`], with the input file
/// read again: at most 6 bytes a pixel for an uncompressed 16-bit file),
/// and [`ALLOCATOR_SLACK`].
pub const HELD_WHILE_WRITING: u64 = 33 + 22 + METADATA_PER_PIXEL + 6 + ALLOCATOR_SLACK;

/// Bytes per pixel that the allocator keeps resident after the encoders
/// free their buffers (glibc returns them to the system late): counted so
/// that the next input of a stream does not start beside them too early.
pub const ALLOCATOR_SLACK: u64 = 8;

/// Bytes per processed pixel of carrying the metadata into the corrected
/// photo (`crate::files::metadata::carry`): the encoded photo and up to two copies
/// (TIFF: the file and its tags read back and rewritten), each at most 6
/// bytes a pixel (16-bit, uncompressed).
pub const METADATA_PER_PIXEL: u64 = 18;

/// Everything the plan needs to know, from the header and the options.
#[derive(Debug, Clone, Copy)]
pub struct Plan {
    /// rows after orientation
    pub height: usize,
    /// columns after orientation
    pub width: usize,
    /// bytes per decoded pixel (e.g. 3 for 8-bit RGB, 8 for 16-bit RGBA)
    pub decoded_bpp: u64,
    /// whether the decoded buffer is already interleaved RGB (no conversion copy)
    pub decoded_is_rgb: bool,
    /// whether EXIF orientation needs a rotated copy
    pub oriented: bool,
    /// `--max-side` block size (1 = none)
    pub factor: usize,
    /// METHOD §2 reference stretch
    pub reference: bool,
    /// masks given (0, 1 or 2)
    pub masks: u8,
    /// bytes per processed pixel a command holds while writing beyond the
    /// binary's `HELD_WHILE_WRITING` (the Python command: 16, its display
    /// copy of the image and Pillow's copy of the codes)
    pub write_extra: u64,
    /// bytes of the sphere index and haze-line state (`--sphere-points`,
    /// `crate::method::sphere::index_bytes`), alive while restoring
    pub index: u64,
}

impl Plan {
    /// The processed size after `--max-side`.
    pub fn processed(&self) -> (usize, usize) {
        let s = self.factor.max(1);
        (self.height.div_ceil(s), self.width.div_ceil(s))
    }

    /// Peak bytes of the largest phase (see the module documentation).
    pub fn bytes(&self) -> u64 {
        let n = (self.height as u64).saturating_mul(self.width as u64);
        let (h, w) = self.processed();
        let m = (h as u64).saturating_mul(w as u64);
        let mul = |a: u64, b: u64| a.saturating_mul(b);
        let decoded = mul(self.decoded_bpp, n);
        let second = if self.oriented || !self.decoded_is_rgb {
            decoded
        } else {
            0
        };
        let decode = decoded.saturating_add(second).saturating_add(mul(12, n));
        let scale = if self.factor > 1 {
            mul(12, n).saturating_add(mul(12, m))
        } else {
            0
        };
        let reference = if self.reference { mul(28, n) } else { 0 };
        let restore = mul(12, m).saturating_add(memory_estimate(h, w, self.masks > 0)).saturating_add(self.index);
        let write = mul((12 + HELD_WHILE_WRITING).saturating_add(self.write_extra), m).saturating_add(decoded);
        let masks = u64::from(self.masks);
        let mask = mul(masks, n).saturating_add(mul(masks, m));
        [decode, scale, reference, restore, write]
            .into_iter()
            .max()
            .unwrap_or(0)
            .saturating_add(mask)
    }

    #[cfg(any(test, feature = "internals"))]
    /// The plan of an 8-bit RGB file of `height` x `width` pixels, upright,
    /// with no `--max-side`, reference preprocessing or masks.
    pub fn rgb8(height: usize, width: usize) -> Plan {
        Plan {
            height,
            width,
            decoded_bpp: 3,
            decoded_is_rgb: true,
            oriented: false,
            factor: 1,
            reference: false,
            masks: 0,
            write_extra: 0,
            index: crate::method::sphere::index_bytes(crate::method::params::Params::default().sphere_points),
        }
    }
}


#[cfg(test)]
mod tests {
    use super::*;

    fn plan(h: usize, w: usize) -> Plan {
        Plan::rgb8(h, w)
    }

    #[test]
    fn the_largest_phase_is_the_plan_and_downscaling_shrinks_it() {
        let p = plan(1000, 1000);
        // at 1 MP the restore phase (12 n + the method's estimate) and the
        // write phase ((12 + HELD_WHILE_WRITING) n + the 3 n decoded) are close
        let restore = 12_000_000 + memory_estimate(1000, 1000, false) + p.index;
        let write = (12 + HELD_WHILE_WRITING) * 1_000_000 + 3_000_000;
        assert_eq!(p.bytes(), restore.max(write));
        let small = Plan { factor: 4, ..p };
        assert_eq!(small.processed(), (250, 250));
        // with the image shrunk 4x the decode phase dominates: 3 n + 12 n
        assert!(small.bytes() >= 15_000_000 && small.bytes() < p.bytes());
    }

    #[test]
    fn a_million_sphere_points_are_in_the_plan_whatever_the_size() {
        // 64 x 64 pixels: the method's buffers are some 360 kB, the index of
        // 1,000,000 points 64 MB (measured 53 MB); the restore phase holds both
        let p = Plan { index: crate::method::sphere::index_bytes(1_000_000), ..plan(64, 64) };
        assert_eq!(p.index, 64_000_000);
        assert_eq!(p.bytes(), 12 * 4096 + memory_estimate(64, 64, false) + 64_000_000);
    }

    #[test]
    fn absurd_headers_saturate_instead_of_overflowing() {
        let p = Plan {
            decoded_bpp: 8,
            ..plan(usize::MAX, usize::MAX)
        };
        assert_eq!(p.bytes(), u64::MAX);
    }
}
