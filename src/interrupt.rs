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
use std::time::{Duration, Instant};

/// Time between two calls of the poll function: well under the 0.1 s a user
/// expects between Ctrl-C and the prompt.
pub const POLL_INTERVAL: Duration = Duration::from_millis(20);

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
        check()?;
        let chunk = (n - v.len()).min(FILL_CHUNK);
        v.extend(std::iter::repeat_n(value.clone(), chunk));
    }
    Ok(v)
}

/// Elements filled between two polls by [`filled`].
const FILL_CHUNK: usize = 1 << 16;
