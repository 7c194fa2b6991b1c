//! A live run's queue: a bounded, drop-oldest queue between a frame source and the
//! estimator (a camera never waits; the estimator always gets the freshest frame), and the
//! frame it carries.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Instant;

use visuotact_image::RgbImage;

/// A captured frame on its way to the estimator.
#[derive(Clone, Debug)]
pub struct Captured {
    /// The frame's name (file name, `camera#N`, `iats_0004#12`).
    pub id: String,
    /// Its place in the source, from 0.
    pub index: u64,
    /// Capture time on the run's clock, seconds.
    pub timestamp_s: f64,
    /// When it was captured (for latency).
    pub captured: Instant,
    /// The pixels.
    pub image: Arc<RgbImage>,
}

/// A bounded queue that drops its oldest item when full: the estimator always gets the
/// freshest frames and never works through a backlog.
pub struct LatestQueue<T> {
    inner: Mutex<(VecDeque<T>, bool)>,
    ready: Condvar,
    cap: usize,
    dropped: AtomicU64,
}

impl<T> LatestQueue<T> {
    /// An empty queue holding at most `cap` items (at least 1).
    pub fn new(cap: usize) -> Self {
        Self {
            // Grown as items come: a large cap reserves nothing up front.
            inner: Mutex::new((VecDeque::with_capacity(cap.clamp(1, 64)), false)),
            ready: Condvar::new(),
            cap: cap.max(1),
            dropped: AtomicU64::new(0),
        }
    }

    /// Adds an item, dropping the oldest when full.
    pub fn push(&self, item: T) {
        let mut g = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        if g.0.len() >= self.cap {
            g.0.pop_front();
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
        g.0.push_back(item);
        self.ready.notify_one();
    }

    /// Adds an item, waiting while the queue is full (a source that must not lose frames:
    /// files and simulations run unpaced).
    pub fn push_wait(&self, item: T) {
        let mut g = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        while g.0.len() >= self.cap && !g.1 {
            g = self.ready.wait(g).unwrap_or_else(|e| e.into_inner());
        }
        g.0.push_back(item);
        self.ready.notify_all();
    }

    /// No more items will come.
    pub fn close(&self) {
        let mut g = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        g.1 = true;
        self.ready.notify_all();
    }

    /// The next item, waiting; `None` once closed and empty.
    pub fn pop(&self) -> Option<T> {
        let mut g = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        loop {
            if let Some(x) = g.0.pop_front() {
                self.ready.notify_all();
                return Some(x);
            }
            if g.1 {
                return None;
            }
            g = self.ready.wait(g).unwrap_or_else(|e| e.into_inner());
        }
    }

    /// Items dropped so far.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

/// Median and 99th percentile of `v` (sorted in place).
pub fn median_p99(v: &mut [f64]) -> (f64, f64) {
    percentiles(v, [0.5, 0.99]).into()
}

/// The `q` quantiles of `v` (nearest rank, sorted in place); NaN for an empty `v`.
pub fn percentiles<const N: usize>(v: &mut [f64], q: [f64; N]) -> [f64; N] {
    if v.is_empty() {
        return [f64::NAN; N];
    }
    v.sort_by(f64::total_cmp);
    q.map(|q| v[((v.len() - 1) as f64 * q).round() as usize])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_queue_keeps_the_newest_and_counts_drops() {
        let q = LatestQueue::new(2);
        for k in 0..5 {
            q.push(k);
        }
        q.close();
        assert_eq!(
            (q.pop(), q.pop(), q.pop(), q.dropped()),
            (Some(3), Some(4), None, 3)
        );
    }

    #[test]
    fn waiting_pushes_lose_nothing() {
        let q = Arc::new(LatestQueue::new(1));
        let producer = {
            let q = q.clone();
            std::thread::spawn(move || {
                for k in 0..50 {
                    q.push_wait(k);
                }
                q.close();
            })
        };
        let got: Vec<i32> = std::iter::from_fn(|| q.pop()).collect();
        producer.join().unwrap();
        assert_eq!(got, (0..50).collect::<Vec<_>>());
        assert_eq!(q.dropped(), 0);
    }

    #[test]
    fn percentiles() {
        let mut v: Vec<f64> = (1..=100).map(f64::from).rev().collect();
        let (m, p) = median_p99(&mut v);
        assert_eq!((m.round(), p), (51.0, 99.0));
        assert!(median_p99(&mut []).0.is_nan());
    }
}
