//! `Solution`: an equilibrium with its status, as NumPy arrays.

use super::convert::*;
use crate::{Quat, Solution};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;

/// An equilibrium (or the best state reached) with its status.
#[pyclass(name = "Solution", module = "softspine._core", frozen)]
pub struct PySolution {
    pub(super) inner: Solution,
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

/// Node quaternions: a Solution's, or an array of shape (n+1, 4).
pub(super) fn quaternions_arg(name: &str, q: &Bound<'_, PyAny>) -> PyResult<Vec<Quat>> {
    if let Ok(s) = q.cast::<PySolution>() {
        return Ok(s.get().inner.quaternions.clone());
    }
    Ok(rows_arg::<4>(name, q)?
        .into_iter()
        .map(Quat::from_array)
        .collect())
}
