//! The `softspine._core` extension: conversions only. Every check lives in the
//! Rust core; its errors become `ValueError` (bad input) or `SolverError`
//! (a solve that did not converge, when the caller asked with `check=True`).

use crate::blocktri::BlockTridiagonal;
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
#[pyo3(signature = (scene, n_elements=20, method="newton", initial=None, tol=1e-10, max_iterations=500, check=false))]
#[allow(clippy::too_many_arguments)]
fn solve(
    py: Python<'_>,
    scene: &Bound<'_, PyAny>,
    n_elements: i64,
    method: &str,
    initial: Option<&Bound<'_, PyAny>>,
    tol: f64,
    max_iterations: i64,
    check: bool,
) -> PyResult<PySolution> {
    let scene = scene_arg(scene)?;
    if n_elements <= 0 {
        return Err(PyValueError::new_err(format!(
            "n_elements: must be positive, got {n_elements}"
        )));
    }
    if max_iterations <= 0 {
        return Err(PyValueError::new_err(format!(
            "max_iterations: must be positive, got {max_iterations}"
        )));
    }
    let settings = Settings {
        n_elements: n_elements as usize,
        method: method.parse::<Method>()?,
        tol,
        max_iterations: max_iterations as usize,
        ..Settings::default()
    };
    let initial = initial.map(|q| quaternions_arg("initial", q)).transpose()?;
    let mut solver = Solver::new(&scene, settings)?;
    let solution = py.detach(move || solver.solve(initial.as_deref()))?;
    let solution = if check { solution.check()? } else { solution };
    Ok(PySolution { inner: solution })
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

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyScene>()?;
    m.add_class::<PySolution>()?;
    m.add_function(wrap_pyfunction!(solve, m)?)?;
    m.add_function(wrap_pyfunction!(residual, m)?)?;
    m.add_function(wrap_pyfunction!(jacobian, m)?)?;
    m.add("SolverError", m.py().get_type::<SolverError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
