//! Dead moments, world frame (docs/model.md "Moments"): at the tip, at
//! points of the rod, and per length along it (the rod's, or a section's
//! own). A dead moment has no potential in 3D: it enters the residual as
//! its virtual work `M . R(q) dtheta` (a node's, or a scheme's quadrature of
//! the distributed one), so the Jacobian is not symmetric there, and the
//! stability of an equilibrium is judged on its symmetric part (as for any
//! dead moment: a sufficient condition, see `stable`).

use super::{component, split_index, unit, BendingLoads, PerSection, Term};
use crate::disc::{Loading, NodeMoment};
use crate::error::Result;
use crate::mesh::Mesh;
use crate::scene::Scene;
use nalgebra::Vector3;

/// Dead moments at nodes and per length.
#[derive(Debug, Clone)]
pub struct Moments {
    /// The tip's [N m].
    pub tip: Vector3<f64>,
    /// At nodes `(node, moment)` [N m]: every point load's moment, zero or not.
    pub points: Vec<(usize, Vector3<f64>)>,
    /// Per length on each section [N m / m], and whether it is the
    /// section's own.
    pub distributed: PerSection<(Vector3<f64>, bool)>,
}

impl Moments {
    pub fn new(scene: &Scene, mesh: &Mesh) -> Self {
        let distributed = (0..scene.sections())
            .map(|s| match scene.section_moment(s) {
                Some(m) => (m, true),
                None => (scene.distributed_moment, false),
            })
            .collect();
        Moments {
            tip: scene.tip_moment,
            points: scene
                .point_loads
                .iter()
                .map(|p| (mesh.nearest_node(p.s), p.moment))
                .collect(),
            distributed: PerSection::new(distributed, mesh.n()),
        }
    }

    /// Whether a distributed moment acts.
    fn distributed_acts(&self) -> bool {
        self.distributed
            .values()
            .iter()
            .any(|(m, _)| *m != Vector3::zeros())
    }

    /// Set the tip moment.
    pub fn set_tip(&mut self, moment: Vector3<f64>) {
        self.tip = moment;
    }
}

impl Term for Moments {
    fn apply(&self, mesh: &Mesh, loading: &mut Loading) {
        if self.tip != Vector3::zeros() {
            loading.node_moments.push(NodeMoment {
                node: mesh.n(),
                moment: self.tip,
            });
        }
        for (node, moment) in self.points.iter().filter(|(_, m)| *m != Vector3::zeros()) {
            loading.node_moments.push(NodeMoment {
                node: *node,
                moment: *moment,
            });
        }
        if self.distributed_acts() {
            loading.distributed_moment = self
                .distributed
                .expand()
                .into_iter()
                .map(|(m, _)| m)
                .collect();
        }
    }

    fn moment_scale(&self, length: f64) -> f64 {
        let largest = self
            .distributed
            .values()
            .iter()
            .map(|(m, _)| m.norm())
            .fold(0.0, f64::max);
        self.tip.norm() + self.points.iter().map(|(_, m)| m.norm()).sum::<f64>() + length * largest
    }

    fn bending_loads(&self, length: f64) -> BendingLoads {
        BendingLoads {
            force: 0.0,
            moment: self.moment_scale(length),
        }
    }

    fn vanishes(&self) -> bool {
        self.tip == Vector3::zeros()
            && self.points.iter().all(|(_, m)| *m == Vector3::zeros())
            && !self.distributed_acts()
    }

    fn breaks(&self, _mesh: &Mesh, out: &mut Vec<usize>) {
        if self.distributed_acts() {
            self.distributed.breaks(out);
        }
        out.extend(
            self.points
                .iter()
                .filter(|(_, m)| *m != Vector3::zeros())
                .map(|(k, _)| *k),
        );
    }

    fn derivative(&self, parameter: &str, mesh: &Mesh, tangent: &mut Loading) -> Result<bool> {
        let n = mesh.n();
        let node_moment = |node: usize, c: usize| NodeMoment {
            node,
            moment: unit(c),
        };
        if let Some(c) = component(parameter, "tip_moment") {
            tangent.node_moments.push(node_moment(n, c));
            return Ok(true);
        }
        if let Some(c) = component(parameter, "distributed_moment") {
            tangent.distributed_moment.resize(n, Vector3::zeros());
            for (i, m) in tangent.distributed_moment.iter_mut().enumerate() {
                if !self.distributed.at(i).1 {
                    *m += unit(c);
                }
            }
            return Ok(true);
        }
        if let Some((s, rest)) = split_index(parameter, "sections") {
            let Some(c) = component(rest, ".distributed_moment") else {
                return Ok(false);
            };
            tangent.distributed_moment.resize(n, Vector3::zeros());
            let sections = self.distributed.values().len();
            for (i, m) in tangent.distributed_moment.iter_mut().enumerate() {
                if super::section_of(i, sections, n) == s {
                    *m += unit(c);
                }
            }
            return Ok(true);
        }
        if let Some((k, rest)) = split_index(parameter, "point_loads") {
            let Some(c) = component(rest, ".moment") else {
                return Ok(false);
            };
            let Some((node, _)) = self.points.get(k) else {
                return Ok(false);
            };
            tangent.node_moments.push(node_moment(*node, c));
            return Ok(true);
        }
        Ok(false)
    }
}
