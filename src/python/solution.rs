//! `Solution`: an equilibrium with its status, as NumPy arrays.

use super::convert::*;
use crate::{Quat, Solution};
use nalgebra::Vector3;
use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// An equilibrium (or the best state reached) with its status.
///
/// Arrays are in SI units and the world frame unless a property says
/// otherwise; quaternions are scalar-first ``[w, x, y, z]`` (SciPy's
/// ``Rotation.from_quat`` takes scalar-last: ``q[:, [1, 2, 3, 0]]``).
/// ``to_dict()`` gives every stored field; a Solution pickles.
#[pyclass(name = "Solution", module = "softspine._core", frozen)]
pub struct PySolution {
    pub(super) inner: Solution,
}

#[pymethods]
impl PySolution {
    /// Number of elements ``n``.
    #[getter]
    fn n_elements(&self) -> usize {
        self.inner.n_elements
    }
    /// How the nodes were computed, a ``softspine.Scheme`` (a string enum:
    /// ``"fd2"`` or ``"fe4"``, or ``"rk4"`` for shooting's integrator).
    #[getter]
    fn scheme<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        super::enums::scheme(py, self.inner.scheme)
    }
    /// Length of the rod, m.
    #[getter]
    fn length(&self) -> f64 {
        self.inner.length
    }
    /// Arc length of the nodes, ``s_i = i L / n``, shape (n+1,), m.
    #[getter]
    fn arc_length<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner.arc_length().into_pyarray(py)
    }
    /// Node positions, shape (n+1, 3), m.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows3(py, &self.inner.positions)
    }
    /// Node quaternions ``[w, x, y, z]`` (material frame to world frame), shape (n+1, 4).
    #[getter]
    fn quaternions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows4(py, &self.inner.quaternions)
    }
    /// Positions at the arc lengths ``s`` (any array of them in ``[0, L]``),
    /// shape ``s.shape + (3,)``, m: between the nodes at the scheme's order
    /// (the tangent integrated along each element as the scheme integrates
    /// it to the next node; a node's arc length gives the node).
    fn positions_at<'py>(
        &self,
        py: Python<'py>,
        s: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (stations, shape) = stations_arg(s)?;
        let out = self.inner.positions_at(&stations)?;
        shaped(
            py,
            out.iter().flat_map(|v| v.iter().copied()).collect(),
            shape,
            3,
        )
    }
    /// Rotations at the arc lengths ``s`` as unit quaternions ``[w, x, y,
    /// z]``, shape ``s.shape + (4,)``: between the nodes at the scheme's
    /// order (linear for ``fd2``; for ``fe4`` the polynomial through the
    /// element's nodes, its internal node and its neighbours' where the
    /// shape is smooth across the node between), normalised.
    fn rotations_at<'py>(
        &self,
        py: Python<'py>,
        s: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (stations, shape) = stations_arg(s)?;
        let out = self.inner.rotations_at(&stations)?;
        shaped(
            py,
            out.iter().flat_map(|q| q.to_array()).collect(),
            shape,
            4,
        )
    }
    /// Node rotation matrices (material frame to world frame; column 3 is the
    /// tangent), shape (n+1, 3, 3).
    #[getter]
    fn rotation_matrices<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray3<f64>> {
        let r = self.inner.rotation_matrices();
        Array3::from_shape_fn((r.len(), 3, 3), |(i, a, b)| r[i][(a, b)]).into_pyarray(py)
    }
    /// Internal force at the nodes, world frame, shape (n+1, 3), N: the force
    /// that the rod beyond node j exerts on the rod before it. ``forces[0]`` is
    /// the force of the rod on its base support (the support's reaction on the
    /// rod is minus it).
    #[getter]
    fn forces<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows3(py, &self.inner.forces)
    }
    /// Internal moment at the nodes, world frame, shape (n+1, 3), N m: the
    /// moment that the rod beyond node j exerts on the rod before it.
    /// ``moments[0]`` is the moment of the rod on its base support;
    /// ``moments[-1]`` is the tip's applied moment (plus a clamp's reaction).
    /// Interior nodes: the mean of the two elements' moments (second order,
    /// whatever the ``scheme``: read from the nodes by finite differences).
    #[getter]
    fn moments<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows3(py, &self.inner.moments())
    }
    /// Curvature and twist ``(kappa_x, kappa_y, tau)`` of each element in its
    /// material frame, shape (n, 3), 1/m (the finite-difference curvature of
    /// the nodes, second order whatever the ``scheme``).
    #[getter]
    fn curvatures<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows3(py, &self.inner.curvatures())
    }
    /// The tip position, shape (3,), m: the last node, or the
    /// Richardson-extrapolated tip when ``extrapolated``.
    #[getter]
    fn tip_position<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vec3_array(py, &self.inner.tip_position())
    }
    /// The tip quaternion ``[w, x, y, z]``, shape (4,).
    #[getter]
    fn tip_quaternion<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.inner
            .tip_quaternion()
            .to_array()
            .to_vec()
            .into_pyarray(py)
    }
    /// Force of a pinned or clamped tip's support on the rod, world frame, shape (3,), N;
    /// None if the tip is free.
    #[getter]
    fn tip_reaction_force<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.inner.tip_reaction_force.map(|f| vec3_array(py, &f))
    }
    /// Moment of a clamped tip's support on the rod, world frame, shape (3,), N m;
    /// None otherwise.
    #[getter]
    fn tip_reaction_moment<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.inner.tip_reaction_moment.map(|m| vec3_array(py, &m))
    }
    /// Force of each guide on the rod, world frame, shape (guides, 3), N.
    #[getter]
    fn guide_reactions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        rows3(py, &self.inner.guide_reactions)
    }
    /// Where the rod touches the obstacles, by arc length: a dict of arrays
    /// ``obstacle`` (index in the scene's list, shape (k,)), ``arc_length``
    /// (k,) m, ``point`` (the obstacle's surface point touched, (k, 3) m),
    /// ``normal`` (into free space, the force's direction, (k, 3)) and
    /// ``force`` (its magnitude, (k,) N, >= 0), ``friction`` (the friction
    /// force on the rod, along the surface, (k, 3) N; zero on frictionless
    /// obstacles) and ``sliding`` (whether the contact slides, its friction
    /// at ``mu * force`` against its motion, else it sticks, (k,) bool).
    /// Empty without obstacles.
    #[getter]
    fn contacts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (key, value) in contact_arrays(py, &self.inner.contacts) {
            d.set_item(key, value)?;
        }
        Ok(d)
    }
    /// Where the rod passes each port, in the scene's order: a dict of
    /// arrays ``port`` (index in the scene's list, shape (k,)),
    /// ``arc_length`` (k,) m, ``point`` (the backbone point in the port,
    /// (k, 3) m), ``force`` (the port's force on the rod, (k, 3) N: across
    /// the rod, and along it with friction), ``friction`` (the part of
    /// ``force`` along the rod, (k, 3) N; zero without friction) and
    /// ``sliding`` (whether the rod slides through the port, its friction
    /// at ``mu`` times the rest of its force, (k,) bool). Empty without ports.
    #[getter]
    fn ports<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (key, value) in port_arrays(py, &self.inner.ports) {
            d.set_item(key, value)?;
        }
        Ok(d)
    }
    /// Whether ``status`` is ``Status.CONVERGED``: the only ending that is an answer.
    #[getter]
    fn converged(&self) -> bool {
        self.inner.converged()
    }
    /// How the solve ended, a ``softspine.Status`` (a string enum: it equals
    /// its name, e.g. ``"converged"``); ``message`` says more.
    #[getter]
    fn status<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        super::enums::status(py, self.inner.status)
    }
    /// Newton or LM iterations, every continuation step included.
    #[getter]
    fn iterations(&self) -> usize {
        self.inner.iterations
    }
    /// Load-continuation steps taken (0: solved directly).
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
    /// Whether the equilibrium is stable (positive definite reduced Hessian);
    /// False when not converged.
    #[getter]
    fn stable(&self) -> bool {
        self.inner.stable
    }
    /// A short account of how the solve ended.
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
    /// Wall-clock time of the solve, s (the set-up of the discretisation and
    /// every n of accuracy on demand included).
    #[getter]
    fn solve_time(&self) -> f64 {
        self.inner.solve_time
    }

    /// Every stored field as a dict of NumPy arrays and scalars (``status`` as
    /// its name); ``Solution.from_dict`` rebuilds the Solution. Derived
    /// properties (``arc_length``, ``rotation_matrices``, ``moments``,
    /// ``curvatures``, ``tip_position``, ``tip_quaternion``, ``converged``)
    /// are not in it; ``stiffness``, ``rest_curvature`` and ``tip_moment``
    /// (what the moments are computed from) are.
    pub(super) fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = &self.inner;
        let d = PyDict::new(py);
        d.set_item("n_elements", s.n_elements)?;
        d.set_item("scheme", s.scheme.name())?;
        d.set_item("length", s.length)?;
        d.set_item("section_lengths", s.section_lengths.clone())?;
        d.set_item("positions", rows3(py, &s.positions))?;
        d.set_item("quaternions", rows4(py, &s.quaternions))?;
        d.set_item("internal_quaternions", rows4(py, &s.internal_quaternions))?;
        d.set_item("breaks", s.breaks.clone())?;
        d.set_item("forces", rows3(py, &s.forces))?;
        d.set_item("stiffness", vec3_array(py, &s.stiffness))?;
        d.set_item("section_stiffness", rows3(py, &s.section_stiffness))?;
        d.set_item("rest_curvature", rows_n(py, &s.rest_curvature))?;
        d.set_item("tip_moment", vec3_array(py, &s.tip_moment))?;
        let optional = |v: Option<Vector3<f64>>| v.map(|v| vec3_array(py, &v));
        d.set_item("tip_reaction_force", optional(s.tip_reaction_force))?;
        d.set_item("tip_reaction_moment", optional(s.tip_reaction_moment))?;
        d.set_item("guide_reactions", rows3(py, &s.guide_reactions))?;
        for (key, value) in contact_arrays(py, &s.contacts) {
            d.set_item(format!("contact_{key}"), value)?;
        }
        for (key, value) in port_arrays(py, &s.ports) {
            d.set_item(format!("port_{key}"), value)?;
        }
        d.set_item("status", s.status.name())?;
        d.set_item("iterations", s.iterations)?;
        d.set_item("continuation_steps", s.continuation_steps)?;
        d.set_item("residual_norm", s.residual_norm)?;
        d.set_item("energy", s.energy)?;
        d.set_item("stable", s.stable)?;
        d.set_item("message", &s.message)?;
        d.set_item("error_estimate", s.error_estimate)?;
        d.set_item("extrapolated_tip", optional(s.extrapolated_tip))?;
        d.set_item("solve_time", s.solve_time)?;
        Ok(d)
    }

    /// A Solution from ``to_dict()``'s dict (every key required);
    /// ``ValueError`` names a missing, malformed or inconsistent field.
    #[staticmethod]
    pub(super) fn from_dict(data: &Bound<'_, PyAny>) -> PyResult<Self> {
        let d = Fields::new("solution", data, &SOLUTION_KEYS)?;
        let solution = Solution {
            n_elements: int_arg("solution.n_elements", &d.get("n_elements")?)?,
            scheme: {
                let name = str_arg("solution.scheme", &d.get("scheme")?)?;
                crate::disc::Scheme::ALL
                    .into_iter()
                    .find(|s| s.name() == name)
                    .ok_or_else(|| {
                        crate::error::Error::argument(
                            "solution.scheme",
                            format!(
                                "unknown scheme '{name}' (expected one of {:?})",
                                crate::disc::Scheme::ALL.map(|s| s.name())
                            ),
                        )
                    })?
            },
            length: float_arg("solution.length", &d.get("length")?)?,
            // Absent from the dicts of earlier versions: equal sections.
            section_lengths: d.floats_or_empty("section_lengths")?,
            positions: d.vectors("positions")?,
            quaternions: d
                .rows::<4>("quaternions")?
                .into_iter()
                .map(Quat::from_array)
                .collect(),
            // Absent from the dicts of earlier versions: no shape between
            // the nodes of a fourth-order solution.
            internal_quaternions: d
                .rows_or_empty::<4>("internal_quaternions")?
                .into_iter()
                .map(Quat::from_array)
                .collect(),
            // Absent from the dicts of earlier versions: unknown (the shape
            // between the nodes is then each element's own).
            breaks: match d.floats_if_given("breaks")? {
                None => None,
                Some(b) => Some(
                    b.into_iter()
                        .map(|j| match j.fract() == 0.0 && (0.0..1e15).contains(&j) {
                            true => Ok(j as usize),
                            false => Err(crate::error::Error::argument(
                                "solution.breaks",
                                format!("expected node indices, got {j}"),
                            )),
                        })
                        .collect::<crate::error::Result<Vec<usize>>>()?,
                ),
            },
            forces: d.vectors("forces")?,
            stiffness: d.vector("stiffness")?,
            section_stiffness: d.vectors("section_stiffness")?,
            rest_curvature: d.rows::<2>("rest_curvature")?,
            tip_moment: d.vector("tip_moment")?,
            tip_reaction_force: d.optional_vector("tip_reaction_force")?,
            tip_reaction_moment: d.optional_vector("tip_reaction_moment")?,
            guide_reactions: d.vectors("guide_reactions")?,
            contacts: contacts_of(&d)?,
            ports: ports_of(&d)?,
            status: str_arg("solution.status", &d.get("status")?)?.parse()?,
            iterations: int_arg("solution.iterations", &d.get("iterations")?)?,
            continuation_steps: int_arg(
                "solution.continuation_steps",
                &d.get("continuation_steps")?,
            )?,
            residual_norm: number_or_infinite("solution.residual_norm", &d.get("residual_norm")?)?,
            energy: number_or_infinite("solution.energy", &d.get("energy")?)?,
            stable: bool_arg("solution.stable", &d.get("stable")?)?,
            message: str_arg("solution.message", &d.get("message")?)?,
            error_estimate: d
                .optional("error_estimate")?
                .map(|e| float_arg("solution.error_estimate", &e))
                .transpose()?,
            extrapolated_tip: d.optional_vector("extrapolated_tip")?,
            solve_time: float_arg("solution.solve_time", &d.get("solve_time")?)?,
        };
        solution.check_layout()?;
        Ok(PySolution { inner: solution })
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
        let t = self.inner.tip_position();
        format!(
            "Solution(status={}, n_elements={}, iterations={}, residual_norm={:.2e}, stable={}, tip_position=[{:.6}, {:.6}, {:.6}])",
            self.inner.status.name(),
            self.inner.n_elements,
            self.inner.iterations,
            self.inner.residual_norm,
            python_bool(self.inner.stable),
            t.x,
            t.y,
            t.z
        )
    }
}

