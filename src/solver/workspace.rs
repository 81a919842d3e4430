//! The buffers of a solve and the interface of the local methods (Newton,
//! Levenberg-Marquardt) that the driver runs on them.

use super::constrained;
use crate::blocktri::{symmetric_part_is_positive_definite, BlockLu, BlockTridiagonal};
use crate::disc::Interior;
use crate::error::Result;
use crate::interrupt;
use crate::model::RodModel;
use crate::quat::Quat;
use nalgebra::Vector3;

/// Buffers of one solve, allocated once and reused by warm-started solves.
#[derive(Debug, Clone)]
pub(crate) struct Workspace {
    pub q: Vec<Quat>,
    pub trial: Vec<Quat>,
    pub saved: Vec<Quat>,
    pub g: Vec<Vector3<f64>>,
    pub g_trial: Vec<Vector3<f64>>,
    pub step: Vec<Vector3<f64>>,
    pub scratch: Vec<Vector3<f64>>,
    pub jac: BlockTridiagonal,
    pub lu: BlockLu,
    /// The scheme's interior unknowns of the last evaluation (fe4's
    /// internal nodes; empty for fd2): a cache of this solve.
    pub interior: Interior,
    /// Constrained scenes only (empty otherwise): see `constrained.rs`.
    pub kkt: constrained::KktWorkspace,
    /// The largest load scale a continuation of this solve reached (1 when
    /// one ended), for the message of a solve that failed.
    pub reached_load: f64,
}

impl Workspace {
    /// Allocated fallibly and between interrupt polls (about 0.5 KB a node).
    pub(super) fn new(model: &RodModel) -> Result<Self> {
        let n = model.n();
        let nodes = || interrupt::filled(n + 1, model.base(), "workspace");
        let vectors = || interrupt::filled(n, Vector3::zeros(), "workspace");
        Ok(Workspace {
            q: nodes()?,
            trial: nodes()?,
            saved: nodes()?,
            g: vectors()?,
            g_trial: vectors()?,
            step: vectors()?,
            scratch: vectors()?,
            jac: BlockTridiagonal::try_zeros(n)?,
            lu: BlockLu::try_new(n)?,
            interior: model.new_interior(),
            kkt: constrained::KktWorkspace::new(model),
            reached_load: 0.0,
        })
    }
}

/// Result of one local solve at a fixed load scale.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LocalOutcome {
    pub converged: bool,
    pub iterations: usize,
}

/// A local method: drive `w.q` to an equilibrium at load scale `lambda`.
/// On return `w.g` and `w.jac` hold the residual and Jacobian at `w.q`.
pub(crate) trait LocalSolver {
    fn run(
        &mut self,
        model: &RodModel,
        w: &mut Workspace,
        lambda: f64,
        max_iter: usize,
        tol: f64,
    ) -> LocalOutcome;

    /// A direct attempt from an arbitrary start (the initial guess, a warm
    /// start), with load continuation as the fallback: it may give up as soon
    /// as it stops making progress. By default the same as `run`.
    fn attempt(
        &mut self,
        model: &RodModel,
        w: &mut Workspace,
        lambda: f64,
        max_iter: usize,
        tol: f64,
    ) -> LocalOutcome {
        self.run(model, w, lambda, max_iter, tol)
    }

    /// The same method, with its buffers sized for `model`.
    fn for_model(&self, model: &RodModel) -> Box<dyn LocalSolver + Send + Sync>;
}

/// Residual and Jacobian at the workspace state, free or constrained.
pub(crate) fn evaluate(model: &RodModel, w: &mut Workspace, lambda: f64) {
    if model.is_constrained() {
        constrained::evaluate(model, w, lambda, true);
    } else {
        model.residual_jacobian(&w.q, lambda, &mut w.interior, &mut w.g, &mut w.jac);
    }
}

pub(super) fn residual_norm(model: &RodModel, w: &Workspace) -> f64 {
    if model.is_constrained() {
        constrained::residual_norm(model, w)
    } else {
        model.residual_norm(&w.g)
    }
}

pub(crate) fn is_stable(model: &RodModel, w: &mut Workspace) -> bool {
    // Condensed internal nodes (fe4): the full Hessian is positive definite
    // iff every internal block and the Schur complement are.
    if !model.interior_at_minima(&w.interior) {
        return false;
    }
    if model.is_constrained() {
        constrained::is_stable(model, w)
    } else {
        symmetric_part_is_positive_definite(&w.jac)
    }
}

/// Scale the step so that no node turns by more than `max_node` and no element
/// by more than `max_element` radians in one update (keeps `conj(a) b` far from
/// the antipodal branch of the curvature formula).
pub(crate) fn step_limit(step: &[Vector3<f64>], max_node: f64, max_element: f64) -> f64 {
    let mut limit = 1.0f64;
    let mut prev = Vector3::zeros();
    for d in step {
        let node = d.norm();
        if node > max_node {
            limit = limit.min(max_node / node);
        }
        let rel = (d - prev).norm();
        if rel > max_element {
            limit = limit.min(max_element / rel);
        }
        prev = *d;
    }
    limit
}
