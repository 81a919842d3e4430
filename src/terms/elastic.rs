//! The elastic energy `1/2 (omega - omega0)^T K (omega - omega0)` per length
//! (docs/model.md "The elastic energy"): a diagonal stiffness `K` and a rest
//! curvature `omega0` (material frame) for each element, from the rod's and
//! its sections'. Its parameters are the stiffness (diagonal or a round
//! rod's `E`, `G` and diameter, the rod's or a section's) and the rest
//! curvature of each section.

use super::{section_of, split_index, Term};
use crate::disc::Loading;
use crate::error::Result;
use crate::mesh::Mesh;
use crate::scene::{Scene, Stiffness};
use nalgebra::Vector3;
use std::f64::consts::PI;

/// Stiffness and rest curvature, element by element.
#[derive(Debug, Clone)]
pub struct Elastic {
    /// Stiffness of each element [N m^2].
    pub stiffness: Vec<Vector3<f64>>,
    /// Rest curvature of each element, material frame [1/m].
    pub rest_curvature: Vec<Vector3<f64>>,
    /// The rod's stiffness as given, and each section's (None: the rod's).
    spec: Stiffness,
    section_specs: Vec<Option<Stiffness>>,
    /// The scene's number of sections, and of rest curvature entries.
    sections: usize,
    rest_sections: usize,
}

impl Elastic {
    pub fn new(scene: &Scene, mesh: &Mesh) -> Self {
        let n = mesh.n();
        let sections = scene.sections();
        let stiffness = (0..n)
            .map(|i| match scene.sections.is_empty() {
                true => scene.stiffness_spec.diagonal(),
                false => scene.section_stiffness(section_of(i, sections, n)),
            })
            .collect();
        let mut elastic = Elastic {
            stiffness,
            rest_curvature: vec![Vector3::zeros(); n],
            spec: scene.stiffness_spec.clone(),
            section_specs: scene.sections.iter().map(|p| p.stiffness.clone()).collect(),
            sections,
            rest_sections: scene.rest_curvature.len(),
        };
        elastic.set_rest_curvature(&scene.rest_curvature);
        elastic
    }

    /// Replace the rest curvature, one `[kappa_x, kappa_y]` a section (the
    /// number of sections divides `n`; none: straight).
    pub fn set_rest_curvature(&mut self, sections: &[[f64; 2]]) {
        let n = self.rest_curvature.len();
        let m = sections.len().max(1);
        self.rest_sections = sections.len();
        for (i, k) in self.rest_curvature.iter_mut().enumerate() {
            *k = sections
                .get(section_of(i, m, n))
                .map_or(Vector3::zeros(), |s| Vector3::new(s[0], s[1], 0.0));
        }
    }

    /// `dK / dp` of a stiffness given as `spec` in its component `key`
    /// (`kx`, `ky`, `kz`, `E`, `G`, `diameter`), or None if it has none.
    fn stiffness_derivative(spec: &Stiffness, key: &str) -> Option<Vector3<f64>> {
        match (spec, key) {
            (Stiffness::Diagonal { .. }, "kx") => Some(Vector3::x()),
            (Stiffness::Diagonal { .. }, "ky") => Some(Vector3::y()),
            (Stiffness::Diagonal { .. }, "kz") => Some(Vector3::z()),
            (Stiffness::RoundRod { diameter, .. }, "E") => {
                let i = PI * diameter.powi(4) / 64.0;
                Some(Vector3::new(i, i, 0.0))
            }
            (Stiffness::RoundRod { diameter, .. }, "G") => {
                let i = PI * diameter.powi(4) / 64.0;
                Some(Vector3::new(0.0, 0.0, 2.0 * i))
            }
            // K is proportional to d^4.
            (Stiffness::RoundRod { diameter, .. }, "diameter") => {
                Some(4.0 / diameter * spec.diagonal())
            }
            _ => None,
        }
    }

    /// The elements a stiffness parameter moves (a section's, or the rod's
    /// where no section has its own) and `dK/dp` there.
    fn stiffness_tangent(&self, parameter: &str) -> Option<(Vec<bool>, Vector3<f64>)> {
        let n = self.stiffness.len();
        if let Some(key) = parameter.strip_prefix("stiffness.") {
            let d = Elastic::stiffness_derivative(&self.spec, key)?;
            let moved = (0..n)
                .map(|i| {
                    let s = section_of(i, self.sections, n);
                    self.section_specs.get(s).is_none_or(|k| k.is_none())
                })
                .collect();
            return Some((moved, d));
        }
        let (s, rest) = split_index(parameter, "sections")?;
        let key = rest.strip_prefix(".stiffness.")?;
        let d = Elastic::stiffness_derivative(self.section_specs.get(s)?.as_ref()?, key)?;
        let moved = (0..n)
            .map(|i| section_of(i, self.sections, n) == s)
            .collect();
        Some((moved, d))
    }
}

impl Term for Elastic {
    fn apply(&self, _mesh: &Mesh, loading: &mut Loading) {
        match self.stiffness.windows(2).all(|w| w[0] == w[1]) {
            true => loading.stiffness = self.stiffness[..1].to_vec(),
            false => loading.stiffness.clone_from(&self.stiffness),
        }
        loading.rest_curvature.clone_from(&self.rest_curvature);
    }

    fn moment_scale(&self, _length: f64) -> f64 {
        0.0
    }

    fn vanishes(&self) -> bool {
        true
    }

    fn breaks(&self, _mesh: &Mesh) -> Vec<usize> {
        let mut out = super::jumps(&self.stiffness);
        out.extend(super::jumps(&self.rest_curvature));
        out
    }

    fn derivative(&self, parameter: &str, _mesh: &Mesh, tangent: &mut Loading) -> Result<bool> {
        let n = self.stiffness.len();
        if let Some((moved, d)) = self.stiffness_tangent(parameter) {
            tangent.stiffness.resize(n, Vector3::zeros());
            for (k, m) in tangent.stiffness.iter_mut().zip(moved) {
                if m {
                    *k += d;
                }
            }
            return Ok(true);
        }
        if let Some((s, rest)) = split_index(parameter, "rest_curvature") {
            let c = match rest {
                "[0]" => 0,
                "[1]" => 1,
                _ => return Ok(false),
            };
            if s >= self.rest_sections {
                return Ok(false);
            }
            tangent.rest_curvature.resize(n, Vector3::zeros());
            for (i, k) in tangent.rest_curvature.iter_mut().enumerate() {
                if section_of(i, self.rest_sections, n) == s {
                    k[c] += 1.0;
                }
            }
            return Ok(true);
        }
        Ok(false)
    }
}
