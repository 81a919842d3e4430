//! Methods beside the schemes: each solves the same scene its own way, on
//! the same model (its mesh, loads and held tip), and hands back its raw
//! answer; the solver's driver reports it as the same `Solution` as
//! the local solvers, with the model's residual, stability and reactions.
//!
//! ```text
//! shooting.rs   RK4 on the Kirchhoff rod equations, Newton on the base wrench
//! paper/        the seed paper's least-squares system: particle swarm, then LM
//! ```
//!
//! Nothing here imports the solver: what a method needs of it (whether a
//! shape is a stable equilibrium of the discrete model) comes in as a closure.

pub mod paper;
pub mod shooting;
