//! Dead forces along the rod (docs/model.md "Loads"): a distributed force per
//! length on each element (the scene's `distributed_force` plus gravity on
//! the rod's or its section's linear density) and forces at nodes (point
//! loads). Their potential is the work of the internal force they make,
//! `-F(s) . T(s)` per length with `F(s)` the sum of the forces beyond `s`:
//! a term of the internal force in the loading.

use super::{component, split_index, unit, BendingLoads, PerSection, Term};
use crate::disc::Loading;
use crate::error::Result;
use crate::mesh::Mesh;
use crate::scene::Scene;
use nalgebra::Vector3;

/// Distributed and point forces, world frame.
#[derive(Debug, Clone)]
pub struct DeadForces {
    /// Force per length on each section [N/m].
    pub distributed: PerSection<Vector3<f64>>,
    /// Forces at nodes `(node, force)` [N], and their arc lengths [m].
    pub points: Vec<(usize, Vector3<f64>)>,
    point_arcs: Vec<f64>,
    /// Linear density of each section [kg/m] and whether it is its own;
    /// the gravity it weighs under [m/s^2].
    density: PerSection<(f64, bool)>,
    gravity: Option<Vector3<f64>>,
}

impl DeadForces {
    pub fn new(scene: &Scene, mesh: &Mesh) -> Self {
        let n = mesh.n();
        let rod_density = scene.gravity.as_ref().map_or(0.0, |g| g.linear_density);
        let (distributed, density) = match scene.sections.is_empty() {
            true => (vec![scene.distributed_force()], vec![(rod_density, false)]),
            false => (0..scene.sections())
                .map(|s| {
                    let own = scene.sections.get(s).and_then(|p| p.linear_density);
                    (
                        scene.section_force(s),
                        (own.unwrap_or(rod_density), own.is_some()),
                    )
                })
                .unzip(),
        };
        DeadForces {
            distributed: PerSection::new(distributed, n),
            points: scene
                .point_loads
                .iter()
                .map(|p| (mesh.nearest_node(p.s), p.force))
                .collect(),
            point_arcs: scene.point_loads.iter().map(|p| p.s).collect(),
            density: PerSection::new(density, n),
            gravity: scene.gravity.as_ref().map(|g| g.vector),
        }
    }

    /// Add the internal force of the distributed forces `f` (of element `i`
    /// from 0) and the point forces `points` to `loading`.
    fn add_internal_force(
        mesh: &Mesh,
        f: impl Fn(usize) -> Vector3<f64>,
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
            let on_element = f(j - 1) * h[j - 1];
            loading.mean_force[j - 1] += beyond + 0.5 * on_element + points_from(j, false);
            loading.force_drop[j - 1] += on_element;
            beyond += on_element;
        }
    }
}

impl DeadForces {
    /// The largest force per length on any section [N/m].
    fn largest_distributed(&self) -> f64 {
        self.distributed
            .values()
            .iter()
            .map(|f| f.norm())
            .fold(0.0, f64::max)
    }
}

impl Term for DeadForces {
    fn apply(&self, mesh: &Mesh, loading: &mut Loading) {
        if self.vanishes() {
            return;
        }
        DeadForces::add_internal_force(mesh, |i| self.distributed.at(i), &self.points, loading);
    }

    fn moment_scale(&self, length: f64) -> f64 {
        let largest = self.largest_distributed();
        0.5 * length * length * largest
            + self
                .points
                .iter()
                .zip(&self.point_arcs)
                .map(|((_, p), s)| p.norm() * s)
                .sum::<f64>()
    }

    fn bending_loads(&self, length: f64) -> BendingLoads {
        let largest = self.largest_distributed();
        BendingLoads {
            force: length * largest + self.points.iter().map(|(_, p)| p.norm()).sum::<f64>(),
            moment: 0.0,
        }
    }

    fn vanishes(&self) -> bool {
        self.distributed
            .values()
            .iter()
            .all(|f| *f == Vector3::zeros())
            && self.points.iter().all(|(_, p)| *p == Vector3::zeros())
    }

    fn breaks(&self, _mesh: &Mesh, out: &mut Vec<usize>) {
        self.distributed.breaks(out);
        out.extend(
            self.points
                .iter()
                .filter(|(_, p)| *p != Vector3::zeros())
                .map(|(k, _)| *k),
        );
    }

    fn derivative(&self, parameter: &str, mesh: &Mesh, tangent: &mut Loading) -> Result<bool> {
        let g = self.gravity.unwrap_or_else(Vector3::zeros);
        let sections = self.density.values().len();
        let n = mesh.n();
        // The distributed force's derivative on each section, or a point force's.
        let df: Vec<Vector3<f64>> = if let Some(c) = component(parameter, "distributed_force") {
            vec![unit(c); sections]
        } else if parameter == "gravity.linear_density" {
            let rod = |(_, own): &(f64, bool)| if *own { Vector3::zeros() } else { g };
            self.density.values().iter().map(rod).collect()
        } else if let Some(c) = component(parameter, "gravity.vector") {
            self.density
                .values()
                .iter()
                .map(|(rho, _)| *rho * unit(c))
                .collect()
        } else if let Some((s, ".linear_density")) = split_index(parameter, "sections") {
            let own = |(k, (_, own)): (usize, &(f64, bool))| match k == s && *own {
                true => g,
                false => Vector3::zeros(),
            };
            self.density.values().iter().enumerate().map(own).collect()
        } else if let Some((k, rest)) = split_index(parameter, "point_loads") {
            let (Some(c), Some((node, _))) = (component(rest, ".force"), self.points.get(k)) else {
                return Ok(false);
            };
            let none = |_| Vector3::zeros();
            DeadForces::add_internal_force(mesh, none, &[(*node, unit(c))], tangent);
            return Ok(true);
        } else {
            return Ok(false);
        };
        let df = PerSection::new(df, n);
        DeadForces::add_internal_force(mesh, |i| df.at(i), &[], tangent);
        Ok(true)
    }
}
