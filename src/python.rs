//! The `softspine._core` extension: conversions only. Every check lives in the
//! Rust core; its errors become `ValueError` (bad input) or `SolverError`
//! (a solve that did not converge, when the caller asked with `check=True`).

use crate::blocktri::BlockTridiagonal;
use crate::paper_method::PaperSettings;
use crate::robot::{trajectory, IkOptions, IkResult, InverseSolver, Robot, Strategy};
use crate::solver::{solve_to_accuracy, Accuracy};
use crate::value::MAX_DEPTH;
use crate::{interrupt, Error, Method, Quat, RodModel, Scene, Settings, Solution, Solver, Value};
use nalgebra::Vector3;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::{
    PyException, PyKeyboardInterrupt, PyMemoryError, PyRuntimeError, PyValueError,
};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple, PyType};
use std::sync::{Arc, Mutex};

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
            Error::Interrupted => PyKeyboardInterrupt::new_err(e.to_string()),
            Error::OutOfMemory { .. } => PyMemoryError::new_err(e.to_string()),
            _ => PyValueError::new_err(e.to_string()),
        }
    }
}

/// Run `f` without the GIL while Python's signal handlers are polled (see
/// `crate::interrupt`), so that Ctrl-C stops a long solve within about 20 ms;
/// the handler's own exception (KeyboardInterrupt) is raised.
fn detach_interruptible<T: Send>(
    py: Python<'_>,
    f: impl FnOnce() -> crate::Result<T> + Send,
) -> PyResult<T> {
    let (poll, pending) = signal_poll();
    raise_interrupt(py.detach(move || interrupt::with_check(poll, f)), &pending)
}

/// As [`detach_interruptible`], with `f` on a worker thread that is left to
/// wind down after Ctrl-C (`interrupt::on_worker`): for solves large enough
/// that one pass over the rod takes longer than the user should wait.
fn detach_on_worker<T: Send + 'static>(
    py: Python<'_>,
    f: impl FnOnce() -> crate::Result<T> + Send + 'static,
) -> PyResult<T> {
    let (poll, pending) = signal_poll();
    raise_interrupt(py.detach(move || interrupt::on_worker(poll, f)), &pending)
}

/// [`detach_on_worker`] if one pass of `f` may outlast the poll interval
/// (`long`: `Settings::has_long_passes`), else [`detach_interruptible`].
fn detach_solve<T: Send + 'static>(
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

type PendingSignal = Arc<Mutex<Option<PyErr>>>;

/// A poll of Python's signal handlers that keeps the exception a handler
/// raised (KeyboardInterrupt for Ctrl-C) for [`raise_interrupt`].
fn signal_poll() -> (impl FnMut() -> bool + Send + 'static, PendingSignal) {
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
fn raise_interrupt<T>(result: crate::Result<T>, pending: &PendingSignal) -> PyResult<T> {
    match result {
        Err(Error::Interrupted) => Err(pending
            .lock()
            .ok()
            .and_then(|mut p| p.take())
            .unwrap_or_else(|| PyKeyboardInterrupt::new_err("interrupted"))),
        other => other.map_err(PyErr::from),
    }
}

/// Where a value sits in the caller's input, for refusals: a chain of steps on
/// the stack, rendered only for an error. Inside a dict (a scene, a robot) the
/// key path names the field as the validators do (`tip.position[1]`); inside an
/// argument the argument's name comes first, so that every refusal starts with
/// it (`target: at [1]: ...`).
struct Path<'a> {
    step: Step<'a>,
    parent: Option<&'a Path<'a>>,
    /// Lists, dicts and arrays entered so far.
    depth: usize,
}

