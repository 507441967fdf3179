//! Cooperative cancellation of tile computations that nobody waits for any more, with request
//! coalescing that stays correct for those who still wait.
//!
//! A request that may be abandoned (its client leaves, its deadline passes) runs its computation
//! under a [`CancelToken`] with [`run_cancellable`]. Every computation of a cache entry goes
//! through [`Flights::run`], which coalesces concurrent computations of one key: the first caller
//! computes ("leads the flight"), later callers wait for its result. Each flight records the
//! *interest* of everyone waiting for it: a token, or the flight of an enclosing computation that
//! needs this one. A flight counts as cancelled only when every one of its waiters is cancelled, so
//! a computation stops only when nobody wants it any more, however the requests that need it
//! overlap; a waiter whose own interest is cancelled stops waiting at once.
//!
//! The interest of the computation running on a thread is kept in a thread-local, so that the
//! pyramids' recursive `get_or_compute` calls (each one a cancellation point) need no extra
//! parameter. Work started without a token — a background thread, a command-line tool, a test —
//! is never cancelled. A cancelled computation returns [`TileError::Cancelled`] and leaves no
//! trace in any cache: a waiter that joined after its leader gave up computes it again.
//!
//! [`concurrently`] runs independent computations (the cold parent tiles of a landscape chain;
//! [`join`] two of different kinds, such as gathering a world's inputs and reading its stored
//! layers) on scoped threads of their own, each with its caller's interest, so that a cancellation
//! reaches them as it would reach the caller. They are plain threads, not rayon tasks: a rayon
//! worker that blocks on a flight may be the one that would have run the work the flight's leader
//! waits for, while a thread blocked here holds nothing anyone else needs (a tile only ever waits
//! for tiles of lower zooms or other layers of its own zoom, never for itself). Called on a rayon
//! worker, it runs the computations on that worker, one after the other.

use std::cell::RefCell;
use std::collections::HashMap;
use std::hash::Hash;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::Duration;

use crate::error::TileError;

/// How often a waiting thread checks whether its own interest was cancelled.
const WAIT_SLICE: Duration = Duration::from_millis(20);

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// The cancellation flag of one request: cancelled once, for ever.
#[derive(Clone, Debug, Default)]
pub struct CancelToken(Arc<AtomicBool>);

impl CancelToken {
    /// A token not cancelled yet.
    pub fn new() -> Self {
        CancelToken::default()
    }

    /// Cancels the token (and every computation only it still waits for).
    pub fn cancel(&self) {
        self.0.store(true, Ordering::Release);
    }

    /// Whether the token was cancelled.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Acquire)
    }

    /// A guard that cancels the token when dropped: hold it in the future that waits for the
    /// computation, so that dropping the future (client gone, deadline passed) cancels it.
    pub fn cancel_on_drop(&self) -> CancelOnDrop {
        CancelOnDrop(self.clone())
    }
}

/// Cancels its token when dropped (see [`CancelToken::cancel_on_drop`]).
#[derive(Debug)]
pub struct CancelOnDrop(CancelToken);

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        self.0.cancel();
    }
}

/// Who wants a computation: nobody who can leave, a request's token, or an enclosing flight.
#[derive(Clone, Debug)]
enum Interest {
    Always,
    Token(CancelToken),
    Flight(Arc<Waiters>),
}

impl Interest {
    fn is_cancelled(&self) -> bool {
        match self {
            Interest::Always => false,
            Interest::Token(t) => t.is_cancelled(),
            Interest::Flight(w) => w.is_cancelled(),
        }
    }

    fn same(&self, other: &Interest) -> bool {
        match (self, other) {
            (Interest::Always, Interest::Always) => true,
            (Interest::Token(a), Interest::Token(b)) => Arc::ptr_eq(&a.0, &b.0),
            (Interest::Flight(a), Interest::Flight(b)) => Arc::ptr_eq(a, b),
            _ => false,
        }
    }
}

/// The interests waiting for one flight.
#[derive(Debug, Default)]
struct Waiters(Mutex<Vec<Interest>>);

