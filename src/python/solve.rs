//! `solve`, `residual` and `jacobian`.

use super::convert::*;
use super::detach::detach_solve;
use super::scene::scene_arg;
use super::solution::{quaternions_arg, PySolution};
use crate::blocktri::BlockTridiagonal;
use crate::paper_method::PaperSettings;
use crate::solver::{solve_to_accuracy, Accuracy};
use crate::{Error, Method, Quat, RodModel, Settings, Solver};
use nalgebra::Vector3;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};

/// Solve the statics of a scene. See ``softspine.solve`` for the documentation.
#[pyfunction]
#[pyo3(signature = (scene, n_elements=None, method=None, initial=None, tol=None, refine=None, residual_tol=None, max_iterations=None, check=false, paper_options=None))]
#[allow(clippy::too_many_arguments)]
pub(super) fn solve(
    py: Python<'_>,
    scene: &Bound<'_, PyAny>,
    n_elements: Option<&Bound<'_, PyAny>>,
    method: Option<&Bound<'_, PyAny>>,
    initial: Option<&Bound<'_, PyAny>>,
    tol: Option<&Bound<'_, PyAny>>,
    refine: Option<&Bound<'_, PyAny>>,
    residual_tol: Option<&Bound<'_, PyAny>>,
    max_iterations: Option<&Bound<'_, PyAny>>,
    check: bool,
    paper_options: Option<&Bound<'_, PyAny>>,
) -> PyResult<PySolution> {
    let scene = scene_arg(scene)?;
    let n_elements = given(n_elements)
        .map(|o| int_arg("n_elements", &o))
        .transpose()?;
    let tol = given(tol).map(|o| float_arg("tol", &o)).transpose()?;
    let refine = given(refine).map(|o| str_arg("refine", &o)).transpose()?;
    let defaults = Settings::default();
    let method = match given(method) {
        None => defaults.method,
        Some(o) => str_arg("method", &o)?.parse::<Method>()?,
    };
    let residual_tol = given(residual_tol)
        .map(|o| float_arg("residual_tol", &o))
        .transpose()?
        .unwrap_or(defaults.residual_tol);
    let max_iterations = given(max_iterations)
        .map(|o| int_arg("max_iterations", &o))
        .transpose()?
        .unwrap_or(defaults.max_iterations);
    let paper_options = match given(paper_options) {
        None => None,
        Some(o) => Some(o.cast_into::<PyDict>().map_err(|e| {
            PyValueError::new_err(format!(
                "paper_options: expected a dict, got {}",
                e.into_inner()
                    .get_type()
                    .name()
                    .map_or("?".into(), |n| n.to_string())
            ))
        })?),
    };
    let richardson = match refine.as_deref() {
        None => false,
        Some("richardson") if tol.is_some() => true,
        Some("richardson") => {
            return Err(PyValueError::new_err(
                "refine: 'richardson' needs tol (accuracy on demand)",
            ))
        }
        Some(other) => {
            return Err(PyValueError::new_err(format!(
                "refine: unknown '{other}' (expected 'richardson')"
            )))
        }
    };
    let settings = Settings {
        n_elements,
        method,
        residual_tol,
        max_iterations,
        paper: paper_settings(paper_options.as_ref())?,
        ..defaults
    };
    let solution = match tol {
        None => {
            let initial = initial.map(|q| quaternions_arg("initial", q)).transpose()?;
            // Building the solver allocates O(n): without the GIL too.
            let long = settings.resolved(&scene).has_long_passes();
            detach_solve(py, long, move || {
                Solver::new(&scene, settings)?.solve(initial.as_deref())
            })?
        }
        Some(tol) => {
            if initial.is_some() {
                return Err(PyValueError::new_err(
                    "initial: not used with tol (the discretisation is chosen by the solver)",
                ));
            }
            let accuracy = Accuracy {
                richardson,
                ..Accuracy::new(tol)
            };
            // It may end at any n up to the limit. A worker thread costs a
            // thread start, which made a solve of tens of microseconds take
            // 1.6 ms: only for passes that may outlast the poll.
            let long = accuracy.has_long_passes(&settings);
            detach_solve(py, long, move || {
                solve_to_accuracy(&scene, settings, &accuracy)
            })?
        }
    };
    let solution = if check { solution.check()? } else { solution };
    Ok(PySolution { inner: solution })
}

/// The paper's method settings from a dict (every key optional).
pub(super) fn paper_settings(options: Option<&Bound<'_, PyDict>>) -> PyResult<PaperSettings> {
    let mut p = PaperSettings::default();
    let Some(options) = options else {
        return Ok(p);
    };
    for (key, value) in options.iter() {
        let key = match key.cast::<PyString>() {
            Ok(k) => k.to_cow()?.into_owned(),
            Err(_) => {
                return Err(Path::argument("paper_options")
                    .error(format!("keys must be strings, got {}", type_name(&key))))
            }
        };
        let name = format!("paper_options.{key}");
        let bad = |what: &str| PyValueError::new_err(format!("{name}: {what}"));
        let count = || int_arg(&name, &value);
        let real = || float_arg(&name, &value);
        match key.as_str() {
            "particles" => p.swarm.particles = count()?.max(1),
            "iterations" => p.swarm.iterations = count()?,
            "chi" => p.swarm.chi = real()?,
            "inertia" => p.swarm.inertia = real()?,
            "c1" => p.swarm.c1 = real()?,
            "c2" => p.swarm.c2 = real()?,
            "seed" => p.swarm.seed = count()? as u64,
            "gauss_newton_iterations" => p.gauss_newton_iterations = count()?,
            "lm_iterations" => p.lm_iterations = count()?,
            "tol" => p.tol = real()?,
            _ => return Err(bad("unknown option (particles, iterations, chi, inertia, c1, c2, seed, gauss_newton_iterations, lm_iterations, tol)")),
        }
    }
    Ok(p)
}

pub(super) fn model_and_state(
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
    q[0] = model.base;
    let mut g = vec![Vector3::zeros(); model.n];
    model.residual(&q, 1.0, &mut g);
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
    q[0] = model.base;
    let n = model.n;
    let mut g = vec![Vector3::zeros(); n];
    let mut jac = BlockTridiagonal::zeros(n);
    model.residual_jacobian(&q, 1.0, &mut g, &mut jac);
    let mut dense = Array2::<f64>::zeros((3 * n, 3 * n));
    jac.for_each_entry(|r, c, v| dense[(r, c)] = v);
    Ok(dense.into_pyarray(py))
}
