//! Prometheus metrics: request counts and latency histograms by route and status, plus the
//! worlds' cache and synthesis counters, rendered as the text exposition format.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::Mutex;
use std::time::Duration;

use terrasynth_tiles::World;

/// Upper bounds of the latency histogram buckets, seconds.
pub const BUCKETS: [f64; 12] = [
    0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 5.0,
];

#[derive(Clone, Debug, Default)]
struct Series {
    count: u64,
    sum: f64,
    buckets: [u64; BUCKETS.len()],
}

/// A world counter: name, Prometheus type, help text and how to read it.
type Counter = (&'static str, &'static str, &'static str, fn(&World) -> f64);

/// Request metrics, keyed by (route template, method, status).
#[derive(Debug, Default)]
pub struct Metrics {
    series: Mutex<BTreeMap<(String, String, u16), Series>>,
}

impl Metrics {
    /// Records one request.
    pub fn record(&self, route: &str, method: &str, status: u16, elapsed: Duration) {
        let secs = elapsed.as_secs_f64();
        let mut map = match self.series.lock() {
            Ok(m) => m,
            Err(poisoned) => poisoned.into_inner(),
        };
        let s = map
            .entry((route.to_string(), method.to_string(), status))
            .or_default();
        s.count += 1;
        s.sum += secs;
        for (i, b) in BUCKETS.iter().enumerate() {
            if secs <= *b {
                s.buckets[i] += 1;
            }
        }
    }

    /// The Prometheus text exposition of the request metrics and the worlds' counters.
    pub fn render<'a>(&self, worlds: impl Iterator<Item = &'a World>) -> String {
        let mut out = String::new();
        let map = match self.series.lock() {
            Ok(m) => m.clone(),
            Err(poisoned) => poisoned.into_inner().clone(),
        };
        let _ = writeln!(
            out,
            "# HELP terrasynth_requests_total HTTP requests by route and status."
        );
        let _ = writeln!(out, "# TYPE terrasynth_requests_total counter");
        for ((route, method, status), s) in &map {
            let _ = writeln!(
                out,
                "terrasynth_requests_total{{route=\"{route}\",method=\"{method}\",status=\"{status}\"}} {}",
                s.count
            );
        }
        let _ = writeln!(
            out,
            "# HELP terrasynth_request_duration_seconds HTTP request latency."
        );
        let _ = writeln!(out, "# TYPE terrasynth_request_duration_seconds histogram");
        for ((route, method, status), s) in &map {
            let labels = format!("route=\"{route}\",method=\"{method}\",status=\"{status}\"");
            for (i, b) in BUCKETS.iter().enumerate() {
                let _ = writeln!(
                    out,
                    "terrasynth_request_duration_seconds_bucket{{{labels},le=\"{b}\"}} {}",
                    s.buckets[i]
                );
            }
            let _ = writeln!(
                out,
                "terrasynth_request_duration_seconds_bucket{{{labels},le=\"+Inf\"}} {}",
                s.count
            );
            let _ = writeln!(
                out,
                "terrasynth_request_duration_seconds_sum{{{labels}}} {}",
                s.sum
            );
            let _ = writeln!(
                out,
                "terrasynth_request_duration_seconds_count{{{labels}}} {}",
                s.count
            );
        }
        let worlds: Vec<&World> = worlds.collect();
        let counters: [Counter; 5] = [
            (
                "terrasynth_cache_hits_total",
                "counter",
                "Level tiles served from the cache.",
                |w| w.stats().cache_hits as f64,
            ),
            (
                "terrasynth_cache_misses_total",
                "counter",
                "Level tiles computed on a cache miss.",
                |w| w.stats().cache_misses as f64,
            ),
            (
                "terrasynth_tiles_synthesized_total",
                "counter",
                "Level tiles produced by amplification.",
                |w| w.stats().tiles_synthesized as f64,
            ),
            (
                "terrasynth_synthesis_seconds_total",
                "counter",
                "Seconds spent computing level tiles.",
                |w| w.stats().synthesis_seconds,
            ),
            (
                "terrasynth_cache_bytes",
                "gauge",
                "Bytes held by the level-tile cache.",
                |w| w.cache_bytes() as f64,
            ),
        ];
        for (name, kind, help, get) in counters {
            let _ = writeln!(out, "# HELP {name} {help}");
            let _ = writeln!(out, "# TYPE {name} {kind}");
            for w in &worlds {
                let _ = writeln!(out, "{name}{{world=\"{}\"}} {}", w.name(), get(w));
            }
        }
        out
    }
}
