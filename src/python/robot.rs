//! `Robot`, its inverse kinematics (`InverseSolver`, `IkResult`) and the seed's trajectories.

use super::batch::{
    batch_result, batch_settings, cluster_plan, ik_batch_result, run_batch, Drives,
};
use super::convert::*;
use super::detach::detach_solve;
use super::scene::PyScene;
use super::settings::ik_settings_arg;
use super::solution::{previous_solution, quaternions_arg, PySolution};
use crate::robot::{trajectory, Actuation, IkOptions, IkResult, IkStart, InverseSolver, Robot};
use crate::value::Format;
use nalgebra::Vector3;
use numpy::{PyArray1, PyArray2};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::{Arc, Mutex};

/// A continuum robot: a body (sections, stiffness, mass, base pose, tool)
/// and one drive (pneumatic muscles, tendons or a magnetic field).
///
/// ``Robot()`` resembles the seed's prototype (1 m, 10 sections of three
/// muscles, hanging); ``Robot({...})`` overrides any field (see
/// ``Robot().to_dict()``). Tendons (``tendons``, ``max_tension``) or magnets
/// (``magnetization``, ``tip_magnet``, ``max_field``) replace the muscles
/// (``muscle_*``, ``inflation_rate``): a robot has one drive.
///
/// Its fields, SI units (default in brackets):
///
/// * ``length`` m [1]; ``sections`` [10], equal unless ``section_properties``
///   (one ``{length, stiffness, linear_density, disk_mass}`` a section, each
///   optional) gives each its own; ``n_elements`` [20], a multiple of them.
/// * ``stiffness``: ``{E, G, diameter}`` Pa, Pa, m [steel, 3 mm] or
///   ``{kx, ky, kz}`` N m^2; ``linear_density`` kg/m [0.2]; ``disk_mass`` kg
///   at each section end [0.01]; ``gravity`` m/s^2, world frame [0, 0, -9.81].
/// * ``base_quaternion`` [w, x, y, z], a 3x3 matrix or a scipy Rotation
///   [pointing down, -z]; ``base_position`` m [origin]; ``tool_mass`` kg [0] and
///   ``tool_offset`` m from the tip in its frame [0]: where the tool and the
///   payload act.
/// * Muscles: ``muscle_radius`` m from the backbone [0.02]; ``muscle_angles``
///   degrees in the cross-section [90, 210, 330]; ``muscle_rest_length`` m
///   [the section length]; ``inflation_rate`` m/s in ``length =
///   rest_length + rate * time`` [-0.01: 1 cm shorter a second];
///   ``muscle_length_range`` m [0.8 and 1.05 rest lengths].
/// * Tendons: ``tendons``, each ``{offset [x, y] m (or one a section it runs
///   through), twist rad/m, section}`` anchored at that section's end;
///   ``max_tension`` N [unbounded].
/// * Magnets: ``magnetization`` A m^2/m a section, material frame;
///   ``tip_magnet`` A m^2; ``max_field`` T [unbounded].
/// * Surroundings: ``obstacles``, ``ports``, ``radius`` m for contact [the
///   drive's reach off the backbone], ``insertion_range`` m [none: the base
///   stays].
#[pyclass(
    name = "Robot",
    module = "softspine._core",
    frozen,
    skip_from_py_object
)]
pub struct PyRobot {
    pub(super) inner: Robot,
}