impl Waiters {
    /// Cancelled when every waiter is (or none is left). The list is copied out of the lock, so
    /// no two of these locks are ever held together.
    fn is_cancelled(&self) -> bool {
        let waiters = lock(&self.0).clone();
        waiters.iter().all(Interest::is_cancelled)
    }

    fn push(&self, i: Interest) {
        lock(&self.0).push(i);
    }

    fn remove(&self, i: &Interest) {
        let mut w = lock(&self.0);
        if let Some(k) = w.iter().position(|x| x.same(i)) {
            w.swap_remove(k);
        }
    }
}

thread_local! {
    static CURRENT: RefCell<Interest> = const { RefCell::new(Interest::Always) };
}

fn current() -> Interest {
    CURRENT.with(|c| c.borrow().clone())
}

/// Restores the previous interest of the thread when dropped (also on unwinding).
struct Restore(Option<Interest>);

impl Drop for Restore {
    fn drop(&mut self) {
        if let Some(prev) = self.0.take() {
            CURRENT.with(|c| *c.borrow_mut() = prev);
        }
    }
}

fn with_interest<R>(interest: Interest, f: impl FnOnce() -> R) -> R {
    let prev = CURRENT.with(|c| c.replace(interest));
    let _restore = Restore(Some(prev));
    f()
}

/// Runs `f` on this thread on behalf of `token`: the computations it starts or joins stop as
/// soon as `token` and every other party waiting for them are cancelled.
pub fn run_cancellable<R>(token: &CancelToken, f: impl FnOnce() -> R) -> R {
    with_interest(Interest::Token(token.clone()), f)
}

/// Runs `f` on this thread as work nobody can abandon (computations it leads are never
/// cancelled): for results that are cached for ever once computed, such as a world's
/// whole-world layers.
pub fn uncancellable<R>(f: impl FnOnce() -> R) -> R {
    with_interest(Interest::Always, f)
}

/// Whether the computation running on this thread has been abandoned by everyone who wanted it.
pub fn is_cancelled() -> bool {
    current().is_cancelled()
}

/// `f` of every item, concurrently: the first on this thread, each other on a scoped thread of
/// its own that works on behalf of this thread's interest (a computation it starts or joins
/// stops when this thread's would). The results come in the order of `items`. Items whose thread
/// cannot be created run on this thread, after the first.
///
/// On a rayon worker (a caller's parallel loop; `terrasynth export` renders its tiles on plain
/// threads for the same reason) every item runs on this thread, in order: the items' own parallel kernels need the pool's workers, and a
/// worker blocked here waiting for the threads would be one fewer — with every worker waiting
/// so, the pool would never run them.
pub fn concurrently<I: Sync, R: Send>(items: &[I], f: impl Fn(&I) -> R + Sync) -> Vec<R> {
    let Some((first, rest)) = items.split_first() else {
        return Vec::new();
    };
    if rayon::current_thread_index().is_some() {
        return items.iter().map(f).collect();
    }
    let interest = current();
    let f = &f;
    std::thread::scope(|s| {
        let spawned: Vec<_> = rest
            .iter()
            .map(|item| spawn_on_behalf(s, &interest, move || f(item)).map_err(|_| item))
            .collect();
        let mut out = Vec::with_capacity(items.len());
        out.push(f(first));
        for handle in spawned {
            out.push(match handle {
                Ok(h) => joined(h),
                Err(item) => f(item),
            });
        }
        out
    })
}