/// The keys of `Solution.to_dict()`.
const SOLUTION_KEYS: [&str; 39] = [
    "n_elements",
    "scheme",
    "length",
    "section_lengths",
    "positions",
    "quaternions",
    "internal_quaternions",
    "breaks",
    "forces",
    "stiffness",
    "section_stiffness",
    "rest_curvature",
    "tip_moment",
    "tip_reaction_force",
    "tip_reaction_moment",
    "guide_reactions",
    "contact_obstacle",
    "contact_arc_length",
    "contact_point",
    "contact_normal",
    "contact_force",
    "contact_friction",
    "contact_sliding",
    "port_port",
    "port_arc_length",
    "port_point",
    "port_force",
    "port_friction",
    "port_sliding",
    "status",
    "iterations",
    "continuation_steps",
    "residual_norm",
    "energy",
    "stable",
    "message",
    "error_estimate",
    "extrapolated_tip",
    "solve_time",
];

/// A solution's contacts as arrays, by field (see `PySolution::contacts`).
fn contact_arrays<'py>(
    py: Python<'py>,
    contacts: &[crate::solver::Contact],
) -> [(&'static str, Bound<'py, PyAny>); 7] {
    let column = |f: fn(&crate::solver::Contact) -> f64| {
        contacts
            .iter()
            .map(f)
            .collect::<Vec<f64>>()
            .into_pyarray(py)
            .into_any()
    };
    let rows = |f: fn(&crate::solver::Contact) -> Vector3<f64>| {
        rows3(py, &contacts.iter().map(f).collect::<Vec<_>>()).into_any()
    };
    let obstacles: Vec<usize> = contacts.iter().map(|c| c.obstacle).collect();
    [
        ("obstacle", obstacles.into_pyarray(py).into_any()),
        ("arc_length", column(|c| c.arc_length)),
        ("point", rows(|c| c.point)),
        ("normal", rows(|c| c.normal)),
        ("force", column(|c| c.force)),
        ("friction", rows(|c| c.friction)),
        (
            "sliding",
            contacts
                .iter()
                .map(|c| c.sliding)
                .collect::<Vec<bool>>()
                .into_pyarray(py)
                .into_any(),
        ),
    ]
}

