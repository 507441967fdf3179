//! The Priority-Flood's queue for grids of fewer than 2³¹ cells: every cell's entry (its order key
//! and its row-major index) is known before the flood starts and a cell enters at most once, so
//! the entries are ranked once, by a radix sort, and the queue is a bitset over the ranks. Each
//! cell's rank is its tag in the flood's grid, kept beside its value ([`MinQueue::tag_cells`]),
//! so a push sets its bit without looking the rank up in another array. The smallest entry is
//! the first set bit, found from a cursor that only moves back when a push lands before it. The
//! flood's pushes all lie above the entry being processed, so the cursor sweeps the bitset once:
//! a pop costs a bit scan instead of a heap's sift-down.
//!
//! It pops the same sequence as any other [`MinQueue`] holding the same entries (they are
//! distinct), so the flood's bits do not depend on it; the flood's property test compares it with
//! the standard library's binary heap.

use super::flood::MinQueue;

/// A min-queue of the entries `(key << 32) | index` of one grid's cells, each cell's key fixed
/// in advance. A cell's rank (the position of its entry in increasing order) is the tag
/// [`MinQueue::tag_cells`] gives it, and [`MinQueue::push`] takes the entry's place from it.
/// Pushing an entry with another cell's tag is a logic error (debug-asserted).
#[derive(Debug)]
pub(crate) struct RankQueue {
    /// Every cell's entry, in increasing order.
    sorted: Vec<u64>,
    /// One bit per rank, set while that entry is queued.
    bits: Vec<u64>,
    /// The first non-zero word of `bits`, or `bits.len()` when the queue is empty.
    first: usize,
}

impl RankQueue {
    /// An empty queue for the cells whose entries are `entries` (`(key << 32) | index`, in
    /// increasing index order). There must be fewer than 2³¹ entries.
    pub(crate) fn new(mut entries: Vec<u64>) -> Self {
        debug_assert!(entries.len() < 1 << 31);
        sort_by_key(&mut entries);
        let words = entries.len().div_ceil(64);
        RankQueue {
            sorted: entries,
            bits: vec![0; words],
            first: words,
        }
    }
}

/// Bits per digit of [`sort_by_key`]: three digits cover the 32-bit key (eleven, eleven, ten),
/// one pass fewer than bytes when all four bytes of the keys vary (an elevation grid's exponent
/// spans the top byte as soon as its range crosses a power of two), and 2,048 counters a digit
/// still sit in the L1 cache.
const DIGIT_BITS: u32 = 11;

/// Sorts entries `(key << 32) | index` that come in increasing index order into increasing
/// order: a stable least-significant-digit radix sort on the key's [`DIGIT_BITS`]-bit digits,
/// skipping the digits every entry shares, so ties stay in index order.
fn sort_by_key(v: &mut Vec<u64>) {
    const RADIX: usize = 1 << DIGIT_BITS;
    const DIGITS: usize = 32usize.div_ceil(DIGIT_BITS as usize);
    let digit = |e: u64, d: usize| ((e >> (32 + DIGIT_BITS as usize * d)) as usize) & (RADIX - 1);
    let mut counts = vec![[0usize; RADIX]; DIGITS];
    for &e in v.iter() {
        for (d, count) in counts.iter_mut().enumerate() {
            count[digit(e, d)] += 1;
        }
    }
    let mut out = vec![0u64; v.len()];
    for (d, count) in counts.iter().enumerate() {
        if count.contains(&v.len()) {
            continue;
        }
        let mut next = [0usize; RADIX];
        let mut sum = 0;
        for (slot, &k) in next.iter_mut().zip(count) {
            *slot = sum;
            sum += k;
        }
        for &e in v.iter() {
            let k = digit(e, d);
            out[next[k]] = e;
            next[k] += 1;
        }
        std::mem::swap(v, &mut out);
    }
}