/// `a()` and `b()` concurrently, as [`concurrently`] runs items of one kind: `a` on this thread,
/// `b` on a scoped thread working on behalf of this thread's interest; one after the other on a
/// rayon worker, or when the thread cannot be created.
pub fn join<A, B: Send>(a: impl FnOnce() -> A, b: impl FnOnce() -> B + Send) -> (A, B) {
    if rayon::current_thread_index().is_some() {
        return (a(), b());
    }
    let interest = current();
    // The other thread takes `b` from here; if it cannot be created, `b` is still here.
    let slot = Mutex::new(Some(b));
    let take = || lock(&slot).take();
    std::thread::scope(|s| {
        let handle = spawn_on_behalf(s, &interest, || take().map(|b| b()));
        let first = a();
        // `b` ran on the other thread, or (when it could not be created) runs here: it is taken
        // exactly once, so one of the two gives its result.
        match handle.ok().and_then(joined).or_else(|| take().map(|b| b())) {
            Some(second) => (first, second),
            None => unreachable!("join: `b` is taken exactly once"),
        }
    })
}

/// Spawns `f` on a scoped thread that works on behalf of `interest`.
fn spawn_on_behalf<'scope, R: Send + 'scope>(
    s: &'scope std::thread::Scope<'scope, '_>,
    interest: &Interest,
    f: impl FnOnce() -> R + Send + 'scope,
) -> std::io::Result<std::thread::ScopedJoinHandle<'scope, R>> {
    let interest = interest.clone();
    std::thread::Builder::new()
        .name("terrasynth-chain".into())
        .spawn_scoped(s, move || with_interest(interest, f))
}

/// The result of a scoped thread; its panic goes on in the caller.
fn joined<R>(h: std::thread::ScopedJoinHandle<'_, R>) -> R {
    match h.join() {
        Ok(r) => r,
        Err(panic) => std::panic::resume_unwind(panic),
    }
}

/// One computation in progress: who waits for it, and its result once done.
struct Flight<V> {
    waiters: Arc<Waiters>,
    result: Mutex<Option<Result<V, TileError>>>,
    done: Condvar,
}

enum Waited<V> {
    Done(Result<V, TileError>),
    Left,
}

impl<V: Clone> Flight<V> {
    fn finish(&self, r: Result<V, TileError>) {
        *lock(&self.result) = Some(r);
        self.done.notify_all();
    }

    /// Waits for the result, or leaves (dropping its interest) once `me` is cancelled.
    fn wait(&self, me: &Interest) -> Waited<V> {
        let mut result = lock(&self.result);
        loop {
            if let Some(r) = result.as_ref() {
                return Waited::Done(r.clone());
            }
            if me.is_cancelled() {
                drop(result);
                self.waiters.remove(me);
                return Waited::Left;
            }
            result = match self.done.wait_timeout(result, WAIT_SLICE) {
                Ok((g, _)) => g,
                Err(p) => p.into_inner().0,
            };
        }
    }
}

/// Computations in progress by key, coalesced: one computes, the others wait (see the module
/// documentation for cancellation).
pub struct Flights<K, V> {
    map: Mutex<HashMap<K, Arc<Flight<V>>>>,
}

impl<K, V> Default for Flights<K, V> {
    fn default() -> Self {
        Flights {
            map: Mutex::new(HashMap::new()),
        }
    }
}

impl<K, V> std::fmt::Debug for Flights<K, V> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Flights")
            .field("in_flight", &lock(&self.map).len())
            .finish()
    }
}

impl<K: Hash + Eq + Clone, V: Clone> Flights<K, V> {
    /// No computation in progress.
    pub fn new() -> Self {
        Flights::default()
    }

