//! The physical effects on a rod, one file each: what each puts on the rod
//! in the kinds a scheme integrates ([`Loading`], `crate::disc`), and its
//! derivative in each of its own parameters (a tangent of the loading, from
//! which the sensitivities are exact in any units).
//!
//! ```text
//! elastic.rs    the elastic energy with rest curvature (stiffness, rest curvature)
//! forces.rs     dead forces along the rod: distributed (gravity, per section) and at points
//! tip_force.rs  the tip force, at the tip or at an offset from it (a tool)
//! moments.rs    dead moments: at the tip, at points, per length
//! tendons.rs    frictionless tendons (a curvature density)
//! magnets.rs    a magnetised rod and tip magnet in a uniform field
//! ```
//!
//! A term never reaches into a scheme: it fills in the loading, and the
//! schemes integrate the loading. A new effect is a new file here, its
//! entry in [`Terms`], and no change to any scheme or solver.

mod elastic;
mod forces;
mod magnets;
mod moments;
pub(crate) mod tendons;
mod tip_force;

pub use elastic::Elastic;
pub use forces::DeadForces;
pub use magnets::Magnets;
pub use moments::Moments;
pub use tendons::{density as tendon_density, Tendons};
pub use tip_force::TipForce;

use crate::disc::Loading;
use crate::error::Result;
use crate::mesh::Mesh;
use crate::scene::Scene;

/// One physical effect on the rod.
pub trait Term: std::fmt::Debug + Send + Sync {
    /// Add what it puts on the rod (at load scale 1) to `loading`.
    fn apply(&self, mesh: &Mesh, loading: &mut Loading);

    /// Add its curvature densities alone (a term of that kind; `apply`
    /// adds them too): what [`Terms::refresh_densities`] redoes when only
    /// they change.
    fn apply_densities(&self, mesh: &Mesh, loading: &mut Loading) {
        let _ = (mesh, loading);
    }

    /// The largest moment it can exert on the rod [N m]: its share of the
    /// load parameter (the curvature scale that sets the round-off floor).
    fn moment_scale(&self, length: f64) -> f64;

    /// The largest resultant force and moment it can put on the rod: the
    /// scales of how fast the loaded rod turns, from which accuracy on demand
    /// draws its first n (`solver::adaptive`).
    fn bending_loads(&self, length: f64) -> BendingLoads;

    /// Whether it puts nothing on the rod (the rest shape is then its equilibrium).
    fn vanishes(&self) -> bool;

    /// Add its derivative in `parameter` (a scene path, `"tip_force[0]"`) to
    /// `tangent`: true when the parameter is its own, false otherwise.
    fn derivative(&self, parameter: &str, mesh: &Mesh, tangent: &mut Loading) -> Result<bool>;

    /// Add the interior nodes where it makes the rod's shape not smooth (a
    /// jump of what it puts on the rod: a section's end, a point load, an
    /// anchor), which the shape between the nodes does not interpolate
    /// across, to `out`.
    fn breaks(&self, mesh: &Mesh, out: &mut Vec<usize>) {
        let _ = (mesh, out);
    }
}

/// The largest resultant force [N] and moment [N m] a term can put on the
/// rod. A force `F` bends the rod over the length `sqrt(EI / F)` (the
/// elastica's), a moment `M` at the curvature `M / EI`: the two turn the
/// rod at different rates, so they are kept apart (the load parameter of
/// the round-off floor sums them as moments).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BendingLoads {
    pub force: f64,
    pub moment: f64,
}

impl std::ops::Add for BendingLoads {
    type Output = BendingLoads;
    fn add(self, other: BendingLoads) -> BendingLoads {
        BendingLoads {
            force: self.force + other.force,
            moment: self.moment + other.moment,
        }
    }
}

/// How fast a loaded rod can turn ([`Terms::turning`]): a curvature `kappa`
/// turns it at `kappa` (the rest curvature's, a moment's `M / EI`), a force
/// `F` over the elastica's length `sqrt(EI / F)`, at a rate whose square is
/// `F / EI`: both [1/m^2].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Turning {
    /// The largest curvature's square: rest curvature and moments.
    pub curvature_squared: f64,
    /// The largest force over the softest bending stiffness.
    pub force: f64,
}

/// Every term of a scene.
#[derive(Debug, Clone)]
pub struct Terms {
    pub elastic: Elastic,
    pub forces: DeadForces,
    pub tip_force: TipForce,
    pub moments: Moments,
    pub tendons: Tendons,
    pub magnets: Magnets,
}

