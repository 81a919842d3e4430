//! `Solver`: one scene's reusable solver (its workspace allocated once), for
//! control loops: set the actuation or the tip load, solve warm.

use super::convert::*;
use super::detach::detach_solve;
use super::scene::{scene_arg, PyScene};
use super::solution::{previous_solution, quaternions_arg, PySolution};
use super::solve::settings_with;
use crate::{Quat, Solver};
use nalgebra::Vector3;
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use std::sync::{Arc, Mutex};
use std::thread::ThreadId;

/// The solver and the warm start it keeps.
pub(super) struct Held {
    solver: Solver,
    /// The last converged and stable equilibrium (`initial="last"`).
    last: Option<Vec<Quat>>,
    /// The thread that changed the scene (`set_*`) since the last solve: a
    /// `set_*` and the `solve` that uses it belong to one thread, or a
    /// thread would solve another's actuation without knowing it.
    changed_by: Option<ThreadId>,
}

impl Held {
    /// Refuse to go on when another thread changed the scene and has not
    /// solved it yet.
    fn check_turn(&self, what: &str) -> PyResult<()> {
        match self.changed_by {
            Some(other) if other != std::thread::current().id() => Err(not_your_turn(what)),
            _ => Ok(()),
        }
    }

    /// Run a change of the scene as the current thread's.
    fn change(
        &mut self,
        what: &str,
        set: impl FnOnce(&mut Solver) -> crate::Result<()>,
    ) -> PyResult<()> {
        self.check_turn(what)?;
        set(&mut self.solver)?;
        self.changed_by = Some(std::thread::current().id());
        Ok(())
    }
}

/// A reusable solver of one scene: build once, then ``set_rest_curvature``,
/// ``set_tip_force``, ``set_tip_moment`` and ``solve``, warm from the last
/// equilibrium by default.
///
/// Safe to share between threads: one solve runs at a time, and a thread
/// waiting for its turn does not hold the GIL. A ``set_*`` and the ``solve``
/// that uses it belong to one thread: another thread's ``set_*`` or
/// ``solve`` in between raises ``RuntimeError`` (pass the drives to
/// ``solve`` to change and solve in one call).
#[pyclass(name = "Solver", module = "softspine._core", frozen)]
pub struct PySolver {
    inner: Arc<Mutex<Held>>,
    long_passes: bool,
}

impl PySolver {
    fn held(&self) -> PyResult<std::sync::MutexGuard<'_, Held>> {
        self.inner.lock().map_err(|_| poisoned())
    }
}

fn poisoned() -> PyErr {
    PyRuntimeError::new_err(
        "Solver: an earlier solve failed with a panic and left this solver unusable; make a new one",
    )
}

