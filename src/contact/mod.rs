//! Contact with the surroundings: the obstacles a rod may touch and the gap
//! between the rod's surface and each of them.
//!
//! This is the first layer of frictionless contact (the constrained
//! equilibrium builds on it): each obstacle gives, at a point of the
//! backbone, the signed gap `g(p)` from the obstacle's surface (positive in
//! free space, negative inside the solid) and its gradient, the unit normal
//! along which a contact force pushes. A rod of radius `r` touches where
//! `g(p) = r` on its backbone; the condition to enforce is `g(p) - r >= 0`.
//! Every shape's gap is a true signed distance, so `|grad g| = 1` wherever it
//! is smooth, except a lumen of varying radius (see [`Obstacle::Lumen`]).

pub mod mesh_file;
pub(crate) mod obstacle;
mod port;
mod triangle_mesh;

pub(crate) use obstacle::files_beside;
pub use obstacle::{Obstacle, Proximity};
pub use port::{Crossing, Port};
pub use triangle_mesh::{MeshError, TriangleMesh};

/// A friction coefficient (an obstacle's, a port's) must be finite and
/// non-negative.
pub(crate) fn check_friction(mu: f64, key: &str) -> crate::error::Result<f64> {
    if mu.is_finite() && mu >= 0.0 {
        Ok(mu)
    } else {
        Err(crate::error::Error::scene(
            key,
            format!("a friction coefficient must be finite and >= 0, got {mu}"),
        ))
    }
}
