//! How a solve ended: the one status every method, batch and binding reports.
//! Below every solver and the errors (an error carries one): it knows none
//! of them. Its parsing from a name sits with the solution.

/// How a solve ended. Only `Converged` is an answer; every other ending
/// carries the best state reached, its residual and a message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// The relative residual is below `residual_tol`, the state is finite and
    /// every element turns within what the scheme resolves.
    Converged,
    /// The methods stalled before the iteration budget ran out: the line
    /// search or the load continuation (below `min_continuation_step`) could
    /// not progress, or the paper's method ended above its tolerance.
    NotConverged,
    /// The iteration budget (`max_iterations`) ran out before convergence.
    IterationLimit,
    /// Accuracy on demand stopped at its largest `n` with the error estimate
    /// above the tolerance (the state is a converged equilibrium at that `n`).
    ToleranceNotMet,
    /// The discrete rod cannot follow the shape; solve with more elements.
    /// Either an equilibrium whose elements turn by more than the solver's
    /// `MAX_RESOLVED_TURN` (a coiled rod folds onto itself), or, not
    /// attempted, a held point beyond the discrete rod's reach (the scene's
    /// `clamped_end_deficit`).
    Underresolved,
    /// The state or the residual is not finite (an overflow).
    NumericalError,
    /// Not attempted: the scene has no well-defined answer (a held point
    /// within the scene's `FULL_REACH_BAND` of full reach, whose reaction
    /// is indeterminate or unbounded).
    Indeterminate,
}

impl Status {
    /// Every status, in the order of the declaration.
    pub const ALL: [Status; 7] = [
        Status::Converged,
        Status::NotConverged,
        Status::IterationLimit,
        Status::ToleranceNotMet,
        Status::Underresolved,
        Status::NumericalError,
        Status::Indeterminate,
    ];

    /// The snake_case name used by the Python API and in messages.
    pub fn name(self) -> &'static str {
        match self {
            Status::Converged => "converged",
            Status::NotConverged => "not_converged",
            Status::IterationLimit => "iteration_limit",
            Status::ToleranceNotMet => "tolerance_not_met",
            Status::Underresolved => "underresolved",
            Status::NumericalError => "numerical_error",
            Status::Indeterminate => "indeterminate",
        }
    }
}