    /// The value of `key` computed by `compute`, once even when several threads ask for it at the
    /// same time (the others wait for that computation). A successful value is handed to
    /// `publish` (to cache it) before later callers stop finding the flight, so that they find
    /// it in the cache instead. Fails with [`TileError::Cancelled`] when the caller's interest is
    /// cancelled; a caller still interested never receives a cancellation meant for others.
    pub fn run(
        &self,
        key: K,
        compute: impl FnOnce() -> Result<V, TileError>,
        publish: impl FnOnce(&V),
    ) -> Result<V, TileError> {
        let me = current();
        let mut compute = Some(compute);
        let mut publish = Some(publish);
        loop {
            if me.is_cancelled() {
                return Err(TileError::Cancelled);
            }
            let (flight, leader) = {
                let mut map = lock(&self.map);
                match map.get(&key) {
                    Some(f) => {
                        f.waiters.push(me.clone());
                        (f.clone(), false)
                    }
                    None => {
                        let f = Arc::new(Flight {
                            waiters: Arc::new(Waiters(Mutex::new(vec![me.clone()]))),
                            result: Mutex::new(None),
                            done: Condvar::new(),
                        });
                        map.insert(key.clone(), f.clone());
                        (f, true)
                    }
                }
            };
            if leader {
                let r = match compute.take() {
                    Some(c) => with_interest(Interest::Flight(flight.waiters.clone()), c),
                    None => Err(TileError::Cancelled),
                };
                if let (Ok(v), Some(p)) = (&r, publish.take()) {
                    p(v);
                }
                {
                    let mut map = lock(&self.map);
                    if map.get(&key).is_some_and(|f| Arc::ptr_eq(f, &flight)) {
                        map.remove(&key);
                    }
                }
                flight.finish(r.clone());
                return r;
            }
            match flight.wait(&me) {
                // The leader gave up before this caller joined (or because everyone it knew of
                // left): compute it again.
                Waited::Done(Err(TileError::Cancelled)) if !me.is_cancelled() => continue,
                Waited::Done(r) => return r,
                Waited::Left => return Err(TileError::Cancelled),
            }
        }
    }

    /// Whether `key` is being computed right now.
    pub fn is_running(&self, key: &K) -> bool {
        lock(&self.map).contains_key(key)
    }