/// The actuation of one inverse solve in every space, with its equilibrium.
#[pyclass(name = "IkResult", module = "softspine._core", frozen)]
pub struct PyIkResult {
    pub(super) inner: IkResult,
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
    /// Tendon tensions, N (a tendon-driven robot; empty otherwise).
    #[getter]
    fn tensions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.inner.tensions)
    }
    /// The uniform magnetic field, world frame, T (a magnetic robot; zero otherwise).
    #[getter]
    fn field<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vec3_array(py, &self.inner.field)
    }
    /// How far the base was moved along its tangent, m (a robot with an
    /// ``insertion_range``, whose inverse kinematics chooses it; zero otherwise).
    #[getter]
    fn insertion(&self) -> f64 {
        self.inner.insertion
    }
    /// The loaded equilibrium with this actuation.
    #[getter]
    fn solution(&self) -> PySolution {
        PySolution {
            inner: self.inner.solution.clone(),
        }
    }
    /// The point aimed at the target, shape (3,), m: the tool's (`tool_offset`
    /// from the tip) or the tip without a tool.
    #[getter]
    fn tip_position<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vec3_array(py, &self.inner.tip_position)
    }
    /// Distance from the tip to the target, m.
    #[getter]
    fn tip_miss(&self) -> f64 {
        self.inner.tip_miss
    }
    /// Whether the tip (and direction) is within the tolerance, on a stable equilibrium.
    #[getter]
    fn reached(&self) -> bool {
        self.inner.reached
    }
    /// Why the inverse solve ended, a ``softspine.IkEnding`` (a string enum:
    /// it equals its name, e.g. ``"reached"``).
    #[getter]
    fn ending<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        super::enums::ik_ending(py, self.inner.ending)
    }
    /// Starting actuations tried (1: the fast path sufficed).
    #[getter]
    fn starts(&self) -> usize {
        self.inner.starts
    }
    /// A short account of how the inverse solve ended.
    #[getter]
    fn message(&self) -> String {
        self.inner.message.clone()
    }
    /// Gauss-Newton and Levenberg-Marquardt iterations, every start included.
    #[getter]
    fn iterations(&self) -> usize {
        self.inner.iterations
    }
    /// Wall-clock time of the inverse solve, s.
    #[getter]
    fn time(&self) -> f64 {
        self.inner.seconds
    }
    /// Every field as a dict of NumPy arrays and scalars (``solution`` as its
    /// own ``to_dict()``, ``ending`` as its name); ``IkResult.from_dict``
    /// rebuilds the result.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let r = &self.inner;
        let d = PyDict::new(py);
        d.set_item("rest_curvature", rows_n(py, &r.rest_curvature))?;
        d.set_item("muscle_lengths", rows_n(py, &r.muscle_lengths))?;
        d.set_item("inflation_times", rows_n(py, &r.inflation_times))?;
        d.set_item("tensions", PyArray1::from_slice(py, &r.tensions))?;
        d.set_item("field", vec3_array(py, &r.field))?;
        d.set_item("insertion", r.insertion)?;
        let solution = PySolution {
            inner: r.solution.clone(),
        };
        d.set_item("solution", solution.to_dict(py)?)?;
        d.set_item("tip_position", vec3_array(py, &r.tip_position))?;
        d.set_item("tip_miss", r.tip_miss)?;
        d.set_item("reached", r.reached)?;
        d.set_item("ending", r.ending.name())?;
        d.set_item("message", &r.message)?;
        d.set_item("iterations", r.iterations)?;
        d.set_item("starts", r.starts)?;
        d.set_item("time", r.seconds)?;
        Ok(d)
    }

    /// An IkResult from ``to_dict()``'s dict (every key required).
    #[staticmethod]
    fn from_dict(data: &Bound<'_, PyAny>) -> PyResult<Self> {
        const KEYS: [&str; 15] = [
            "rest_curvature",
            "muscle_lengths",
            "inflation_times",
            "tensions",
            "field",
            "insertion",
            "solution",
            "tip_position",
            "tip_miss",
            "reached",
            "ending",
            "message",
            "iterations",
            "starts",
            "time",
        ];
        let d = Fields::new("ik_result", data, &KEYS)?;
        let inner = IkResult {
            rest_curvature: d.rows::<2>("rest_curvature")?,
            muscle_lengths: d.rows::<3>("muscle_lengths")?,
            inflation_times: d.rows::<3>("inflation_times")?,
            tensions: d.floats("tensions")?,
            field: d.vector("field")?,
            // Absent from earlier versions' dicts: no insertion.
            insertion: d.float_or("insertion", 0.0)?,
            solution: PySolution::from_dict(&d.get("solution")?)?.inner,
            tip_position: d.vector("tip_position")?,
            tip_miss: number_or_infinite("ik_result.tip_miss", &d.get("tip_miss")?)?,
            reached: bool_arg("ik_result.reached", &d.get("reached")?)?,
            ending: str_arg("ik_result.ending", &d.get("ending")?)?.parse()?,
            message: str_arg("ik_result.message", &d.get("message")?)?,
            iterations: int_arg("ik_result.iterations", &d.get("iterations")?)?,
            starts: int_arg("ik_result.starts", &d.get("starts")?)?,
            seconds: float_arg("ik_result.time", &d.get("time")?)?,
        };
        inner.check_stored()?;
        Ok(PyIkResult { inner })
    }

    /// Pickling goes through ``to_dict`` and ``from_dict``.
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyDict>,))> {
        Ok((
            slf.get_type().getattr("from_dict")?,
            (slf.get().to_dict(slf.py())?,),
        ))
    }

    fn __repr__(&self) -> String {
        format!(
            "IkResult(reached={}, tip_miss={:.3e}, iterations={}, time={:.1} us, message={:?})",
            python_bool(self.inner.reached),
            self.inner.tip_miss,
            self.inner.iterations,
            self.inner.seconds * 1e6,
            self.inner.message
        )
    }
}

/// Inverse kinematics of one robot under one load, warm from its last answer.
///
/// Safe to share between threads: one solve runs at a time (the warm start is
/// shared state), and a thread waiting for its turn does not hold the GIL.
#[pyclass(name = "InverseSolver", module = "softspine._core", frozen)]
pub struct PyInverseSolver {
    /// Shared with a worker thread during a long solve (see `detach_solve`).
    pub(super) inner: Arc<Mutex<InverseSolver>>,
    pub(super) long_passes: bool,
}

