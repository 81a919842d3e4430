//! `solve`, `residual` and `jacobian`.

use super::convert::*;
use super::detach::{detach_interruptible, detach_solve};
use super::scene::scene_arg;
use super::settings::{entries, PyAccuracy, PyPaperSettings, PySettings};
use super::solution::{previous_solution, quaternions_arg, PySolution};
use crate::blocktri::BlockTridiagonal;
use crate::solver::{solve_to_accuracy, Accuracy};
use crate::{Error, Quat, RodModel, Settings, Value};
use nalgebra::Vector3;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Solve the statics of a scene. See ``softspine.solve`` for the documentation.
#[pyfunction]
#[pyo3(signature = (scene, settings=None, *, n_elements=None, method=None, scheme=None, initial=None, accuracy=None, tol=None, refine=None, residual_tol=None, max_iterations=None, check=false, paper=None))]
#[allow(clippy::too_many_arguments)]
pub(super) fn solve(
    py: Python<'_>,
    scene: &Bound<'_, PyAny>,
    settings: Option<&Bound<'_, PyAny>>,
    n_elements: Option<&Bound<'_, PyAny>>,
    method: Option<&Bound<'_, PyAny>>,
    scheme: Option<&Bound<'_, PyAny>>,
    initial: Option<&Bound<'_, PyAny>>,
    accuracy: Option<&Bound<'_, PyAny>>,
    tol: Option<&Bound<'_, PyAny>>,
    refine: Option<&Bound<'_, PyAny>>,
    residual_tol: Option<&Bound<'_, PyAny>>,
    max_iterations: Option<&Bound<'_, PyAny>>,
    #[pyo3(from_py_with = check_arg)] check: bool,
    paper: Option<&Bound<'_, PyAny>>,
) -> PyResult<PySolution> {
    let scene = scene_arg(scene)?;
    let settings = settings_with(
        py,
        settings,
        &[
            ("n_elements", n_elements),
            ("method", method),
            ("scheme", scheme),
            ("residual_tol", residual_tol),
            ("max_iterations", max_iterations),
            ("paper", paper),
        ],
    )?;
    let accuracy = accuracy_arg(accuracy, tol, refine)?;
    let solution = match accuracy {
        None => {
            // A Solution starts the next step of its history (its rod where
            // it stood: see `Solver::solve_after`); an array, its rotations.
            let previous = initial.and_then(previous_solution);
            let initial = initial.map(|q| quaternions_arg("initial", q)).transpose()?;
            // Building the solver allocates O(n): without the GIL too.
            let long = settings.resolved(&scene).has_long_passes();
            detach_solve(py, long, move || match &previous {
                Some(previous) => crate::solve_after(&scene, settings, previous),
                None => crate::solve(&scene, settings, initial.as_deref()),
            })?
        }
        Some(accuracy) => {
            if initial.is_some() {
                return Err(PyValueError::new_err(
                    "initial: not used with tol (the discretisation is chosen by the solver)",
                ));
            }
            // It may end at any n up to the limit: the core puts the passes
            // that may outlast the poll on a worker thread, one by one.
            detach_interruptible(py, move || solve_to_accuracy(&scene, settings, &accuracy))?
        }
    };
    let solution = if check { solution.check()? } else { solution };
    Ok(PySolution { inner: solution })
}

