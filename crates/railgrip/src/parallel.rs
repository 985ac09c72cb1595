//! Work over the runs of a campaign on a pool of threads, at most two runs per thread under
//! way at a time.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

/// The least stack of a thread of a campaign's pool, bytes: 16 MiB, 8× rayon's default.
const MIN_STACK_BYTES: usize = 16 << 20;

/// Stack room per run under way, bytes: 256 KiB, twice what one run needed (the bundled
/// archive's eight runs were estimated and calibrated on pools of 1 and 2 threads with
/// 128 KiB stacks; with 64 KiB they overflowed).
const RUN_STACK_BYTES: usize = 256 << 10;

/// A pool of `jobs` threads (`None`: as many as rayon's global pool) for [`each`], each with
/// room on its stack for every run [`each`] can have under way (2 × threads runs), and at
/// least [`MIN_STACK_BYTES`]. The stacks are reserved address space, touched only as used.
pub fn pool(jobs: Option<usize>) -> Result<rayon::ThreadPool, rayon::ThreadPoolBuildError> {
    let threads = jobs
        .filter(|j| *j > 0)
        .unwrap_or_else(rayon::current_num_threads);
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .stack_size(MIN_STACK_BYTES.max(2 * threads * RUN_STACK_BYTES))
        .build()
}

/// `f` on every item of `items` on `pool`'s threads, the results in the items' order, with at
/// most two items per thread of the pool under way at a time.
///
/// Why not `items.par_iter()` inside `pool.install`: polars reads CSV and reads and writes
/// Parquet on a thread pool of its own, and a rayon worker that waits for another pool runs
/// whatever its own pool has queued meanwhile. With every item queued at once, each such wait
/// could start another item on top of the waiting one's stack (holding that one's data as
/// well): `railgrip run` on a folder of 636 logs overflowed a worker's stack that way. Here two
/// feeder threads per thread of the pool each hand the pool their next item only when their
/// last one is done, so at most 2 × threads items are under way, and no stack can hold more of
/// them than that ([`pool`] gives the threads room for it). Two, not one: while a worker waits
/// for polars it can run the next item instead of idling; with one feeder per thread the
/// bundled archive's estimation took ~15 % longer.
///
/// Must not be called from a thread of `pool` itself (that thread would wait in the scope
/// instead of working, and with one thread nothing would run the items). A panic in `f` stops
/// the feeders from starting further items and reaches the caller with its own payload once
/// the items under way are done.
pub fn each<I: Sync, T: Send>(
    pool: &rayon::ThreadPool,
    items: &[I],
    f: impl Fn(&I) -> T + Sync,
) -> Vec<T> {
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let panicked = Mutex::new(None);
    let slots: Vec<Mutex<Option<T>>> = items.iter().map(|_| Mutex::new(None)).collect();
    let feeders = (2 * pool.current_num_threads()).clamp(1, items.len().max(1));
    std::thread::scope(|s| {
        for _ in 0..feeders {
            s.spawn(|| {
                while !stop.load(Ordering::Relaxed) {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(item) = items.get(i) else { break };
                    let run = std::panic::AssertUnwindSafe(|| pool.install(|| f(item)));
                    match std::panic::catch_unwind(run) {
                        Ok(done) => {
                            *slots[i].lock().unwrap_or_else(|e| e.into_inner()) = Some(done)
                        }
                        Err(payload) => {
                            stop.store(true, Ordering::Relaxed);
                            panicked
                                .lock()
                                .unwrap_or_else(|e| e.into_inner())
                                .get_or_insert(payload);
                        }
                    }
                }
            });
        }
    });
    if let Some(payload) = panicked.into_inner().unwrap_or_else(|e| e.into_inner()) {
        std::panic::resume_unwind(payload);
    }
    slots
        .into_iter()
        .map(|m| {
            m.into_inner()
                .unwrap_or_else(|e| e.into_inner())
                .expect("every item was done: the feeders stop early only on a panic")
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;

    thread_local! {
        static DEPTH: Cell<usize> = const { Cell::new(0) };
    }

    /// Items that wait for another pool (as a polars read does) are never started more than
    /// twice the pool's threads deep on one thread's stack, over hundreds of items (with
    /// `par_iter` they were started 178 deep); every result comes back in order.
    #[test]
    fn items_that_wait_for_another_pool_do_not_nest_deeper_than_the_pool() {
        let pool = pool(Some(2)).unwrap();
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
        let pool = pool(Some(3)).unwrap();
        assert!(each(&pool, &[] as &[u8], |_| 0).is_empty());
        assert_eq!(each(&pool, &[7], |x| x + 1), vec![8]);
    }

    /// A panic in one item reaches the caller with its own message, and the feeders stop
    /// starting items after it.
    #[test]
    fn a_panic_reaches_the_caller_with_its_message() {
        let pool = pool(Some(2)).unwrap();
        let started = AtomicUsize::new(0);
        let items: Vec<usize> = (0..1000).collect();
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            each(&pool, &items, |&i| {
                started.fetch_add(1, Ordering::Relaxed);
                if i == 3 {
                    panic!("item three is bad");
                }
                // All of them would take 0.5 s on the pool's two threads; the panic (its
                // message and backtrace printed first) stops the feeders well before.
                std::thread::sleep(std::time::Duration::from_millis(1));
            })
        }))
        .unwrap_err();
        assert_eq!(caught.downcast_ref::<&str>(), Some(&"item three is bad"));
        let n = started.load(Ordering::Relaxed);
        assert!(n < items.len(), "the feeders went on: {n} items started");
    }
}