#[derive(Clone, Copy)]
enum Step<'a> {
    Input(&'a str),
    Argument(&'a str),
    Key(&'a str),
    Index(usize),
    /// An array's `tolist()`: one level deeper at the same place.
    Same,
}

impl<'a> Path<'a> {
    fn input(name: &'a str) -> Self {
        Path {
            step: Step::Input(name),
            parent: None,
            depth: 0,
        }
    }

    fn argument(name: &'a str) -> Self {
        Path {
            step: Step::Argument(name),
            parent: None,
            depth: 0,
        }
    }

    fn child(&'a self, step: Step<'a>) -> Path<'a> {
        Path {
            step,
            parent: Some(self),
            depth: self.depth + 1,
        }
    }

    fn key(&'a self, key: &'a str) -> Path<'a> {
        self.child(Step::Key(key))
    }

    fn index(&'a self, i: usize) -> Path<'a> {
        self.child(Step::Index(i))
    }

    fn error(&self, reason: impl std::fmt::Display) -> PyErr {
        let mut steps = Vec::new();
        let mut node = Some(self);
        while let Some(p) = node {
            steps.push(p.step);
            node = p.parent;
        }
        let (mut name, mut argument, mut at) = ("", false, String::new());
        for step in steps.into_iter().rev() {
            match step {
                Step::Input(n) => name = n,
                Step::Argument(n) => (name, argument) = (n, true),
                Step::Key(k) if at.is_empty() => at.push_str(k),
                Step::Key(k) => at.push_str(&format!(".{k}")),
                Step::Index(i) => at.push_str(&format!("[{i}]")),
                Step::Same => {}
            }
        }
        PyValueError::new_err(match (at.is_empty(), argument) {
            (true, _) => format!("{name}: {reason}"),
            (false, false) => format!("{at}: {reason}"),
            (false, true) => format!("{name}: at {at}: {reason}"),
        })
    }
}

fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map_or_else(|_| "?".to_owned(), |n| n.to_string())
}

fn unsupported(obj: &Bound<'_, PyAny>, path: &Path) -> PyErr {
    path.error(format!("unsupported value of type {}", type_name(obj)))
}

/// NumPy's scalar types, looked up once.
struct NumpyTypes {
    generic: Py<PyType>,
    bool_: Py<PyType>,
    integer: Py<PyType>,
    floating: Py<PyType>,
}

