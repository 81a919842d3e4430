//! `Settings`, `PaperSettings` and `Accuracy`: the core's settings structs,
//! mirrored. Every value goes through the core's `set` (which names the key
//! and checks its kind) and `validate` (ranges); defaults are the core's.

use super::convert::*;
use crate::methods::paper::PaperSettings;
use crate::{Accuracy, IkSettings, Settings, Value};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Keyword arguments as a value tree whose keys name the fields, so that a
/// refusal reads `paper.chi: ...` whatever the depth.
fn fields_value(fields: Option<&Bound<'_, PyDict>>) -> PyResult<Value> {
    match fields {
        Some(d) => to_value(d.as_any(), &Path::input("settings")),
        None => Ok(Value::Map(Vec::new())),
    }
}

/// One keyword's value (a setter's), refused under its own name.
fn field_value(key: &str, value: &Bound<'_, PyAny>) -> PyResult<Value> {
    let d = PyDict::new(value.py());
    d.set_item(key, value)?;
    match fields_value(Some(&d))? {
        Value::Map(mut entries) => Ok(entries.pop().map(|(_, v)| v).unwrap_or(Value::Null)),
        other => Ok(other),
    }
}

pub(super) fn entries(v: &Value) -> &[(String, Value)] {
    match v {
        Value::Map(entries) => entries,
        _ => &[],
    }
}

/// Settings of the paper's method (``method="paper"``): the particle swarm, then
/// Gauss-Newton and Levenberg-Marquardt.
///
/// ``PaperSettings(particles=80, seed=3)``; every field can be set afterwards
/// (its kind is checked at once, its range by ``validate()`` and by the solve).
#[pyclass(
    name = "PaperSettings",
    module = "softspine._core",
    eq,
    skip_from_py_object
)]
#[derive(Clone, PartialEq)]
pub struct PyPaperSettings {
    pub(super) inner: PaperSettings,
}

#[pymethods]
impl PyPaperSettings {
    #[new]
    #[pyo3(signature = (**fields), text_signature = "(**fields)")]
    fn new(fields: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let mut inner = PaperSettings::default();
        for (k, v) in entries(&fields_value(fields)?) {
            inner.set(k, v)?;
        }
        inner.validate()?;
        Ok(PyPaperSettings { inner })
    }

    /// Refuse a field out of its range, naming it (``ValueError``).
    fn validate(&self) -> PyResult<()> {
        Ok(self.inner.validate()?)
    }

    /// Every field as a dict (``PaperSettings(**d)`` reads it back).
    fn to_dict<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyDict>> {
        fields_dict(slf.as_any(), &PaperSettings::KEYS)
    }

