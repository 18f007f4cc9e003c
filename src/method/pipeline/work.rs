//! The work buffers of one [`restore`](crate::restore) call: those of the
//! type being evaluated, the row scratch, and the planes a
//! [`Sequence`](crate::Sequence) keeps between frames.

use crate::kernels::util::{reuse, reuse_zeroed};
use std::ops::Range;

/// Row buffers of [`Shared::recover_row`], reused from row to row.
pub(crate) struct RowScratch {
    pub(crate) tr: Vec<f32>,
    pub(crate) tb: Vec<f32>,
    /// all true
    pub(crate) yes: Vec<bool>,
    /// all false
    pub(crate) no: Vec<bool>,
}

impl RowScratch {
    pub(crate) fn new(w: usize) -> Self {
        Self {
            tr: vec![0.0; w],
            tb: vec![0.0; w],
            yes: vec![true; w],
            no: vec![false; w],
        }
    }
}

/// The buffers of the type being evaluated (reused from type to type).
pub(crate) struct Work {
    /// the refined transmission p in the first n entries, then J (3 per pixel)
    pub(crate) j: Vec<f32>,
    /// t_LB and cluster per pixel (METHOD §4-5), then the guided filter's (a, b)
    pub(crate) aux: Vec<[f32; 4]>,
    /// the filtered plane q after the chart fill (METHOD §6): what the
    /// recovery reads, kept so that the chosen type need not be filtered
    /// again ([`Shared::score`])
    pub(crate) q: Vec<f32>,
}

impl Work {
    pub(crate) fn new(n: usize) -> Self {
        Self::from_pool(n, &mut Buffers::default())
    }

    /// The buffers for n pixels, (a, b) and q taken from `pool` when they
    /// have the right length. No pass reads a value of these buffers that
    /// it has not written (the types already share them), so old contents
    /// do not matter.
    pub(crate) fn from_pool(n: usize, pool: &mut Buffers) -> Self {
        Self {
            j: reuse_zeroed(std::mem::take(&mut pool.spare.j), 3 * n),
            aux: reuse(std::mem::take(&mut pool.aux), n),
            q: reuse(std::mem::take(&mut pool.q), n),
        }
    }
}

/// Full-resolution work buffers that a [`crate::method::sequence::Sequence`] keeps
/// from one frame to the next (the guide image, the guided filter's (a, b)
/// and the filtered plane: 32 B per pixel), so that a frame of the same
/// size reuses their pages instead of having the kernel map and zero new
/// ones (METHOD §10, sequence mode). A plain [`restore`](crate::restore) starts from empty buffers and
/// frees each plane as soon as it is no longer read (`keep` false).
#[derive(Debug, Default)]
pub struct Buffers {
    pub(crate) guide: Vec<f32>,
    pub(crate) aux: Vec<[f32; 4]>,
    pub(crate) q: Vec<f32>,
    /// keep the planes at the end of a call (else they are freed as soon as
    /// they are no longer needed)
    pub(crate) keep: bool,
    /// the output planes of a finished restoration, given back for the
    /// next call's outputs ([`Buffers::recycle`])
    pub(crate) spare: Spare,
}

/// Output planes of a [`crate::Restoration`] given back to be written
/// again (zeroed first, so results do not depend on them).
#[derive(Debug, Default)]
pub(crate) struct Spare {
    /// the radiance (J, 3 per pixel), the next call's J
    pub(crate) j: Vec<f32>,
    /// t_B
    pub(crate) transmission: Vec<f32>,
    /// the displayed image (3 per pixel)
    pub(crate) image: Vec<f32>,
}

impl Buffers {
    /// Buffers that keep their planes between calls.
    pub fn kept() -> Self {
        Self { keep: true, ..Self::default() }
    }

    /// Bytes currently held.
    pub fn bytes(&self) -> usize {
        let s = &self.spare;
        4 * (self.guide.len() + 4 * self.aux.len() + self.q.len() + s.j.len() + s.transmission.len() + s.image.len())
    }

    /// Takes back the output planes of a restoration the caller is done
    /// with, so that the next call of the same size makes none (a video or
    /// a pipe of frames in steady state). Only kept buffers take them.
    pub fn recycle(&mut self, res: crate::method::params::Restoration) {
        if self.keep {
            self.spare = Spare { j: res.radiance, transmission: res.transmission, image: res.image };
        }
    }

    /// Takes back the work planes at the end of a call (drops them unless kept).
    pub(crate) fn put(&mut self, aux: Vec<[f32; 4]>, q: Vec<f32>) {
        if self.keep {
            self.aux = aux;
            self.q = q;
        }
    }
}

/// The filtered plane q of a scored type (its index among the scored ones).
pub(crate) struct Kept {
    pub(crate) index: usize,
    pub(crate) q: Vec<f32>,
}

/// Splits a buffer of `row_len` items per row at the row ranges.
pub(crate) fn split_rows<'a, T>(buf: &'a mut [T], row_len: usize, ranges: &[Range<usize>]) -> Vec<&'a mut [T]> {
    crate::kernels::boxsum::split_bands(buf, row_len, ranges)
}

