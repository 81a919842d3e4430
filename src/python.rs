//! The `softspine._core` extension: conversions only. Every check lives in the
//! Rust core; its errors become `ValueError` (bad input) or `SolverError`
//! (a solve that did not converge, when the caller asked with `check=True`).

use crate::blocktri::BlockTridiagonal;
use crate::paper_method::PaperSettings;
use crate::robot::{trajectory, IkOptions, IkResult, InverseSolver, Robot, Strategy};
use crate::solver::{solve_to_accuracy, Accuracy};
use crate::{Error, Method, Quat, RodModel, Scene, Settings, Solution, Solver, Value};
use nalgebra::Vector3;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2};
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

pyo3::create_exception!(
    _core,
    SolverError,
    PyException,
    "A solve did not converge (raised with check=True)."
);

impl From<Error> for PyErr {
    fn from(e: Error) -> PyErr {
        match e {
            Error::NotConverged { .. } => SolverError::new_err(e.to_string()),
            _ => PyValueError::new_err(e.to_string()),
        }
    }
}

/// Python object -> value tree (dicts, lists, tuples, NumPy arrays and scalars).
fn to_value(obj: &Bound<'_, PyAny>, path: &str) -> PyResult<Value> {
    if obj.is_none() {
        return Ok(Value::Null);
    }
    if obj.is_instance_of::<PyBool>() {
        return Ok(Value::Bool(obj.extract()?));
    }
    if obj.is_instance_of::<PyString>() {
        return Ok(Value::String(obj.extract()?));
    }
    if let Ok(d) = obj.cast::<PyDict>() {
        let mut entries = Vec::with_capacity(d.len());
        for (k, v) in d.iter() {
            let key: String = k
                .extract()
                .map_err(|_| PyValueError::new_err(format!("{path}: keys must be strings")))?;
            let child = if path.is_empty() {
                key.clone()
            } else {
                format!("{path}.{key}")
            };
            entries.push((key, to_value(&v, &child)?));
        }
        return Ok(Value::Map(entries));
    }
    if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        let items: Vec<Bound<'_, PyAny>> = obj.try_iter()?.collect::<PyResult<_>>()?;
        return items
            .iter()
            .map(|x| to_value(x, path))
            .collect::<PyResult<_>>()
            .map(Value::List);
    }
    if obj.is_instance_of::<PyFloat>() || obj.is_instance_of::<PyInt>() {
        return Ok(Value::Number(obj.extract()?));
    }
    if obj.hasattr("tolist")? {
        // NumPy arrays and scalars.
        return to_value(&obj.call_method0("tolist")?, path);
    }
    let shown = if path.is_empty() { "scene" } else { path };
    Err(PyValueError::new_err(format!(
        "{shown}: unsupported value of type {}",
        obj.get_type().name()?
    )))
}

fn from_value<'py>(py: Python<'py>, v: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => PyBool::new(py, *b).to_owned().into_any(),
        Value::Number(x) => PyFloat::new(py, *x).into_any(),
        Value::String(s) => PyString::new(py, s).into_any(),
        Value::List(items) => {
            let l = PyList::empty(py);
            for x in items {
                l.append(from_value(py, x)?)?;
            }
            l.into_any()
        }
        Value::Map(entries) => {
            let d = PyDict::new(py);
            for (k, x) in entries {
                d.set_item(k, from_value(py, x)?)?;
            }
            d.into_any()
        }
    })
}

/// What is being solved: a rod or robot backbone, its loads and boundary conditions.
///
/// Build it from a dict (``Scene({...})``), a JSON or TOML file
/// (``Scene.from_file(path)``); invalid input raises ``ValueError`` naming the key.
#[pyclass(
    name = "Scene",
    module = "softspine._core",
    frozen,
    skip_from_py_object
)]
#[derive(Clone)]
pub struct PyScene {
    inner: Scene,
}

#[pymethods]
impl PyScene {
    #[new]
    fn new(data: &Bound<'_, PyAny>) -> PyResult<Self> {
        if let Ok(s) = data.cast::<PyScene>() {
            return Ok(s.get().clone());
        }
        if !data.is_instance_of::<PyDict>() {
            return Err(PyValueError::new_err(format!(
                "scene: expected a dict, got {}",
                data.get_type().name()?
            )));
        }
        Ok(PyScene {
            inner: Scene::from_value(&to_value(data, "")?)?,
        })
    }

