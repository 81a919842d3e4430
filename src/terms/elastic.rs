//! The elastic energy `1/2 (omega - omega0)^T K (omega - omega0)` per length
//! (docs/model.md "The elastic energy"): a diagonal stiffness `K` and a rest
//! curvature `omega0` (material frame), one a section, from the rod's and
//! its sections'. Its parameters are the stiffness (diagonal or a round
//! rod's `E`, `G` and diameter, the rod's or a section's) and the rest
//! curvature of each section.

use super::{section_of, split_index, BendingLoads, PerSection, Term};
use crate::disc::Loading;
use crate::error::Result;
use crate::mesh::Mesh;
use crate::scene::{Scene, Stiffness};
use nalgebra::Vector3;
use std::f64::consts::PI;

/// Stiffness and rest curvature, section by section.
#[derive(Debug, Clone)]
pub struct Elastic {
    /// Stiffness of each section [N m^2].
    pub stiffness: PerSection<Vector3<f64>>,
    /// Rest curvature of each of the rest curvature's sections, material
    /// frame [1/m] (one zero: straight).
    pub rest_curvature: PerSection<Vector3<f64>>,
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
        let stiffness = match scene.sections.is_empty() {
            true => vec![scene.stiffness_spec.diagonal()],
            false => (0..sections).map(|s| scene.section_stiffness(s)).collect(),
        };
        let mut elastic = Elastic {
            stiffness: PerSection::new(stiffness, n),
            rest_curvature: PerSection::new(vec![Vector3::zeros()], n),
            spec: scene.stiffness_spec.clone(),
            section_specs: scene.sections.iter().map(|p| p.stiffness.clone()).collect(),
            sections,
            rest_sections: scene.rest_curvature.len(),
        };
        elastic.set_rest_curvature(&scene.rest_curvature, n);
        elastic
    }

    /// Replace the rest curvature, one `[kappa_x, kappa_y]` a section of `n`
    /// elements (the number of sections divides `n`; none: straight).
    pub fn set_rest_curvature(&mut self, sections: &[[f64; 2]], n: usize) {
        self.rest_sections = sections.len();
        let values = match sections.is_empty() {
            true => vec![Vector3::zeros()],
            false => sections
                .iter()
                .map(|k| Vector3::new(k[0], k[1], 0.0))
                .collect(),
        };
        self.rest_curvature = PerSection::new(values, n);
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

    /// The sections a stiffness parameter moves (a section's, or the rod's
    /// where no section has its own) and `dK/dp` there.
    fn stiffness_tangent(&self, parameter: &str) -> Option<(Vec<bool>, Vector3<f64>)> {
        if let Some(key) = parameter.strip_prefix("stiffness.") {
            let d = Elastic::stiffness_derivative(&self.spec, key)?;
            let moved = (0..self.sections)
                .map(|s| self.section_specs.get(s).is_none_or(|k| k.is_none()))
                .collect();
            return Some((moved, d));
        }
        let (s, rest) = split_index(parameter, "sections")?;
        let key = rest.strip_prefix(".stiffness.")?;
        let d = Elastic::stiffness_derivative(self.section_specs.get(s)?.as_ref()?, key)?;
        Some(((0..self.sections).map(|k| k == s).collect(), d))
    }
}

impl Term for Elastic {
    fn apply(&self, _mesh: &Mesh, loading: &mut Loading) {
        loading.stiffness = match self.stiffness.uniform() {
            Some(k) => vec![k],
            None => self.stiffness.expand(),
        };
        self.rest_curvature.expand_into(&mut loading.rest_curvature);
    }

    fn moment_scale(&self, _length: f64) -> f64 {
        0.0
    }

    fn bending_loads(&self, _length: f64) -> BendingLoads {
        // The rest curvature's turning is counted apart, as the rest turn.
        BendingLoads::default()
    }

    fn vanishes(&self) -> bool {
        true
    }

    fn breaks(&self, _mesh: &Mesh, out: &mut Vec<usize>) {
        self.stiffness.breaks(out);
        self.rest_curvature.breaks(out);
    }

    fn derivative(&self, parameter: &str, mesh: &Mesh, tangent: &mut Loading) -> Result<bool> {
        let n = mesh.n();
        if let Some((moved, d)) = self.stiffness_tangent(parameter) {
            tangent.stiffness.resize(n, Vector3::zeros());
            for (i, k) in tangent.stiffness.iter_mut().enumerate() {
                if moved[section_of(i, self.sections, n)] {
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
            // The section's elements alone.
            let per = n / self.rest_sections;
            tangent.support = match tangent.is_empty() {
                true => Some((s * per + 1, (s + 1) * per)),
                false => None,
            };
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