/// A solution's ports as arrays, by field (see `PySolution::ports`).
fn port_arrays<'py>(
    py: Python<'py>,
    ports: &[crate::solver::PortReaction],
) -> [(&'static str, Bound<'py, PyAny>); 6] {
    let index: Vec<usize> = ports.iter().map(|p| p.port).collect();
    let arc_length: Vec<f64> = ports.iter().map(|p| p.arc_length).collect();
    let points: Vec<Vector3<f64>> = ports.iter().map(|p| p.point).collect();
    let forces: Vec<Vector3<f64>> = ports.iter().map(|p| p.force).collect();
    let friction: Vec<Vector3<f64>> = ports.iter().map(|p| p.friction).collect();
    let sliding: Vec<bool> = ports.iter().map(|p| p.sliding).collect();
    [
        ("port", index.into_pyarray(py).into_any()),
        ("arc_length", arc_length.into_pyarray(py).into_any()),
        ("point", rows3(py, &points).into_any()),
        ("force", rows3(py, &forces).into_any()),
        ("friction", rows3(py, &friction).into_any()),
        ("sliding", sliding.into_pyarray(py).into_any()),
    ]
}

/// A column absent from an earlier version's dict (empty): `k` of `value`.
fn or_filled<T: Clone>(column: Vec<T>, k: usize, value: T) -> Vec<T> {
    if column.is_empty() {
        vec![value; k]
    } else {
        column
    }
}

