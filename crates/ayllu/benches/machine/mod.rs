//! The machine a benchmark ran on, printed beside its figures so numbers are never quoted
//! without their context. Shared by every benchmark of this crate.

/// CPU count, CPU model, OS and architecture, in one line.
pub fn machine() -> String {
    let cpus = std::thread::available_parallelism().map_or(0, |n| n.get());
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_owned())
        })
        .unwrap_or_else(|| "unknown CPU".to_owned());
    format!("{cpus} CPUs (nproc), {model}, {} {}", std::env::consts::OS, std::env::consts::ARCH)
}