impl MinQueue<u64> for RankQueue {
    #[inline]
    fn push(&mut self, e: u64, tag: u32) {
        let r = tag as usize;
        debug_assert_eq!(self.sorted[r], e, "an entry with another cell's tag");
        self.bits[r >> 6] |= 1 << (r & 63);
        self.first = self.first.min(r >> 6);
    }

    #[inline]
    fn peek(&self) -> Option<u64> {
        let word = *self.bits.get(self.first)?;
        Some(self.sorted[self.first * 64 + word.trailing_zeros() as usize])
    }

    #[inline]
    fn pop(&mut self) -> Option<u64> {
        let word = self.bits.get_mut(self.first)?;
        let r = self.first * 64 + word.trailing_zeros() as usize;
        *word &= *word - 1;
        while self.bits.get(self.first) == Some(&0) {
            self.first += 1;
        }
        Some(self.sorted[r])
    }

    fn tag_cells(&self, mut tag: impl FnMut(usize, u32)) {
        for (r, &e) in self.sorted.iter().enumerate() {
            tag((e & 0xFFFF_FFFF) as usize, r as u32);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    fn xorshift(mut x: u64) -> impl FnMut() -> u64 {
        move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        }
    }

    /// The entries `(key << 32) | index` of `keys`, in index order.
    fn entries(keys: &[u32]) -> Vec<u64> {
        keys.iter()
            .enumerate()
            .map(|(i, &k)| (u64::from(k) << 32) | i as u64)
            .collect()
    }

    /// The ranked entries are the cells' entries in increasing order, for keys that are all
    /// equal (no byte to sort on), keys with many ties and keys that differ in every byte; each
    /// cell is tagged once, with its entry's rank.
    #[test]
    fn the_ranks_sort_the_entries() {
        let mut next = xorshift(0x9E37_79B9_7F4A_7C15);
        for spread in [1u64, 7, 1 << 12, 1 << 32] {
            let keys: Vec<u32> = (0..5000).map(|_| (next() % spread) as u32).collect();
            let q = RankQueue::new(entries(&keys));
            let mut expected = entries(&keys);
            expected.sort_unstable();
            assert_eq!(q.sorted, expected);
            let mut tags = vec![None; keys.len()];
            q.tag_cells(|i, r| {
                assert_eq!(tags[i].replace(r), None, "cell {i} tagged twice");
            });
            for (r, &e) in q.sorted.iter().enumerate() {
                assert_eq!(tags[(e & 0xFFFF_FFFF) as usize], Some(r as u32));
            }
        }
    }

    /// Pushes in any order (before the cursor too) and pops interleaved: the queue pops what an
    /// ordered set pops.
    #[test]
    fn the_rank_queue_pops_in_order() {
        let mut next = xorshift(0x2545_F491_4F6C_DD1D);
        let n = 3000usize;
        let keys: Vec<u32> = (0..n).map(|_| (next() % 400) as u32).collect();
        let entry = |i: usize| (u64::from(keys[i]) << 32) | i as u64;
        let mut queue = RankQueue::new(entries(&keys));
        let mut rank = vec![0u32; n];
        queue.tag_cells(|i, r| rank[i] = r);
        let mut reference = BTreeSet::new();
        let mut unpushed: Vec<usize> = (0..n).collect();
        for round in 0..2 * n {
            if round % 3 == 2 || unpushed.is_empty() {
                assert_eq!(queue.pop(), reference.pop_first());
            } else {
                let i = unpushed.swap_remove((next() % unpushed.len() as u64) as usize);
                queue.push(entry(i), rank[i]);
                reference.insert(entry(i));
            }
            assert_eq!(queue.peek(), reference.first().copied());
        }
        while let Some(e) = reference.pop_first() {
            assert_eq!(queue.pop(), Some(e));
        }
        assert_eq!((queue.peek(), queue.pop()), (None, None));
        let mut empty = RankQueue::new(Vec::new());
        assert_eq!((empty.peek(), empty.pop()), (None, None));
    }
}