/// The ports of a solution's dict (absent from earlier versions': none).
fn ports_of(d: &Fields) -> PyResult<Vec<crate::solver::PortReaction>> {
    let index = d.floats_or_empty("port_port")?;
    let arc_length = d.floats_or_empty("port_arc_length")?;
    let point = d.rows_or_empty::<3>("port_point")?;
    let force = d.rows_or_empty::<3>("port_force")?;
    let k = index.len();
    // Frictionless where absent (earlier versions').
    let friction = or_filled(d.rows_or_empty::<3>("port_friction")?, k, [0.0; 3]);
    let sliding = or_filled(d.bools_or_empty("port_sliding")?, k, false);
    if [
        arc_length.len(),
        point.len(),
        force.len(),
        friction.len(),
        sliding.len(),
    ] != [k; 5]
    {
        return Err(crate::error::Error::argument(
            "solution.port_port",
            "the port_* fields must have one row a port each",
        )
        .into());
    }
    (0..k)
        .map(|i| {
            let j = index[i];
            if j.fract() != 0.0 || !(0.0..1e15).contains(&j) {
                return Err(crate::error::Error::argument(
                    "solution.port_port",
                    format!("expected port indices, got {j}"),
                )
                .into());
            }
            Ok(crate::solver::PortReaction {
                port: j as usize,
                arc_length: arc_length[i],
                point: Vector3::from(point[i]),
                force: Vector3::from(force[i]),
                friction: Vector3::from(friction[i]),
                sliding: sliding[i],
            })
        })
        .collect()
}

