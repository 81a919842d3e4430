//! Dead moments, world frame (docs/model.md "Moments"): at the tip, at
//! points of the rod, and per length along it (the rod's, or a section's
//! own). A dead moment has no potential in 3D: it enters the residual as
//! its virtual work `M . R(q) dtheta` (a node's, or a scheme's quadrature of
//! the distributed one), so the Jacobian is not symmetric there, and the
//! stability of an equilibrium is judged on its symmetric part (as for any
//! dead moment: a sufficient condition, see `stable`).

use super::{component, split_index, unit, Term};
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
    /// Per length on each element [N m / m] (empty: none).
    pub distributed: Vec<Vector3<f64>>,
    /// Whether each element's section gives its own distributed moment.
    own: Vec<bool>,
    sections: usize,
}

impl Moments {
    pub fn new(scene: &Scene, mesh: &Mesh) -> Self {
        let n = mesh.n();
        let sections = scene.sections();
        let own: Vec<bool> = (0..n)
            .map(|i| {
                let s = super::section_of(i, sections, n);
                scene.section_moment(s).is_some()
            })
            .collect();
        let distributed = match scene.has_distributed_moment() {
            false => Vec::new(),
            true => (0..n)
                .map(|i| {
                    let s = super::section_of(i, sections, n);
                    scene.section_moment(s).unwrap_or(scene.distributed_moment)
                })
                .collect(),
        };
        Moments {
            tip: scene.tip_moment,
            points: scene
                .point_loads
                .iter()
                .map(|p| (mesh.nearest_node(p.s), p.moment))
                .collect(),
            distributed,
            own,
            sections,
        }
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
        if self.distributed.iter().any(|m| *m != Vector3::zeros()) {
            loading.distributed_moment.clone_from(&self.distributed);
        }
    }

    fn moment_scale(&self, length: f64) -> f64 {
        let largest = self
            .distributed
            .iter()
            .map(|m| m.norm())
            .fold(0.0, f64::max);
        self.tip.norm() + self.points.iter().map(|(_, m)| m.norm()).sum::<f64>() + length * largest
    }

    fn vanishes(&self) -> bool {
        self.tip == Vector3::zeros()
            && self.points.iter().all(|(_, m)| *m == Vector3::zeros())
            && self.distributed.iter().all(|m| *m == Vector3::zeros())
    }

    fn breaks(&self, _mesh: &Mesh) -> Vec<usize> {
        let mut out = super::jumps(&self.distributed);
        out.extend(
            self.points
                .iter()
                .filter(|(_, m)| *m != Vector3::zeros())
                .map(|(k, _)| *k),
        );
        out
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
            for (m, own) in tangent.distributed_moment.iter_mut().zip(&self.own) {
                if !own {
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
            for (i, m) in tangent.distributed_moment.iter_mut().enumerate() {
                if super::section_of(i, self.sections, n) == s {
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
