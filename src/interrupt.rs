//! Cooperative interruption of long computations (Ctrl-C from Python).
//!
//! A caller that can be interrupted runs its computation inside
//! [`with_check`], giving a poll function (Python: "has a signal arrived?").
//! The solvers call [`requested`] in their loops; it costs a thread-local read
//! and a clock read, and calls the poll function at most every
//! [`POLL_INTERVAL`], so the hot loops may call it often. Once the poll says
//! stop, [`requested`] stays true until `with_check` returns, every loop winds
//! down, and the entry points return [`Error::Interrupted`].

use crate::error::{Error, Result};
use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::time::{Duration, Instant};

/// Time between two calls of the poll function: well under the 0.1 s a user
/// expects between Ctrl-C and the prompt.
pub const POLL_INTERVAL: Duration = Duration::from_millis(20);

/// Elements or nodes between two interrupt polls in the O(n) passes.
pub(crate) const POLL_STRIDE: usize = 1 << 14;

struct Checker {
    poll: Box<dyn FnMut() -> bool>,
    last: Instant,
    stopped: bool,
}

thread_local! {
    static CHECKER: RefCell<Option<Checker>> = const { RefCell::new(None) };
}

/// Run `f` with `poll` as this thread's interrupt check. Nested calls keep the
/// outer check.
pub fn with_check<R>(poll: impl FnMut() -> bool + 'static, f: impl FnOnce() -> R) -> R {
    let installed = CHECKER.with(|c| {
        let mut c = c.borrow_mut();
        if c.is_some() {
            return false;
        }
        *c = Some(Checker {
            poll: Box::new(poll),
            last: Instant::now(),
            stopped: false,
        });
        true
    });
    // Remove the check even if `f` unwinds.
    struct Reset(bool);
    impl Drop for Reset {
        fn drop(&mut self) {
            if self.0 {
                CHECKER.with(|c| *c.borrow_mut() = None);
            }
        }
    }
    let _reset = Reset(installed);
    f()
}

/// Run `work` on a worker thread while the calling thread calls `poll` every
/// [`POLL_INTERVAL`]. When the poll says stop, the caller returns
/// [`Error::Interrupted`] at once and the worker, told through
/// [`requested`], winds down and frees its memory on its own: at millions of
/// elements one pass over the rod, or freeing its gigabyte of workspace,
/// takes longer than the 0.1 s a user waits after Ctrl-C, and the solvers
/// poll between passes, not inside every one. A panic in `work` resumes on
/// the caller's thread. Costs a thread start (tens of microseconds): for
/// large computations only.
pub fn on_worker<R: Send + 'static>(
    mut poll: impl FnMut() -> bool,
    work: impl FnOnce() -> Result<R> + Send + 'static,
) -> Result<R> {
    let stop = Arc::new(AtomicBool::new(false));
    let told = Arc::clone(&stop);
    let (sender, receiver) = mpsc::channel();
    std::thread::Builder::new()
        .name("softspine-solve".into())
        // The size of the main thread's stack, which the solvers were written for.
        .stack_size(8 << 20)
        .spawn(move || {
            let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                with_check(move || told.load(Ordering::Relaxed), work)
            }));
            // The caller may have left already: nobody to tell.
            let _ = sender.send(result);
        })
        .map_err(|e| Error::OutOfMemory {
            what: format!("starting a worker thread ({e})"),
            bytes: 8 << 20,
        })?;
    loop {
        match receiver.recv_timeout(POLL_INTERVAL) {
            Ok(Ok(result)) => return result,
            Ok(Err(panic)) => std::panic::resume_unwind(panic),
            Err(mpsc::RecvTimeoutError::Timeout) => {
                if poll() {
                    stop.store(true, Ordering::Relaxed);
                    return Err(Error::Interrupted);
                }
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                unreachable!("the worker sends before it ends, even after a panic")
            }
        }
    }
}

/// Run `work`, one pass that may outlast the poll interval where `long`, on
/// a worker thread while this thread polls its installed check
/// ([`on_worker`]); inline otherwise, or where no check is installed. For a
/// computation whose passes grow (accuracy on demand): the thread start
/// (about a millisecond here) only for the passes that need it.
pub fn on_worker_if<R: Send + 'static>(
    long: bool,
    work: impl FnOnce() -> Result<R> + Send + 'static,
) -> Result<R> {
    let installed = CHECKER.with(|c| c.try_borrow().is_ok_and(|c| c.is_some()));
    if !long || !installed {
        return work();
    }
    on_worker(requested, work)
}

/// Whether the computation should stop: polls the installed check at most
/// every [`POLL_INTERVAL`]; false when none is installed.
pub fn requested() -> bool {
    CHECKER.with(|c| {
        let Ok(mut c) = c.try_borrow_mut() else {
            return false;
        };
        let Some(checker) = c.as_mut() else {
            return false;
        };
        if !checker.stopped && checker.last.elapsed() >= POLL_INTERVAL {
            checker.last = Instant::now();
            checker.stopped = (checker.poll)();
        }
        checker.stopped
    })
}

/// `Err(Error::Interrupted)` once an interrupt was requested.
pub fn check() -> Result<()> {
    if requested() {
        Err(Error::Interrupted)
    } else {
        Ok(())
    }
}

/// A vector of `n` copies of `value`, allocated fallibly (a failed allocation
/// is [`Error::OutOfMemory`], never an abort) and filled in chunks between
/// interrupt polls: at millions of elements the first touch of the pages
/// alone takes a second.
pub fn filled<T: Clone>(n: usize, value: T, what: &str) -> Result<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|_| Error::OutOfMemory {
        what: what.to_string(),
        bytes: n.saturating_mul(std::mem::size_of::<T>()),
    })?;
    while v.len() < n {
        // The first chunk needs no poll: a small vector is filled at once.
        if !v.is_empty() {
            check()?;
        }
        let chunk = (n - v.len()).min(FILL_CHUNK);
        v.extend(std::iter::repeat_n(value.clone(), chunk));
    }
    Ok(v)
}

/// Elements filled between two polls by [`filled`].
const FILL_CHUNK: usize = 1 << 16;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_worker_is_left_behind_at_once_on_an_interrupt() {
        let started = Instant::now();
        let mut polls = 0;
        let result: Result<()> = on_worker(
            move || {
                polls += 1;
                polls == 2
            },
            || {
                // A pass that never polls, as one over millions of elements.
                std::thread::sleep(Duration::from_secs(2));
                Ok(())
            },
        );
        assert_eq!(result, Err(Error::Interrupted));
        assert!(started.elapsed() < Duration::from_millis(500));
    }

    #[test]
    fn a_worker_returns_its_result_and_tells_it_to_stop() {
        let result = on_worker(
            || true,
            || {
                while !requested() {
                    std::thread::sleep(Duration::from_millis(1));
                }
                Ok(7)
            },
        );
        // Told to stop on the first poll: the caller leaves, the worker ends.
        assert_eq!(result, Err(Error::Interrupted));
        assert_eq!(on_worker(|| false, || Ok(7)), Ok(7));
    }

    #[test]
    #[should_panic(expected = "from the worker")]
    fn a_panic_on_the_worker_resumes_on_the_caller() {
        let _ = on_worker(|| false, || -> Result<()> { panic!("from the worker") });
    }
}
