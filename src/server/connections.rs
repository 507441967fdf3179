//! The accept loop: HTTP/1.1 connections served by hyper with the limits a server on the
//! internet needs (nginx's `client_header_timeout`, `keepalive_timeout` and `worker_connections`
//! are the model):
//!
//! - **header-read timeout**: a request head (request line and headers) must arrive within
//!   `header_read_timeout_s` of the server starting to wait for it — hyper's own timer, which on a
//!   kept-alive connection also bounds the wait for the next request — and a new connection must
//!   complete its first request head within that time, whatever it trickles;
//! - **idle timeout**: a connection without a request in progress for `idle_timeout_s` is closed;
//! - **connection cap**: at most `max_connections` connections are open. A new connection beyond
//!   the cap closes the connection idle the longest (no request in progress — slow or idle
//!   clients are the ones to go); when every connection has a request in progress, the new one is
//!   refused. The process's open-file limit is raised to fit the cap (or the cap lowered), so
//!   accepting never fails for want of file descriptors and health checks still get through.
//!
//! Every request carries its peer address (`ConnectInfo<SocketAddr>`) for the admin API's
//! failed-authentication throttle. Closed and refused connections are counted in the metrics, not
//! logged one line each. On shutdown the loop stops accepting, idle connections close at once and
//! requests in progress are answered before their connections close.

use std::collections::HashMap;
use std::convert::Infallible;
use std::net::SocketAddr;
use std::pin::pin;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use axum::body::Body;
use axum::extract::ConnectInfo;
use axum::Router;
use hyper::body::Incoming;
use hyper_util::rt::{TokioIo, TokioTimer};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{watch, Notify};

use super::metrics::Metrics;

/// File descriptors kept free beyond the connection cap (store files, the listener, logs).
pub const FD_RESERVE: u64 = 128;

/// How many times the accept loop yields at most for an evicted connection to close its socket
/// (the reserve of [`FD_RESERVE`] descriptors covers one that takes longer).
const EVICTION_YIELDS: u32 = 64;

/// How often a connection checks its idle time.
const IDLE_CHECK: Duration = Duration::from_millis(250);

/// The limits of the accept loop.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// Time to send a request head.
    pub header_read_timeout: Duration,
    /// Time a connection may stay without a request in progress.
    pub idle_timeout: Duration,
    /// Open connections at most.
    pub max_connections: usize,
}

/// One open connection, as the registry sees it.
#[derive(Debug)]
struct Conn {
    /// Requests in progress.
    in_flight: AtomicUsize,
    /// Requests whose head was received.
    requests: AtomicU64,
    /// When the connection last became idle, milliseconds since the registry started.
    idle_since: AtomicU64,
    /// Told to close (evicted).
    close: Notify,
}

/// The open connections.
#[derive(Debug)]
struct Registry {
    epoch: Instant,
    next_id: AtomicU64,
    conns: Mutex<HashMap<u64, Arc<Conn>>>,
}

