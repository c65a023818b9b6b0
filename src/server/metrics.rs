//! Prometheus metrics in the text exposition format, kept with atomics and one small map.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

/// Latency histogram bucket bounds, in seconds.
const BUCKETS: [f64; 12] = [
    0.001, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 10.0, 60.0,
];

#[derive(Default)]
struct Histogram {
    counts: [u64; BUCKETS.len()],
    count: u64,
    sum: f64,
}

#[derive(Default)]
pub struct Metrics {
    /// (route, status) → count.
    requests: Mutex<BTreeMap<(String, u16), u64>>,
    /// route → latency histogram.
    latency: Mutex<BTreeMap<String, Histogram>>,
    pub triangles: AtomicU64,
    pub vertices_added: AtomicU64,
    /// Jobs that stopped (or never started) because their request had stopped waiting.
    pub jobs_cancelled: AtomicU64,
    /// reason → count (overloaded, too_large, timeout).
    rejections: Mutex<BTreeMap<&'static str, u64>>,
}

impl Metrics {
    pub fn record(&self, route: &str, status: u16, elapsed: Duration) {
        if let Ok(mut requests) = self.requests.lock() {
            *requests.entry((route.to_owned(), status)).or_insert(0) += 1;
        }
        if let Ok(mut latency) = self.latency.lock() {
            let h = latency.entry(route.to_owned()).or_default();
            let seconds = elapsed.as_secs_f64();
            for (bound, count) in BUCKETS.iter().zip(h.counts.iter_mut()) {
                if seconds <= *bound {
                    *count += 1;
                }
            }
            h.count += 1;
            h.sum += seconds;
        }
    }

    pub fn reject(&self, reason: &'static str) {
        if let Ok(mut rejections) = self.rejections.lock() {
            *rejections.entry(reason).or_insert(0) += 1;
        }
    }

    /// The exposition text; `queued` and `running` are read from the pool at scrape time.
    pub fn render(&self, queued: usize, running: usize) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "# HELP tspace_requests_total Requests answered, by route and status."
        );
        let _ = writeln!(out, "# TYPE tspace_requests_total counter");
        if let Ok(requests) = self.requests.lock() {
            for ((route, status), count) in requests.iter() {
                let _ = writeln!(
                    out,
                    "tspace_requests_total{{route=\"{route}\",status=\"{status}\"}} {count}"
                );
            }
        }
        let _ = writeln!(
            out,
            "# HELP tspace_request_duration_seconds Request latency, by route."
        );
        let _ = writeln!(out, "# TYPE tspace_request_duration_seconds histogram");
        if let Ok(latency) = self.latency.lock() {
            for (route, h) in latency.iter() {
                for (bound, count) in BUCKETS.iter().zip(h.counts.iter()) {
                    let _ = writeln!(
                        out,
                        "tspace_request_duration_seconds_bucket{{route=\"{route}\",le=\"{bound}\"}} {count}"
                    );
                }
                let _ = writeln!(
                    out,
                    "tspace_request_duration_seconds_bucket{{route=\"{route}\",le=\"+Inf\"}} {}",
                    h.count
                );
                let _ = writeln!(
                    out,
                    "tspace_request_duration_seconds_sum{{route=\"{route}\"}} {}",
                    h.sum
                );
                let _ = writeln!(
                    out,
                    "tspace_request_duration_seconds_count{{route=\"{route}\"}} {}",
                    h.count
                );
            }
        }
        let gauges = [
            (
                "tspace_triangles_processed_total",
                "counter",
                "Triangles processed (generated or audited, analyses included; shared geometry once).",
                self.triangles.load(Ordering::Relaxed),
            ),
            (
                "tspace_vertices_added_total",
                "counter",
                "Vertices added by splits.",
                self.vertices_added.load(Ordering::Relaxed),
            ),
            (
                "tspace_jobs_cancelled_total",
                "counter",
                "Jobs stopped, or dropped before they started, because their request timed out or its client went away.",
                self.jobs_cancelled.load(Ordering::Relaxed),
            ),
            (
                "tspace_jobs_queued",
                "gauge",
                "Requests holding a place in the pool and not yet running: uploading, or waiting for a worker.",
                queued as u64,
            ),
            (
                "tspace_jobs_running",
                "gauge",
                "Jobs running.",
                running as u64,
            ),
        ];
        for (name, kind, help, value) in gauges {
            let _ = writeln!(out, "# HELP {name} {help}");
            let _ = writeln!(out, "# TYPE {name} {kind}");
            let _ = writeln!(out, "{name} {value}");
        }
        let _ = writeln!(
            out,
            "# HELP tspace_rejections_total Requests refused before any work, by reason."
        );
        let _ = writeln!(out, "# TYPE tspace_rejections_total counter");
        if let Ok(rejections) = self.rejections.lock() {
            for (reason, count) in rejections.iter() {
                let _ = writeln!(
                    out,
                    "tspace_rejections_total{{reason=\"{reason}\"}} {count}"
                );
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_counts_and_buckets() {
        let m = Metrics::default();
        m.record("/v1/tangents", 200, Duration::from_millis(3));
        m.record("/v1/tangents", 200, Duration::from_millis(30));
        m.record("/v1/tangents", 503, Duration::from_millis(1));
        m.reject("overloaded");
        let text = m.render(2, 1);
        assert!(text.contains("tspace_requests_total{route=\"/v1/tangents\",status=\"200\"} 2"));
        assert!(text.contains(
            "tspace_request_duration_seconds_bucket{route=\"/v1/tangents\",le=\"0.005\"} 2"
        ));
        assert!(text.contains("tspace_request_duration_seconds_count{route=\"/v1/tangents\"} 3"));
        assert!(text.contains("tspace_jobs_queued 2"));
        assert!(text.contains("tspace_rejections_total{reason=\"overloaded\"} 1"));
    }
}
