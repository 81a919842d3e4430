//! Dead forces along the rod (docs/model.md "Loads"): a distributed force per
//! length on each element (the scene's `distributed_force` plus gravity on
//! the rod's or its section's linear density) and forces at nodes (point
//! loads). Their potential is the work of the internal force they make,
//! `-F(s) . T(s)` per length with `F(s)` the sum of the forces beyond `s`:
//! a term of the internal force in the loading.

use super::{component, split_index, unit, Term};
use crate::disc::Loading;
use crate::error::Result;
use crate::mesh::Mesh;
use crate::scene::Scene;
use nalgebra::Vector3;

/// Distributed and point forces, world frame.
#[derive(Debug, Clone)]
pub struct DeadForces {
    /// Force per length on each element [N/m].
    pub distributed: Vec<Vector3<f64>>,
    /// Forces at nodes `(node, force)` [N], and their arc lengths [m].
    pub points: Vec<(usize, Vector3<f64>)>,
    point_arcs: Vec<f64>,
    /// Linear density of each element [kg/m] and whether its section gives
    /// its own; the gravity it weighs under [m/s^2].
    density: Vec<f64>,
    own_density: Vec<bool>,
    gravity: Option<Vector3<f64>>,
    sections: usize,
}

impl DeadForces {
    pub fn new(scene: &Scene, mesh: &Mesh) -> Self {
        let n = mesh.n();
        let sections = scene.sections();
        let section = |i: usize| super::section_of(i, sections, n);
        let rod_density = scene.gravity.as_ref().map_or(0.0, |g| g.linear_density);
        let own = |i: usize| {
            scene
                .sections
                .get(section(i))
                .and_then(|p| p.linear_density)
        };
        let distributed = (0..n)
            .map(|i| match scene.sections.is_empty() {
                true => scene.distributed_force(),
                false => scene.section_force(section(i)),
            })
            .collect();
        DeadForces {
            distributed,
            points: scene
                .point_loads
                .iter()
                .map(|p| (mesh.nearest_node(p.s), p.force))
                .collect(),
            point_arcs: scene.point_loads.iter().map(|p| p.s).collect(),
            density: (0..n).map(|i| own(i).unwrap_or(rod_density)).collect(),
            own_density: (0..n).map(|i| own(i).is_some()).collect(),
            gravity: scene.gravity.as_ref().map(|g| g.vector),
            sections,
        }
    }

    /// Add the internal force of the distributed forces `f` (one an element)
    /// and the point forces `points` to `loading`.
    fn add_internal_force(
        mesh: &Mesh,
        f: &[Vector3<f64>],
        points: &[(usize, Vector3<f64>)],
        loading: &mut Loading,
    ) {
        let n = mesh.n();
        let h = mesh.element_lengths();
        // Point loads by node: a load at node k acts on every element i <= k;
        // on the internal force at node j if it is beyond j (or at the tip).
        let points_from = |node: usize, strictly_distal: bool| -> Vector3<f64> {
            points
                .iter()
                .filter(|(k, _)| match strictly_distal {
                    true => *k > node || *k == n,
                    false => *k >= node,
                })
                .map(|(_, p)| *p)
                .sum()
        };
        let ensure =
            |v: &mut Vec<Vector3<f64>>, len: usize| v.resize(len.max(v.len()), Vector3::zeros());
        ensure(&mut loading.mean_force, n);
        ensure(&mut loading.force_drop, n);
        ensure(&mut loading.node_force, n + 1);
        // The distributed force beyond node j: the sum over the elements past it.
        let mut beyond = Vector3::zeros();
        for j in (0..=n).rev() {
            loading.node_force[j] += beyond + points_from(j, true);
            if j == 0 {
                break;
            }
            let on_element = f.get(j - 1).copied().unwrap_or_else(Vector3::zeros) * h[j - 1];
            loading.mean_force[j - 1] += beyond + 0.5 * on_element + points_from(j, false);
            loading.force_drop[j - 1] += on_element;
            beyond += on_element;
        }
    }
}

impl Term for DeadForces {
    fn apply(&self, mesh: &Mesh, loading: &mut Loading) {
        if self.vanishes() {
            return;
        }
        DeadForces::add_internal_force(mesh, &self.distributed, &self.points, loading);
    }

    fn moment_scale(&self, length: f64) -> f64 {
        let largest = self
            .distributed
            .iter()
            .map(|f| f.norm())
            .fold(0.0, f64::max);
        0.5 * length * length * largest
            + self
                .points
                .iter()
                .zip(&self.point_arcs)
                .map(|((_, p), s)| p.norm() * s)
                .sum::<f64>()
    }

    fn vanishes(&self) -> bool {
        self.distributed.iter().all(|f| *f == Vector3::zeros())
            && self.points.iter().all(|(_, p)| *p == Vector3::zeros())
    }

    fn breaks(&self, _mesh: &Mesh) -> Vec<usize> {
        let mut out = super::jumps(&self.distributed);
        out.extend(
            self.points
                .iter()
                .filter(|(_, p)| *p != Vector3::zeros())
                .map(|(k, _)| *k),
        );
        out
    }

    fn derivative(&self, parameter: &str, mesh: &Mesh, tangent: &mut Loading) -> Result<bool> {
        let n = self.distributed.len();
        let g = self.gravity.unwrap_or_else(Vector3::zeros);
        let mut df = vec![Vector3::zeros(); n];
        let mut dp = Vec::new();
        if let Some(c) = component(parameter, "distributed_force") {
            df.iter_mut().for_each(|f| *f = unit(c));
        } else if parameter == "gravity.linear_density" {
            for (f, own) in df.iter_mut().zip(&self.own_density) {
                if !own {
                    *f = g;
                }
            }
        } else if let Some(c) = component(parameter, "gravity.vector") {
            for (f, rho) in df.iter_mut().zip(&self.density) {
                *f = *rho * unit(c);
            }
        } else if let Some((s, ".linear_density")) = split_index(parameter, "sections") {
            for (i, f) in df.iter_mut().enumerate() {
                if super::section_of(i, self.sections, n) == s && self.own_density[i] {
                    *f = g;
                }
            }
        } else if let Some((k, rest)) = split_index(parameter, "point_loads") {
            let Some(c) = component(rest, ".force") else {
                return Ok(false);
            };
            let Some((node, _)) = self.points.get(k) else {
                return Ok(false);
            };
            dp.push((*node, unit(c)));
        } else {
            return Ok(false);
        }
        DeadForces::add_internal_force(mesh, &df, &dp, tangent);
        Ok(true)
    }
}
