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

/// The `#[pymethods]` of a settings class: for each plain field (`getter,
/// setter: type = path in the core's struct`), its documented getter and a
/// setter through the core's keyed `set` (by the class's `assign`, which names
/// the key in a refusal); then the class's other methods as written.
macro_rules! settings_methods {
    (
        impl $Py:ident {
            fields {
                $(
                    $(#[doc = $doc:literal])*
                    $get:ident, $set:ident: $ty:ty = $($path:ident).+;
                )*
            }
            $($methods:tt)*
        }
    ) => {
        #[pymethods]
        impl $Py {
            $(
                $(#[doc = $doc])*
                #[getter]
                fn $get(&self) -> $ty {
                    self.inner.$($path).+
                }
                #[setter]
                fn $set(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
                    self.assign(stringify!($get), value)
                }
            )*
            $($methods)*
        }
    };
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

settings_methods! {
    impl PyPaperSettings {
        fields {
            /// Number of particles of the swarm (default 40).
            particles, set_particles: usize = swarm.particles;
            /// Iterations of the plain swarm, phase 1 of the seed's Algorithm 1 (default 60).
            iterations, set_iterations: usize = swarm.iterations;
            /// Constriction factor chi (default 0.729, Clerc and Kennedy).
            chi, set_chi: f64 = swarm.chi;
            /// Inertia weight on the previous velocity (default 1.0: pure constriction).
            inertia, set_inertia: f64 = swarm.inertia;
            /// Pull toward the particle's own best (default 2.05).
            c1, set_c1: f64 = swarm.c1;
            /// Pull toward the swarm's best (default 2.05).
            c2, set_c2: f64 = swarm.c2;
            /// Seed of the random streams (default 0): the same seed, the same answer
            /// on any number of threads.
            seed, set_seed: u64 = swarm.seed;
            /// Phase 2: swarm iterations each followed by a Gauss-Newton step on the
            /// global best (default 20).
            gauss_newton_iterations, set_gauss_newton_iterations: usize = gauss_newton_iterations;
            /// Levenberg-Marquardt iteration limit (default 200).
            lm_iterations, set_lm_iterations: usize = lm_iterations;
            /// Tolerance on the largest scaled residual row (default 1e-10, in [1e-14, 1e-4]).
            tol, set_tol: f64 = tol;
        }

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

settings_methods! {
    impl PySettings {
        fields {
            /// Number of elements ``n``, a multiple of the number of sections; None
            /// (the default) for the smallest multiple of the sections that is at least 20.
            n_elements, set_n_elements: Option<usize> = n_elements;
            /// Tolerance on the relative residual, the largest torque imbalance of a
            /// row over its stiffness scale k_c/L (default 1e-10, in [1e-14, 1e-4];
            /// never below the residual's round-off floor).
            residual_tol, set_residual_tol: f64 = residual_tol;
            /// Iteration budget of the whole solve (default 500): ``Solution.iterations``
            /// never exceeds it.
            max_iterations, set_max_iterations: usize = max_iterations;
            /// Smallest load-continuation step, a fraction of the load (default 1e-6, in (0, 1)).
            min_continuation_step, set_min_continuation_step: f64 = min_continuation_step;
        }

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

        /// ``"auto"`` (default: the core chooses, shooting for accuracy on demand
        /// where it models the scene and converges directly, else ``"newton"``),
        /// ``"newton"``, ``"lm"``, ``"paper"``, ``"paper-literal"`` or ``"shooting"``
        /// (RK4 on the rod equations, Newton on the base wrench).
        #[getter]
        fn method(&self) -> &'static str {
            self.inner.method.name()
        }
        #[setter]
        fn set_method(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
            self.assign("method", value)
        }
        /// The discretisation of the backbone: ``"fd2"`` (the seed's finite
        /// differences, second order), ``"fe4"`` (quadratic elements with two-point
        /// Gauss quadrature, fourth order at the nodes) or None (default: ``"fe4"``
        /// for accuracy on demand below 3e-5 L, 1e-6 L with held points, where it
        /// is the faster, ``"fd2"`` otherwise).
        #[getter]
        fn scheme(&self) -> Option<&'static str> {
            self.inner.scheme.map(|s| s.name())
        }
        #[setter]
        fn set_scheme(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
            self.assign("scheme", value)
        }
        /// Settings of the paper's method, a ``PaperSettings`` (set it to one or to a
        /// dict of its fields, which applies them to the current ones).
        #[getter]
        fn paper(&self, py: Python<'_>) -> Py<PyPaperSettings> {
            self.paper.clone_ref(py)
        }
        #[setter]
        fn set_paper(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
            if let Ok(p) = value.cast::<PyPaperSettings>() {
                self.paper = p.clone().unbind();
                return Ok(());
            }
            self.assign("paper", value)
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
    fn assign(&mut self, key: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let py = value.py();
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

settings_methods! {
    impl PyAccuracy {
        fields {
            /// Tolerance on the backbone's estimated error, relative to the length L
            /// (in [1e-12, 0.1]).
            tol, set_tol: f64 = tol;
            /// Largest number of elements tried (default 10 240).
            max_elements, set_max_elements: usize = max_elements;
        }

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

settings_methods! {
    impl PyIkSettings {
        fields {
            /// Tip position tolerance, m (default 1e-9, in [1e-12 L, 1e-2 L]); a
            /// direction's tolerance is tol / L.
            tol, set_tol: f64 = tol;
            /// Iteration limit of one descent (default 60); a missed target tries at
            /// most 8 descents in all.
            max_iterations, set_max_iterations: usize = max_iterations;
        }

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