#[pymethods]
impl PyInverseSolver {
    /// The actuation whose loaded equilibrium reaches ``target`` (see
    /// ``Robot.inverse``); ``settings`` an ``IkSettings`` (its strategy must
    /// be "equilibrium"), the keywords over it. A tendon-driven or magnetic
    /// robot's: its tensions (closest to ``pretension``) or field.
    #[pyo3(signature = (target, reference=None, direction=None, settings=None, *, tol=None, max_iterations=None, pretension=None, orientation=None))]
    #[allow(clippy::too_many_arguments)]
    fn solve(
        &self,
        py: Python<'_>,
        target: &Bound<'_, PyAny>,
        reference: Option<&Bound<'_, PyAny>>,
        direction: Option<&Bound<'_, PyAny>>,
        settings: Option<&Bound<'_, PyAny>>,
        tol: Option<&Bound<'_, PyAny>>,
        max_iterations: Option<&Bound<'_, PyAny>>,
        pretension: Option<&Bound<'_, PyAny>>,
        orientation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyIkResult> {
        let orientation = given(orientation)
            .map(|q| orientation_arg("orientation", &q))
            .transpose()?;
        let pretension = given(pretension)
            .map(|p| floats_arg("pretension", &p))
            .transpose()?;
        let target = vec3_arg("target", target)?;
        let reference = reference
            .map(|r| rows_arg::<2>("reference", r))
            .transpose()?;
        let direction = direction.map(|d| vec3_arg("direction", d)).transpose()?;
        let settings = ik_settings_arg(
            settings,
            &[("tol", tol), ("max_iterations", max_iterations)],
        )?;
        // Locked without the GIL; None if a solve panicked holding the lock.
        let inner = Arc::clone(&self.inner);
        let r = detach_solve(py, self.long_passes, move || match inner.lock() {
            Ok(mut solver) => {
                let options = IkOptions {
                    load: crate::robot::Load::default(),
                    reference,
                    direction,
                    orientation,
                    settings,
                    pretension,
                    initial: None,
                };
                solver.solve_with(target, &options).map(Some)
            }
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
    #[pyo3(signature = (data=None), text_signature = "(data=None)")]
    fn new(py: Python<'_>, data: Option<&Bound<'_, PyAny>>) -> PyResult<Self> {
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
        PyRobot::read(py, inner)
    }

    /// Read a robot from JSON text (the fields of ``Robot().to_dict()``, each optional).
    #[staticmethod]
    fn from_json(py: Python<'_>, #[pyo3(from_py_with = text_arg)] text: String) -> PyResult<Self> {
        PyRobot::read(
            py,
            Robot::from_json_str(&text).map_err(|e| of_argument("text", e))?,
        )
    }

    /// Read a robot from TOML text.
    #[staticmethod]
    fn from_toml(py: Python<'_>, #[pyo3(from_py_with = text_arg)] text: String) -> PyResult<Self> {
        PyRobot::read(
            py,
            Robot::from_toml_str(&text).map_err(|e| of_argument("text", e))?,
        )
    }

    /// Read a robot from a ``.json`` or ``.toml`` file.
    #[staticmethod]
    fn from_file(
        py: Python<'_>,
        #[pyo3(from_py_with = path_arg)] path: std::path::PathBuf,
    ) -> PyResult<Self> {
        PyRobot::read(
            py,
            Robot::from_file(&path).map_err(|e| of_argument("path", e))?,
        )
    }

    /// The robot as JSON text (``Robot.from_json`` reads it back).
    fn to_json(&self) -> PyResult<String> {
        Ok(self.inner.to_text(Format::Json)?)
    }

    /// The robot as TOML text (``Robot.from_toml`` reads it back).
    fn to_toml(&self) -> PyResult<String> {
        Ok(self.inner.to_text(Format::Toml)?)
    }

    /// Write the robot to a ``.json`` or ``.toml`` file (by its suffix),
    /// which ``Robot.from_file`` reads back to the same robot.
    fn save(&self, #[pyo3(from_py_with = path_arg)] path: std::path::PathBuf) -> PyResult<()> {
        self.inner
            .write_file(&path)
            .map_err(|e| of_argument("path", e))
    }

    /// Number of sections.
    #[getter]
    fn sections(&self) -> usize {
        self.inner.body.sections
    }
    /// Length of the backbone, m.
    #[getter]
    fn length(&self) -> f64 {
        self.inner.body.length
    }
    /// Elements of its forward solves (a multiple of the sections).
    #[getter]
    fn n_elements(&self) -> usize {
        self.inner.n_elements
    }
    /// What the inverse kinematics searches: ``"tensions"`` if the robot has
    /// tendons, else ``"field"`` if it is magnetic, else ``"curvature"``.
    #[getter]
    fn actuation_space(&self) -> &'static str {
        self.inner.actuation_space().name()
    }
    /// ``[min, max]`` muscle length, m (``None``: the robot has no
    /// muscles, tendons or a field drive it).
    #[getter]
    fn muscle_length_range(&self) -> Option<(f64, f64)> {
        let m = self.inner.drive.muscles()?;
        Some((m.length_range[0], m.length_range[1]))
    }

    /// Pickling goes through ``to_dict``.
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyAny>,))> {
        Ok((slf.get_type().into_any(), (slf.get().to_dict(slf.py())?,)))
    }

    /// Every field as a dict (``Robot(robot.to_dict())`` is the same robot).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let d = from_value(py, &self.inner.to_value())?;
        // Counts as Python ints (a value tree holds numbers as floats).
        d.set_item("sections", self.inner.body.sections)?;
        d.set_item("n_elements", self.inner.n_elements)?;
        Ok(d)
    }

