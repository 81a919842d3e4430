//! The `softspine._core` extension: conversions only. Every check lives in the
//! Rust core; its errors become `ValueError` (bad input) or `SolverError`
//! (a solve that did not converge, when the caller asked with `check=True`).
//!
//! One module per Python class or family of functions; `convert` holds the
//! readers every argument goes through and `detach` the GIL-free, interruptible
//! run of Rust work.

mod batch;
mod convert;
mod detach;
mod enums;
mod fitting;
mod robot;
mod scene;
mod settings;
mod solution;
mod solve;
mod solver;

use crate::Error;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt, PyMemoryError, PyValueError};
use pyo3::prelude::*;

pyo3::create_exception!(
    softspine._core,
    SolverError,
    PyException,
    "A solve did not converge (raised with check=True)."
);

impl From<Error> for PyErr {
    fn from(e: Error) -> PyErr {
        match e {
            Error::NotConverged { .. } => SolverError::new_err(e.to_string()),
            Error::Interrupted => PyKeyboardInterrupt::new_err(e.to_string()),
            Error::OutOfMemory { .. } => PyMemoryError::new_err(e.to_string()),
            _ => PyValueError::new_err(e.to_string()),
        }
    }
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<robot::PyRobot>()?;
    m.add_class::<robot::PyIkResult>()?;
    m.add_class::<robot::PyInverseSolver>()?;
    m.add_function(wrap_pyfunction!(robot::trajectory_points, m)?)?;
    m.add_class::<scene::PyScene>()?;
    m.add_function(wrap_pyfunction!(scene::read_obstacle, m)?)?;
    m.add_function(wrap_pyfunction!(scene::keys, m)?)?;
    m.add_class::<settings::PySettings>()?;
    m.add_class::<settings::PyPaperSettings>()?;
    m.add_class::<settings::PyAccuracy>()?;
    m.add_class::<settings::PyIkSettings>()?;
    m.add_class::<solution::PySolution>()?;
    m.add_class::<solver::PySolver>()?;
    m.add_function(wrap_pyfunction!(solve::solve, m)?)?;
    m.add_function(wrap_pyfunction!(batch::solve_batch, m)?)?;
    m.add_function(wrap_pyfunction!(fitting::calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(solve::residual, m)?)?;
    m.add_function(wrap_pyfunction!(solve::jacobian, m)?)?;
    m.add("SolverError", m.py().get_type::<SolverError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    enums::add_enums(m)?;
    Ok(())
}
