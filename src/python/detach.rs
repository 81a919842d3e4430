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