    /// The Scene of this robot with an actuation and a load (a payload mass
    /// in kg, or a dict of mass, tip_force, tip_moment, point_loads):
    /// rest curvature (m, 2) 1/m (default straight), tendon ``tensions`` (N),
    /// an external ``field`` (T, world frame) and the ``insertion`` (m, the
    /// base moved along its tangent).
    #[pyo3(signature = (rest_curvature=None, load=None, *, tensions=None, field=None, insertion=None))]
    fn scene(
        &self,
        py: Python<'_>,
        rest_curvature: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = load_arg)] load: Option<crate::robot::Load>,
        tensions: Option<&Bound<'_, PyAny>>,
        field: Option<&Bound<'_, PyAny>>,
        insertion: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyScene> {
        let load = load.unwrap_or_default();
        warn_user(py, &self.inner.load_warnings(&load))?;
        let a = actuation_arg(rest_curvature, tensions, field, insertion)?;
        Ok(PyScene {
            inner: self.inner.scene(&a, &load)?,
        })
    }

    /// Joint space from rest curvature: muscle lengths (m, 3).
    fn muscle_lengths<'py>(
        &self,
        py: Python<'py>,
        rest_curvature: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let k = rows_arg::<2>("rest_curvature", rest_curvature)?;
        self.inner.check_rows("rest_curvature", k.len())?;
        Ok(rows_n(py, &self.inner.muscle_lengths(&k)?))
    }

    /// Rest curvature (m, 2) from muscle lengths (m, 3).
    fn rest_curvature<'py>(
        &self,
        py: Python<'py>,
        muscle_lengths: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let l = rows_arg::<3>("muscle_lengths", muscle_lengths)?;
        self.inner.check_rows("muscle_lengths", l.len())?;
        Ok(rows_n(py, &self.inner.rest_curvature(&l)?))
    }

    /// Actuator space: inflation times (m, 3) from muscle lengths.
    fn inflation_times<'py>(
        &self,
        py: Python<'py>,
        muscle_lengths: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let l = rows_arg::<3>("muscle_lengths", muscle_lengths)?;
        self.inner.check_rows("muscle_lengths", l.len())?;
        Ok(rows_n(py, &self.inner.inflation_times(&l)?))
    }

    /// Joint space from actuator space: muscle lengths from inflation times.
    fn muscle_lengths_from_times<'py>(
        &self,
        py: Python<'py>,
        times: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let t = rows_arg::<3>("times", times)?;
        self.inner.check_rows("times", t.len())?;
        Ok(rows_n(py, &self.inner.muscle_lengths_from_times(&t)?))
    }

    /// Whether every muscle length lies in the range for this actuation.
    fn within_bounds(&self, rest_curvature: &Bound<'_, PyAny>) -> PyResult<bool> {
        let k = rows_arg::<2>("rest_curvature", rest_curvature)?;
        self.inner.check_rows("rest_curvature", k.len())?;
        Ok(self.inner.within_bounds(&k)?)
    }

    /// Forward statics: the loaded equilibrium of an actuation.
    ///
    /// Parameters
    /// ----------
    /// rest_curvature
    ///     The muscles' rest curvature, (m, 2), 1/m (default straight).
    /// load
    ///     A payload mass [kg], or a dict of ``mass``, ``tip_force`` [N],
    ///     ``tip_moment`` [N m] (world frame) and ``point_loads``
    ///     (``[{s, force, moment}]``).
    /// initial
    ///     A warm start: a Solution of this robot or its quaternions
    ///     (n + 1, 4) (default: from the straight rod). With friction a
    ///     Solution is the last step of the history: the robot starts where
    ///     it stood, at its insertion then.
    /// tensions
    ///     A tendon-driven robot's tensions, N, one a tendon, each within
    ///     ``[0, max_tension]``.
    /// field
    ///     A magnetic robot's uniform field, T, world frame, within
    ///     ``max_field``.
    /// insertion
    ///     How far the base moves along its tangent, m (default 0; within
    ///     ``insertion_range`` where the robot has one): the robot fed
    ///     through its ``ports``.
    ///
    /// Returns
    /// -------
    /// Solution
    ///     At the robot's ``n_elements``; ``status`` says how the solve ended.
    #[pyo3(signature = (rest_curvature=None, load=None, initial=None, *, tensions=None, field=None, insertion=None))]
    #[allow(clippy::too_many_arguments)]
    fn forward(
        &self,
        py: Python<'_>,
        rest_curvature: Option<&Bound<'_, PyAny>>,
        #[pyo3(from_py_with = load_arg)] load: Option<crate::robot::Load>,
        initial: Option<&Bound<'_, PyAny>>,
        tensions: Option<&Bound<'_, PyAny>>,
        field: Option<&Bound<'_, PyAny>>,
        insertion: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PySolution> {
        let load = load.unwrap_or_default();
        warn_user(py, &self.inner.load_warnings(&load))?;
        let a = actuation_arg(rest_curvature, tensions, field, insertion)?;
        let previous = given(initial).and_then(|q| previous_solution(&q));
        let initial = given(initial)
            .map(|q| quaternions_arg("initial", &q))
            .transpose()?;
        let robot = self.inner.clone();
        let long = robot.has_long_passes();
        let sol = detach_solve(py, long, move || match &previous {
            Some(previous) => robot.forward_after(&a, &load, previous),
            None => robot.forward(&a, &load, initial.as_deref()),
        })?;
        Ok(PySolution { inner: sol })
    }

    /// The loaded equilibrium of an actuation and its tip's sensitivity to
    /// the named parameters: the fields of a ``Sensitivity``.
    /// ``Robot.sensitivity`` (``softspine.sensitivity``) calls it.
    #[pyo3(name = "_sensitivity", signature = (rest_curvature=None, load=None, parameters=None, initial=None, *, tensions=None, field=None, insertion=None))]
    #[allow(clippy::too_many_arguments)]
    fn sensitivity<'py>(
        &self,
        py: Python<'py>,
        rest_curvature: Option<&Bound<'py, PyAny>>,
        #[pyo3(from_py_with = load_arg)] load: Option<crate::robot::Load>,
        parameters: Option<&Bound<'py, PyAny>>,
        initial: Option<&Bound<'py, PyAny>>,
        tensions: Option<&Bound<'py, PyAny>>,
        field: Option<&Bound<'py, PyAny>>,
        insertion: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let load = load.unwrap_or_default();
        warn_user(py, &self.inner.load_warnings(&load))?;
        let k = actuation_arg(rest_curvature, tensions, field, insertion)?;
        let names = match given(parameters) {
            Some(p) => super::fitting::parameter_names(&p)?,
            None => vec![self.inner.drive_parameter().to_owned()],
        };
        let initial = given(initial)
            .map(|q| quaternions_arg("initial", &q))
            .transpose()?;
        let robot = self.inner.clone();
        let (sol, sens) = detach_solve(py, self.inner.has_long_passes(), move || {
            let names: Vec<&str> = names.iter().map(|s| s.as_str()).collect();
            robot.sensitivity(&k, &load, &names, initial.as_deref())
        })?;
        super::fitting::sensitivity_result(py, &sens, Some(sol))
    }

    /// Forward statics of many actuations (samples, m, 2), tendon tensions
    /// (samples, tendons) or fields (samples, 3) under one load, on every
    /// core: the fields of a ``BatchResult``. ``Robot.forward_batch``
    /// (``softspine.batch``) calls it.
    #[pyo3(name = "_forward_batch", signature = (actuations=None, load=None, *, tensions=None, field=None, insertion=None, shapes=None, warm_start=None, threads=None, chunk=None, progress=None, part=None, plan=None))]
    #[allow(clippy::too_many_arguments)]
    fn forward_batch<'py>(
        slf: &Bound<'py, Self>,
        py: Python<'py>,
        actuations: Option<&Bound<'py, PyAny>>,
        #[pyo3(from_py_with = load_arg)] load: Option<crate::robot::Load>,
        tensions: Option<&Bound<'py, PyAny>>,
        field: Option<&Bound<'py, PyAny>>,
        insertion: Option<&Bound<'py, PyAny>>,
        shapes: Option<&Bound<'py, PyAny>>,
        warm_start: Option<&Bound<'py, PyAny>>,
        threads: Option<&Bound<'py, PyAny>>,
        chunk: Option<&Bound<'py, PyAny>>,
        progress: Option<&Bound<'py, PyAny>>,
        part: Option<&Bound<'py, PyAny>>,
        plan: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let load = load.unwrap_or_default();
        let robot = &slf.get().inner;
        warn_user(py, &robot.load_warnings(&load))?;
        let settings = batch_settings(threads, chunk, warm_start, shapes)?;
        let k = given(actuations)
            .map(|a| samples_arg::<2>("actuations", &a, robot.body.sections))
            .transpose()?;
        let t = given(tensions)
            .map(|t| {
                robot.check_drive_given("tensions")?;
                sample_rows("tensions", &t, robot.drive.tendon_routes().len())
            })
            .transpose()?;
        let b = given(field)
            .map(|b| {
                robot.check_drive_given("field")?;
                sample_rows("field", &b, 3)
            })
            .transpose()?
            .map(|rows| rows.iter().map(|r| [r[0], r[1], r[2]]).collect::<Vec<_>>());
        let d = given(insertion)
            .map(|d| floats_arg("insertion", &d))
            .transpose()?;
        let drives =
            robot.batch_actuations(k.as_deref(), t.as_deref(), b.as_deref(), d.as_deref())?;
        if let Some(cut) = cluster_plan(py, plan, part, &settings)? {
            return Ok(cut);
        }
        let samples = run_batch(py, drives.len(), progress, |control| {
            robot.forward_batch(&drives, &load, &settings, control)
        })?;
        let drives = Drives {
            actuations: drives.iter().collect(),
            columns: robot.drive_columns(k.is_some()),
            sections: robot.body.sections,
            tendons: robot.drive.tendon_routes().len(),
        };
        Ok(batch_result(py, &samples, Some(&drives))?.into_any())
    }

    /// The equilibria of ``samples`` random drives (seeded) under one load,
    /// on every core: the fields of a ``BatchResult``. ``Robot.workspace``
    /// (``softspine.batch``) calls it.
    #[pyo3(name = "_workspace", signature = (samples, load=None, *, seed=0, first=0, shapes=None, threads=None, chunk=None, progress=None, part=None, plan=None))]
    #[allow(clippy::too_many_arguments)]
    fn workspace<'py>(
        slf: &Bound<'py, Self>,
        py: Python<'py>,
        #[pyo3(from_py_with = samples_count)] samples: usize,
        #[pyo3(from_py_with = load_arg)] load: Option<crate::robot::Load>,
        #[pyo3(from_py_with = seed_arg)] seed: u64,
        #[pyo3(from_py_with = first_arg)] first: u64,
        shapes: Option<&Bound<'py, PyAny>>,
        threads: Option<&Bound<'py, PyAny>>,
        chunk: Option<&Bound<'py, PyAny>>,
        progress: Option<&Bound<'py, PyAny>>,
        part: Option<&Bound<'py, PyAny>>,
        plan: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let load = load.unwrap_or_default();
        warn_user(py, &slf.get().inner.load_warnings(&load))?;
        let settings = batch_settings(threads, chunk, None, shapes)?;
        let robot = &slf.get().inner;
        robot.check_workspace(samples, first, &settings)?;
        if let Some(cut) = cluster_plan(py, plan, part, &settings)? {
            return Ok(cut);
        }
        let (drawn, out) = run_batch(py, samples, progress, |control| {
            robot.workspace(samples, first, &load, seed, &settings, control)
        })?;
        let drives = Drives {
            actuations: drawn.iter().collect(),
            columns: robot.drive_columns(false),
            sections: robot.body.sections,
            tendons: robot.drive.tendon_routes().len(),
        };
        Ok(batch_result(py, &out, Some(&drives))?.into_any())
    }

    /// Load-aware inverse kinematics of many targets (samples, 3), each on
    /// its own, on every core: the fields of an ``IkBatchResult``.
    /// ``Robot.inverse_batch`` (``softspine.batch``) calls it.
    #[pyo3(name = "_inverse_batch", signature = (targets, load=None, reference=None, direction=None, settings=None, *, pretension=None, orientation=None, threads=None, chunk=None, progress=None, part=None, plan=None))]
    #[allow(clippy::too_many_arguments)]
    fn inverse_batch<'py>(
        slf: &Bound<'py, Self>,
        py: Python<'py>,
        targets: &Bound<'py, PyAny>,
        #[pyo3(from_py_with = load_arg)] load: Option<crate::robot::Load>,
        reference: Option<&Bound<'py, PyAny>>,
        direction: Option<&Bound<'py, PyAny>>,
        settings: Option<&Bound<'py, PyAny>>,
        pretension: Option<&Bound<'py, PyAny>>,
        orientation: Option<&Bound<'py, PyAny>>,
        threads: Option<&Bound<'py, PyAny>>,
        chunk: Option<&Bound<'py, PyAny>>,
        progress: Option<&Bound<'py, PyAny>>,
        part: Option<&Bound<'py, PyAny>>,
        plan: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let load = load.unwrap_or_default();
        warn_user(py, &slf.get().inner.load_warnings(&load))?;
        let this = slf.get();
        let targets: Vec<Vector3<f64>> = rows_of::<3>("targets", targets)?
            .into_iter()
            .map(Vector3::from)
            .collect();
        let options = ik_options_arg(
            &load,
            reference,
            direction,
            orientation,
            pretension,
            settings,
            &[],
        )?;
        let batch = batch_settings(threads, chunk, None, None)?;
        if let Some(cut) = cluster_plan(py, plan, part, &batch)? {
            return Ok(cut);
        }
        let robot = &this.inner;
        let samples = run_batch(py, targets.len(), progress, |control| {
            robot.inverse_batch(&targets, &options, &batch, control)
        })?;
        Ok(ik_batch_result(py, &samples, robot)?.into_any())
    }

    /// A reusable inverse solver for one ``load`` (as ``forward``'s): each
    /// ``solve`` starts warm from the last answer, and along evenly spaced
    /// targets from the extrapolation of the last two (a control loop).
    /// With friction each answer is the next step of the robot's history,
    /// from the last answer (the first from rest).
    #[pyo3(signature = (load=None))]
    fn inverse_solver(
        &self,
        py: Python<'_>,
        #[pyo3(from_py_with = load_arg)] load: Option<crate::robot::Load>,
    ) -> PyResult<PyInverseSolver> {
        let load = load.unwrap_or_default();
        warn_user(py, &self.inner.load_warnings(&load))?;
        let solver = InverseSolver::new(&self.inner, &load)?;
        Ok(PyInverseSolver {
            inner: Arc::new(Mutex::new(solver)),
            long_passes: self.inner.has_long_passes(),
        })
    }

    /// Load-aware inverse kinematics of one target: the drive whose
    /// equilibrium under ``load`` puts the tip (the tool's point) on
    /// ``target``, the one closest to a reference.
    ///
    /// Parameters
    /// ----------
    /// target
    ///     The tip's target, (3,), m, world frame.
    /// load
    ///     What the robot carries, as ``forward``'s.
    /// reference
    ///     The muscles' rest curvature (m, 2) the answer is closest to
    ///     (default zero: the least curvature).
    /// direction
    ///     The tip's tangent, (3,), world frame: met within ``tol / L`` rad,
    ///     whatever drives the robot (default: free).
    /// settings
    ///     An ``IkSettings`` or a dict of its fields; ``strategy``, ``tol``
    ///     (m) and ``max_iterations`` override them.
    /// initial
    ///     A warm start: an earlier ``IkResult`` or a Solution's quaternions.
    ///     With friction, where the robot stands: the answer is where it
    ///     settles when its drive moves from there (default: from rest).
    /// pretension
    ///     A tendon-driven robot's tensions (N, one a tendon) the answer is
    ///     closest to (default zero: the least tension).
    /// orientation
    ///     A full pose: the tip frame's orientation, world frame, a
    ///     quaternion ``[w, x, y, z]`` or a ``scipy.spatial.transform.Rotation``,
    ///     met within ``tol / L`` rad (not with ``direction``).
    ///
    /// Returns
    /// -------
    /// IkResult
    ///     The drive found in every space (``rest_curvature``,
    ///     ``muscle_lengths``, ``tensions``, ``field``), its equilibrium, and
    ///     ``ending``: why it ended (``reached``, or the true reason it could
    ///     not be, with ``message``).
    #[pyo3(signature = (target, load=None, reference=None, direction=None, settings=None, *, strategy=None, tol=None, max_iterations=None, initial=None, pretension=None, orientation=None))]
    #[allow(clippy::too_many_arguments)]
    fn inverse(
        &self,
        py: Python<'_>,
        target: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = load_arg)] load: Option<crate::robot::Load>,
        reference: Option<&Bound<'_, PyAny>>,
        direction: Option<&Bound<'_, PyAny>>,
        settings: Option<&Bound<'_, PyAny>>,
        strategy: Option<&Bound<'_, PyAny>>,
        tol: Option<&Bound<'_, PyAny>>,
        max_iterations: Option<&Bound<'_, PyAny>>,
        initial: Option<&Bound<'_, PyAny>>,
        pretension: Option<&Bound<'_, PyAny>>,
        orientation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyIkResult> {
        let load = load.unwrap_or_default();
        warn_user(py, &self.inner.load_warnings(&load))?;
        let target = vec3_arg("target", target)?;
        let keywords = [
            ("strategy", strategy),
            ("tol", tol),
            ("max_iterations", max_iterations),
        ];
        let mut options = ik_options_arg(
            &load,
            reference,
            direction,
            orientation,
            pretension,
            settings,
            &keywords,
        )?;
        options.initial = given(initial).map(|x| ik_start(&x)).transpose()?;
        let robot = self.inner.clone();
        let long = robot.has_long_passes();
        let r = detach_solve(py, long, move || robot.inverse(target, &options))?;
        Ok(PyIkResult { inner: r })
    }

    /// Inverse kinematics of a sequence of targets (N, 3), m, in order: each
    /// solve starts warm from the previous answer (along evenly spaced
    /// targets, from the extrapolation of the last two). A muscle-driven
    /// robot's answer is the one closest to the previous answer (a smooth
    /// motion); a tendon-driven or magnetic robot's keeps the least tension
    /// (or ``pretension``) or field. The other arguments are ``inverse``'s.
    /// A list of ``IkResult``, one a target.
    #[pyo3(signature = (points, load=None, reference=None, direction=None, settings=None, *, strategy=None, tol=None, max_iterations=None, pretension=None, orientation=None))]
    #[allow(clippy::too_many_arguments)]
    fn track(
        &self,
        py: Python<'_>,
        points: &Bound<'_, PyAny>,
        #[pyo3(from_py_with = load_arg)] load: Option<crate::robot::Load>,
        reference: Option<&Bound<'_, PyAny>>,
        direction: Option<&Bound<'_, PyAny>>,
        settings: Option<&Bound<'_, PyAny>>,
        strategy: Option<&Bound<'_, PyAny>>,
        tol: Option<&Bound<'_, PyAny>>,
        max_iterations: Option<&Bound<'_, PyAny>>,
        pretension: Option<&Bound<'_, PyAny>>,
        orientation: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Vec<PyIkResult>> {
        let load = load.unwrap_or_default();
        warn_user(py, &self.inner.load_warnings(&load))?;
        let pts: Vec<Vector3<f64>> = rows_arg::<3>("points", points)?
            .into_iter()
            .map(Vector3::from)
            .collect();
        let keywords = [
            ("strategy", strategy),
            ("tol", tol),
            ("max_iterations", max_iterations),
        ];
        let options = ik_options_arg(
            &load,
            reference,
            direction,
            orientation,
            pretension,
            settings,
            &keywords,
        )?;
        let robot = self.inner.clone();
        let long = robot.has_long_passes();
        let rs = detach_solve(py, long, move || robot.track(&pts, &options))?;
        Ok(rs.into_iter().map(|inner| PyIkResult { inner }).collect())
    }

    fn __repr__(&self) -> String {
        format!(
            "Robot(length={}, sections={}, n_elements={})",
            self.inner.body.length, self.inner.body.sections, self.inner.n_elements
        )
    }
}

