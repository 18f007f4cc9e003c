//! The memory plan of one input through a command, computed from the
//! image header before anything large is allocated (`--max-memory`), and
//! what the machine can give: the default budget and the probe that turns
//! an allocation the system would refuse into an over-budget error.
//!
//! Phases and what is alive in each (n = input pixels after orientation,
//! m = pixels after `--max-side`, b = decoded bytes per pixel):
//!
//! | phase | bytes |
//! |---|---|
//! | decode | `b n` decoded + `b n` rotated copy (EXIF orientation) or RGB conversion + `12 n` f32 (while the RGB buffer is alive) |
//! | reference stretch | `12 n` in + `12 n` out + `4 n` one channel's percentile copy |
//! | downscale | `12 n` + `12 m` |
//! | restore | `12 m` input + `params::memory_estimate(h, w, k)` |
//! | write | `12 m` input + the restoration (`29 m`) + the three outputs' codes and encoded files, encoded at once (`16 m`) + the photo's metadata carried (`18 m`: three copies of its encoding; `b n`: the input file read again, `crate::metadata`) |
//!
//! plus `n` bytes per mask given (`--mask`, `--water-mask`; read once per run)
//! and `2 m` for their downscaled copies. The plan is the largest phase.
//!
//! The batch and stream loops decode and restore an input while the
//! previous one's outputs are written (`run::overlapped`); that one holds
//! `69 m'` bytes (its restoration, encoders and metadata, `m'` its pixels) until it
//! is written. An input whose plan does not fit in `--max-memory` beside
//! them waits until they are written, so the two together stay within the
//! budget and an input is refused only if its own plan exceeds it.
//!
//! `--max-memory` bounds the process's peak resident memory: the plan is
//! added to [`process_base`], what the process holds before its first
//! input (code, libraries, the Python interpreter) plus [`SLACK`].

use crate::params::memory_estimate;
use std::sync::OnceLock;

/// Bytes per processed pixel an input holds while its outputs are written:
/// the restoration (29), the three outputs' codes and encoded files (16),
/// and carrying the metadata ([`METADATA_PER_PIXEL`], with the input file
/// read again: at most 6 bytes a pixel for an uncompressed 16-bit file).
pub const HELD_WHILE_WRITING: u64 = 29 + 16 + METADATA_PER_PIXEL + 6;

/// Bytes per processed pixel of carrying the metadata into the corrected
/// photo (`crate::metadata::carry`): the encoded photo and up to two copies
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
        let restore = mul(12, m).saturating_add(memory_estimate(h, w, self.masks > 0));
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
        }
    }
}

/// What a process holds beyond its plan that grows with neither the image
/// nor the number of inputs: allocator bookkeeping, worker threads' stacks,
/// codec tables, the reading thread of the overlapped loop, the arenas the
/// metadata's parsing leaves in the writing thread. Measured with 6 MiB:
/// single 0.07-6 MP inputs peaked 2-8 MB under their tightest budget, a
/// stream of six 0.3 MP frames 0.6 MB over it (docs/PERFORMANCE.md); with
/// the metadata carried that stream peaked 0.2-1.1 MB over 8 MiB, so 10.
pub const SLACK: u64 = 10 << 20;

/// The largest default budget, whatever the machine.
pub const CEILING: u64 = crate::options::DEFAULT_MAX_MEMORY;

fn status_kib(field: &str) -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    kib_field(&s, field)
}

/// `Field:   1234 kB` in a /proc file's text, in bytes.
fn kib_field(text: &str, field: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.strip_prefix(field).is_some_and(|r| r.starts_with(':')))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib.saturating_mul(1024))
}

/// What the process holds before its first input, measured once (its
/// resident size, /proc/self/status `VmRSS`; 16 MiB where that cannot be
/// read), plus [`SLACK`].
pub fn process_base() -> u64 {
    static BASE: OnceLock<u64> = OnceLock::new();
    *BASE.get_or_init(|| status_kib("VmRSS").unwrap_or(16 << 20).saturating_add(SLACK))
}

/// A limit line of /proc/self/limits (`Max address space  unlimited  unlimited  bytes`): the soft limit.
fn rlimit(text: &str, name: &str) -> Option<u64> {
    let rest = text.lines().find_map(|l| l.strip_prefix(name))?;
    rest.split_whitespace().next()?.parse().ok()
}

