//! Work over the runs of a campaign on a pool of threads, one run per thread at a time.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// `f` on every item of `items` on `pool`'s threads, the results in the items' order, with at
/// most two items per thread of the pool under way at a time.
///
/// Why not `items.par_iter()` inside `pool.install`: polars reads CSV and Parquet on a thread
/// pool of its own, and a rayon worker that waits for another pool runs whatever its own pool
/// has queued meanwhile. With every item queued at once, each such wait could start another
/// item on top of the waiting one's stack (holding that one's data as well): `railgrip run` on
/// a folder of 636 logs overflowed a worker's stack that way. Here two feeder threads per
/// thread of the pool each hand the pool their next item only when their last one is done, so
/// at most that many items are under way, and no stack holds more of them. Two, not one:
/// while a worker waits for polars to write a run (the atomic write's fsync), it computes the
/// next run, as it did with `par_iter` (one feeder per thread made the bundled archive's
/// estimation ~15 % slower).
///
/// A panic in `f` reaches the caller, as it would from `par_iter`.
pub fn each<I: Sync, T: Send>(
    pool: &rayon::ThreadPool,
    items: &[I],
    f: impl Fn(&I) -> T + Sync,
) -> Vec<T> {
    let next = AtomicUsize::new(0);
    let slots: Vec<Mutex<Option<T>>> = items.iter().map(|_| Mutex::new(None)).collect();
    let feeders = (2 * pool.current_num_threads()).clamp(1, items.len().max(1));
    std::thread::scope(|s| {
        for _ in 0..feeders {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(item) = items.get(i) else { break };
                let done = pool.install(|| f(item));
                *slots[i].lock().unwrap_or_else(|e| e.into_inner()) = Some(done);
            });
        }
    });
    slots
        .into_iter()
        .map(|m| {
            m.into_inner()
                .unwrap_or_else(|e| e.into_inner())
                .expect("every item was done (a feeder that panicked has panicked the scope)")
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;
    use std::sync::atomic::AtomicUsize;

    thread_local! {
        static DEPTH: Cell<usize> = const { Cell::new(0) };
    }

    /// Items that wait for another pool (as a polars read does) are never started more than
    /// twice the pool's threads deep on one thread's stack, over hundreds of items (with
    /// `par_iter` they were started 178 deep); every result comes back in order.
    #[test]
    fn items_that_wait_for_another_pool_do_not_nest_deeper_than_the_pool() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let other = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let deepest = AtomicUsize::new(0);
        let items: Vec<usize> = (0..300).collect();
        let out = each(&pool, &items, |&i| {
            let d = DEPTH.with(|c| {
                c.set(c.get() + 1);
                c.get()
            });
            deepest.fetch_max(d, Ordering::Relaxed);
            other.install(|| std::thread::sleep(std::time::Duration::from_micros(200)));
            DEPTH.with(|c| c.set(c.get() - 1));
            i * 2
        });
        assert_eq!(out, items.iter().map(|i| i * 2).collect::<Vec<_>>());
        let d = deepest.load(Ordering::Relaxed);
        assert!(d <= 4, "an item started {d} deep");
    }

    /// No items, no work; one item on a pool of several threads.
    #[test]
    fn empty_and_single() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap();
        assert!(each(&pool, &[] as &[u8], |_| 0).is_empty());
        assert_eq!(each(&pool, &[7], |x| x + 1), vec![8]);
    }
}