/// The contacts of a solution's dict (absent from earlier versions': none).
fn contacts_of(d: &Fields) -> PyResult<Vec<crate::solver::Contact>> {
    let obstacle = d.floats_or_empty("contact_obstacle")?;
    let arc_length = d.floats_or_empty("contact_arc_length")?;
    let point = d.rows_or_empty::<3>("contact_point")?;
    let normal = d.rows_or_empty::<3>("contact_normal")?;
    let force = d.floats_or_empty("contact_force")?;
    let k = obstacle.len();
    // Frictionless and sticking where absent (earlier versions').
    let friction = or_filled(d.rows_or_empty::<3>("contact_friction")?, k, [0.0; 3]);
    let sliding = or_filled(d.bools_or_empty("contact_sliding")?, k, false);
    if [
        arc_length.len(),
        point.len(),
        normal.len(),
        force.len(),
        friction.len(),
        sliding.len(),
    ] != [k; 6]
    {
        return Err(crate::error::Error::argument(
            "solution.contact_obstacle",
            "the contact_* fields must have one row a contact each",
        )
        .into());
    }
    (0..k)
        .map(|i| {
            let o = obstacle[i];
            if o.fract() != 0.0 || !(0.0..1e15).contains(&o) {
                return Err(crate::error::Error::argument(
                    "solution.contact_obstacle",
                    format!("expected obstacle indices, got {o}"),
                )
                .into());
            }
            Ok(crate::solver::Contact {
                obstacle: o as usize,
                arc_length: arc_length[i],
                point: Vector3::from(point[i]),
                normal: Vector3::from(normal[i]),
                force: force[i],
                friction: Vector3::from(friction[i]),
                sliding: sliding[i],
            })
        })
        .collect()
}

/// Node quaternions: a Solution's, or an array of shape (n+1, 4).
/// The Solution an `initial` argument is, if it is one (a history's last
/// step, `crate::Solver::solve_after`).
pub(super) fn previous_solution(q: &Bound<'_, PyAny>) -> Option<crate::Solution> {
    q.cast::<PySolution>().ok().map(|s| s.get().inner.clone())
}

pub(super) fn quaternions_arg(name: &str, q: &Bound<'_, PyAny>) -> PyResult<Vec<Quat>> {
    if let Ok(s) = q.cast::<PySolution>() {
        return Ok(s.get().inner.quaternions.clone());
    }
    Ok(rows_arg::<4>(name, q)?
        .into_iter()
        .map(Quat::from_array)
        .collect())
}
