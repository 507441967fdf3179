//! Prometheus metrics: request counts and latency histograms by route and status, plus the
//! worlds' cache and synthesis counters, rendered as the text exposition format.
//!
//! Every label set is bounded, whatever clients send: `route` is a route template of the router
//! (or `unmatched`), `method` one of the methods HTTP defines (anything else is `other`), `status`
//! a status the server answers. Conditions clients cause — overload, slow or idle connections,
//! failed authentication — are counted here instead of being logged one line each.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Duration;

use axum::http::Method;

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

/// Why a request was answered 503 without being served.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Overload {
    /// The tile synthesis queue was full.
    SynthQueue,
    /// The request outlived its deadline (`request_timeout_s` or `upload_timeout_s`).
    Timeout,
    /// The dictionary build queue was full.
    BuildQueue,
    /// Every upload slot was taken, or the upload memory budget was spent.
    Uploads,
    /// Nobody waited for the computation any more.
    Abandoned,
}

impl Overload {
    const ALL: [Overload; 5] = [
        Overload::SynthQueue,
        Overload::Timeout,
        Overload::BuildQueue,
        Overload::Uploads,
        Overload::Abandoned,
    ];

    fn label(self) -> &'static str {
        match self {
            Overload::SynthQueue => "synth_queue",
            Overload::Timeout => "timeout",
            Overload::BuildQueue => "build_queue",
            Overload::Uploads => "uploads",
            Overload::Abandoned => "abandoned",
        }
    }
}

/// Counters of conditions clients cause, each a plain number (no label a client chooses).
#[derive(Debug, Default)]
pub struct Counters {
    overload: [AtomicU64; Overload::ALL.len()],
    /// Client connections accepted.
    pub connections_accepted: AtomicU64,
    /// Client connections open now.
    pub connections_open: AtomicU64,
    /// Idle connections closed to make room for a new one (`max_connections` reached).
    pub connections_evicted: AtomicU64,
    /// Connections refused because every open one had a request in progress.
    pub connections_refused: AtomicU64,
    /// Connections closed for sending no complete request head in time, or idling too long.
    pub connections_timed_out: AtomicU64,
    /// Errors accepting connections (such as running out of file descriptors).
    pub accept_errors: AtomicU64,
    /// Failed admin authentications (missing or wrong token).
    pub auth_failures: AtomicU64,
    /// Admin requests refused (429) because their address failed authentication too often.
    pub auth_throttled: AtomicU64,
}

impl Counters {
    /// Counts one overload answer.
    pub fn overload(&self, why: Overload) {
        if let Some(c) = Overload::ALL
            .iter()
            .position(|o| *o == why)
            .and_then(|k| self.overload.get(k))
        {
            c.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// The method label: a method HTTP defines, or `other` (so that clients cannot add series).
pub fn method_label(m: &Method) -> &'static str {
    match *m {
        Method::GET => "GET",
        Method::HEAD => "HEAD",
        Method::POST => "POST",
        Method::PUT => "PUT",
        Method::DELETE => "DELETE",
        Method::OPTIONS => "OPTIONS",
        Method::PATCH => "PATCH",
        Method::TRACE => "TRACE",
        Method::CONNECT => "CONNECT",
        _ => "other",
    }
}

/// One route's series by (method label, status).
type ByStatus = BTreeMap<(&'static str, u16), Series>;

/// Request metrics, keyed by (route template, method, status), and the client-caused counters.
#[derive(Debug, Default)]
pub struct Metrics {
    /// Series by route template, then by (method, status): looked up by `&str`, so recording a
    /// request allocates only the first time its label set is seen.
    series: Mutex<BTreeMap<String, ByStatus>>,
    /// Counters of client-caused conditions.
    pub counters: Counters,
}

impl Metrics {
    /// Records one request. `route` must be a route template (or `unmatched`), never a path a
    /// client chose.
    pub fn record(&self, route: &str, method: &Method, status: u16, elapsed: Duration) {
        let method = method_label(method);
        let secs = elapsed.as_secs_f64();
        let mut map = match self.series.lock() {
            Ok(m) => m,
            Err(poisoned) => poisoned.into_inner(),
        };
        let by_route = match map.get_mut(route) {
            Some(m) => m,
            None => map.entry(route.to_string()).or_default(),
        };
        let s = by_route.entry((method, status)).or_default();
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
        let map: Vec<((String, &'static str, u16), Series)> = {
            let guard = match self.series.lock() {
                Ok(m) => m,
                Err(poisoned) => poisoned.into_inner(),
            };
            guard
                .iter()
                .flat_map(|(route, by)| {
                    by.iter()
                        .map(|((m, st), s)| ((route.clone(), *m, *st), s.clone()))
                })
                .collect()
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
        self.render_counters(&mut out);
        let worlds: Vec<&World> = worlds.collect();
        let counters: [Counter; 7] = [
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
                "terrasynth_windows_synthesized_total",
                "counter",
                "Parent windows amplified directly on cold chains (their tiles follow in the background).",
                |w| w.stats().windows_synthesized as f64,
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
            (
                "terrasynth_synthesis_cancelled_total",
                "counter",
                "Level-tile computations abandoned because nobody waited for them any more.",
                |w| w.stats().cancelled as f64,
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

    fn render_counters(&self, out: &mut String) {
        let c = &self.counters;
        let _ = writeln!(
            out,
            "# HELP terrasynth_overload_total Requests answered 503 without being served, by reason."
        );
        let _ = writeln!(out, "# TYPE terrasynth_overload_total counter");
        for (o, n) in Overload::ALL.iter().zip(&c.overload) {
            let _ = writeln!(
                out,
                "terrasynth_overload_total{{reason=\"{}\"}} {}",
                o.label(),
                n.load(Ordering::Relaxed)
            );
        }
        let plain: [(&str, &str, &str, &AtomicU64); 8] = [
            (
                "terrasynth_connections_accepted_total",
                "counter",
                "Client connections accepted.",
                &c.connections_accepted,
            ),
            (
                "terrasynth_connections_open",
                "gauge",
                "Client connections open.",
                &c.connections_open,
            ),
            (
                "terrasynth_connections_evicted_total",
                "counter",
                "Idle connections closed to make room for new ones (max_connections reached).",
                &c.connections_evicted,
            ),
            (
                "terrasynth_connections_refused_total",
                "counter",
                "Connections refused because every open connection had a request in progress.",
                &c.connections_refused,
            ),
            (
                "terrasynth_connections_timed_out_total",
                "counter",
                "Connections closed for a request head not sent in time or too long an idle time.",
                &c.connections_timed_out,
            ),
            (
                "terrasynth_accept_errors_total",
                "counter",
                "Errors accepting connections (such as running out of file descriptors).",
                &c.accept_errors,
            ),
            (
                "terrasynth_auth_failures_total",
                "counter",
                "Failed admin authentications.",
                &c.auth_failures,
            ),
            (
                "terrasynth_auth_throttled_total",
                "counter",
                "Admin requests refused (429) after too many failed authentications.",
                &c.auth_throttled,
            ),
        ];
        for (name, kind, help, v) in plain {
            let _ = writeln!(out, "# HELP {name} {help}");
            let _ = writeln!(out, "# TYPE {name} {kind}");
            let _ = writeln!(out, "{name} {}", v.load(Ordering::Relaxed));
        }
    }
}