    /// Read a scene from a JSON string.
    #[staticmethod]
    fn from_json(text: &str) -> PyResult<Self> {
        Ok(PyScene {
            inner: Scene::from_json_str(text)?,
        })
    }

    /// Read a scene from a TOML string.
    #[staticmethod]
    fn from_toml(text: &str) -> PyResult<Self> {
        Ok(PyScene {
            inner: Scene::from_toml_str(text)?,
        })
    }

    /// The scene as a plain dict (round-trips through ``Scene(d)``).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        from_value(py, &self.inner.to_value())
    }

    #[getter]
    fn length(&self) -> f64 {
        self.inner.length
    }

    /// ``(kx, ky, kz)`` in N m^2.
    #[getter]
    fn stiffness(&self) -> (f64, f64, f64) {
        let k = self.inner.stiffness();
        (k.x, k.y, k.z)
    }

    #[getter]
    fn sections(&self) -> usize {
        self.inner.sections()
    }

    #[getter]
    fn name(&self) -> Option<String> {
        self.inner.name.clone()
    }

    /// Total distributed force, gravity included (N/m).
    #[getter]
    fn distributed_force<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vec3_array(py, &self.inner.distributed_force())
    }

    fn __repr__(&self) -> String {
        let k = self.inner.stiffness();
        format!(
            "Scene(name={:?}, length={}, stiffness=({:.4e}, {:.4e}, {:.4e}), sections={})",
            self.inner.name.as_deref().unwrap_or(""),
            self.inner.length,
            k.x,
            k.y,
            k.z,
            self.inner.sections()
        )
    }
}

fn vec3_array<'py>(py: Python<'py>, v: &Vector3<f64>) -> Bound<'py, PyArray1<f64>> {
    vec![v.x, v.y, v.z].into_pyarray(py)
}

fn rows3<'py>(py: Python<'py>, vs: &[Vector3<f64>]) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((vs.len(), 3), |(i, c)| vs[i][c]).into_pyarray(py)
}

fn rows4<'py>(py: Python<'py>, qs: &[Quat]) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((qs.len(), 4), |(i, c)| qs[i].to_array()[c]).into_pyarray(py)
}

/// An equilibrium (or the best state reached) with its status.
#[pyclass(name = "Solution", module = "softspine._core", frozen)]
pub struct PySolution {
    inner: Solution,
}

#[pymethods]
impl PySolution {
    #[getter]
    fn n_elements(&self) -> usize {
        self.inner.n_elements
    }
    /// Node positions, shape (n+1, 3), m.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows3(py, &self.inner.positions)
    }
    /// Node quaternions [w, x, y, z], shape (n+1, 4).
    #[getter]
    fn quaternions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows4(py, &self.inner.quaternions)
    }
    /// Internal force at the nodes, world frame, shape (n+1, 3), N.
    #[getter]
    fn forces<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows3(py, &self.inner.forces)
    }
    #[getter]
    fn tip_position<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vec3_array(py, &self.inner.tip_position())
    }
    #[getter]
    fn tip_quaternion<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner
            .tip_quaternion()
            .to_array()
            .to_vec()
            .into_pyarray(py)
    }
    /// Force of a pinned or clamped tip's support on the rod, world frame (N); None if free.
    #[getter]
    fn tip_reaction_force<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.inner.tip_reaction_force.map(|f| vec3_array(py, &f))
    }
    /// Moment of a clamped tip's support on the rod, world frame (N m); None otherwise.
    #[getter]
    fn tip_reaction_moment<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.inner.tip_reaction_moment.map(|m| vec3_array(py, &m))
    }
    /// Force of each guide on the rod, world frame, shape (guides, 3), N.
    #[getter]
    fn guide_reactions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows3(py, &self.inner.guide_reactions)
    }
    #[getter]
    fn converged(&self) -> bool {
        self.inner.converged()
    }
    /// "converged" or "not_converged".
    #[getter]
    fn status(&self) -> &'static str {
        if self.inner.converged() {
            "converged"
        } else {
            "not_converged"
        }
    }
    #[getter]
    fn iterations(&self) -> usize {
        self.inner.iterations
    }
    #[getter]
    fn continuation_steps(&self) -> usize {
        self.inner.continuation_steps
    }
    /// Largest torque imbalance over max(k)/L (dimensionless).
    #[getter]
    fn residual_norm(&self) -> f64 {
        self.inner.residual_norm
    }
    /// Elastic energy minus the work of the dead forces, J.
    #[getter]
    fn energy(&self) -> f64 {
        self.inner.energy
    }
    /// Whether the equilibrium is stable (positive definite reduced Hessian).
    #[getter]
    fn stable(&self) -> bool {
        self.inner.stable
    }
    #[getter]
    fn message(&self) -> String {
        self.inner.message.clone()
    }
    /// Accuracy on demand: estimated tip error, m (None for a fixed n).
    #[getter]
    fn error_estimate(&self) -> Option<f64> {
        self.inner.error_estimate
    }
    /// Whether ``tip_position`` is Richardson-extrapolated (``refine="richardson"``);
    /// ``positions[-1]`` is then the last node of the finest solve.
    #[getter]
    fn extrapolated(&self) -> bool {
        self.inner.extrapolated_tip.is_some()
    }
    fn __repr__(&self) -> String {
        let t = self.inner.tip_position();
        format!(
            "Solution(status={}, n_elements={}, iterations={}, residual_norm={:.2e}, stable={}, tip_position=[{:.6}, {:.6}, {:.6}])",
            self.status(),
            self.inner.n_elements,
            self.inner.iterations,
            self.inner.residual_norm,
            self.inner.stable,
            t.x,
            t.y,
            t.z
        )
    }
}

