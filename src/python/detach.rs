//! Running Rust work without the GIL, interruptible by Ctrl-C.

use crate::{interrupt, Error};
use pyo3::exceptions::PyKeyboardInterrupt;
use pyo3::prelude::*;
use std::sync::{Arc, Mutex};

/// Run `f` without the GIL while Python's signal handlers are polled (see
/// `crate::interrupt`), so that Ctrl-C stops a long solve within about 20 ms;
/// the handler's own exception (KeyboardInterrupt) is raised.
pub(super) fn detach_interruptible<T: Send>(
    py: Python<'_>,
    f: impl FnOnce() -> crate::Result<T> + Send,
) -> PyResult<T> {
    let (poll, pending) = signal_poll();
    raise_interrupt(py.detach(move || interrupt::with_check(poll, f)), &pending)
}

/// As [`detach_interruptible`], with `f` on a worker thread that is left to
/// wind down after Ctrl-C (`interrupt::on_worker`): for solves large enough
/// that one pass over the rod takes longer than the user should wait.
pub(super) fn detach_on_worker<T: Send + 'static>(
    py: Python<'_>,
    f: impl FnOnce() -> crate::Result<T> + Send + 'static,
) -> PyResult<T> {
    let (poll, pending) = signal_poll();
    raise_interrupt(py.detach(move || interrupt::on_worker(poll, f)), &pending)
}

/// [`detach_on_worker`] if one pass of `f` may outlast the poll interval
/// (`long`: `Settings::has_long_passes`), else [`detach_interruptible`].
pub(super) fn detach_solve<T: Send + 'static>(
    py: Python<'_>,
    long: bool,
    f: impl FnOnce() -> crate::Result<T> + Send + 'static,
) -> PyResult<T> {
    if long {
        detach_on_worker(py, f)
    } else {
        detach_interruptible(py, f)
    }
}

pub(super) type PendingSignal = Arc<Mutex<Option<PyErr>>>;

/// A poll of Python's signal handlers that keeps the exception a handler
/// raised (KeyboardInterrupt for Ctrl-C) for [`raise_interrupt`].
pub(super) fn signal_poll() -> (impl FnMut() -> bool + Send + 'static, PendingSignal) {
    let pending: PendingSignal = Arc::default();
    let slot = Arc::clone(&pending);
    let poll = move || {
        Python::attach(|py| match py.check_signals() {
            Ok(()) => false,
            Err(e) => {
                if let Ok(mut slot) = slot.lock() {
                    *slot = Some(e);
                }
                true
            }
        })
    };
    (poll, pending)
}

/// An interrupted computation raises the signal handler's exception.
pub(super) fn raise_interrupt<T>(result: crate::Result<T>, pending: &PendingSignal) -> PyResult<T> {
    match result {
        Err(Error::Interrupted) => Err(pending
            .lock()
            .ok()
            .and_then(|mut p| p.take())
            .unwrap_or_else(|| PyKeyboardInterrupt::new_err("interrupted"))),
        other => other.map_err(PyErr::from),
    }
}

/// Run a batch without the GIL on a scoped worker (which spreads it over
/// rayon's threads) while this thread, every [`interrupt::POLL_INTERVAL`],
/// checks Python's signals (a handler's exception stops the batch through
/// `control.stop` and is raised) and reports `control.done` of `total` to
/// `progress`, once more at the end. An exception in `progress` stops the
/// batch and is raised.
pub(super) fn detach_batch<T: Send>(
    py: Python<'_>,
    control: &crate::BatchControl,
    total: usize,
    progress: Option<&Bound<'_, PyAny>>,
    work: impl FnOnce() -> crate::Result<T> + Send,
) -> PyResult<T> {
    use std::sync::atomic::Ordering;
    let progress = progress.map(|p| p.clone().unbind());
    let mut raised: Option<PyErr> = None;
    let report = |done: usize, raised: &mut Option<PyErr>| {
        Python::attach(|py| {
            let outcome = py.check_signals().and_then(|()| match &progress {
                Some(p) => p.call1(py, (done, total)).map(|_| ()),
                None => Ok(()),
            });
            if let Err(e) = outcome {
                raised.get_or_insert(e);
                control.stop.store(true, Ordering::Relaxed);
            }
        })
    };
    let result = py.detach(|| {
        std::thread::scope(|scope| {
            let (sender, receiver) = std::sync::mpsc::channel();
            scope.spawn(move || {
                let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(work));
                let _ = sender.send(result);
            });
            loop {
                match receiver.recv_timeout(interrupt::POLL_INTERVAL) {
                    Ok(result) => return result,
                    Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                        if raised.is_none() {
                            report(control.done.load(Ordering::Relaxed), &mut raised);
                        }
                    }
                    Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                        unreachable!("the worker sends before it ends, even after a panic")
                    }
                }
            }
        })
    });
    let result = match result {
        Ok(result) => result,
        Err(panic) => std::panic::resume_unwind(panic),
    };
    if let Some(e) = raised {
        return Err(e);
    }
    if result.is_ok() {
        report(total, &mut raised);
        if let Some(e) = raised {
            return Err(e);
        }
    }
    result.map_err(PyErr::from)
}