fn numpy_types(py: Python<'_>) -> PyResult<&'static NumpyTypes> {
    static TYPES: PyOnceLock<NumpyTypes> = PyOnceLock::new();
    TYPES.get_or_try_init(py, || {
        let np = py.import("numpy")?;
        let ty = |name: &str| -> PyResult<Py<PyType>> {
            Ok(np.getattr(name)?.cast_into::<PyType>()?.unbind())
        };
        Ok(NumpyTypes {
            generic: ty("generic")?,
            bool_: ty("bool_")?,
            integer: ty("integer")?,
            floating: ty("floating")?,
        })
    })
}

/// A Python int as a number; one beyond the double range is refused by path.
fn int_number(obj: &Bound<'_, PyAny>, path: &Path) -> PyResult<Value> {
    obj.extract::<f64>()
        .map(Value::Number)
        .map_err(|_| path.error("integer too large for a double"))
}

/// A scalar (None, bool, str, int, float or a NumPy scalar) as a value, or None
/// if `obj` is not one. NumPy scalars are converted explicitly: `tolist()` of a
/// `longdouble` returns the `longdouble` itself.
fn scalar(obj: &Bound<'_, PyAny>, path: &Path) -> PyResult<Option<Value>> {
    if obj.is_none() {
        return Ok(Some(Value::Null));
    }
    if let Ok(b) = obj.cast::<PyBool>() {
        return Ok(Some(Value::Bool(b.is_true())));
    }
    if let Ok(s) = obj.cast::<PyString>() {
        let text = s.to_cow().map_err(|_| path.error("not valid text"))?;
        return Ok(Some(Value::String(text.into_owned())));
    }
    if obj.is_instance_of::<PyInt>() {
        return int_number(obj, path).map(Some);
    }
    if obj.is_instance_of::<PyFloat>() {
        return Ok(Some(Value::Number(obj.extract()?)));
    }
    let py = obj.py();
    let np = numpy_types(py)?;
    if !obj.is_instance(np.generic.bind(py))? {
        return Ok(None);
    }
    if obj.is_instance(np.bool_.bind(py))? {
        return Ok(Some(Value::Bool(obj.is_truthy()?)));
    }
    if obj.is_instance(np.integer.bind(py))? {
        return int_number(&obj.call_method0("__index__")?, path).map(Some);
    }
    if obj.is_instance(np.floating.bind(py))? {
        let x: f64 = obj.extract()?;
        // A longdouble beyond the double range becomes inf: refuse it rather
        // than pass on an infinity the input did not hold.
        if x.is_infinite() && !obj.eq(x)? {
            return Err(path.error(format!("{} is out of the range of a double", obj.str()?)));
        }
        return Ok(Some(Value::Number(x)));
    }
    Err(unsupported(obj, path))
}

/// Python object -> value tree: dicts, lists, tuples, scalars (NumPy's too) and
/// arrays (anything with `tolist()`, called once per level). At most
/// `MAX_DEPTH` levels deep, so that a deep or self-containing input is refused
/// instead of overflowing the stack.
fn to_value(obj: &Bound<'_, PyAny>, path: &Path) -> PyResult<Value> {
    if let Some(v) = scalar(obj, path)? {
        return Ok(v);
    }
    if path.depth >= MAX_DEPTH {
        return Err(path.error(format!("nested deeper than {MAX_DEPTH} levels")));
    }
    if let Ok(d) = obj.cast::<PyDict>() {
        // Items first: converting runs Python code that could change the dict.
        let items: Vec<_> = d.iter().collect();
        let mut entries = Vec::with_capacity(items.len());
        for (k, v) in items {
            let key = match k.cast::<PyString>() {
                Ok(s) => s
                    .to_cow()
                    .map_err(|_| path.error("keys must be valid text"))?,
                Err(_) => {
                    return Err(path.error(format!("keys must be strings, got {}", type_name(&k))))
                }
            };
            let value = to_value(&v, &path.key(&key))?;
            entries.push((key.into_owned(), value));
        }
        return Ok(Value::Map(entries));
    }
    if let Ok(l) = obj.cast::<PyList>() {
        return l
            .iter()
            .enumerate()
            .map(|(i, x)| to_value(&x, &path.index(i)))
            .collect::<PyResult<_>>()
            .map(Value::List);
    }
    if let Ok(t) = obj.cast::<PyTuple>() {
        return t
            .iter()
            .enumerate()
            .map(|(i, x)| to_value(&x, &path.index(i)))
            .collect::<PyResult<_>>()
            .map(Value::List);
    }
    if obj.hasattr("tolist")? {
        let list = obj.call_method0("tolist")?;
        return to_value(&list, &path.child(Step::Same));
    }
    Err(unsupported(obj, path))
}

/// A string argument, refused by name (pyo3's own refusal does not name it).
fn str_arg(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<String> {
    let path = Path::argument(name);
    match obj.cast::<PyString>() {
        Ok(s) => Ok(s
            .to_cow()
            .map_err(|_| path.error("not valid text"))?
            .into_owned()),
        Err(_) => Err(path.error(format!("expected a string, got {}", type_name(obj)))),
    }
}

/// A count argument: an int or NumPy integer (not a bool or a float) that fits
/// `usize`, refused by name.
fn int_arg(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    let path = Path::argument(name);
    let py = obj.py();
    let integer = !obj.is_instance_of::<PyBool>()
        && (obj.is_instance_of::<PyInt>() || obj.is_instance(numpy_types(py)?.integer.bind(py))?);
    if !integer {
        return Err(path.error(format!("expected an integer, got {}", type_name(obj))));
    }
    match obj.extract::<usize>() {
        Ok(n) => Ok(n),
        Err(_) if obj.lt(0)? => Err(path.error(format!("must not be negative, got {obj}"))),
        Err(_) => Err(path.error(format!("too large (at most {})", usize::MAX))),
    }
}

/// A finite real argument (int, float, NumPy scalar or 0-d array), refused by name.
fn float_arg(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    let path = Path::argument(name);
    match to_value(obj, &path)? {
        Value::Number(x) if x.is_finite() => Ok(x),
        Value::Number(x) => Err(path.error(format!("must be finite, got {x}"))),
        _ => Err(path.error(format!("expected a number, got {}", type_name(obj)))),
    }
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
            inner: Scene::from_value(&to_value(data, &Path::input("scene"))?)?,
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
    /// Internal force at the nodes, world frame, shape (n+1, 3), N: the force
    /// that the rod beyond node j exerts on the rod before it. ``forces[0]`` is
    /// the force of the rod on its base support (the support's reaction on the
    /// rod is minus it).
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
    /// How the solve ended: "converged", "not_converged", "tolerance_not_met",
    /// "underresolved", "numerical_error" or "indeterminate".
    #[getter]
    fn status(&self) -> &'static str {
        self.inner.status.name()
    }
    #[getter]
    fn iterations(&self) -> usize {
        self.inner.iterations
    }
    #[getter]
    fn continuation_steps(&self) -> usize {
        self.inner.continuation_steps
    }
    /// Largest torque imbalance of a row over its own stiffness scale k_c/L (dimensionless).
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
    /// Accuracy on demand: estimated largest node error over the backbone, m (None for a fixed n).
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

/// Node quaternions: a Solution's, or an array of shape (n+1, 4).
fn quaternions_arg(name: &str, q: &Bound<'_, PyAny>) -> PyResult<Vec<Quat>> {
    if let Ok(s) = q.cast::<PySolution>() {
        return Ok(s.get().inner.quaternions.clone());
    }
    Ok(rows_arg::<4>(name, q)?
        .into_iter()
        .map(Quat::from_array)
        .collect())
}

/// An optional argument that was given (Python's None means "the default").
fn given<'py>(x: Option<&Bound<'py, PyAny>>) -> Option<Bound<'py, PyAny>> {
    x.filter(|o| !o.is_none()).cloned()
}