/// An actuation from the keyword arguments of `forward`, `scene` and
/// `sensitivity` (each optional).
fn actuation_arg(
    rest_curvature: Option<&Bound<'_, PyAny>>,
    tensions: Option<&Bound<'_, PyAny>>,
    field: Option<&Bound<'_, PyAny>>,
    insertion: Option<&Bound<'_, PyAny>>,
) -> PyResult<Actuation> {
    Ok(Actuation {
        rest_curvature: given(rest_curvature)
            .map(|k| rows_arg::<2>("rest_curvature", &k))
            .transpose()?
            .unwrap_or_default(),
        tensions: given(tensions)
            .map(|t| floats_arg("tensions", &t))
            .transpose()?
            .unwrap_or_default(),
        field: given(field)
            .map(|b| vec3_arg("field", &b))
            .transpose()?
            .unwrap_or_else(Vector3::zeros),
        insertion: given(insertion)
            .map(|d| float_arg("insertion", &d))
            .transpose()?
            .unwrap_or(0.0),
    })
}

/// A warm start of an inverse solve: an IkResult (its equilibrium and
/// actuation), a Solution (its quaternions and rest curvature) or quaternions.
fn ik_start(x: &Bound<'_, PyAny>) -> PyResult<IkStart> {
    if let Ok(r) = x.cast::<PyIkResult>() {
        let r = &r.get().inner;
        let actuation = if !r.tensions.is_empty() {
            Some(r.tensions.clone())
        } else if r.field != Vector3::zeros() {
            Some(r.field.iter().copied().collect())
        } else {
            None
        };
        return Ok(IkStart {
            quaternions: r.solution.quaternions.clone(),
            rest_curvature: Some(r.rest_curvature.clone()),
            actuation,
            insertion: Some(r.insertion),
        });
    }
    if let Ok(s) = x.cast::<PySolution>() {
        let s = &s.get().inner;
        return Ok(IkStart {
            quaternions: s.quaternions.clone(),
            rest_curvature: Some(s.rest_curvature.clone()),
            actuation: None,
            insertion: None,
        });
    }
    Ok(IkStart {
        quaternions: quaternions_arg("initial", x)?,
        rest_curvature: None,
        actuation: None,
        insertion: None,
    })
}

