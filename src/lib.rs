//! # softspine
//!
//! Statics of soft continuum robots and elastic rods: the backbone is a chain of
//! unit quaternions at `n + 1` nodes (finite differences), equilibrium comes from
//! the discrete total potential, and the equations are solved by Newton's method
//! on a block-tridiagonal system (O(n) per iteration) or by Levenberg-Marquardt.
//! See `docs/model.md` of the project for the equations and conventions.
//!
//! ```
//! use softspine::nalgebra::Vector3;
//! use softspine::{solve, Scene, Settings};
//!
//! // A cantilever (EI = 1, L = 1) under a tip force P = 3 perpendicular to its axis.
//! let mut scene = Scene::new(1.0, 1.0, 1.0, 1.0);
//! scene.tip_force = Vector3::new(3.0, 0.0, 0.0);
//! let sol = solve(&scene, Settings::default(), None).unwrap();
//! assert!(sol.converged() && sol.stable);
//! // Bisshopp-Drucker: tip deflection 0.6033 L.
//! assert!((sol.tip_position().x - 0.60325344).abs() < 1e-3);
//!
//! // A control loop: one solver (its workspace is allocated once), warm starts.
//! let mut solver = softspine::Solver::new(&scene, Settings { n_elements: Some(40), ..Settings::default() }).unwrap();
//! let mut previous = solver.solve(None).unwrap();
//! for k in 0..10 {
//!     solver.set_rest_curvature(&[[0.1 * k as f64, 0.0]]).unwrap(); // new actuation
//!     previous = solver.solve(Some(&previous.quaternions)).unwrap();
//!     assert!(previous.converged());
//! }
//! ```

mod banded;
pub mod batch;
pub mod blocktri;
pub mod contact;
pub mod disc;
pub mod error;
pub mod interrupt;
pub mod keys;
pub mod mesh;
pub mod methods;
pub mod model;
pub mod quat;
mod read;
pub mod robot;
pub mod scene;
pub mod solver;
pub mod status;
pub mod terms;
pub mod value;

#[cfg(feature = "python")]
mod python;

pub use batch::{solve_batch, BatchControl, BatchSettings, Sample};
pub use error::{Error, Result};
/// The linear algebra crate of the public types (`Vector3`, `Matrix3xX`): a
/// user of softspine needs no dependency of their own on it.
pub use nalgebra;

/// The README's Rust code, compiled and run as a test (`cargo test --doc`).
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;
pub use model::{RodModel, Scheme};
pub use quat::Quat;
pub use robot::{
    Actuation, ActuationSpace, Calibration, CalibrationSettings, DriveColumns, IkEnding, IkOptions,
    IkResult, IkSample, IkSettings, InverseSolver, Load, Robot, SectionSpec, Strategy, TendonRoute,
};
pub use scene::{
    Gravity, Guide, PointLoad, Scene, SectionProperties, Stiffness, Tendon, TipCondition,
};
pub use solver::{
    default_elements, solve, solve_after, solve_to_accuracy, Accuracy, Contact, Method,
    PortReaction, Sensitivity, Settings, Solution, Solver, Status, TipSensitivity,
    DEFAULT_ELEMENTS,
};
pub use value::Value;