/// Solve the statics of a scene. See ``softspine.solve`` for the documentation.
#[pyfunction]
#[pyo3(signature = (scene, n_elements=None, method=None, initial=None, tol=None, refine=None, residual_tol=None, max_iterations=None, check=false, paper_options=None))]
#[allow(clippy::too_many_arguments)]
fn solve(
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
fn paper_settings(options: Option<&Bound<'_, PyDict>>) -> PyResult<PaperSettings> {
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

/// An (m, N) float argument. A float64 array of that shape is read as it is;
/// anything else (lists, other dtypes such as longdouble or object, junk) goes
/// through `to_value`, converted or refused by the rules of a scene's values.
fn rows_arg<const N: usize>(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Vec<[f64; N]>> {
    let path = Path::argument(name);
    let rows: Vec<[f64; N]> = match obj.extract::<PyReadonlyArray2<f64>>() {
        Ok(a) if a.as_array().ncols() == N => a
            .as_array()
            .rows()
            .into_iter()
            .map(|r| std::array::from_fn(|c| r[c]))
            .collect(),
        _ => match to_value(obj, &path)? {
            Value::List(items) => items
                .iter()
                .enumerate()
                .map(|(i, row)| numbers::<N>(row, &path.index(i)))
                .collect::<PyResult<_>>()?,
            other => {
                return Err(path.error(format!(
                    "expected an array of shape (m, {N}), got {}",
                    other.kind()
                )))
            }
        },
    };
    for (i, row) in rows.iter().enumerate() {
        for (j, x) in row.iter().enumerate() {
            if !x.is_finite() {
                return Err(path
                    .index(i)
                    .index(j)
                    .error(format!("must be finite, got {x}")));
            }
        }
    }
    Ok(rows)
}

/// The N numbers of a list (finiteness is the caller's check).
fn numbers<const N: usize>(v: &Value, path: &Path) -> PyResult<[f64; N]> {
    let items = match v {
        Value::List(items) if items.len() == N => items,
        Value::List(items) => {
            return Err(path.error(format!("expected {N} numbers, got {}", items.len())))
        }
        other => return Err(path.error(format!("expected {N} numbers, got {}", other.kind()))),
    };
    let mut out = [0.0; N];
    for (i, item) in items.iter().enumerate() {
        out[i] = match item {
            Value::Number(x) => *x,
            other => {
                return Err(path
                    .index(i)
                    .error(format!("expected a number, got {}", other.kind())))
            }
        };
    }
    Ok(out)
}

/// A 3-vector argument: a row of `rows_arg`'s rules.
fn vec3_arg(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Vector3<f64>> {
    let path = Path::argument(name);
    let v: [f64; 3] = match obj.extract::<PyReadonlyArray1<f64>>() {
        Ok(a) if a.as_array().len() == 3 => std::array::from_fn(|i| a.as_array()[i]),
        _ => numbers::<3>(&to_value(obj, &path)?, &path)?,
    };
    for (i, x) in v.iter().enumerate() {
        if !x.is_finite() {
            return Err(path.index(i).error(format!("must be finite, got {x}")));
        }
    }
    Ok(Vector3::from(v))
}

// `#[pyo3(from_py_with = ...)]` takes a function path: one converter a name.
fn load_arg(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    float_arg("load", obj)
}

fn tol_arg(obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    float_arg("tol", obj)
}

fn max_iterations_arg(obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    int_arg("max_iterations", obj)
}

fn points_arg(obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    int_arg("points", obj)
}

fn strategy_arg(obj: &Bound<'_, PyAny>) -> PyResult<Strategy> {
    match str_arg("strategy", obj)?.as_str() {
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
    /// Why the inverse solve ended: "reached", "out_of_reach", "bounds_active",
    /// "solver_failure", "iteration_limit" or "load_ignored".
    #[getter]
    fn ending(&self) -> &'static str {
        self.inner.ending.name()
    }
    /// Starting actuations tried (1: the fast path sufficed).
    #[getter]
    fn starts(&self) -> usize {
        self.inner.starts
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
///
/// Safe to share between threads: one solve runs at a time (the warm start is
/// shared state), and a thread waiting for its turn does not hold the GIL.
#[pyclass(name = "InverseSolver", module = "softspine._core", frozen)]
pub struct PyInverseSolver {
    /// Shared with a worker thread during a long solve (see `detach_solve`).
    inner: Arc<Mutex<InverseSolver>>,
    long_passes: bool,
}

#[pymethods]
impl PyInverseSolver {
    /// The actuation whose loaded equilibrium reaches ``target`` (see ``Robot.inverse``).
    #[pyo3(signature = (target, reference=None, direction=None, tol=1e-9, max_iterations=60))]
    fn solve(
        &self,
        py: Python<'_>,
        target: &Bound<'_, PyAny>,
        reference: Option<&Bound<'_, PyAny>>,
        direction: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = tol_arg)] tol: f64,
        #[pyo3(from_py_with = max_iterations_arg)] max_iterations: usize,
    ) -> PyResult<PyIkResult> {
        let target = vec3_arg("target", target)?;
        let reference = reference
            .map(|r| rows_arg::<2>("reference", r))
            .transpose()?;
        let direction = direction.map(|d| vec3_arg("direction", d)).transpose()?;
        if tol <= 0.0 {
            return Err(PyValueError::new_err("tol: must be positive"));
        }
        // Locked without the GIL; None if a solve panicked holding the lock.
        let inner = Arc::clone(&self.inner);
        let r = detach_solve(py, self.long_passes, move || match inner.lock() {
            Ok(mut solver) => solver
                .solve(target, direction, reference.as_deref(), tol, max_iterations)
                .map(Some),
            Err(_) => Ok(None),
        })?;
        let r = r.ok_or_else(|| {
            PyRuntimeError::new_err(
                "InverseSolver: an earlier solve failed with a panic and left this solver \
                 unusable; make a new one with Robot.inverse_solver",
            )
        })?;
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
            Some(d) if d.is_instance_of::<PyDict>() => {
                Robot::from_value(&to_value(d, &Path::input("robot"))?)?
            }
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
        let p = r.base_position;
        d.set_item("base_position", vec![p.x, p.y, p.z])?;
        d.set_item("muscle_rest_length", r.muscle_rest_length)?;
        d.set_item("inflation_rate", r.inflation_rate)?;
        d.set_item("muscle_length_range", r.muscle_length_range.to_vec())?;
        d.set_item("n_elements", r.n_elements)?;
        Ok(d.into_any())
    }

    /// The Scene of this robot with an actuation (m, 2) and a tip mass (kg).
    #[pyo3(signature = (rest_curvature, load=0.0))]
    fn scene(
        &self,
        rest_curvature: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = load_arg)] load: f64,
    ) -> PyResult<PyScene> {
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
        #[pyo3(from_py_with = load_arg)] load: f64,
    ) -> PyResult<PySolution> {
        let k = rows_arg::<2>("rest_curvature", rest_curvature)?;
        let scene = self.inner.scene(&k, load)?;
        let settings = Settings {
            n_elements: Some(self.inner.n_elements),
            ..Settings::default()
        };
        let long = self.inner.has_long_passes();
        let sol = detach_solve(py, long, move || crate::solve(&scene, settings, None))?;
        Ok(PySolution { inner: sol })
    }

    /// A reusable inverse solver for one tip mass (warm starts between calls).
    #[pyo3(signature = (load=0.0))]
    fn inverse_solver(
        &self,
        #[pyo3(from_py_with = load_arg)] load: f64,
    ) -> PyResult<PyInverseSolver> {
        Ok(PyInverseSolver {
            inner: Arc::new(Mutex::new(InverseSolver::new(&self.inner, load)?)),
            long_passes: self.inner.has_long_passes(),
        })
    }

    /// Load-aware inverse kinematics of one target.
    #[pyo3(
        signature = (target, load=0.0, reference=None, direction=None, strategy=Strategy::Equilibrium, tol=1e-9, max_iterations=60),
        text_signature = "($self, target, load=0.0, reference=None, direction=None, strategy='equilibrium', tol=1e-9, max_iterations=60)"
    )]
    #[allow(clippy::too_many_arguments)]
    fn inverse(
        &self,
        py: Python<'_>,
        target: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = load_arg)] load: f64,
        reference: Option<&Bound<'_, PyAny>>,
        direction: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = strategy_arg)] strategy: Strategy,
        #[pyo3(from_py_with = tol_arg)] tol: f64,
        #[pyo3(from_py_with = max_iterations_arg)] max_iterations: usize,
    ) -> PyResult<PyIkResult> {
        let target = vec3_arg("target", target)?;
        let options = self.ik_options(load, reference, direction, strategy, tol, max_iterations)?;
        let robot = self.inner.clone();
        let long = robot.has_long_passes();
        let r = detach_solve(py, long, move || robot.inverse(target, &options))?;
        Ok(PyIkResult { inner: r })
    }

    /// Inverse kinematics of a sequence of targets (N, 3), each warm from the
    /// previous one and closest to its actuation.
    #[pyo3(
        signature = (points, load=0.0, reference=None, direction=None, strategy=Strategy::Equilibrium, tol=1e-9, max_iterations=60),
        text_signature = "($self, points, load=0.0, reference=None, direction=None, strategy='equilibrium', tol=1e-9, max_iterations=60)"
    )]
    #[allow(clippy::too_many_arguments)]
    fn track(
        &self,
        py: Python<'_>,
        points: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = load_arg)] load: f64,
        reference: Option<&Bound<'_, PyAny>>,
        direction: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = strategy_arg)] strategy: Strategy,
        #[pyo3(from_py_with = tol_arg)] tol: f64,
        #[pyo3(from_py_with = max_iterations_arg)] max_iterations: usize,
    ) -> PyResult<Vec<PyIkResult>> {
        let pts: Vec<Vector3<f64>> = rows_arg::<3>("points", points)?
            .into_iter()
            .map(Vector3::from)
            .collect();
        let options = self.ik_options(load, reference, direction, strategy, tol, max_iterations)?;
        let robot = self.inner.clone();
        let long = robot.has_long_passes();
        let rs = detach_solve(py, long, move || robot.track(&pts, &options))?;
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
        strategy: Strategy,
        tol: f64,
        max_iterations: usize,
    ) -> PyResult<IkOptions> {
        Ok(IkOptions {
            tip_mass: load,
            reference: reference
                .map(|r| rows_arg::<2>("reference", r))
                .transpose()?,
            direction: direction.map(|d| vec3_arg("direction", d)).transpose()?,
            strategy,
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
    name: &Bound<'py, PyAny>,
    #[pyo3(from_py_with = points_arg)] points: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let name = str_arg("trajectory", name)?;
    if points == 0 {
        return Err(PyValueError::new_err("points: must be positive"));
    }
    let pts = trajectory::by_name(&name, points).ok_or_else(|| {
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
