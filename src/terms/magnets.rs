//! A magnetised rod and a tip magnet in a uniform external field (docs/model.md
//! "Magnetic actuation"): the potential `-B . R(s) m(s)` per length of a
//! magnetisation `m` (dipole moment per length, material frame, one per
//! equal section) and `-B . R(q_n) mu` of a tip magnet, body-vector
//! potentials in the loading. Its parameters are the field, the
//! magnetisation and the tip magnet.

use super::{component, split_index, unit, BendingLoads, PerSection, Term};
use crate::disc::{BodyLoad, Loading, NodePair};
use crate::error::Result;
use crate::mesh::Mesh;
use crate::scene::Scene;
use nalgebra::Vector3;

/// Magnetisation, tip magnet and field.
#[derive(Debug, Clone)]
pub struct Magnets {
    /// Magnetisation of each of its sections, material frame [A m^2 / m]
    /// (None: none).
    pub magnetization: Option<PerSection<Vector3<f64>>>,
    /// The tip magnet's dipole moment, material frame [A m^2].
    pub tip_magnet: Vector3<f64>,
    /// Uniform field, world frame [T].
    pub field: Vector3<f64>,
    /// The scene's number of magnetised sections.
    sections: usize,
}

impl Magnets {
    pub fn new(scene: &Scene, mesh: &Mesh) -> Self {
        let n = mesh.n();
        let k = scene.magnetization.len();
        Magnets {
            magnetization: (k > 0).then(|| PerSection::new(scene.magnetization.clone(), n)),
            tip_magnet: scene.tip_magnet,
            field: scene.magnetic_field,
            sections: k,
        }
    }

    /// Add the potentials of `magnetization` (one a section, or none) and
    /// `tip_magnet` in the field `field` to `loading`.
    fn add(
        mesh: &Mesh,
        field: Vector3<f64>,
        magnetization: Option<&PerSection<Vector3<f64>>>,
        tip_magnet: Vector3<f64>,
        loading: &mut Loading,
    ) {
        if field == Vector3::zeros() {
            return;
        }
        if let Some(m) = magnetization {
            loading.body_loads.push(BodyLoad {
                world: field,
                body: m.expand(),
            });
        }
        if tip_magnet != Vector3::zeros() {
            loading.node_pairs.push(NodePair {
                node: mesh.n(),
                world: field,
                body: tip_magnet,
            });
        }
    }
}

impl Term for Magnets {
    fn apply(&self, mesh: &Mesh, loading: &mut Loading) {
        let m = self.magnetization.as_ref();
        Magnets::add(mesh, self.field, m, self.tip_magnet, loading);
    }

    fn moment_scale(&self, length: f64) -> f64 {
        let largest = self
            .magnetization
            .iter()
            .flat_map(|m| m.values())
            .map(|m| m.norm())
            .fold(0.0, f64::max);
        self.field.norm() * (self.tip_magnet.norm() + length * largest)
    }

    fn bending_loads(&self, length: f64) -> BendingLoads {
        BendingLoads {
            force: 0.0,
            moment: self.moment_scale(length),
        }
    }

    fn vanishes(&self) -> bool {
        self.field == Vector3::zeros()
            || (self
                .magnetization
                .iter()
                .flat_map(|m| m.values())
                .all(|m| *m == Vector3::zeros())
                && self.tip_magnet == Vector3::zeros())
    }

    fn breaks(&self, _mesh: &Mesh, out: &mut Vec<usize>) {
        if let (Some(m), false) = (&self.magnetization, self.field == Vector3::zeros()) {
            m.breaks(out);
        }
    }

    fn derivative(&self, parameter: &str, mesh: &Mesh, tangent: &mut Loading) -> Result<bool> {
        if let Some(c) = component(parameter, "magnetic_field") {
            let m = self.magnetization.as_ref();
            Magnets::add(mesh, unit(c), m, self.tip_magnet, tangent);
            return Ok(true);
        }
        if let Some(c) = component(parameter, "tip_magnet") {
            Magnets::add(mesh, self.field, None, unit(c), tangent);
            return Ok(true);
        }
        if let Some((s, rest)) = split_index(parameter, "magnetization") {
            let n = mesh.n();
            let Some(c) = component(rest, "") else {
                return Ok(false);
            };
            if s >= self.sections {
                return Ok(false);
            }
            let body: Vec<Vector3<f64>> = (0..self.sections)
                .map(|k| match k == s {
                    true => unit(c),
                    false => Vector3::zeros(),
                })
                .collect();
            let body = PerSection::new(body, n);
            Magnets::add(mesh, self.field, Some(&body), Vector3::zeros(), tangent);
            return Ok(true);
        }
        Ok(false)
    }
}
