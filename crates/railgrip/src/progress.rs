//! One way long work reports while it runs: a campaign's runs and stages, a study's cells, a
//! network's epochs. The work calls [`Progress::event`] with its own event type; the caller
//! decides what to show (the CLI draws bars on a terminal and lines otherwise). Events may come
//! from worker threads, so receivers are shared (`&self`, `Sync`).
//!
//! The library never prints: a closure `|e| …` is a receiver, and [`Quiet`] ignores everything.

/// Receives events of type `E` from long-running work.
pub trait Progress<E>: Sync {
    fn event(&self, event: E);
}

/// A receiver that ignores every event (benchmarks, tests, library callers without a display).
#[derive(Debug, Clone, Copy, Default)]
pub struct Quiet;

impl<E> Progress<E> for Quiet {
    fn event(&self, _: E) {}
}

impl<E, F: Fn(E) + Sync> Progress<E> for F {
    fn event(&self, event: E) {
        self(event)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    fn count_to(n: usize, p: &dyn Progress<usize>) {
        for i in 0..n {
            p.event(i);
        }
    }

    #[test]
    fn closures_and_quiet_receive_events() {
        let sum = AtomicUsize::new(0);
        count_to(4, &|i| {
            sum.fetch_add(i, Ordering::Relaxed);
        });
        assert_eq!(sum.load(Ordering::Relaxed), 6);
        count_to(4, &Quiet);
    }
}