fn scene_arg(scene: &Bound<'_, PyAny>) -> PyResult<Scene> {
    Ok(PyScene::new(scene)?.inner)
}

fn quaternions_arg(name: &str, q: &Bound<'_, PyAny>) -> PyResult<Vec<Quat>> {
    if let Ok(s) = q.cast::<PySolution>() {
        return Ok(s.get().inner.quaternions.clone());
    }
    let arr: PyReadonlyArray2<f64> = q.extract().map_err(|_| {
        PyValueError::new_err(format!(
            "{name}: expected a Solution or a float array of shape (n+1, 4)"
        ))
    })?;
    let a = arr.as_array();
    if a.ncols() != 4 {
        return Err(PyValueError::new_err(format!(
            "{name}: expected shape (n+1, 4), got {:?}",
            a.shape()
        )));
    }
    Ok(a.rows()
        .into_iter()
        .map(|r| Quat::new(r[0], r[1], r[2], r[3]))
        .collect())
}

/// Solve the statics of a scene. See ``softspine.solve`` for the documentation.
#[pyfunction]
#[pyo3(signature = (scene, n_elements=None, method="newton", initial=None, tol=None, refine=None, residual_tol=1e-10, max_iterations=500, check=false, paper_options=None))]
#[allow(clippy::too_many_arguments)]
fn solve(
    py: Python<'_>,
    scene: &Bound<'_, PyAny>,
    n_elements: Option<i64>,
    method: &str,
    initial: Option<&Bound<'_, PyAny>>,
    tol: Option<f64>,
    refine: Option<&str>,
    residual_tol: f64,
    max_iterations: i64,
    check: bool,
    paper_options: Option<&Bound<'_, PyDict>>,
) -> PyResult<PySolution> {
    let scene = scene_arg(scene)?;
    if let Some(n) = n_elements {
        if n <= 0 {
            return Err(PyValueError::new_err(format!(
                "n_elements: must be positive, got {n}"
            )));
        }
    }
    if max_iterations <= 0 {
        return Err(PyValueError::new_err(format!(
            "max_iterations: must be positive, got {max_iterations}"
        )));
    }
    let richardson = match refine {
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
    let sections = scene.sections();
    let default_n = if tol.is_some() {
        sections * 10usize.div_ceil(sections)
    } else {
        20
    };
    let settings = Settings {
        n_elements: n_elements.map_or(default_n, |n| n as usize),
        method: method.parse::<Method>()?,
        residual_tol,
        max_iterations: max_iterations as usize,
        paper: paper_settings(paper_options)?,
        ..Settings::default()
    };
    let solution = match tol {
        None => {
            let initial = initial.map(|q| quaternions_arg("initial", q)).transpose()?;
            let mut solver = Solver::new(&scene, settings)?;
            py.detach(move || solver.solve(initial.as_deref()))?
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
            py.detach(|| solve_to_accuracy(&scene, settings, &accuracy))?
        }
    };
    let solution = if check { solution.check()? } else { solution };
    Ok(PySolution { inner: solution })
}

/// The paper's method settings from a dict (every key optional).
fn paper_settings(options: Option<&Bound<'_, PyDict>>) -> PyResult<PaperSettings> {
    let mut p = PaperSettings::default();
    let Some(options) = options else {
        return Ok(p);
    };
    for (key, value) in options.iter() {
        let key: String = key.extract()?;
        let bad = |what: &str| PyValueError::new_err(format!("paper_options.{key}: {what}"));
        let count = || -> PyResult<usize> {
            let v: i64 = value.extract().map_err(|_| bad("expected an integer"))?;
            usize::try_from(v).map_err(|_| bad("must not be negative"))
        };
        let real = || -> PyResult<f64> {
            let v: f64 = value.extract().map_err(|_| bad("expected a number"))?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(bad("must be finite"))
            }
        };
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

fn model_and_state(
    scene: &Bound<'_, PyAny>,
    quaternions: &Bound<'_, PyAny>,
) -> PyResult<(RodModel, Vec<Quat>)> {
    let scene = scene_arg(scene)?;
    let q = quaternions_arg("quaternions", quaternions)?;
    if q.len() < 2 {
        return Err(PyValueError::new_err("quaternions: need at least 2 nodes"));
    }
    scene.check_elements(q.len() - 1)?;
    Ok((RodModel::new(&scene, q.len() - 1), q))
}

/// The discrete residual, shape (n, 3): body-frame torque imbalance of nodes 1..n
/// (N m) at the given node quaternions (base node included, replaced by the scene's).
#[pyfunction]
fn residual<'py>(
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
fn jacobian<'py>(
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

fn rows_n<'py, const N: usize>(py: Python<'py>, rows: &[[f64; N]]) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((rows.len(), N), |(i, c)| rows[i][c]).into_pyarray(py)
}