/// The `settings` argument with keywords over its fields (read by the core's
/// `Settings::set`), validated.
pub(super) fn settings_with(
    py: Python<'_>,
    settings: Option<&Bound<'_, PyAny>>,
    overrides: &[(&str, Option<&Bound<'_, PyAny>>)],
) -> PyResult<Settings> {
    let mut settings = settings_arg(py, settings)?;
    let keywords = PyDict::new(py);
    for (key, value) in overrides {
        match given(*value) {
            Some(p) if *key == "paper" && p.is_instance_of::<PyPaperSettings>() => {
                settings.paper = p.cast::<PyPaperSettings>()?.borrow().inner.clone();
            }
            Some(v) => keywords.set_item(key, v)?,
            None => {}
        }
    }
    for (key, value) in entries(&to_value(keywords.as_any(), &Path::input("settings"))?) {
        settings.set(key, value)?;
    }
    settings.validate()?;
    Ok(settings)
}

/// The `settings` argument: a `Settings`, a dict of its fields or None (the defaults).
fn settings_arg(py: Python<'_>, settings: Option<&Bound<'_, PyAny>>) -> PyResult<Settings> {
    let Some(s) = given(settings) else {
        return Ok(Settings::default());
    };
    if let Ok(s) = s.cast::<PySettings>() {
        return Ok(s.borrow().to_core(py));
    }
    if s.is_instance_of::<PyDict>() {
        return Ok(Settings::from_value(&to_value(
            &s,
            &Path::input("settings"),
        )?)?);
    }
    Err(PyValueError::new_err(format!(
        "settings: expected a Settings or a dict of its fields, got {}",
        type_name(&s)
    )))
}

/// Accuracy on demand, if asked for: an `Accuracy` or a dict of its fields,
/// with the `tol` and `refine` keywords over it.
fn accuracy_arg(
    accuracy: Option<&Bound<'_, PyAny>>,
    tol: Option<&Bound<'_, PyAny>>,
    refine: Option<&Bound<'_, PyAny>>,
) -> PyResult<Option<Accuracy>> {
    let mut fields: Vec<(String, Value)> = match given(accuracy) {
        None => Vec::new(),
        Some(a) => {
            if let Ok(a) = a.cast::<PyAccuracy>() {
                entries(&a.borrow().inner.to_value()).to_vec()
            } else if a.is_instance_of::<PyDict>() {
                entries(&to_value(&a, &Path::input("accuracy"))?).to_vec()
            } else {
                return Err(PyValueError::new_err(format!(
                    "accuracy: expected an Accuracy or a dict of its fields, got {}",
                    type_name(&a)
                )));
            }
        }
    };
    let py_keywords = [("tol", tol), ("refine", refine)];
    for (key, value) in py_keywords {
        if let Some(v) = given(value) {
            let d = PyDict::new(v.py());
            d.set_item(key, v)?;
            let value = entries(&to_value(d.as_any(), &Path::input("accuracy"))?)[0]
                .1
                .clone();
            fields.retain(|(k, _)| k != key);
            fields.push((key.to_string(), value));
        }
    }
    if fields.is_empty() {
        return Ok(None);
    }
    Ok(Some(Accuracy::from_value(&Value::Map(fields))?))
}

fn model_and_state(
    scene: &Bound<'_, PyAny>,
    quaternions: &Bound<'_, PyAny>,
) -> PyResult<(RodModel, Vec<Quat>)> {
    let scene = scene_arg(scene)?;
    let q = quaternions_arg("quaternions", quaternions)?;
    let n = q.len().saturating_sub(1);
    // The array's length sets n: a bad n is the array's shape, not an n_elements argument.
    scene.check_elements(n).map_err(|e| match e {
        Error::InvalidArgument { .. } => PyValueError::new_err(format!(
            "quaternions: expected shape (n+1, 4) with n a positive multiple of the number of \
             sections ({}), got ({}, 4)",
            scene.sections(),
            q.len()
        )),
        other => other.into(),
    })?;
    Ok((RodModel::new(&scene, n), q))
}

/// The discrete residual, shape (n, 3): body-frame torque imbalance of nodes 1..n
/// (N m) at the given node quaternions (base node included, replaced by the scene's).
#[pyfunction]
pub(super) fn residual<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyAny>,
    quaternions: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let (model, mut q) = model_and_state(scene, quaternions)?;
    q[0] = model.base();
    let mut g = vec![Vector3::zeros(); model.n()];
    model.residual(&q, 1.0, &mut model.new_interior(), &mut g);
    Ok(rows3(py, &g))
}

/// The analytic Jacobian of ``residual`` under the body-frame update
/// ``q_j <- q_j * exp(theta_j / 2)``, dense, shape (3n, 3n).
#[pyfunction]
pub(super) fn jacobian<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyAny>,
    quaternions: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let (model, mut q) = model_and_state(scene, quaternions)?;
    q[0] = model.base();
    let n = model.n();
    let mut g = vec![Vector3::zeros(); n];
    let mut jac = BlockTridiagonal::zeros(n);
    model.residual_jacobian(&q, 1.0, &mut model.new_interior(), &mut g, &mut jac);
    let mut dense = Array2::<f64>::zeros((3 * n, 3 * n));
    jac.for_each_entry(|r, c, v| dense[(r, c)] = v);
    Ok(dense.into_pyarray(py))
}