/// A `Robot` argument, refused by name.
pub(super) fn robot_arg(obj: &Bound<'_, PyAny>) -> PyResult<Robot> {
    obj.cast::<PyRobot>()
        .map(|r| r.get().inner.clone())
        .map_err(|_| {
            Path::argument("robot").error(format!("expected a Robot, got {}", type_name(obj)))
        })
}

impl PyRobot {
    /// A robot read from the caller's input, its warnings shown.
    fn read(py: Python<'_>, inner: Robot) -> PyResult<Self> {
        warn_user(py, &inner.warnings())?;
        Ok(PyRobot { inner })
    }
}

/// One of the seed's trajectories for the default robot: "pentagram", "circle"
/// or "spiral", shape (points, 3), m; with ``robot``, placed at that robot
/// (scaled by its length, carried to its base pose).
#[pyfunction]
#[pyo3(signature = (name, points=60, robot=None))]
pub(super) fn trajectory_points<'py>(
    py: Python<'py>,
    name: &Bound<'py, PyAny>,
    #[pyo3(from_py_with = points_arg)] points: usize,
    robot: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let robot = given(robot).map(|r| robot_arg(&r)).transpose()?;
    let name = str_arg("name", name)?;
    if points == 0 {
        return Err(PyValueError::new_err("points: must be positive"));
    }
    let pts = trajectory::by_name(&name, points).ok_or_else(|| {
        PyValueError::new_err(format!(
            "name: unknown trajectory '{name}' (expected pentagram, circle or spiral)"
        ))
    })?;
    let pts = match robot {
        Some(r) => trajectory::placed(&pts, &r),
        None => pts,
    };
    Ok(rows3(py, &pts))
}

/// The options of an inverse solve from the bindings' arguments (each
/// converted and named; the core checks them).
#[allow(clippy::too_many_arguments)]
fn ik_options_arg(
    load: &crate::robot::Load,
    reference: Option<&Bound<'_, PyAny>>,
    direction: Option<&Bound<'_, PyAny>>,
    orientation: Option<&Bound<'_, PyAny>>,
    pretension: Option<&Bound<'_, PyAny>>,
    settings: Option<&Bound<'_, PyAny>>,
    keywords: &[(&str, Option<&Bound<'_, PyAny>>)],
) -> PyResult<IkOptions> {
    Ok(IkOptions {
        load: load.clone(),
        reference: given(reference)
            .map(|r| rows_arg::<2>("reference", &r))
            .transpose()?,
        direction: given(direction)
            .map(|d| vec3_arg("direction", &d))
            .transpose()?,
        orientation: given(orientation)
            .map(|q| orientation_arg("orientation", &q))
            .transpose()?,
        settings: ik_settings_arg(settings, keywords)?,
        pretension: given(pretension)
            .map(|p| floats_arg("pretension", &p))
            .transpose()?,
        initial: None,
    })
}
