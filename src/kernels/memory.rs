//! What the machine can give: the default memory budget, the process's
//! own base, and the probe that turns an allocation the system would
//! refuse into an over-budget error instead of an abort.

use std::sync::OnceLock;

/// What a process holds beyond its plan that grows with neither the image
/// nor the number of inputs: allocator bookkeeping, worker threads' stacks,
/// codec tables, the reading thread of the overlapped loop, the arenas the
/// metadata's parsing leaves in the writing thread. Measured with 6 MiB:
/// single 0.07-6 MP inputs peaked 2-8 MB under their tightest budget, a
/// stream of six 0.3 MP frames 0.6 MB over it (docs/PERFORMANCE.md); with
/// the metadata carried that stream peaked 0.2-1.1 MB over 8 MiB, so 10.
pub const SLACK: u64 = 10 << 20;

/// The largest default budget, whatever the machine.
pub const CEILING: u64 = 16 << 30;

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

}
