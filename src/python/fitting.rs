//! Sensitivities (`Solver.sensitivity`, `Robot.sensitivity`) and
//! `softspine.calibrate`, into the dataclasses of `softspine.sensitivity`.

use super::convert::*;
use super::robot::{robot_arg, PyRobot};
use super::solution::PySolution;
use crate::{CalibrationSettings, Robot, Sensitivity, Solution};
use nalgebra::Vector3;
use numpy::ndarray::{Array1, Array2};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString, PyTuple};

/// `parameters`: a name or a sequence of names, each refused by its index.
pub(super) fn parameter_names(obj: &Bound<'_, PyAny>) -> PyResult<Vec<String>> {
    if obj.is_instance_of::<PyString>() {
        return Ok(vec![str_arg("parameters", obj)?]);
    }
    let path = Path::argument("parameters");
    let items: Vec<Bound<'_, PyAny>> = match (obj.cast::<PyList>(), obj.cast::<PyTuple>()) {
        (Ok(l), _) => l.iter().collect(),
        (_, Ok(t)) => t.iter().collect(),
        _ => {
            return Err(path.error(format!(
                "expected a name or a list of names, got {}",
                type_name(obj)
            )))
        }
    };
    items
        .iter()
        .enumerate()
        .map(|(i, x)| {
            x.cast::<PyString>()
                .map_err(|_| {
                    path.index(i)
                        .error(format!("expected a name, got {}", type_name(x)))
                })
                .and_then(|s| Ok(s.to_str()?.to_owned()))
        })
        .collect()
}

fn matrix<'py>(py: Python<'py>, m: &nalgebra::Matrix3xX<f64>) -> Bound<'py, PyAny> {
    Array2::from_shape_fn((3, m.ncols()), |(r, c)| m[(r, c)])
        .into_pyarray(py)
        .into_any()
}

/// The fields of the `softspine.sensitivity.Sensitivity` of the core's.
pub(super) fn sensitivity_result<'py>(
    py: Python<'py>,
    s: &Sensitivity,
    solution: Option<Solution>,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("parameters", s.parameters.clone())?;
    d.set_item("tip_position", matrix(py, &s.tip_position))?;
    d.set_item("tip_rotation", matrix(py, &s.tip_rotation))?;
    d.set_item(
        "tip_reaction_force",
        s.tip_reaction_force.as_ref().map(|m| matrix(py, m)),
    )?;
    d.set_item(
        "tip_reaction_moment",
        s.tip_reaction_moment.as_ref().map(|m| matrix(py, m)),
    )?;
    d.set_item("exact", s.exact.clone())?;
    d.set_item("solution", solution.map(|inner| PySolution { inner }))?;
    Ok(d)
}

/// Fit robot fields to measured tips: the fields of a ``Calibration``.
/// ``softspine.calibrate`` calls it.
#[pyfunction(name = "_calibrate")]
#[pyo3(signature = (robot, actuations, measured_tips, parameters, load=None, *, max_iterations=None, threads=None))]
#[allow(clippy::too_many_arguments)]
pub(super) fn calibrate<'py>(
    py: Python<'py>,
    #[pyo3(from_py_with = robot_arg)] robot: Robot,
    actuations: &Bound<'py, PyAny>,
    measured_tips: &Bound<'py, PyAny>,
    parameters: &Bound<'py, PyAny>,
    #[pyo3(from_py_with = load_arg)] load: Option<crate::robot::Load>,
    max_iterations: Option<&Bound<'py, PyAny>>,
    threads: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let load = load.unwrap_or_default();
    warn_user(py, &robot.load_warnings(&load))?;
    let k = samples_arg::<2>("actuations", actuations, robot.body.sections)?;
    let measured: Vec<Vector3<f64>> = rows_of::<3>("measured_tips", measured_tips)?
        .into_iter()
        .map(Vector3::from)
        .collect();
    let names = parameter_names(parameters)?;
    let mut settings = CalibrationSettings::default();
    if let Some(m) = given(max_iterations) {
        settings.max_iterations = int_arg("max_iterations", &m)?;
    }
    if let Some(t) = given(threads) {
        settings.batch.threads = Some(int_arg("threads", &t)?);
    }
    let fit = super::detach::detach_interruptible(py, move || {
        let names: Vec<&str> = names.iter().map(|s| s.as_str()).collect();
        robot.calibrate(&k, &measured, &load, &names, &settings)
    })?;
    let count = fit.parameters.len();
    let d = PyDict::new(py);
    d.set_item("parameters", fit.parameters.clone())?;
    d.set_item(
        "estimates",
        Array1::from(fit.estimates.clone()).into_pyarray(py),
    )?;
    d.set_item(
        "standard_errors",
        Array1::from(fit.standard_errors.clone()).into_pyarray(py),
    )?;
    let covariance = Array2::from_shape_vec((count, count), fit.covariance.clone())
        .expect("k x k")
        .into_pyarray(py);
    d.set_item("covariance", covariance)?;
    let residuals = Array2::from_shape_fn((fit.residuals.len(), 3), |(i, c)| fit.residuals[i][c]);
    d.set_item("residuals", residuals.into_pyarray(py))?;
    d.set_item("rms", fit.rms)?;
    d.set_item("iterations", fit.iterations)?;
    d.set_item("converged", fit.converged)?;
    d.set_item("robot", PyRobot { inner: fit.robot })?;
    d.set_item("message", fit.message)?;
    Ok(d)
}