    /// Number of particles of the swarm (default 40).
    #[getter]
    fn particles(&self) -> usize {
        self.inner.swarm.particles
    }
    #[setter]
    fn set_particles(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign("particles", value)
    }
    /// Iterations of the plain swarm, phase 1 of the seed's Algorithm 1 (default 60).
    #[getter]
    fn iterations(&self) -> usize {
        self.inner.swarm.iterations
    }
    #[setter]
    fn set_iterations(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign("iterations", value)
    }
    /// Constriction factor chi (default 0.729, Clerc and Kennedy).
    #[getter]
    fn chi(&self) -> f64 {
        self.inner.swarm.chi
    }
    #[setter]
    fn set_chi(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign("chi", value)
    }
    /// Inertia weight on the previous velocity (default 1.0: pure constriction).
    #[getter]
    fn inertia(&self) -> f64 {
        self.inner.swarm.inertia
    }
    #[setter]
    fn set_inertia(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign("inertia", value)
    }
    /// Pull toward the particle's own best (default 2.05).
    #[getter]
    fn c1(&self) -> f64 {
        self.inner.swarm.c1
    }
    #[setter]
    fn set_c1(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign("c1", value)
    }
    /// Pull toward the swarm's best (default 2.05).
    #[getter]
    fn c2(&self) -> f64 {
        self.inner.swarm.c2
    }
    #[setter]
    fn set_c2(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign("c2", value)
    }
    /// Seed of the random streams (default 0): the same seed, the same answer
    /// on any number of threads.
    #[getter]
    fn seed(&self) -> u64 {
        self.inner.swarm.seed
    }
    #[setter]
    fn set_seed(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign("seed", value)
    }
    /// Phase 2: swarm iterations each followed by a Gauss-Newton step on the
    /// global best (default 20).
    #[getter]
    fn gauss_newton_iterations(&self) -> usize {
        self.inner.gauss_newton_iterations
    }
    #[setter]
    fn set_gauss_newton_iterations(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign("gauss_newton_iterations", value)
    }
    /// Levenberg-Marquardt iteration limit (default 200).
    #[getter]
    fn lm_iterations(&self) -> usize {
        self.inner.lm_iterations
    }
    #[setter]
    fn set_lm_iterations(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign("lm_iterations", value)
    }
    /// Tolerance on the largest scaled residual row (default 1e-10, in [1e-14, 1e-4]).
    #[getter]
    fn tol(&self) -> f64 {
        self.inner.tol
    }
    #[setter]
    fn set_tol(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign("tol", value)
    }

    /// Pickling goes through ``to_dict``.
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, (), Bound<'py, PyAny>)> {
        let state = Self::to_dict(slf)?.into_any();
        Ok((slf.get_type().into_any(), (), state))
    }

    fn __setstate__(&mut self, state: &Bound<'_, PyDict>) -> PyResult<()> {
        *self = PyPaperSettings::new(Some(state))?;
        Ok(())
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        settings_repr(slf.as_any(), "PaperSettings", &PaperSettings::KEYS)
    }
}

impl PyPaperSettings {
    fn assign(&mut self, key: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        Ok(self.inner.set(key, &field_value(key, value)?)?)
    }
}

/// The fields `keys` of a settings object as a dict, read through its typed
/// getters (counts as ints; a nested settings object as its own dict).
fn fields_dict<'py>(obj: &Bound<'py, PyAny>, keys: &[&str]) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(obj.py());
    for key in keys {
        let value = obj.getattr(*key)?;
        if value.hasattr("to_dict")? {
            d.set_item(*key, value.call_method0("to_dict")?)?;
        } else {
            d.set_item(*key, value)?;
        }
    }
    Ok(d)
}

/// ``Name(key=value, ...)`` of a settings object.
fn settings_repr(obj: &Bound<'_, PyAny>, name: &str, keys: &[&str]) -> PyResult<String> {
    let parts = keys
        .iter()
        .map(|key| Ok(format!("{key}={}", obj.getattr(*key)?.repr()?)))
        .collect::<PyResult<Vec<_>>>()?;
    Ok(format!("{name}({})", parts.join(", ")))
}

/// Settings of an equilibrium solve (``softspine.solve(scene, settings)``).
///
/// ``Settings(n_elements=40, residual_tol=1e-12)``; every field can be set
/// afterwards (its kind is checked at once, its range by ``validate()`` and by
/// the solve). ``paper`` is a ``PaperSettings`` shared with these settings:
/// ``settings.paper.particles = 80`` changes them.
#[pyclass(name = "Settings", module = "softspine._core")]
pub struct PySettings {
    /// Every field but `paper`, which lives in `paper` (shared with Python).
    inner: Settings,
    paper: Py<PyPaperSettings>,
}

#[pymethods]
impl PySettings {
    #[new]
    #[pyo3(signature = (**fields), text_signature = "(**fields)")]
    fn new(py: Python<'_>, fields: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let mut inner = Settings::default();
        for (k, v) in entries(&fields_value(fields)?) {
            inner.set(k, v)?;
        }
        inner.validate()?;
        let paper = Py::new(
            py,
            PyPaperSettings {
                inner: inner.paper.clone(),
            },
        )?;
        Ok(PySettings { inner, paper })
    }

