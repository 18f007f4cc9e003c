//! Allocations of a sequence's frames in steady state (docs/PERFORMANCE.md
//! "Raw frames"): with the planes of each restoration given back
//! (`Sequence::recycle`), a frame of the same size allocates no plane of
//! the image's size for its image, radiance and t_B; the bytes it still
//! allocates in large blocks are counted and bounded.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use uwhl::{ImageRef, Input, Params, Sequence};

/// Counts the bytes and number of allocations of at least 64 KiB.
struct Counting;

static BIG_BYTES: AtomicU64 = AtomicU64::new(0);
static BIG_COUNT: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if layout.size() >= 64 << 10 {
            BIG_BYTES.fetch_add(layout.size() as u64, Ordering::Relaxed);
            BIG_COUNT.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if layout.size() >= 64 << 10 {
            BIG_BYTES.fetch_add(layout.size() as u64, Ordering::Relaxed);
            BIG_COUNT.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size >= 64 << 10 {
            BIG_BYTES.fetch_add(new_size as u64, Ordering::Relaxed);
            BIG_COUNT.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static A: Counting = Counting;

/// Large-block bytes and count allocated per steady frame (frames 3..8 of
/// a pan), with and without the planes given back.
fn per_frame(h: usize, w: usize, subsample: usize, recycle: bool) -> (u64, usize) {
    let big = common::scene(h, w + 40, 3);
    let frames: Vec<Vec<f32>> = (0..8)
        .map(|k| (0..h).flat_map(|y| big[3 * (y * (w + 40) + 4 * k)..3 * (y * (w + 40) + 4 * k + w)].to_vec()).collect())
        .collect();
    let mut seq = Sequence::new(Params { threads: Some(1), guided_subsample: subsample, ..Params::default() });
    seq.refresh_every = 1000;
    let (mut bytes, mut count) = (0, 0);
    for (k, f) in frames.iter().enumerate() {
        let input = Input { image: ImageRef::new(f, h, w).unwrap(), mask: None, water_mask: None };
        let (b0, c0) = (BIG_BYTES.load(Ordering::Relaxed), BIG_COUNT.load(Ordering::Relaxed));
        let res = seq.restore(&input).unwrap();
        if recycle {
            seq.recycle(res);
        } else {
            drop(res);
        }
        if k >= 3 {
            bytes += BIG_BYTES.load(Ordering::Relaxed) - b0;
            count += BIG_COUNT.load(Ordering::Relaxed) - c0;
        }
    }
    (bytes / 5, count / 5)
}

#[test]
fn recycled_planes_are_not_allocated_again() {
    // the exact guided filter at 192 x 256, the fast one at 540 x 960 (a video's case)
    for (h, w, sub) in [(192usize, 256usize, 1usize), (540, 960, 0)] {
        let n = (h * w) as u64;
        let (with, count_with) = per_frame(h, w, sub, true);
        let (without, count_without) = per_frame(h, w, sub, false);
        eprintln!(
            "{w}x{h}, guided_subsample {sub}: {:.1} B a pixel in {count_with} blocks a frame with the planes given back, \
             {:.1} in {count_without} without",
            with as f64 / n as f64,
            without as f64 / n as f64
        );
        // the image and the radiance (12 bytes a pixel each) and t_B (4) come back
        assert!(without - with >= 28 * n, "{without} - {with}");
        assert!(count_without - count_with >= 3);
    }
}