    /// Number of computations in progress.
    pub fn in_flight(&self) -> usize {
        lock(&self.map).len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicUsize;
    use std::sync::Barrier;

    /// Spins until `cond` holds; fails the test after 10 s (a hang is a failure, not a wait).
    fn wait_until(what: &str, cond: impl Fn() -> bool) {
        let deadline = std::time::Instant::now() + Duration::from_secs(10);
        while !cond() {
            assert!(std::time::Instant::now() < deadline, "never: {what}");
            std::thread::yield_now();
        }
    }

    /// A computation that runs until told to finish (or until cancelled), checking like the
    /// pyramid does between steps.
    fn slow(release: &AtomicBool, steps: &AtomicUsize) -> Result<u32, TileError> {
        loop {
            if is_cancelled() {
                return Err(TileError::Cancelled);
            }
            if release.load(Ordering::Acquire) {
                return Ok(7);
            }
            steps.fetch_add(1, Ordering::Relaxed);
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    #[test]
    fn concurrent_items_keep_their_order_and_run_on_threads_of_their_own() {
        let items: Vec<u32> = (0..6).collect();
        let threads = Mutex::new(Vec::new());
        let out = concurrently(&items, |&i| {
            lock(&threads).push(std::thread::current().id());
            i * 10
        });
        assert_eq!(out, vec![0, 10, 20, 30, 40, 50]);
        let mut ids = lock(&threads).clone();
        assert_eq!(ids.len(), 6);
        assert!(
            ids.contains(&std::thread::current().id()),
            "the first runs here"
        );
        ids.sort_by_key(|id| format!("{id:?}"));
        ids.dedup();
        assert_eq!(ids.len(), 6, "one thread per item");
        assert!(concurrently(&[] as &[u32], |&i| i).is_empty());
    }

    #[test]
    fn concurrent_items_on_a_rayon_worker_leave_the_pool_its_workers() {
        // Every worker of a one-thread pool asks for items whose work runs on that same pool
        // (an export's tiles, each with a drainage chain that amplifies in parallel). Items on
        // threads of their own would wait for a worker that waits for them; run on the worker
        // itself they finish. A hang fails the test after 20 s.
        let pool = match rayon::ThreadPoolBuilder::new().num_threads(1).build() {
            Ok(p) => Arc::new(p),
            Err(e) => panic!("a one-thread pool: {e}"),
        };
        let (tx, rx) = std::sync::mpsc::channel();
        let inner = pool.clone();
        std::thread::spawn(move || {
            let sums = pool.install(|| {
                concurrently(&[1u64, 2, 3], |&k| {
                    inner.install(|| {
                        use rayon::prelude::*;
                        (0..1000u64).into_par_iter().map(|v| v * k).sum::<u64>()
                    })
                })
            });
            let _ = tx.send(sums);
        });
        let sums = rx
            .recv_timeout(Duration::from_secs(20))
            .unwrap_or_else(|e| panic!("the pool's work never ran: {e}"));
        assert_eq!(sums, vec![499_500, 999_000, 1_498_500]);
    }

    #[test]
    fn a_join_runs_its_second_computation_on_another_thread_for_the_caller() {
        let here = std::thread::current().id();
        // Both run at once: each tells the other it started and waits for the other's word. Run
        // one after the other, the first would wait in vain (10 s) and report it.
        let (to_b, from_a) = std::sync::mpsc::channel();
        let (to_a, from_b) = std::sync::mpsc::channel();
        let meet = |to: std::sync::mpsc::Sender<()>, from: std::sync::mpsc::Receiver<()>| {
            move || {
                let _ = to.send(());
                let met = from.recv_timeout(Duration::from_secs(10)).is_ok();
                (std::thread::current().id(), met)
            }
        };
        let ((first, a_met), (second, b_met)) = join(meet(to_b, from_b), meet(to_a, from_a));
        assert!(a_met && b_met, "the two ran one after the other");
        assert_eq!(first, here, "the first runs here");
        assert_ne!(second, here, "the second on a thread of its own");
        // The second works on behalf of the caller's token.
        let token = CancelToken::new();
        token.cancel();
        let (a, b) = run_cancellable(&token, || join(is_cancelled, is_cancelled));
        assert!(a && b);
        assert_eq!(join(is_cancelled, || 5), (false, 5));
    }

    #[test]
    fn a_join_on_a_rayon_worker_runs_both_there() {
        let pool = match rayon::ThreadPoolBuilder::new().num_threads(1).build() {
            Ok(p) => p,
            Err(e) => panic!("a one-thread pool: {e}"),
        };
        let (a, b) = pool.install(|| {
            join(
                || std::thread::current().id(),
                || std::thread::current().id(),
            )
        });
        assert_eq!(a, b);
    }

    #[test]
    fn concurrent_items_work_on_behalf_of_the_caller() {
        // A cancellation of the caller's token reaches the computations on the other threads,
        // as it would reach the caller's own: each stops at its next check.
        let token = CancelToken::new();
        let started = AtomicUsize::new(0);
        let out = run_cancellable(&token, || {
            concurrently(&[0, 1, 2], |_| {
                started.fetch_add(1, Ordering::AcqRel);
                let deadline = std::time::Instant::now() + Duration::from_secs(10);
                while std::time::Instant::now() < deadline {
                    if started.load(Ordering::Acquire) == 3 {
                        token.cancel();
                    }
                    if is_cancelled() {
                        return Err(TileError::Cancelled);
                    }
                    std::thread::yield_now();
                }
                Ok(())
            })
        });
        assert_eq!(out, vec![Err(TileError::Cancelled); 3]);
        // Without a token nothing is cancelled, on any thread.
        assert_eq!(
            concurrently(&[0, 1], |_| is_cancelled()),
            vec![false, false]
        );
    }

    #[test]
    fn a_lone_abandoned_computation_stops_and_leaves_nothing() {
        let flights: Flights<u8, u32> = Flights::new();
        let token = CancelToken::new();
        let release = AtomicBool::new(false);
        let steps = AtomicUsize::new(0);
        let published = AtomicUsize::new(0);
        std::thread::scope(|s| {
            let h = s.spawn(|| {
                run_cancellable(&token, || {
                    flights.run(
                        1,
                        || slow(&release, &steps),
                        |_| {
                            published.fetch_add(1, Ordering::Relaxed);
                        },
                    )
                })
            });
            wait_until("started", || steps.load(Ordering::Relaxed) >= 3);
            token.cancel();
            assert_eq!(h.join().unwrap(), Err(TileError::Cancelled));
        });
        assert_eq!(published.load(Ordering::Relaxed), 0);
        assert_eq!(flights.in_flight(), 0);
        // Nothing is poisoned: the next caller computes it.
        let again = flights.run(1, || Ok(9), |_| {});
        assert_eq!(again, Ok(9));
    }

    #[test]
    fn the_computation_goes_on_while_someone_still_waits() {
        let flights: Flights<u8, u32> = Flights::new();
        let (a, b) = (CancelToken::new(), CancelToken::new());
        let release = AtomicBool::new(false);
        let steps = AtomicUsize::new(0);
        let computed = AtomicUsize::new(0);
        std::thread::scope(|s| {
            let leader = s.spawn(|| {
                run_cancellable(&a, || {
                    flights.run(
                        1,
                        || {
                            computed.fetch_add(1, Ordering::Relaxed);
                            slow(&release, &steps)
                        },
                        |_| {},
                    )
                })
            });
            wait_until("started", || steps.load(Ordering::Relaxed) >= 2);
            let waiter = s.spawn(|| run_cancellable(&b, || flights.run(1, || Ok(0), |_| {})));
            // Wait until b has joined the flight, then the leader's own client leaves.
            wait_until("b joined", || {
                lock(&flights.map)
                    .get(&1)
                    .is_some_and(|f| lock(&f.waiters.0).len() >= 2)
            });
            a.cancel();
            std::thread::sleep(Duration::from_millis(30));
            release.store(true, Ordering::Release);
            // b still wanted it: it gets the value, computed once.
            assert_eq!(waiter.join().unwrap(), Ok(7));
            let _ = leader.join().unwrap();
        });
        assert_eq!(computed.load(Ordering::Relaxed), 1);
    }

    #[test]
    fn nested_computations_stop_only_when_every_outer_waiter_left() {
        // Outer flights 1 and 2 (two requests) both need inner flight 10.
        let outer: Flights<u8, u32> = Flights::new();
        let inner: Flights<u8, u32> = Flights::new();
        let (a, b) = (CancelToken::new(), CancelToken::new());
        let release = AtomicBool::new(false);
        let steps = AtomicUsize::new(0);
        let barrier = Barrier::new(3);
        let run = |token: &CancelToken, key: u8| {
            run_cancellable(token, || {
                outer.run(
                    key,
                    || {
                        barrier.wait();
                        inner.run(10, || slow(&release, &steps), |_| {})
                    },
                    |_| {},
                )
            })
        };
        std::thread::scope(|s| {
            let ha = s.spawn(|| run(&a, 1));
            let hb = s.spawn(|| run(&b, 2));
            barrier.wait();
            wait_until("both joined", || {
                lock(&inner.map)
                    .get(&10)
                    .is_some_and(|f| lock(&f.waiters.0).len() >= 2)
            });
            a.cancel();
            // b's request still needs the inner computation: it goes on (on whichever thread
            // leads it).
            let before = steps.load(Ordering::Relaxed);
            wait_until("the inner computation goes on", || {
                steps.load(Ordering::Relaxed) >= before + 3
            });
            b.cancel();
            assert_eq!(ha.join().unwrap(), Err(TileError::Cancelled));
            assert_eq!(hb.join().unwrap(), Err(TileError::Cancelled));
        });
        assert_eq!(inner.in_flight(), 0);
        assert_eq!(outer.in_flight(), 0);
    }

    #[test]
    fn work_without_a_token_is_never_cancelled() {
        let flights: Flights<u8, u32> = Flights::new();
        assert!(!is_cancelled());
        let t = CancelToken::new();
        t.cancel();
        let r = run_cancellable(&t, || uncancellable(|| flights.run(3, || Ok(4), |_| {})));
        assert_eq!(r, Ok(4));
        assert_eq!(
            run_cancellable(&t, || flights.run(3, || Ok(4), |_| {})),
            Err(TileError::Cancelled)
        );
    }
}