    /// Refuse a field out of its range, or an ``n_elements`` beyond what
    /// ``method`` allows, naming the field (``ValueError``).
    fn validate(&self, py: Python<'_>) -> PyResult<()> {
        Ok(self.to_core(py).validate()?)
    }

    /// Every field as a dict (``Settings(**d)`` reads it back; ``paper`` as a dict).
    fn to_dict<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyDict>> {
        fields_dict(slf.as_any(), &Settings::KEYS)
    }

    /// Number of elements ``n``, a multiple of the number of sections; None
    /// (the default) for the smallest multiple of the sections that is at least 20.
    #[getter]
    fn n_elements(&self) -> Option<usize> {
        self.inner.n_elements
    }
    #[setter]
    fn set_n_elements(&mut self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign(py, "n_elements", value)
    }
    /// ``"newton"`` (default), ``"lm"``, ``"paper"``, ``"paper-literal"`` or
    /// ``"shooting"`` (RK4 on the rod equations, Newton on the base wrench).
    #[getter]
    fn method(&self) -> &'static str {
        self.inner.method.name()
    }
    #[setter]
    fn set_method(&mut self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign(py, "method", value)
    }
    /// The discretisation of the backbone: ``"fd2"`` (the seed's finite
    /// differences, second order), ``"fe4"`` (quadratic elements with two-point
    /// Gauss quadrature, fourth order at the nodes) or None (default: ``"fe4"``
    /// for accuracy on demand below 1e-5 L, 1e-6 L with held points, where it
    /// is the faster, ``"fd2"`` otherwise).
    #[getter]
    fn scheme(&self) -> Option<&'static str> {
        self.inner.scheme.map(|s| s.name())
    }
    #[setter]
    fn set_scheme(&mut self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign(py, "scheme", value)
    }
    /// Tolerance on the relative residual, the largest torque imbalance of a
    /// row over its stiffness scale k_c/L (default 1e-10, in [1e-14, 1e-4];
    /// never below the residual's round-off floor).
    #[getter]
    fn residual_tol(&self) -> f64 {
        self.inner.residual_tol
    }
    #[setter]
    fn set_residual_tol(&mut self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign(py, "residual_tol", value)
    }
    /// Iteration budget of the whole solve (default 500): ``Solution.iterations``
    /// never exceeds it.
    #[getter]
    fn max_iterations(&self) -> usize {
        self.inner.max_iterations
    }
    #[setter]
    fn set_max_iterations(&mut self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign(py, "max_iterations", value)
    }
    /// Smallest load-continuation step, a fraction of the load (default 1e-6, in (0, 1)).
    #[getter]
    fn min_continuation_step(&self) -> f64 {
        self.inner.min_continuation_step
    }
    #[setter]
    fn set_min_continuation_step(
        &mut self,
        py: Python<'_>,
        value: &Bound<'_, PyAny>,
    ) -> PyResult<()> {
        self.assign(py, "min_continuation_step", value)
    }
    /// Settings of the paper's method, a ``PaperSettings`` (set it to one or to a
    /// dict of its fields, which applies them to the current ones).
    #[getter]
    fn paper(&self, py: Python<'_>) -> Py<PyPaperSettings> {
        self.paper.clone_ref(py)
    }
    #[setter]
    fn set_paper(&mut self, py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<()> {
        if let Ok(p) = value.cast::<PyPaperSettings>() {
            self.paper = p.clone().unbind();
            return Ok(());
        }
        self.assign(py, "paper", value)
    }

    /// Pickling goes through ``to_dict``.
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, (), Bound<'py, PyAny>)> {
        let state = Self::to_dict(slf)?.into_any();
        Ok((slf.get_type().into_any(), (), state))
    }

    fn __setstate__(&mut self, py: Python<'_>, state: &Bound<'_, PyDict>) -> PyResult<()> {
        *self = PySettings::new(py, Some(state))?;
        Ok(())
    }

    fn __eq__(&self, py: Python<'_>, other: &Bound<'_, PyAny>) -> bool {
        other
            .cast::<PySettings>()
            .is_ok_and(|o| o.borrow().to_core(py) == self.to_core(py))
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        settings_repr(slf.as_any(), "Settings", &Settings::KEYS)
    }
}