fn rows_arg<const N: usize>(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Vec<[f64; N]>> {
    let bad = || PyValueError::new_err(format!("{name}: expected a float array of shape (m, {N})"));
    let converted = obj
        .py()
        .import("numpy")?
        .call_method1("asarray", (obj, "float64"))
        .map_err(|_| bad())?;
    let arr: PyReadonlyArray2<f64> = converted.extract().map_err(|_| bad())?;
    let a = arr.as_array();
    if a.ncols() != N {
        return Err(PyValueError::new_err(format!(
            "{name}: expected shape (m, {N}), got {:?}",
            a.shape()
        )));
    }
    let rows: Vec<[f64; N]> = a
        .rows()
        .into_iter()
        .map(|r| std::array::from_fn(|c| r[c]))
        .collect();
    if rows.iter().flatten().any(|x| !x.is_finite()) {
        return Err(PyValueError::new_err(format!("{name}: must be finite")));
    }
    Ok(rows)
}

fn vec3_arg(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Vector3<f64>> {
    let v: Vec<f64> = obj
        .call_method0("__iter__")
        .and_then(|_| obj.extract())
        .or_else(|_| obj.call_method0("tolist").and_then(|l| l.extract()))
        .map_err(|_| PyValueError::new_err(format!("{name}: expected 3 numbers")))?;
    if v.len() != 3 || v.iter().any(|x| !x.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "{name}: expected 3 finite numbers, got {v:?}"
        )));
    }
    Ok(Vector3::new(v[0], v[1], v[2]))
}

fn strategy_arg(s: &str) -> PyResult<Strategy> {
    match s {
        "equilibrium" => Ok(Strategy::Equilibrium),
        "geometric" => Ok(Strategy::Geometric),
        other => Err(PyValueError::new_err(format!(
            "strategy: unknown strategy '{other}' (expected 'equilibrium' or 'geometric')"
        ))),
    }
}

/// A multi-section pneumatic continuum robot (three muscles a section).
///
/// ``Robot()`` resembles the seed's prototype (1 m, 10 sections, hanging);
/// ``Robot({...})`` overrides any field (see ``Robot().to_dict()``).
#[pyclass(
    name = "Robot",
    module = "softspine._core",
    frozen,
    skip_from_py_object
)]
pub struct PyRobot {
    inner: Robot,
}