impl Terms {
    /// The terms of `scene` on the mesh `mesh`.
    pub fn new(scene: &Scene, mesh: &Mesh) -> Self {
        Terms {
            elastic: Elastic::new(scene, mesh),
            forces: DeadForces::new(scene, mesh),
            tip_force: TipForce::new(scene, mesh),
            moments: Moments::new(scene, mesh),
            tendons: Tendons::new(scene, mesh),
            magnets: Magnets::new(scene, mesh),
        }
    }

    /// Every term, for what is done to each alike.
    pub fn all(&self) -> [&dyn Term; 6] {
        [
            &self.elastic,
            &self.forces,
            &self.tip_force,
            &self.moments,
            &self.tendons,
            &self.magnets,
        ]
    }

    /// What they put on the rod.
    pub fn loading(&self, mesh: &Mesh) -> Loading {
        let mut loading = Loading::zeros(mesh.n());
        for term in self.all() {
            term.apply(mesh, &mut loading);
        }
        loading
    }

    /// The loading's curvature densities again, the rest of it kept (after
    /// a change of a density's parameter: the tensions, set at every trial
    /// of the IK in tension space).
    pub fn refresh_densities(&self, mesh: &Mesh, loading: &mut Loading) {
        loading.densities.clear();
        for term in self.all() {
            term.apply_densities(mesh, loading);
        }
    }

    /// The largest moment the loads can exert [N m] (the elastic law's own
    /// turning is counted apart, as the rest turn).
    pub fn moment_scale(&self, length: f64) -> f64 {
        self.all().iter().map(|t| t.moment_scale(length)).sum()
    }

    /// Their largest force and moment, summed (see [`BendingLoads`]).
    pub fn bending_loads(&self, length: f64) -> BendingLoads {
        self.all()
            .iter()
            .map(|t| t.bending_loads(length))
            .fold(BendingLoads::default(), |a, b| a + b)
    }

    /// How fast the loaded rod can turn, from its rest curvature and the
    /// loads' largest force and moment over the softest bending stiffness
    /// (see [`BendingLoads`]; torsion aside). The scale of a scheme's error
    /// (`solver::adaptive`).
    pub fn turning(&self, length: f64) -> Turning {
        let bending = self
            .elastic
            .stiffness
            .values()
            .iter()
            .map(|k| k.x.min(k.y))
            .fold(f64::INFINITY, f64::min);
        let rest = self
            .elastic
            .rest_curvature
            .values()
            .iter()
            .map(|k| k.norm())
            .fold(0.0, f64::max);
        let loads = self.bending_loads(length);
        let moment = loads.moment / bending;
        Turning {
            curvature_squared: rest * rest + moment * moment,
            force: loads.force / bending,
        }
    }

    /// Whether nothing but the elastic law acts.
    pub fn vanish(&self) -> bool {
        self.all().iter().all(|t| t.vanishes())
    }

    /// Every term's breaks (see [`Term::breaks`]) into `out`, unsorted.
    pub fn breaks(&self, mesh: &Mesh, out: &mut Vec<usize>) {
        for term in self.all() {
            term.breaks(mesh, out);
        }
    }

    /// The loading's derivative in `parameter` (a scene path), or `None`
    /// when no term owns it (the equations then depend on it otherwise:
    /// the mesh, the base, the held points).
    pub fn derivative(&self, parameter: &str, mesh: &Mesh) -> Result<Option<Loading>> {
        let mut tangent = Loading::empty();
        let mut owners = 0;
        for term in self.all() {
            owners += usize::from(term.derivative(parameter, mesh, &mut tangent)?);
        }
        if owners > 1 {
            // Each owner's support was its own: the union is not known.
            tangent.support = None;
        }
        Ok((owners > 0).then_some(tangent))
    }
}

/// Values one a section (or one for the rod) of a rod of `n` elements, each
/// section cut into the same number of them: what a term keeps of the scene,
/// expanded to the elements only in the loading.
#[derive(Debug, Clone, PartialEq)]
pub struct PerSection<T> {
    values: Vec<T>,
    n: usize,
}

impl<T: Copy + PartialEq> PerSection<T> {
    /// `values` (at least one) over `n` elements.
    pub fn new(values: Vec<T>, n: usize) -> Self {
        debug_assert!(!values.is_empty());
        PerSection { values, n }
    }

    /// The value of element `i` (from 0).
    #[inline]
    pub fn at(&self, i: usize) -> T {
        self.values[section_of(i, self.values.len(), self.n)]
    }