impl PySettings {
    /// The core's settings, `paper` included.
    pub(super) fn to_core(&self, py: Python<'_>) -> Settings {
        Settings {
            paper: self.paper.borrow(py).inner.clone(),
            ..self.inner.clone()
        }
    }

    /// Set one field through the core (a `paper` table applies to the
    /// current paper settings, as the core's `set` does).
    fn assign(&mut self, py: Python<'_>, key: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let mut core = self.to_core(py);
        core.set(key, &field_value(key, value)?)?;
        if key == "paper" {
            self.paper = Py::new(py, PyPaperSettings { inner: core.paper })?;
        } else {
            self.inner = core;
        }
        Ok(())
    }
}

/// Accuracy on demand (``softspine.solve(scene, accuracy=Accuracy(1e-6))``):
/// the n whose backbone's estimated error is below ``tol * L``.
#[pyclass(name = "Accuracy", module = "softspine._core", eq, skip_from_py_object)]
#[derive(Clone, PartialEq)]
pub struct PyAccuracy {
    pub(super) inner: Accuracy,
}

#[pymethods]
impl PyAccuracy {
    #[new]
    #[pyo3(
        signature = (tol, **fields),
        text_signature = "(tol, refine=None, max_elements=10240)"
    )]
    fn new(tol: &Bound<'_, PyAny>, fields: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        let mut all = vec![("tol".to_string(), field_value("tol", tol)?)];
        all.extend(entries(&fields_value(fields)?).iter().cloned());
        Ok(PyAccuracy {
            inner: Accuracy::from_value(&Value::Map(all))?,
        })
    }

    /// Refuse a field out of its range, naming it (``ValueError``).
    fn validate(&self) -> PyResult<()> {
        Ok(self.inner.validate()?)
    }

    /// Every field as a dict (``Accuracy(**d)`` reads it back).
    fn to_dict<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyDict>> {
        fields_dict(slf.as_any(), &Accuracy::KEYS)
    }

    /// Tolerance on the backbone's estimated error, relative to the length L
    /// (in [1e-12, 0.1]).
    #[getter]
    fn tol(&self) -> f64 {
        self.inner.tol
    }
    #[setter]
    fn set_tol(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign("tol", value)
    }
    /// ``"richardson"``: return the Richardson-extrapolated tip ``(4 r_2n - r_n) / 3``;
    /// None (the default): the last node of the finest solve.
    #[getter]
    fn refine(&self) -> Option<&'static str> {
        self.inner.richardson.then_some("richardson")
    }
    #[setter]
    fn set_refine(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign("refine", value)
    }
    /// Largest number of elements tried (default 10 240).
    #[getter]
    fn max_elements(&self) -> usize {
        self.inner.max_elements
    }
    #[setter]
    fn set_max_elements(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign("max_elements", value)
    }

    /// Pickling goes through ``to_dict``.
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, (f64,), Bound<'py, PyAny>)> {
        let state = Self::to_dict(slf)?.into_any();
        Ok((slf.get_type().into_any(), (slf.borrow().inner.tol,), state))
    }

    fn __setstate__(&mut self, state: &Bound<'_, PyDict>) -> PyResult<()> {
        self.inner = Accuracy::from_value(&fields_value(Some(state))?)?;
        Ok(())
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        settings_repr(slf.as_any(), "Accuracy", &Accuracy::KEYS)
    }
}

impl PyAccuracy {
    fn assign(&mut self, key: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        Ok(self.inner.set(key, &field_value(key, value)?)?)
    }
}