#[pymethods]
impl PySolver {
    /// ``Solver(scene, settings=None, *, n_elements, method, scheme,
    /// residual_tol, max_iterations)``: the keywords override the settings'
    /// fields, as in ``softspine.solve``.
    #[new]
    #[pyo3(signature = (scene, settings=None, *, n_elements=None, method=None, scheme=None, residual_tol=None, max_iterations=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        scene: &Bound<'_, PyAny>,
        settings: Option<&Bound<'_, PyAny>>,
        n_elements: Option<&Bound<'_, PyAny>>,
        method: Option<&Bound<'_, PyAny>>,
        scheme: Option<&Bound<'_, PyAny>>,
        residual_tol: Option<&Bound<'_, PyAny>>,
        max_iterations: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
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
            ],
        )?;
        let long_passes = settings.resolved(&scene).has_long_passes();
        let solver = py.detach(|| Solver::new(&scene, settings))?;
        Ok(PySolver {
            inner: Arc::new(Mutex::new(Held {
                solver,
                last: None,
                changed_by: None,
            })),
            long_passes,
        })
    }

    /// Solve from ``initial`` (a Solution or quaternions (n + 1, 4)) or,
    /// without it, from the last converged and stable equilibrium of this
    /// solver (``warm=True``, the default; the straight rod before there is
    /// one) or the straight rod (``warm=False``). ``check=True`` raises
    /// ``SolverError`` unless the solve converged. ``rest_curvature``,
    /// ``tip_force``, ``tip_moment``, ``tensions`` and ``field``, where
    /// given, are set first as by their ``set_*``, in the same call (what
    /// threads sharing a solver use).
    #[pyo3(signature = (initial=None, *, warm=true, check=false, rest_curvature=None, tip_force=None, tip_moment=None, tensions=None, field=None))]
    #[allow(clippy::too_many_arguments)]
    fn solve(
        &self,
        py: Python<'_>,
        initial: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = warm_arg)] warm: bool,
        #[pyo3(from_py_with = check_arg)] check: bool,
        rest_curvature: Option<&Bound<'_, PyAny>>,
        tip_force: Option<&Bound<'_, PyAny>>,
        tip_moment: Option<&Bound<'_, PyAny>>,
        tensions: Option<&Bound<'_, PyAny>>,
        field: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PySolution> {
        let start = match (given(initial), warm) {
            (Some(x), _) => match previous_solution(&x) {
                Some(previous) => Start::After(Box::new(previous)),
                None => Start::Given(quaternions_arg("initial", &x)?),
            },
            (None, true) => Start::Last,
            (None, false) => Start::Straight,
        };
        let drives = Drives {
            rest_curvature: given(rest_curvature)
                .map(|k| rows_arg::<2>("rest_curvature", &k))
                .transpose()?,
            tip_force: given(tip_force)
                .map(|f| vec3_arg("tip_force", &f))
                .transpose()?,
            tip_moment: given(tip_moment)
                .map(|m| vec3_arg("tip_moment", &m))
                .transpose()?,
            tensions: given(tensions)
                .map(|t| floats_arg("tensions", &t))
                .transpose()?,
            field: given(field).map(|b| vec3_arg("field", &b)).transpose()?,
        };
        let caller = std::thread::current().id();
        let inner = Arc::clone(&self.inner);
        let sol = detach_solve(py, self.long_passes, move || {
            let Ok(mut held) = inner.lock() else {
                return Ok(None);
            };
            let held = &mut *held;
            // The solve may run on a worker thread: the turn is the caller's.
            if held.changed_by.is_some_and(|t| t != caller) {
                return Ok(Some(Err(())));
            }
            if let Err(e) = drives.apply(&mut held.solver) {
                // Some of them may be set: this thread's, unsolved.
                held.changed_by = Some(caller);
                return Err(e);
            }
            held.changed_by = None;
            let sol = match &start {
                Start::Last => held.solver.solve(held.last.as_deref())?,
                Start::Straight => held.solver.solve(None)?,
                Start::Given(q) => held.solver.solve(Some(q.as_slice()))?,
                // The next step of its history (`Solver::solve_after`).
                Start::After(previous) => held.solver.solve_after(previous)?,
            };
            if sol.converged() && sol.stable {
                match held.last.as_mut() {
                    // In place: a control loop allocates nothing here.
                    Some(last) => last.copy_from_slice(&sol.quaternions),
                    None => held.last = Some(sol.quaternions.clone()),
                }
            }
            Ok(Some(Ok(sol)))
        })?
        .ok_or_else(poisoned)?;
        let sol = sol.map_err(|()| not_your_turn("solve"))?;
        let sol = if check { sol.check()? } else { sol };
        Ok(PySolution { inner: sol })
    }

    /// Set the actuation: rest curvature ``[kappa_x, kappa_y]`` per section
    /// (m, 2), 1/m; the number of sections must divide ``n_elements``.
    fn set_rest_curvature(&self, rest_curvature: &Bound<'_, PyAny>) -> PyResult<()> {
        let k = rows_arg::<2>("rest_curvature", rest_curvature)?;
        self.held()?
            .change("set_rest_curvature", |s| s.set_rest_curvature(&k))
    }

    /// Set the dead force at the tip, world frame, N.
    fn set_tip_force(&self, force: &Bound<'_, PyAny>) -> PyResult<()> {
        let f = vec3_arg("force", force)?;
        self.held()?.change("set_tip_force", |s| {
            let moment = s.scene().tip_moment;
            s.set_tip_load(f, moment)
        })
    }

    /// Set the dead moment at the tip, world frame, N m.
    fn set_tip_moment(&self, moment: &Bound<'_, PyAny>) -> PyResult<()> {
        let m = vec3_arg("moment", moment)?;
        self.held()?.change("set_tip_moment", |s| {
            let force = s.scene().tip_force;
            s.set_tip_load(force, m)
        })
    }

    /// Sensitivity of the last solve's equilibrium (solve first) to the
    /// named parameters: paths in the scene's dict (``"tip_force[0]"``,
    /// ``"stiffness.kx"``, ``"gravity.linear_density"``,
    /// ``"rest_curvature[2][1]"``), ``"rest_curvature"`` (every section) or
    /// ``"tip_wrench"`` (tip force and moment: the 6x6 tip compliance).
    /// The fields of a ``softspine.sensitivity.Sensitivity``;
    /// ``Solver.sensitivity`` (``softspine.sensitivity``) calls it.
    #[pyo3(name = "_sensitivity")]
    fn sensitivity<'py>(
        &self,
        py: Python<'py>,
        parameters: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
        let names = super::fitting::parameter_names(parameters)?;
        let inner = Arc::clone(&self.inner);
        let s = detach_solve(py, self.long_passes, move || {
            let Ok(mut held) = inner.lock() else {
                return Ok(None);
            };
            let names: Vec<&str> = names.iter().map(|s| s.as_str()).collect();
            held.solver.sensitivity(&names).map(Some)
        })?
        .ok_or_else(poisoned)?;
        super::fitting::sensitivity_result(py, &s, None)
    }

    /// Set the tendons' tensions, N: one a tendon, in the scene's order, >= 0.
    fn set_tensions(&self, tensions: &Bound<'_, PyAny>) -> PyResult<()> {
        let t = floats_arg("tensions", tensions)?;
        self.held()?.change("set_tensions", |s| s.set_tensions(&t))
    }

    /// Set the uniform magnetic field, world frame, T.
    fn set_magnetic_field(&self, field: &Bound<'_, PyAny>) -> PyResult<()> {
        let b = vec3_arg("field", field)?;
        self.held()?
            .change("set_magnetic_field", |s| s.set_magnetic_field(b))
    }

    /// Forget the last equilibrium (the next ``solve()`` starts from the
    /// straight rod) and which thread changed the scene last.
    fn reset(&self) -> PyResult<()> {
        let mut held = self.held()?;
        held.last = None;
        held.changed_by = None;
        Ok(())
    }

    /// The scene as the solver holds it (its actuation and tip load included).
    #[getter]
    fn scene(&self) -> PyResult<PyScene> {
        Ok(PyScene {
            inner: self.held()?.solver.scene().clone(),
        })
    }

    /// Elements of the discretisation.
    #[getter]
    fn n_elements(&self) -> PyResult<usize> {
        Ok(self.held()?.solver.model().n())
    }

    /// The dead force at the tip, world frame, N.
    #[getter]
    fn tip_force<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray1<f64>>> {
        let f: Vector3<f64> = self.held()?.solver.scene().tip_force;
        Ok(vec3_array(py, &f))
    }

    fn __repr__(&self) -> PyResult<String> {
        let held = self.held()?;
        Ok(format!(
            "Solver(n_elements={}, warm={})",
            held.solver.model().n(),
            python_bool(held.last.is_some())
        ))
    }
}