/// The actuation of one inverse solve in every space, with its equilibrium.
#[pyclass(name = "IkResult", module = "softspine._core", frozen)]
pub struct PyIkResult {
    inner: IkResult,
}

#[pymethods]
impl PyIkResult {
    /// ``[kappa_x, kappa_y]`` per section, shape (m, 2), 1/m.
    #[getter]
    fn rest_curvature<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows_n(py, &self.inner.rest_curvature)
    }
    /// Muscle lengths, shape (m, 3), m.
    #[getter]
    fn muscle_lengths<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows_n(py, &self.inner.muscle_lengths)
    }
    /// Inflation times, shape (m, 3), s.
    #[getter]
    fn inflation_times<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows_n(py, &self.inner.inflation_times)
    }
    /// The loaded equilibrium with this actuation.
    #[getter]
    fn solution(&self) -> PySolution {
        PySolution {
            inner: self.inner.solution.clone(),
        }
    }
    #[getter]
    fn tip_position<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vec3_array(py, &self.inner.tip_position)
    }
    /// Distance from the tip to the target, m.
    #[getter]
    fn tip_miss(&self) -> f64 {
        self.inner.tip_miss
    }
    #[getter]
    fn reached(&self) -> bool {
        self.inner.reached
    }
    #[getter]
    fn message(&self) -> String {
        self.inner.message.clone()
    }
    #[getter]
    fn iterations(&self) -> usize {
        self.inner.iterations
    }
    /// Wall-clock time of the inverse solve, s.
    #[getter]
    fn time(&self) -> f64 {
        self.inner.seconds
    }
    fn __repr__(&self) -> String {
        format!(
            "IkResult(reached={}, tip_miss={:.3e}, iterations={}, time={:.1} us, message={:?})",
            self.inner.reached,
            self.inner.tip_miss,
            self.inner.iterations,
            self.inner.seconds * 1e6,
            self.inner.message
        )
    }
}

/// Inverse kinematics of one robot under one tip mass, warm from its last answer.
#[pyclass(name = "InverseSolver", module = "softspine._core")]
pub struct PyInverseSolver {
    inner: InverseSolver,
}

#[pymethods]
impl PyInverseSolver {
    /// The actuation whose loaded equilibrium reaches ``target`` (see ``Robot.inverse``).
    #[pyo3(signature = (target, reference=None, direction=None, tol=1e-9, max_iterations=60))]
    fn solve(
        &mut self,
        py: Python<'_>,
        target: &Bound<'_, PyAny>,
        reference: Option<&Bound<'_, PyAny>>,
        direction: Option<&Bound<'_, PyAny>>,
        tol: f64,
        max_iterations: usize,
    ) -> PyResult<PyIkResult> {
        let target = vec3_arg("target", target)?;
        let reference = reference
            .map(|r| rows_arg::<2>("reference", r))
            .transpose()?;
        let direction = direction.map(|d| vec3_arg("direction", d)).transpose()?;
        if !(tol.is_finite() && tol > 0.0) {
            return Err(PyValueError::new_err("tol: must be positive"));
        }
        let inner = &mut self.inner;
        let r = py
            .detach(|| inner.solve(target, direction, reference.as_deref(), tol, max_iterations))?;
        Ok(PyIkResult { inner: r })
    }
}

#[pymethods]
impl PyRobot {
    #[new]
    #[pyo3(signature = (data=None))]
    fn new(data: Option<&Bound<'_, PyAny>>) -> PyResult<Self> {
        let inner = match data {
            None => Robot::default(),
            Some(d) if d.is_instance_of::<PyDict>() => Robot::from_value(&to_value(d, "")?)?,
            Some(d) => {
                return Err(PyValueError::new_err(format!(
                    "robot: expected a dict, got {}",
                    d.get_type().name()?
                )))
            }
        };
        Ok(PyRobot { inner })
    }

    #[getter]
    fn sections(&self) -> usize {
        self.inner.sections
    }
    #[getter]
    fn length(&self) -> f64 {
        self.inner.length
    }
    #[getter]
    fn n_elements(&self) -> usize {
        self.inner.n_elements
    }
    /// ``[min, max]`` muscle length, m.
    #[getter]
    fn muscle_length_range(&self) -> (f64, f64) {
        (
            self.inner.muscle_length_range[0],
            self.inner.muscle_length_range[1],
        )
    }