/// Settings of inverse kinematics (``Robot.inverse``, ``Robot.track``,
/// ``InverseSolver.solve``).
#[pyclass(
    name = "IkSettings",
    module = "softspine._core",
    eq,
    skip_from_py_object
)]
#[derive(Clone, PartialEq)]
pub struct PyIkSettings {
    pub(super) inner: IkSettings,
}

#[pymethods]
impl PyIkSettings {
    #[new]
    #[pyo3(signature = (**fields), text_signature = "(**fields)")]
    fn new(fields: Option<&Bound<'_, PyDict>>) -> PyResult<Self> {
        Ok(PyIkSettings {
            inner: IkSettings::from_value(&fields_value(fields)?)?,
        })
    }

    /// Refuse a field out of its range, naming it (``ValueError``).
    fn validate(&self) -> PyResult<()> {
        Ok(self.inner.validate()?)
    }

    /// Every field as a dict (``IkSettings(**d)`` reads it back).
    fn to_dict<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyDict>> {
        fields_dict(slf.as_any(), &IkSettings::KEYS)
    }

    /// ``"equilibrium"`` (default): the loaded robot reaches the target;
    /// ``"geometric"``: the seed's fit that ignores weight and load, applied
    /// to the loaded robot.
    #[getter]
    fn strategy(&self) -> &'static str {
        self.inner.strategy.name()
    }
    #[setter]
    fn set_strategy(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign("strategy", value)
    }
    /// Tip position tolerance, m (default 1e-9, in [1e-12 L, 1e-2 L]); a
    /// direction's tolerance is tol / L.
    #[getter]
    fn tol(&self) -> f64 {
        self.inner.tol
    }
    #[setter]
    fn set_tol(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign("tol", value)
    }
    /// Iteration limit of one descent (default 60); a missed target tries at
    /// most 8 descents in all.
    #[getter]
    fn max_iterations(&self) -> usize {
        self.inner.max_iterations
    }
    #[setter]
    fn set_max_iterations(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.assign("max_iterations", value)
    }

    /// Pickling goes through ``to_dict``.
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, (), Bound<'py, PyAny>)> {
        let state = Self::to_dict(slf)?.into_any();
        Ok((slf.get_type().into_any(), (), state))
    }

    fn __setstate__(&mut self, state: &Bound<'_, PyDict>) -> PyResult<()> {
        *self = PyIkSettings::new(Some(state))?;
        Ok(())
    }

    fn __repr__(slf: &Bound<'_, Self>) -> PyResult<String> {
        settings_repr(slf.as_any(), "IkSettings", &IkSettings::KEYS)
    }
}

impl PyIkSettings {
    fn assign(&mut self, key: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        Ok(self.inner.set(key, &field_value(key, value)?)?)
    }
}

/// The IK settings of a call: `settings` (an `IkSettings`, a dict of its
/// fields or None) with the given keywords over it, read by the core.
pub(super) fn ik_settings_arg(
    settings: Option<&Bound<'_, PyAny>>,
    keywords: &[(&str, Option<&Bound<'_, PyAny>>)],
) -> PyResult<IkSettings> {
    let mut out = match given(settings) {
        None => IkSettings::default(),
        Some(s) => {
            if let Ok(s) = s.cast::<PyIkSettings>() {
                s.borrow().inner.clone()
            } else if s.is_instance_of::<PyDict>() {
                IkSettings::from_value(&to_value(&s, &Path::input("settings"))?)?
            } else {
                return Err(pyo3::exceptions::PyValueError::new_err(format!(
                    "settings: expected an IkSettings or a dict of its fields, got {}",
                    type_name(&s)
                )));
            }
        }
    };
    for (key, value) in keywords {
        if let Some(v) = given(*value) {
            out.set(key, &field_value(key, &v)?)?;
        }
    }
    out.validate()?;
    Ok(out)
}
