//! Failed admin authentications, per client address: logged (at most once per address and
//! window, and at most [`MAX_LOG_LINES`] lines per window over all addresses) and rate-limited.
//! An address that fails `limit` times within a one-minute window gets 429 for every admin
//! request until its window ends — a correct token included, or the limit would not slow down
//! guessing. The table is bounded ([`MAX_ADDRESSES`]): expired windows are dropped first, then the
//! oldest.

use std::collections::HashMap;
use std::net::IpAddr;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Length of a rate-limiting window.
pub const WINDOW: Duration = Duration::from_secs(60);
/// Addresses tracked at most.
pub const MAX_ADDRESSES: usize = 4096;
/// Log lines about failed authentications per window, over all addresses.
pub const MAX_LOG_LINES: u32 = 30;

#[derive(Clone, Copy, Debug)]
struct Window {
    start: Instant,
    failures: u32,
}

#[derive(Debug)]
struct Table {
    by_address: HashMap<IpAddr, Window>,
    log_window: Instant,
    log_lines: u32,
    unlogged: u64,
}

/// The failure table of the admin API.
#[derive(Debug)]
pub struct AuthThrottle {
    limit: u32,
    table: Mutex<Table>,
}

/// What to do with a request from an address.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Check its token.
    Check,
    /// Refuse it (429) for this many more seconds.
    Throttled(u64),
}

impl AuthThrottle {
    /// A throttle allowing `limit` failures per address and minute.
    pub fn new(limit: u32) -> Self {
        AuthThrottle {
            limit: limit.max(1),
            table: Mutex::new(Table {
                by_address: HashMap::new(),
                log_window: Instant::now(),
                log_lines: 0,
                unlogged: 0,
            }),
        }
    }

    fn table(&self) -> std::sync::MutexGuard<'_, Table> {
        self.table.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Whether a request from `addr` may have its token checked.
    pub fn verdict(&self, addr: IpAddr) -> Verdict {
        let now = Instant::now();
        let t = self.table();
        match t.by_address.get(&addr) {
            Some(w) if w.failures >= self.limit => {
                let left = WINDOW.saturating_sub(now.duration_since(w.start));
                if left.is_zero() {
                    Verdict::Check
                } else {
                    Verdict::Throttled(left.as_secs().max(1))
                }
            }
            _ => Verdict::Check,
        }
    }

    /// Records a failed authentication from `addr` (`why`: missing or wrong token) and logs it
    /// when this address has not been logged in its window and the global log budget allows.
    pub fn failed(&self, addr: IpAddr, why: &str) {
        let now = Instant::now();
        let mut t = self.table();
        if now.duration_since(t.log_window) >= WINDOW {
            if t.unlogged > 0 {
                tracing::warn!(
                    failures = t.unlogged,
                    "admin authentication: further failures were not logged in the last minute"
                );
            }
            t.log_window = now;
            t.log_lines = 0;
            t.unlogged = 0;
        }
        if !t.by_address.contains_key(&addr) && t.by_address.len() >= MAX_ADDRESSES {
            t.by_address
                .retain(|_, w| now.duration_since(w.start) < WINDOW);
            if t.by_address.len() >= MAX_ADDRESSES {
                if let Some(oldest) = t
                    .by_address
                    .iter()
                    .min_by_key(|(_, w)| w.start)
                    .map(|(a, _)| *a)
                {
                    t.by_address.remove(&oldest);
                }
            }
        }
        let limit = self.limit;
        let w = t.by_address.entry(addr).or_insert(Window {
            start: now,
            failures: 0,
        });
        if now.duration_since(w.start) >= WINDOW {
            *w = Window {
                start: now,
                failures: 0,
            };
        }
        w.failures = w.failures.saturating_add(1);
        let failures = w.failures;
        // One line when an address first fails in its window, one when it is throttled.
        let worth_a_line = failures == 1 || failures == limit;
        if worth_a_line && t.log_lines < MAX_LOG_LINES {
            t.log_lines += 1;
            if failures >= limit {
                tracing::warn!(client = %addr, failures, "admin authentication failed too often: address throttled for a minute");
            } else {
                tracing::warn!(client = %addr, reason = why, "admin authentication failed");
            }
        } else {
            t.unlogged = t.unlogged.saturating_add(1);
        }
    }

    /// Addresses tracked now.
    pub fn tracked(&self) -> usize {
        self.table().by_address.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_address_is_throttled_after_its_limit_and_others_are_not() {
        let t = AuthThrottle::new(3);
        let a: IpAddr = [10, 0, 0, 1].into();
        let b: IpAddr = [10, 0, 0, 2].into();
        for _ in 0..3 {
            assert_eq!(t.verdict(a), Verdict::Check);
            t.failed(a, "wrong token");
        }
        assert!(matches!(t.verdict(a), Verdict::Throttled(s) if (1..=60).contains(&s)));
        assert_eq!(t.verdict(b), Verdict::Check);
    }

    #[test]
    fn the_table_stays_bounded() {
        let t = AuthThrottle::new(3);
        for i in 0..(MAX_ADDRESSES as u32 + 100) {
            t.failed(IpAddr::from(i.to_be_bytes()), "wrong token");
        }
        assert!(t.tracked() <= MAX_ADDRESSES);
    }
}