/// The scene's changes a `solve` call makes first.
struct Drives {
    rest_curvature: Option<Vec<[f64; 2]>>,
    tip_force: Option<Vector3<f64>>,
    tip_moment: Option<Vector3<f64>>,
    tensions: Option<Vec<f64>>,
    field: Option<Vector3<f64>>,
}

impl Drives {
    fn apply(&self, solver: &mut Solver) -> crate::Result<()> {
        if let Some(k) = &self.rest_curvature {
            solver.set_rest_curvature(k)?;
        }
        if self.tip_force.is_some() || self.tip_moment.is_some() {
            let scene = solver.scene();
            let force = self.tip_force.unwrap_or(scene.tip_force);
            let moment = self.tip_moment.unwrap_or(scene.tip_moment);
            solver.set_tip_load(force, moment)?;
        }
        if let Some(t) = &self.tensions {
            solver.set_tensions(t)?;
        }
        if let Some(b) = self.field {
            solver.set_magnetic_field(b)?;
        }
        Ok(())
    }
}

/// The refusal of a `set_*` or `solve` between another thread's `set_*`
/// and its solve.
fn not_your_turn(what: &str) -> PyErr {
    PyRuntimeError::new_err(format!(
        "Solver.{what}: another thread changed this solver's scene (set_*) and has not solved \
         it yet; between a set_* and its solve a Solver serves one thread: give the drives to \
         solve(rest_curvature=..., tensions=..., ...) in one call, or use a Solver per thread"
    ))
}

fn warm_arg(obj: &Bound<'_, PyAny>) -> PyResult<bool> {
    bool_arg("warm", obj)
}

/// Where a solve starts.
enum Start {
    Last,
    Straight,
    Given(Vec<Quat>),
    /// A Solution: the last step of the history.
    After(Box<crate::Solution>),
}