/// The memory limit left in the cgroup (v2 `memory.max - memory.current`
/// along the process's cgroup path, or v1 `memory.limit_in_bytes -
/// memory.usage_in_bytes`), if any.
fn cgroup_room() -> Option<u64> {
    let read = |p: &std::path::Path| std::fs::read_to_string(p).ok().and_then(|s| s.trim().parse::<u64>().ok());
    let cg = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let mut room: Option<u64> = None;
    for line in cg.lines() {
        let mut parts = line.splitn(3, ':');
        let (_, ctrl, path) = (parts.next()?, parts.next()?, parts.next()?);
        let rel = path.trim_start_matches('/');
        let (root, max, cur) = if ctrl.is_empty() {
            ("/sys/fs/cgroup", "memory.max", "memory.current")
        } else if ctrl.split(',').any(|c| c == "memory") {
            ("/sys/fs/cgroup/memory", "memory.limit_in_bytes", "memory.usage_in_bytes")
        } else {
            continue;
        };
        // the limit of every level up to the root applies
        let mut dir = std::path::Path::new(root).join(rel);
        loop {
            if let (Some(m), Some(c)) = (read(&dir.join(max)), read(&dir.join(cur))) {
                room = Some(room.map_or(m.saturating_sub(c), |r| r.min(m.saturating_sub(c))));
            }
            if dir == std::path::Path::new(root) || !dir.pop() {
                break;
            }
        }
    }
    room
}

/// What the machine can give this process now, or None if nothing can be
/// read: the least of the memory available (/proc/meminfo `MemAvailable`),
/// the room left in its cgroup, and the room left under its address-space
/// and data rlimits (`ulimit -v`, `ulimit -d`) after what it maps already
/// and 64 MiB per core for the allocator's arenas.
pub fn machine_room() -> Option<u64> {
    let mut room: Vec<u64> = Vec::new();
    if let Ok(m) = std::fs::read_to_string("/proc/meminfo") {
        room.extend(kib_field(&m, "MemAvailable"));
    }
    room.extend(cgroup_room());
    if let Ok(l) = std::fs::read_to_string("/proc/self/limits") {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as u64;
        let arenas = (cores + 2).saturating_mul(64 << 20);
        for (name, used) in [("Max address space", "VmSize"), ("Max data size", "VmData")] {
            if let (Some(limit), Some(used)) = (rlimit(&l, name), status_kib(used)) {
                room.push(limit.saturating_sub(used).saturating_sub(arenas));
            }
        }
    }
    room.into_iter().min()
}

/// The default `--max-memory` / `max_memory`: [`CEILING`] (16 GiB), or
/// what the machine can give ([`machine_room`]) if less; read once.
pub fn default_max_memory() -> u64 {
    static DEFAULT: OnceLock<u64> = OnceLock::new();
    *DEFAULT.get_or_init(|| machine_room().map_or(CEILING, |r| r.min(CEILING)))
}

/// Whether the system would give `bytes` at once now: reserves them
/// (address space only, never touched) and frees them. An address-space
/// rlimit or a machine without that much memory and swap refuses here, as
/// an error, instead of aborting the process at the first large
/// allocation.
pub fn can_allocate(bytes: u64) -> bool {
    let Ok(n) = usize::try_from(bytes) else { return false };
    let mut v: Vec<u8> = Vec::new();
    v.try_reserve_exact(n).is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn proc_fields_and_limits_are_read() {
        let status = "Name:\tx\nVmRSS:\t   1234 kB\nVmSize:\t 99 kB\n";
        assert_eq!(kib_field(status, "VmRSS"), Some(1234 * 1024));
        assert_eq!(kib_field(status, "VmRS"), None);
        let limits = "Limit                     Soft Limit           Hard Limit           Units\n\
                      Max data size             unlimited            unlimited            bytes\n\
                      Max address space         6144000000           unlimited            bytes\n";
        assert_eq!(rlimit(limits, "Max address space"), Some(6_144_000_000));
        assert_eq!(rlimit(limits, "Max data size"), None);
        // this machine: a default within the ceiling, a base of a few MB at least
        assert!(default_max_memory() <= CEILING && default_max_memory() > 0);
        assert!(process_base() > SLACK);
        assert!(can_allocate(1 << 20) && !can_allocate(u64::MAX / 2));
    }

    fn plan(h: usize, w: usize) -> Plan {
        Plan::rgb8(h, w)
    }

    #[test]
    fn restore_dominates_and_downscaling_shrinks_it() {
        let p = plan(1000, 1000);
        assert_eq!(p.bytes(), 12_000_000 + memory_estimate(1000, 1000, false));
        let small = Plan { factor: 4, ..p };
        assert_eq!(small.processed(), (250, 250));
        // with the image shrunk 4x the decode phase dominates: 3 n + 12 n
        assert!(small.bytes() >= 15_000_000 && small.bytes() < p.bytes());
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
