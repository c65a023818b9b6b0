//! The bounded worker pool that mesh work runs on: never the async runtime's threads, never an
//! unbounded blocking pool.
//!
//! `concurrency` jobs run at once on a dedicated rayon pool (the core's own parallelism stays
//! inside it); up to `queue` more wait. A job beyond that is refused at once, so that a burst
//! costs the client a 503 and a retry, not the server its memory. A job that panics reports the
//! panic instead of a result; the worker thread survives.
//!
//! A request takes its place with [`WorkerPool::reserve`] when it arrives, before its body is
//! read: a place is then a promise of service, and what waits for a worker is bounded by
//! `concurrency + queue` whether it is still uploading or already queued. Taking the place only
//! once the body was in let every arrival upload while the pool looked free: under overload
//! dozens of uploads shared the cores, each took hundreds of milliseconds, and most then found
//! the queue full and were refused having been read for nothing.

use std::panic::AssertUnwindSafe;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use tokio::sync::oneshot;

/// Refused: the pool is running and queueing as many jobs as it may.
#[derive(Debug)]
pub struct Overloaded;

/// The job panicked; the message, if it had one.
#[derive(Debug)]
pub struct Panicked(pub String);

pub struct WorkerPool {
    threads: rayon::ThreadPool,
    capacity: usize,
    /// Jobs accepted and not finished (queued + running).
    admitted: Arc<AtomicUsize>,
    running: Arc<AtomicUsize>,
}

/// Releases a job's slot when dropped, whether the job finished, panicked or was never run.
struct Slot {
    admitted: Arc<AtomicUsize>,
}

impl Drop for Slot {
    fn drop(&mut self) {
        self.admitted.fetch_sub(1, Ordering::AcqRel);
    }
}

impl WorkerPool {
    pub fn new(concurrency: usize, queue: usize) -> std::io::Result<Self> {
        let threads = rayon::ThreadPoolBuilder::new()
            .num_threads(concurrency.max(1))
            .thread_name(|i| format!("tspace-worker-{i}"))
            .build()
            .map_err(std::io::Error::other)?;
        Ok(WorkerPool {
            threads,
            capacity: concurrency.max(1) + queue,
            admitted: Arc::new(AtomicUsize::new(0)),
            running: Arc::new(AtomicUsize::new(0)),
        })
    }

    /// Places taken and not running: requests whose body is still arriving, and jobs waiting
    /// for a worker.
    pub fn queued(&self) -> usize {
        self.admitted
            .load(Ordering::Acquire)
            .saturating_sub(self.running.load(Ordering::Acquire))
    }

    /// Whether [`WorkerPool::reserve`] would refuse now.
    pub fn is_full(&self) -> bool {
        self.admitted.load(Ordering::Acquire) >= self.capacity
    }

    pub fn running(&self) -> usize {
        self.running.load(Ordering::Acquire)
    }

    /// A place for one job, or a refusal when the pool is full. The place is given back when
    /// the job it was submitted with is done, or when it is dropped unused.
    pub fn reserve(&self) -> Result<Reservation<'_>, Overloaded> {
        let admitted = self
            .admitted
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |n| {
                (n < self.capacity).then_some(n + 1)
            });
        if admitted.is_err() {
            return Err(Overloaded);
        }
        Ok(Reservation {
            pool: self,
            slot: Slot {
                admitted: Arc::clone(&self.admitted),
            },
        })
    }

    /// Queues `job`, or refuses it when the pool is full. The receiver yields the job's result,
    /// or its panic.
    #[cfg(test)]
    pub fn submit<T, F>(&self, job: F) -> Result<oneshot::Receiver<Result<T, Panicked>>, Overloaded>
    where
        T: Send + 'static,
        F: FnOnce() -> T + Send + 'static,
    {
        Ok(self.reserve()?.submit(job))
    }
}

/// A place in the pool, taken by [`WorkerPool::reserve`].
pub struct Reservation<'a> {
    pool: &'a WorkerPool,
    slot: Slot,
}

impl Reservation<'_> {
    /// Queues `job` in this place. The receiver yields the job's result, or its panic.
    pub fn submit<T, F>(self, job: F) -> oneshot::Receiver<Result<T, Panicked>>
    where
        T: Send + 'static,
        F: FnOnce() -> T + Send + 'static,
    {
        let Reservation { pool, slot } = self;
        let running = Arc::clone(&pool.running);
        let (sender, receiver) = oneshot::channel();
        pool.threads.spawn(move || {
            running.fetch_add(1, Ordering::AcqRel);
            let outcome = std::panic::catch_unwind(AssertUnwindSafe(job)).map_err(|payload| {
                let message = payload
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| payload.downcast_ref::<String>().cloned())
                    .unwrap_or_default();
                Panicked(message)
            });
            running.fetch_sub(1, Ordering::AcqRel);
            drop(slot);
            // The client may have gone (timed out or disconnected); the result is then dropped.
            let _ = sender.send(outcome);
        });
        receiver
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::mpsc;

    #[tokio::test]
    async fn refuses_beyond_capacity_and_recovers() {
        let pool = WorkerPool::new(1, 1).unwrap();
        let (release, gate) = mpsc::channel::<()>();
        let gate = Arc::new(std::sync::Mutex::new(gate));
        let blocked = |gate: Arc<std::sync::Mutex<mpsc::Receiver<()>>>| {
            move || {
                let _ = gate.lock().map(|g| g.recv());
                7
            }
        };
        let first = pool.submit(blocked(Arc::clone(&gate))).unwrap();
        let second = pool.submit(blocked(Arc::clone(&gate))).unwrap();
        assert!(pool.submit(|| 0).is_err(), "a third job must be refused");
        release.send(()).unwrap();
        release.send(()).unwrap();
        assert_eq!(first.await.unwrap().unwrap(), 7);
        assert_eq!(second.await.unwrap().unwrap(), 7);
        assert_eq!(pool.submit(|| 1).unwrap().await.unwrap().unwrap(), 1);
    }

    #[tokio::test]
    async fn a_reserved_place_counts_until_used_or_dropped() {
        let pool = WorkerPool::new(1, 1).unwrap();
        let first = pool.reserve().unwrap();
        let second = pool.reserve().unwrap();
        assert!(pool.is_full() && pool.reserve().is_err());
        drop(second);
        assert!(!pool.is_full());
        assert_eq!(first.submit(|| 3).await.unwrap().unwrap(), 3);
        assert_eq!(pool.queued() + pool.running(), 0);
    }

    #[tokio::test]
    async fn a_panic_is_a_result_and_the_pool_goes_on() {
        let pool = WorkerPool::new(1, 0).unwrap();
        let outcome = pool
            .submit(|| -> u8 { panic!("boom") })
            .unwrap()
            .await
            .unwrap();
        assert_eq!(outcome.unwrap_err().0, "boom");
        assert_eq!(pool.submit(|| 2).unwrap().await.unwrap().unwrap(), 2);
        assert_eq!(pool.queued() + pool.running(), 0);
    }
}