    /// One value an element.
    pub fn expand(&self) -> Vec<T> {
        (0..self.n).map(|i| self.at(i)).collect()
    }

    /// One value an element, into `out` (its buffer kept).
    pub fn expand_into(&self, out: &mut Vec<T>) {
        out.clear();
        out.extend((0..self.n).map(|i| self.at(i)));
    }

    /// The one value, when every section has it.
    pub fn uniform(&self) -> Option<T> {
        let first = self.values[0];
        self.values.iter().all(|v| *v == first).then_some(first)
    }

    /// The values, one a section.
    pub fn values(&self) -> &[T] {
        &self.values
    }

    /// The nodes between sections whose values differ, into `out`.
    pub fn breaks(&self, out: &mut Vec<usize>) {
        let m = self.values.len();
        out.extend(
            (1..m)
                .filter(|k| self.values[k - 1] != self.values[*k])
                .map(|k| k * self.n / m),
        );
    }
}

/// The section of element `i` (from 0) of a rod of `n` elements in
/// `sections` sections (each cut into the same number of elements).
pub(crate) fn section_of(i: usize, sections: usize, n: usize) -> usize {
    i * sections / n
}

/// `"prefix[i]suffix"` read as `i`, for parameter paths.
pub(crate) fn indexed(name: &str, prefix: &str, suffix: &str) -> Option<usize> {
    name.strip_prefix(prefix)?
        .strip_prefix('[')?
        .strip_suffix(suffix)?
        .strip_suffix(']')?
        .parse()
        .ok()
}

/// The component `c` of a vector parameter `"{key}[c]"` (0..3).
pub(crate) fn component(name: &str, key: &str) -> Option<usize> {
    indexed(name, key, "").filter(|c| *c < 3)
}

/// `"{prefix}[i]{rest}"`: the index and what follows the bracket.
pub(crate) fn split_index<'a>(name: &'a str, prefix: &str) -> Option<(usize, &'a str)> {
    let rest = name.strip_prefix(prefix)?.strip_prefix('[')?;
    let close = rest.find(']')?;
    Some((rest[..close].parse().ok()?, &rest[close + 1..]))
}

/// The interior nodes between elements whose values in `per_element`
/// differ, into `out`.
pub(crate) fn jumps<T: PartialEq>(per_element: &[T], out: &mut Vec<usize>) {
    out.extend(
        per_element
            .windows(2)
            .enumerate()
            .filter(|(_, w)| w[0] != w[1])
            .map(|(i, _)| i + 1),
    );
}

/// A unit vector along axis `c`.
pub(crate) fn unit(c: usize) -> nalgebra::Vector3<f64> {
    nalgebra::Vector3::ith(c, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(json: &str) -> Scene {
        Scene::from_json_str(json).unwrap()
    }

    #[test]
    fn a_force_turns_the_rod_at_the_root_of_its_load_and_a_moment_at_its_curvature() {
        // F = 3 EI / L^2 across the rod turns it at sqrt(F / EI); a tip
        // moment M of 2 EI / L bends it at M / EI; the softer bending axis
        // counts (kx = 0.5), torsion not (kz = 0.1).
        let force = scene(
            r#"{"length": 2.0, "stiffness": {"kx": 0.5, "ky": 1.0, "kz": 0.1}, "tip_force": [0, -0.375, 0]}"#,
        );
        let terms = Terms::new(&force, &force.mesh(4));
        let loads = terms.bending_loads(2.0);
        assert_eq!((loads.force, loads.moment), (0.375, 0.0));
        let turning = terms.turning(2.0);
        assert_eq!((turning.curvature_squared, turning.force), (0.0, 0.75));
        let moment = scene(
            r#"{"length": 1.0, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0}, "tip_moment": [2, 0, 0], "rest_curvature": [[0, 1.5]]}"#,
        );
        let terms = Terms::new(&moment, &moment.mesh(4));
        assert_eq!(terms.bending_loads(1.0).moment, 2.0);
        // With the rest curvature: kappa0^2 + (M / EI)^2.
        assert_eq!(terms.turning(1.0).curvature_squared, 6.25);
        // Gravity: its whole weight, rho g L.
        let hanging = scene(
            r#"{"length": 0.5, "stiffness": {"kx": 1.0, "ky": 1.0, "kz": 1.0}, "gravity": {"linear_density": 2.0, "vector": [0, 0, -10]}}"#,
        );
        let terms = Terms::new(&hanging, &hanging.mesh(4));
        assert!((terms.bending_loads(0.5).force - 10.0).abs() < 1e-12);
    }
}