    /// Every field as a dict (``Robot(robot.to_dict())`` is the same robot).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let r = &self.inner;
        let d = PyDict::new(py);
        d.set_item("length", r.length)?;
        let stiffness = from_value(
            py,
            &Scene {
                stiffness_spec: r.stiffness.clone(),
                ..Scene::new(1.0, 1.0, 1.0, 1.0)
            }
            .to_value(),
        )?;
        d.set_item("stiffness", stiffness.get_item("stiffness")?)?;
        d.set_item("linear_density", r.linear_density)?;
        d.set_item("sections", r.sections)?;
        d.set_item("muscle_radius", r.muscle_radius)?;
        d.set_item("muscle_angles", r.muscle_angles.to_vec())?;
        d.set_item("disk_mass", r.disk_mass)?;
        d.set_item("gravity", vec![r.gravity.x, r.gravity.y, r.gravity.z])?;
        d.set_item("base_quaternion", r.base_quaternion.to_array().to_vec())?;
        d.set_item("muscle_rest_length", r.muscle_rest_length)?;
        d.set_item("inflation_rate", r.inflation_rate)?;
        d.set_item("muscle_length_range", r.muscle_length_range.to_vec())?;
        d.set_item("n_elements", r.n_elements)?;
        Ok(d.into_any())
    }

    /// The Scene of this robot with an actuation (m, 2) and a tip mass (kg).
    #[pyo3(signature = (rest_curvature, load=0.0))]
    fn scene(&self, rest_curvature: &Bound<'_, PyAny>, load: f64) -> PyResult<PyScene> {
        let k = rows_arg::<2>("rest_curvature", rest_curvature)?;
        Ok(PyScene {
            inner: self.inner.scene(&k, load)?,
        })
    }

    /// Joint space from rest curvature: muscle lengths (m, 3).
    fn muscle_lengths<'py>(
        &self,
        py: Python<'py>,
        rest_curvature: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let k = rows_arg::<2>("rest_curvature", rest_curvature)?;
        Ok(rows_n(py, &self.inner.muscle_lengths(&k)))
    }

    /// Rest curvature (m, 2) from muscle lengths (m, 3).
    fn rest_curvature<'py>(
        &self,
        py: Python<'py>,
        muscle_lengths: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let l = rows_arg::<3>("muscle_lengths", muscle_lengths)?;
        Ok(rows_n(py, &self.inner.rest_curvature(&l)?))
    }

    /// Actuator space: inflation times (m, 3) from muscle lengths.
    fn inflation_times<'py>(
        &self,
        py: Python<'py>,
        muscle_lengths: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let l = rows_arg::<3>("muscle_lengths", muscle_lengths)?;
        Ok(rows_n(py, &self.inner.inflation_times(&l)))
    }

    /// Joint space from actuator space: muscle lengths from inflation times.
    fn muscle_lengths_from_times<'py>(
        &self,
        py: Python<'py>,
        times: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let t = rows_arg::<3>("times", times)?;
        Ok(rows_n(py, &self.inner.muscle_lengths_from_times(&t)))
    }

    /// Whether every muscle length lies in the range for this actuation.
    fn within_bounds(&self, rest_curvature: &Bound<'_, PyAny>) -> PyResult<bool> {
        Ok(self
            .inner
            .within_bounds(&rows_arg::<2>("rest_curvature", rest_curvature)?))
    }

    /// Forward statics: the loaded equilibrium of an actuation.
    #[pyo3(signature = (rest_curvature, load=0.0))]
    fn forward(
        &self,
        py: Python<'_>,
        rest_curvature: &Bound<'_, PyAny>,
        load: f64,
    ) -> PyResult<PySolution> {
        let k = rows_arg::<2>("rest_curvature", rest_curvature)?;
        let scene = self.inner.scene(&k, load)?;
        let settings = Settings {
            n_elements: self.inner.n_elements,
            ..Settings::default()
        };
        let sol = py.detach(|| crate::solve(&scene, settings, None))?;
        Ok(PySolution { inner: sol })
    }

    /// A reusable inverse solver for one tip mass (warm starts between calls).
    #[pyo3(signature = (load=0.0))]
    fn inverse_solver(&self, load: f64) -> PyResult<PyInverseSolver> {
        Ok(PyInverseSolver {
            inner: InverseSolver::new(&self.inner, load)?,
        })
    }

    /// Load-aware inverse kinematics of one target.
    #[pyo3(signature = (target, load=0.0, reference=None, direction=None, strategy="equilibrium", tol=1e-9, max_iterations=60))]
    #[allow(clippy::too_many_arguments)]
    fn inverse(
        &self,
        py: Python<'_>,
        target: &Bound<'_, PyAny>,
        load: f64,
        reference: Option<&Bound<'_, PyAny>>,
        direction: Option<&Bound<'_, PyAny>>,
        strategy: &str,
        tol: f64,
        max_iterations: usize,
    ) -> PyResult<PyIkResult> {
        let target = vec3_arg("target", target)?;
        let options = self.ik_options(load, reference, direction, strategy, tol, max_iterations)?;
        let robot = &self.inner;
        let r = py.detach(|| robot.inverse(target, &options))?;
        Ok(PyIkResult { inner: r })
    }

    /// Inverse kinematics of a sequence of targets (N, 3), each warm from the
    /// previous one and closest to its actuation.
    #[pyo3(signature = (points, load=0.0, reference=None, direction=None, strategy="equilibrium", tol=1e-9, max_iterations=60))]
    #[allow(clippy::too_many_arguments)]
    fn track(
        &self,
        py: Python<'_>,
        points: &Bound<'_, PyAny>,
        load: f64,
        reference: Option<&Bound<'_, PyAny>>,
        direction: Option<&Bound<'_, PyAny>>,
        strategy: &str,
        tol: f64,
        max_iterations: usize,
    ) -> PyResult<Vec<PyIkResult>> {
        let pts: Vec<Vector3<f64>> = rows_arg::<3>("points", points)?
            .into_iter()
            .map(Vector3::from)
            .collect();
        let options = self.ik_options(load, reference, direction, strategy, tol, max_iterations)?;
        let robot = &self.inner;
        let rs = py.detach(|| robot.track(&pts, &options))?;
        Ok(rs.into_iter().map(|inner| PyIkResult { inner }).collect())
    }

    fn __repr__(&self) -> String {
        format!(
            "Robot(length={}, sections={}, n_elements={})",
            self.inner.length, self.inner.sections, self.inner.n_elements
        )
    }
}