impl Registry {
    fn now_ms(&self) -> u64 {
        u64::try_from(self.epoch.elapsed().as_millis()).unwrap_or(u64::MAX)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<u64, Arc<Conn>>> {
        self.conns.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Makes room for a new connection when `max` are open: closes the one idle the longest.
    /// `false` when every open connection has a request in progress.
    fn make_room(&self, max: usize, metrics: &Metrics) -> bool {
        let mut conns = self.lock();
        if conns.len() < max {
            return true;
        }
        let idlest = conns
            .iter()
            .filter(|(_, c)| c.in_flight.load(Ordering::Acquire) == 0)
            .min_by_key(|(_, c)| c.idle_since.load(Ordering::Relaxed))
            .map(|(id, _)| *id);
        match idlest.and_then(|id| conns.remove(&id)) {
            Some(c) => {
                c.close.notify_one();
                metrics
                    .counters
                    .connections_evicted
                    .fetch_add(1, Ordering::Relaxed);
                true
            }
            None => false,
        }
    }

    fn insert(&self) -> (u64, Arc<Conn>) {
        let id = self.next_id.fetch_add(1, Ordering::Relaxed);
        let conn = Arc::new(Conn {
            in_flight: AtomicUsize::new(0),
            requests: AtomicU64::new(0),
            idle_since: AtomicU64::new(self.now_ms()),
            close: Notify::new(),
        });
        self.lock().insert(id, conn.clone());
        (id, conn)
    }

    fn remove(&self, id: u64) {
        self.lock().remove(&id);
    }
}

/// Counts a client socket open (`terrasynth_connections_open`) from its accept until it is
/// dropped.
struct OpenSocket(Arc<Metrics>);

impl OpenSocket {
    fn new(metrics: Arc<Metrics>) -> Self {
        metrics
            .counters
            .connections_open
            .fetch_add(1, Ordering::AcqRel);
        OpenSocket(metrics)
    }
}

impl Drop for OpenSocket {
    fn drop(&mut self) {
        self.0
            .counters
            .connections_open
            .fetch_sub(1, Ordering::AcqRel);
    }
}

/// Marks a request in progress on its connection; on drop the connection is idle again (when it
/// was the last one).
struct InFlight {
    conn: Arc<Conn>,
    registry: Arc<Registry>,
}

impl InFlight {
    fn new(conn: Arc<Conn>, registry: Arc<Registry>) -> Self {
        conn.in_flight.fetch_add(1, Ordering::AcqRel);
        conn.requests.fetch_add(1, Ordering::Relaxed);
        InFlight { conn, registry }
    }
}

impl Drop for InFlight {
    fn drop(&mut self) {
        self.conn
            .idle_since
            .store(self.registry.now_ms(), Ordering::Relaxed);
        self.conn.in_flight.fetch_sub(1, Ordering::AcqRel);
    }
}

/// Raises the soft open-file limit so that `max_connections` connections and [`FD_RESERVE`]
/// other files fit (up to the hard limit); returns the connection cap that fits.
pub fn fit_open_files(max_connections: usize) -> usize {
    #[cfg(unix)]
    {
        let want = (max_connections as u64).saturating_add(FD_RESERVE);
        let mut lim = libc::rlimit {
            rlim_cur: 0,
            rlim_max: 0,
        };
        // SAFETY: getrlimit/setrlimit only read and write the struct passed.
        let got = unsafe { libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim) };
        if got != 0 {
            return max_connections;
        }
        let cur: u64 = lim.rlim_cur;
        let max: u64 = lim.rlim_max;
        let mut have = cur;
        if cur < want {
            let raised = libc::rlimit {
                rlim_cur: want.min(max),
                rlim_max: lim.rlim_max,
            };
            // SAFETY: as above.
            if unsafe { libc::setrlimit(libc::RLIMIT_NOFILE, &raised) } == 0 {
                have = want.min(max);
            }
        }
        let fits =
            usize::try_from(have.saturating_sub(FD_RESERVE).max(1)).unwrap_or(max_connections);
        if fits < max_connections {
            tracing::warn!(
                max_connections,
                open_file_limit = have,
                cap = fits,
                "the open-file limit cannot hold max_connections: connections capped lower (raise `ulimit -n`)"
            );
            return fits;
        }
        max_connections
    }
    #[cfg(not(unix))]
    max_connections
}

/// Serves `app` on `listener` with `limits` until `shutdown` resolves, then drains.
pub async fn serve(
    listener: TcpListener,
    app: Router,
    limits: Limits,
    metrics: Arc<Metrics>,
    shutdown: impl std::future::Future<Output = ()>,
) {
    let registry = Arc::new(Registry {
        epoch: Instant::now(),
        next_id: AtomicU64::new(0),
        conns: Mutex::new(HashMap::new()),
    });
    let (stop_tx, stop_rx) = watch::channel(false);
    // Every connection task holds a receiver: `closed()` resolves once all of them ended.
    let (done_tx, done_rx) = watch::channel(());
    let mut shutdown = pin!(shutdown);
    let mut last_accept_error: Option<Instant> = None;
    loop {
        let accepted = tokio::select! {
            _ = &mut shutdown => break,
            a = listener.accept() => a,
        };
        let (stream, peer) = match accepted {
            Ok(a) => a,
            Err(e) => {
                metrics
                    .counters
                    .accept_errors
                    .fetch_add(1, Ordering::Relaxed);
                // At most one line a minute; the metric counts them all.
                if last_accept_error.is_none_or(|t| t.elapsed() >= Duration::from_secs(60)) {
                    tracing::warn!(error = %e, "cannot accept connections (counted in terrasynth_accept_errors_total)");
                    last_accept_error = Some(Instant::now());
                }
                tokio::time::sleep(Duration::from_millis(50)).await;
                continue;
            }
        };
        if !registry.make_room(limits.max_connections, &metrics) {
            metrics
                .counters
                .connections_refused
                .fetch_add(1, Ordering::Relaxed);
            drop(stream);
            continue;
        }
        metrics
            .counters
            .connections_accepted
            .fetch_add(1, Ordering::Relaxed);
        // Registered now, so that the next accept already counts it; its socket is counted
        // open until it is actually closed.
        let socket = OpenSocket::new(metrics.clone());
        let (id, conn) = registry.insert();
        let task = Connection {
            registry: registry.clone(),
            metrics: metrics.clone(),
            app: app.clone(),
            limits,
            stop: stop_rx.clone(),
            done: done_rx.clone(),
        };
        tokio::spawn(task.run(stream, peer, socket, id, conn));
        // An evicted connection closes its socket on its own task: wait (briefly) until it has,
        // so that the sockets open never exceed the cap by more than the one just accepted,
        // however fast clients connect.
        let mut yields = 0;
        while metrics.counters.connections_open.load(Ordering::Acquire)
            > limits.max_connections as u64
            && yields < EVICTION_YIELDS
        {
            tokio::task::yield_now().await;
            yields += 1;
        }
    }
    drop(listener);
    let _ = stop_tx.send(true);
    drop(done_rx);
    done_tx.closed().await;
}

/// What a connection task needs.
struct Connection {
    registry: Arc<Registry>,
    metrics: Arc<Metrics>,
    app: Router,
    limits: Limits,
    stop: watch::Receiver<bool>,
    done: watch::Receiver<()>,
}

impl Connection {
    async fn run(
        mut self,
        stream: TcpStream,
        peer: SocketAddr,
        socket: OpenSocket,
        id: u64,
        conn: Arc<Conn>,
    ) {
        // Dropped after the connection (declared first, dropped last): the socket is closed then.
        let _socket = socket;
        // Tiles are written whole: without TCP_NODELAY a tile's last segment can wait on the
        // client's delayed ACK.
        let _ = stream.set_nodelay(true);
        let counters = &self.metrics.counters;
        let (app, registry, state) = (self.app.clone(), self.registry.clone(), conn.clone());
        let service = hyper::service::service_fn(move |req: hyper::Request<Incoming>| {
            let guard = InFlight::new(state.clone(), registry.clone());
            let mut req = req.map(Body::new);
            req.extensions_mut().insert(ConnectInfo(peer));
            let app = app.clone();
            async move {
                let resp: Result<_, Infallible> = tower::ServiceExt::oneshot(app, req).await;
                drop(guard);
                resp
            }
        });
        let mut builder = hyper::server::conn::http1::Builder::new();
        builder
            .timer(TokioTimer::new())
            .header_read_timeout(self.limits.header_read_timeout)
            .keep_alive(true);
        let mut http = pin!(builder
            .serve_connection(TokioIo::new(stream), service)
            .with_upgrades());
        let mut tick = tokio::time::interval(IDLE_CHECK);
        let mut stopping = *self.stop.borrow();
        if stopping {
            http.as_mut().graceful_shutdown();
        }
        loop {
            tokio::select! {
                served = http.as_mut() => {
                    if served.is_err_and(|e| e.is_timeout()) {
                        counters.connections_timed_out.fetch_add(1, Ordering::Relaxed);
                    }
                    break;
                }
                _ = conn.close.notified() => break,
                changed = self.stop.changed(), if !stopping => {
                    if changed.is_err() || *self.stop.borrow() {
                        stopping = true;
                        http.as_mut().graceful_shutdown();
                    }
                }
                _ = tick.tick() => {
                    if conn.in_flight.load(Ordering::Acquire) > 0 {
                        continue;
                    }
                    let idle = self.registry.now_ms().saturating_sub(conn.idle_since.load(Ordering::Relaxed));
                    // A connection that never completed a request head gets the header-read
                    // time; afterwards, the idle time.
                    let allowed = if conn.requests.load(Ordering::Relaxed) == 0 {
                        self.limits.header_read_timeout
                    } else {
                        self.limits.idle_timeout
                    };
                    if u128::from(idle) >= allowed.as_millis() {
                        counters.connections_timed_out.fetch_add(1, Ordering::Relaxed);
                        break;
                    }
                }
            }
        }
        self.registry.remove(id);
        drop(self.done);
    }
}
