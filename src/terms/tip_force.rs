//! The tip force `P` (world frame), acting at the tip or at an offset `c`
//! from it in the tip's material frame (a tool): its potential `-P . (r_n +
//! R(q_n) c)` is the internal force `P` along the whole rod (a term of the
//! internal force) plus the body-vector potential `-P . R(q_n) c` at the tip
//! node, whose moment turns with the tip.

use super::{component, unit, BendingLoads, Term};
use crate::disc::{Loading, NodePair};
use crate::error::Result;
use crate::mesh::Mesh;
use crate::scene::Scene;
use nalgebra::Vector3;

/// The tip force and where it acts.
#[derive(Debug, Clone)]
pub struct TipForce {
    /// World frame [N].
    pub force: Vector3<f64>,
    /// From the tip, in its material frame [m].
    pub offset: Vector3<f64>,
}

impl TipForce {
    pub fn new(scene: &Scene, _mesh: &Mesh) -> Self {
        TipForce {
            force: scene.tip_force,
            offset: scene.tip_force_offset,
        }
    }

    /// Add a tip force `force` acting at `offset` to `loading`.
    fn add(mesh: &Mesh, force: Vector3<f64>, offset: Vector3<f64>, loading: &mut Loading) {
        let n = mesh.n();
        for (v, len) in [
            (&mut loading.mean_force, n),
            (&mut loading.force_drop, n),
            (&mut loading.node_force, n + 1),
        ] {
            v.resize(len.max(v.len()), Vector3::zeros());
        }
        if force != Vector3::zeros() {
            loading.mean_force.iter_mut().for_each(|f| *f += force);
            loading.node_force.iter_mut().for_each(|f| *f += force);
        }
        if force != Vector3::zeros() && offset != Vector3::zeros() {
            loading.node_pairs.push(NodePair {
                node: n,
                world: force,
                body: offset,
            });
        }
    }
}

impl Term for TipForce {
    fn apply(&self, mesh: &Mesh, loading: &mut Loading) {
        TipForce::add(mesh, self.force, self.offset, loading);
    }

    fn moment_scale(&self, length: f64) -> f64 {
        self.force.norm() * (length + self.offset.norm())
    }

    fn bending_loads(&self, _length: f64) -> BendingLoads {
        BendingLoads {
            force: self.force.norm(),
            moment: self.force.norm() * self.offset.norm(),
        }
    }

    fn vanishes(&self) -> bool {
        self.force == Vector3::zeros()
    }

    fn derivative(&self, parameter: &str, mesh: &Mesh, tangent: &mut Loading) -> Result<bool> {
        if let Some(c) = component(parameter, "tip_force") {
            TipForce::add(mesh, unit(c), self.offset, tangent);
            return Ok(true);
        }
        if let Some(c) = component(parameter, "tip_force_offset") {
            // Only the offset's moment changes: a node pair alone.
            tangent.node_pairs.push(NodePair {
                node: mesh.n(),
                world: self.force,
                body: unit(c),
            });
            return Ok(true);
        }
        Ok(false)
    }
}
