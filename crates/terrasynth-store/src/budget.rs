//! A memory budget shared by work in progress (exemplar uploads): each piece of work reserves the
//! bytes it will hold before it allocates them, and gives them back when its [`Reservation`] is
//! dropped. A reservation larger than the whole budget is refused as too large; one that does not
//! fit in what is free now is refused as busy (the caller answers "retry later"), so the budget
//! bounds the memory of all the work together without making anyone wait.

use std::sync::{Arc, Mutex};

use crate::error::ServiceError;

/// Bytes in a MiB, for messages.
const MIB: u64 = 1 << 20;

/// The budget.
#[derive(Debug)]
pub struct MemoryBudget {
    capacity: u64,
    used: Mutex<u64>,
}

/// Bytes reserved from a [`MemoryBudget`], given back on drop.
#[derive(Debug)]
pub struct Reservation {
    budget: Arc<MemoryBudget>,
    bytes: u64,
}

impl Drop for Reservation {
    fn drop(&mut self) {
        let mut used = self.budget.lock();
        *used = used.saturating_sub(self.bytes);
    }
}

impl Reservation {
    /// Bytes reserved.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }
}

impl MemoryBudget {
    /// A budget of `capacity` bytes.
    pub fn new(capacity: u64) -> Arc<Self> {
        Arc::new(MemoryBudget {
            capacity,
            used: Mutex::new(0),
        })
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, u64> {
        self.used.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The budget's size, bytes.
    pub fn capacity(&self) -> u64 {
        self.capacity
    }

    /// Bytes reserved now.
    pub fn used(&self) -> u64 {
        *self.lock()
    }

    /// Reserves `bytes` for `what`: [`ServiceError::TooLarge`] when they exceed the whole budget,
    /// [`ServiceError::Busy`] when they exceed what is free now.
    pub fn reserve(self: &Arc<Self>, bytes: u64, what: &str) -> Result<Reservation, ServiceError> {
        if bytes > self.capacity {
            return Err(ServiceError::TooLarge(format!(
                "{what} needs about {} MiB of memory to decode, more than the upload memory \
                 budget of {} MiB",
                bytes.div_ceil(MIB),
                self.capacity / MIB
            )));
        }
        let mut used = self.lock();
        if used.saturating_add(bytes) > self.capacity {
            return Err(ServiceError::Busy(format!(
                "{what} needs about {} MiB of memory to decode and other uploads hold the upload \
                 memory budget; retry shortly",
                bytes.div_ceil(MIB)
            )));
        }
        *used += bytes;
        Ok(Reservation {
            budget: self.clone(),
            bytes,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reservations_add_up_and_come_back() {
        let b = MemoryBudget::new(100);
        let r1 = b.reserve(60, "a").unwrap();
        assert!(matches!(b.reserve(50, "b"), Err(ServiceError::Busy(_))));
        assert!(matches!(
            b.reserve(101, "c"),
            Err(ServiceError::TooLarge(_))
        ));
        let r2 = b.reserve(40, "d").unwrap();
        assert_eq!(b.used(), 100);
        drop(r1);
        assert_eq!(b.used(), 40);
        drop(r2);
        assert_eq!(b.used(), 0);
    }
}
