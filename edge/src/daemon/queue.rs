//! A bounded hand-off between the frame source and the pipeline that drops
//! the oldest frame when the pipeline falls behind: a navigation estimate
//! wants the newest frame, not a backlog.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Condvar, Mutex};

pub struct DropOldest<T> {
    state: Mutex<(VecDeque<T>, bool)>,
    ready: Condvar,
    space: Condvar,
    capacity: usize,
    dropped: AtomicU64,
}

impl<T> DropOldest<T> {
    pub fn new(capacity: usize) -> Self {
        Self {
            state: Mutex::new((VecDeque::with_capacity(capacity.max(1)), false)),
            ready: Condvar::new(),
            space: Condvar::new(),
            capacity: capacity.max(1),
            dropped: AtomicU64::new(0),
        }
    }

    /// Add `item`; when full, the oldest waiting item is dropped (and counted).
    pub fn push(&self, item: T) {
        let mut state = self.state.lock().unwrap_or_else(|p| p.into_inner());
        if state.0.len() >= self.capacity {
            state.0.pop_front();
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
        state.0.push_back(item);
        self.ready.notify_one();
    }

    /// Add `item`, waiting for room instead of dropping: for replays that
    /// need every frame rather than the newest.
    pub fn push_blocking(&self, item: T) {
        let mut state = self.state.lock().unwrap_or_else(|p| p.into_inner());
        while state.0.len() >= self.capacity && !state.1 {
            state = self.space.wait(state).unwrap_or_else(|p| p.into_inner());
        }
        state.0.push_back(item);
        self.ready.notify_one();
    }

    /// The oldest waiting item; blocks until there is one. `None` once closed and empty.
    pub fn pop(&self) -> Option<T> {
        let mut state = self.state.lock().unwrap_or_else(|p| p.into_inner());
        loop {
            if let Some(item) = state.0.pop_front() {
                self.space.notify_one();
                return Some(item);
            }
            if state.1 {
                return None;
            }
            state = self.ready.wait(state).unwrap_or_else(|p| p.into_inner());
        }
    }

    /// No more items will come: `pop` drains what is left, then returns `None`.
    pub fn close(&self) {
        let mut state = self.state.lock().unwrap_or_else(|p| p.into_inner());
        state.1 = true;
        self.ready.notify_all();
        self.space.notify_all();
    }

    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    #[test]
    fn a_full_queue_drops_the_oldest_and_counts_it() {
        let q = DropOldest::new(2);
        for i in 0..5 {
            q.push(i);
        }
        assert_eq!(q.dropped(), 3);
        q.close();
        assert_eq!((q.pop(), q.pop(), q.pop()), (Some(3), Some(4), None));
    }

    #[test]
    fn blocking_push_loses_nothing() {
        let q = Arc::new(DropOldest::new(1));
        let producer = {
            let q = q.clone();
            std::thread::spawn(move || {
                for i in 0..50 {
                    q.push_blocking(i);
                }
                q.close();
            })
        };
        let got: Vec<i32> = std::iter::from_fn(|| q.pop()).collect();
        producer.join().expect("producer");
        assert_eq!(got, (0..50).collect::<Vec<_>>());
        assert_eq!(q.dropped(), 0);
    }

    #[test]
    fn pop_waits_for_a_producer_and_ends_when_closed() {
        let q = Arc::new(DropOldest::new(4));
        let producer = {
            let q = q.clone();
            std::thread::spawn(move || {
                for i in 0..3 {
                    q.push(i);
                }
                q.close();
            })
        };
        let mut got = Vec::new();
        while let Some(i) = q.pop() {
            got.push(i);
        }
        producer.join().expect("producer");
        assert_eq!(got.len() as u64 + q.dropped(), 3);
        assert_eq!(got.last(), Some(&2), "the newest always arrives");
    }
}