impl PyRobot {
    fn ik_options(
        &self,
        load: f64,
        reference: Option<&Bound<'_, PyAny>>,
        direction: Option<&Bound<'_, PyAny>>,
        strategy: &str,
        tol: f64,
        max_iterations: usize,
    ) -> PyResult<IkOptions> {
        Ok(IkOptions {
            tip_mass: load,
            reference: reference
                .map(|r| rows_arg::<2>("reference", r))
                .transpose()?,
            direction: direction.map(|d| vec3_arg("direction", d)).transpose()?,
            strategy: strategy_arg(strategy)?,
            tol,
            max_iterations,
        })
    }
}

/// One of the seed's trajectories for the default robot: "pentagram", "circle"
/// or "spiral", shape (points, 3), m.
#[pyfunction]
#[pyo3(signature = (name, points=60))]
fn trajectory_points<'py>(
    py: Python<'py>,
    name: &str,
    points: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    if points == 0 {
        return Err(PyValueError::new_err("points: must be positive"));
    }
    let pts = trajectory::by_name(name, points).ok_or_else(|| {
        PyValueError::new_err(format!(
            "trajectory: unknown '{name}' (expected pentagram, circle or spiral)"
        ))
    })?;
    Ok(rows3(py, &pts))
}

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyRobot>()?;
    m.add_class::<PyIkResult>()?;
    m.add_class::<PyInverseSolver>()?;
    m.add_function(wrap_pyfunction!(trajectory_points, m)?)?;
    m.add_class::<PyScene>()?;
    m.add_class::<PySolution>()?;
    m.add_function(wrap_pyfunction!(solve, m)?)?;
    m.add_function(wrap_pyfunction!(residual, m)?)?;
    m.add_function(wrap_pyfunction!(jacobian, m)?)?;
    m.add("SolverError", m.py().get_type::<SolverError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
