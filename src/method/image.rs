//! Validated image and mask views (METHOD §2): shape, value and mask checks.

use crate::error::{Error, Result};
use rayon::prelude::*;

/// The smallest image side accepted: the method needs neighbourhoods
/// (guided-filter windows, 3x3 Sobel and noise kernels).
pub const MIN_SIDE: usize = 4;

/// A borrowed linear RGB image, H x W x 3, row-major, interleaved, f32.
#[derive(Debug, Clone, Copy)]
pub struct ImageRef<'a> {
    /// rows
    pub height: usize,
    /// columns
    pub width: usize,
    /// `height * width * 3` values
    pub data: &'a [f32],
}

impl<'a> ImageRef<'a> {
    /// Wraps `data` as an image after checking its length and minimum size.
    /// Values are checked separately by [`ImageRef::validate_values`].
    pub fn new(data: &'a [f32], height: usize, width: usize) -> Result<Self> {
        if height == 0 || width == 0 {
            return Err(Error::Shape(format!(
                "image is empty ({height}x{width} pixels)"
            )));
        }
        let n = height
            .checked_mul(width)
            .and_then(|n| n.checked_mul(3))
            .ok_or_else(|| {
                Error::Shape(format!(
                    "{height}x{width} pixels overflows the address space"
                ))
            })?;
        if data.len() != n {
            return Err(Error::Shape(format!(
                "{} values given for a {height}x{width}x3 image ({n} needed)",
                data.len()
            )));
        }
        if height < MIN_SIDE || width < MIN_SIDE {
            return Err(Error::TooSmall {
                height,
                width,
                min: MIN_SIDE,
            });
        }
        Ok(Self {
            height,
            width,
            data,
        })
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.height * self.width
    }

    /// Always false for a constructed image (kept for clippy's len/is_empty pair).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The color of pixel `i` (raster index); black for an index past the
    /// end (a caller's bug, never reached from valid input: no panic path).
    #[inline]
    pub fn px(&self, i: usize) -> [f32; 3] {
        match self.data.get(3 * i..3 * i + 3) {
            Some(&[r, g, b]) => [r, g, b],
            _ => [0.0; 3],
        }
    }

    /// Every value finite and in [0, 1], and the image not constant (METHOD §2).
    /// The first offending value in raster order is reported.
    pub fn validate_values(&self) -> Result<()> {
        let w = self.width;
        let bad = self
            .data
            .par_chunks(3 * w)
            .enumerate()
            .find_map_first(|(row, vals)| {
                vals.iter().enumerate().find_map(|(j, &v)| {
                    let (col, channel) = (j / 3, j % 3);
                    if !v.is_finite() {
                        Some(Error::NonFinite {
                            value: v,
                            row,
                            col,
                            channel,
                        })
                    } else if !(0.0..=1.0).contains(&v) {
                        Some(Error::OutOfRange {
                            value: v,
                            row,
                            col,
                            channel,
                        })
                    } else {
                        None
                    }
                })
            });
        if let Some(e) = bad {
            return Err(e);
        }
        let first = self.data.first().copied().unwrap_or(0.0);
        if self.data.par_iter().all(|&v| v == first) {
            return Err(Error::Constant(first));
        }
        Ok(())
    }
}

/// Checks that an optional mask has one entry per pixel, and (if
/// `need_true`) that at least `min_true` entries are true.
pub fn check_mask(
    name: &'static str,
    mask: Option<&[bool]>,
    n: usize,
    min_true: usize,
) -> Result<()> {
    if let Some(m) = mask {
        if m.len() != n {
            return Err(Error::Mask {
                name,
                msg: format!("{} entries for an image of {n} pixels", m.len()),
            });
        }
        if min_true > 0 {
            let count = m.par_iter().filter(|&&b| b).count();
            if count < min_true {
                return Err(Error::Mask {
                    name,
                    msg: format!("only {count} pixels are true; at least {min_true} are needed"),
                });
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shape_errors() {
        assert!(matches!(ImageRef::new(&[], 0, 0), Err(Error::Shape(_))));
        assert!(matches!(
            ImageRef::new(&[0.5; 3], 1, 1),
            Err(Error::TooSmall { .. })
        ));
        assert!(matches!(
            ImageRef::new(&[0.5; 10], 2, 2),
            Err(Error::Shape(_))
        ));
        assert!(ImageRef::new(&[0.5; 48], 4, 4).is_ok());
    }

    #[test]
    fn value_errors_name_the_place() {
        let mut d = vec![0.5f32; 4 * 5 * 3];
        d[0] = 0.1;
        d[(2 * 5 + 3) * 3 + 1] = f32::NAN;
        let e = ImageRef::new(&d, 4, 5)
            .unwrap()
            .validate_values()
            .unwrap_err();
        assert!(
            matches!(e, Error::NonFinite { row: 2, col: 3, channel: 1, value } if value.is_nan()),
            "{e}"
        );
        d[(2 * 5 + 3) * 3 + 1] = 1.5;
        let e = ImageRef::new(&d, 4, 5)
            .unwrap()
            .validate_values()
            .unwrap_err();
        assert_eq!(
            e,
            Error::OutOfRange {
                value: 1.5,
                row: 2,
                col: 3,
                channel: 1
            }
        );
        d[(2 * 5 + 3) * 3 + 1] = f32::NEG_INFINITY;
        assert!(matches!(
            ImageRef::new(&d, 4, 5).unwrap().validate_values(),
            Err(Error::NonFinite { row: 2, col: 3, .. })
        ));
        let c = vec![0.25f32; 48];
        assert_eq!(
            ImageRef::new(&c, 4, 4).unwrap().validate_values(),
            Err(Error::Constant(0.25))
        );
    }

    #[test]
    fn mask_checks() {
        assert!(check_mask("mask", Some(&[true; 3]), 4, 0).is_err());
        assert!(check_mask("mask", Some(&[false; 4]), 4, 1).is_err());
        assert!(check_mask("mask", Some(&[false, true, true, false]), 4, 2).is_ok());
        assert!(check_mask("mask", None, 4, 1).is_ok());
    }
}
