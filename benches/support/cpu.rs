//! Per-thread CPU time and run-queue wait, from Linux's `/proc/self/task/*/schedstat`.
//!
//! On a busy two-core machine the wall-clock parallel speedup says more about the other
//! processes than about the code: when they hold the second core, rayon's worker waits. The
//! scheduler's own accounting separates the two. For a run it gives the time the calling thread
//! spent on a CPU (the serial part: rayon blocks the caller while its pool works), the time the
//! pool threads spent on a CPU (the parallel part), and how long the calling thread, ready to
//! run, waited for a CPU (the interference). Elsewhere than Linux every reading is `None` and the derived columns
//! stay empty.

use std::collections::HashMap;
use std::fs;

/// Nanoseconds on a CPU and waiting on a run queue, per thread id.
#[derive(Clone, Debug, Default)]
pub struct Snapshot {
    threads: HashMap<u32, (u64, u64)>,
}

/// What one run cost in scheduler time, in seconds.
#[derive(Clone, Copy, Debug, Default)]
pub struct Usage {
    /// On-CPU time of the thread that called the generator.
    pub caller_cpu: f64,
    /// On-CPU time of every other thread of the process (rayon's pool), summed.
    pub others_cpu: f64,
    /// Time the calling thread was runnable but waited for a CPU.
    pub caller_waited: f64,
    /// Time the other threads were runnable but waited for a CPU, summed.
    pub others_waited: f64,
}

impl Usage {
    /// What the run would take on `cores` idle cores: the serial part plus the parallel part
    /// spread evenly. An estimate that ignores load imbalance, memory-bandwidth sharing and
    /// rayon's idle spinning, but not disturbed by other processes.
    pub fn idle_estimate(&self, cores: usize) -> f64 {
        self.caller_cpu + self.others_cpu / cores.max(1) as f64
    }
}

fn caller_tid() -> Option<u32> {
    // `/proc/thread-self` is a link to `/proc/<pid>/task/<tid>`.
    let link = fs::read_link("/proc/thread-self").ok()?;
    link.file_name()?.to_str()?.parse().ok()
}

/// Reads the scheduler statistics of every thread of this process.
pub fn snapshot() -> Option<Snapshot> {
    let mut threads = HashMap::new();
    for entry in fs::read_dir("/proc/self/task").ok()? {
        let entry = entry.ok()?;
        let Some(tid) = entry.file_name().to_str().and_then(|s| s.parse().ok()) else {
            continue;
        };
        // A thread may exit between listing and reading; it is then simply left out.
        let Ok(text) = fs::read_to_string(entry.path().join("schedstat")) else {
            continue;
        };
        let mut fields = text.split_whitespace().map(str::parse::<u64>);
        if let (Some(Ok(on_cpu)), Some(Ok(waiting))) = (fields.next(), fields.next()) {
            threads.insert(tid, (on_cpu, waiting));
        }
    }
    Some(Snapshot { threads })
}

/// The scheduler time spent between two snapshots taken on the calling thread.
pub fn usage_between(before: &Snapshot, after: &Snapshot) -> Option<Usage> {
    let caller = caller_tid()?;
    let mut usage = Usage::default();
    for (tid, &(on_cpu, waiting)) in &after.threads {
        let (cpu0, wait0) = before.threads.get(tid).copied().unwrap_or((0, 0));
        let cpu = on_cpu.saturating_sub(cpu0) as f64 * 1e-9;
        if *tid == caller {
            usage.caller_cpu += cpu;
            usage.caller_waited += waiting.saturating_sub(wait0) as f64 * 1e-9;
        } else {
            usage.others_cpu += cpu;
            usage.others_waited += waiting.saturating_sub(wait0) as f64 * 1e-9;
        }
    }
    Some(usage)
}
