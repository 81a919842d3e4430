//! Inputs no rod can mean and inputs merely suspicious. SI units are easy to
//! get wrong by a factor of a thousand (millimetres, grams) or a billion
//! (gigapascals): a diameter of 1.4 meant in millimetres made a rod thicker
//! than long that stayed perfectly straight, an `E` of 210 meant in GPa a rod
//! no solve could bend back. What cannot mean a rod is refused by key with
//! the likely mistake ([`Scene::check_plausible`], part of the scene's
//! checks); what a real rod may still be is a warning the caller shows
//! ([`Scene::warnings`]): soft robots are short and thick, and the warning
//! names the model's limit instead of refusing them.

use super::{Scene, Stiffness};
use crate::error::{Error, Result};

/// Largest load parameter of any load (its curvature scale `kappa L`): past
/// it no double-precision solve resolves the rod (its boundary layers need
/// about a million elements), and it takes a unit off by 1e9 to get there.
pub const MAX_LOAD_PARAMETER: f64 = 1e12;

/// Diameter over length beyond which a round rod is outside the slender-rod
/// (Kirchhoff) model: its error grows like `(d / L)^2` (shear, extension and
/// the cross-section's own deformation are not modelled).
pub const SLENDER_LIMIT: f64 = 0.1;

/// Young's and shear moduli of rod materials [Pa], from soft gels (1 kPa)
/// to diamond (1.2 TPa).
pub const MODULUS_RANGE: (f64, f64) = (1e3, 1.2e12);

/// Largest load parameter of a loaded rod that round-off would swallow:
/// loads this small move it by less than double precision resolves.
pub const ROUNDOFF_LOAD: f64 = 1e-12;

/// A tendon farther from the backbone than this fraction of the rod's
/// length is suspicious (robots route them within a few percent).
pub const TENDON_OFFSET_WARNING: f64 = 0.25;

/// A round rod of the scene: its key, moduli [Pa], diameter and length [m].
struct RoundRod {
    key: String,
    e: f64,
    g: f64,
    diameter: f64,
    length: f64,
}

impl Scene {
    /// The round rods the scene's stiffness comes from: the rod's and each
    /// section's own (with that section's length).
    fn round_rods(&self) -> Vec<RoundRod> {
        let m = self.sections.len().max(1) as f64;
        let of = |key: String, spec: &Stiffness, length: f64| match *spec {
            Stiffness::RoundRod { e, g, diameter } => Some(RoundRod {
                key,
                e,
                g,
                diameter,
                length,
            }),
            Stiffness::Diagonal { .. } => None,
        };
        let own = self.sections.iter().enumerate().filter_map(|(i, p)| {
            let length = p.length.unwrap_or(self.length / m);
            of(
                format!("sections[{i}].stiffness"),
                p.stiffness.as_ref()?,
                length,
            )
        });
        of("stiffness".into(), &self.stiffness_spec, self.length)
            .into_iter()
            .chain(own)
            .collect()
    }

    /// Refuse what no rod can mean, naming the key and the likely unit
    /// mistake: a round rod thicker than it is long, a tendon as far from
    /// the backbone as the rod is long (loads beyond any solve are refused
    /// with the loads, see `check_load`).
    pub(super) fn check_plausible(&self) -> Result<()> {
        for rod in self.round_rods() {
            if rod.diameter > rod.length {
                return Err(Error::scene(
                    format!("{}.diameter", rod.key),
                    format!(
                        "{} m is more than the length it stiffens ({} m): no rod is thicker \
                         than it is long (millimetres meant? SI units: m)",
                        rod.diameter, rod.length
                    ),
                ));
            }
        }
        for (i, t) in self.tendons.iter().enumerate() {
            let offset = t.largest_offset();
            if offset >= self.length {
                return Err(Error::scene(
                    format!("tendons[{i}].offset"),
                    format!(
                        "{offset} m from the backbone is as far as the rod is long ({} m): no \
                         tendon runs there (millimetres meant? SI units: m)",
                        self.length
                    ),
                ));
            }
        }
        Ok(())
    }

    /// What a real rod may be but is more likely a unit mistake, or outside
    /// what the model is good for: one message each, naming the key, the
    /// value and the limit. A caller shows them (Python: `UserWarning`).
    pub fn warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        let (lo, hi) = MODULUS_RANGE;
        for rod in self.round_rods() {
            for (name, modulus) in [("E", rod.e), ("G", rod.g)] {
                if !(lo..=hi).contains(&modulus) {
                    let hint = if modulus < lo {
                        "GPa or MPa meant?"
                    } else {
                        "a factor of a thousand too many?"
                    };
                    out.push(format!(
                        "{}.{name} = {modulus:e} Pa is outside the moduli of rod materials \
                         ({lo:e} Pa for soft gels to {hi:e} Pa for diamond): {hint} (SI units: Pa)",
                        rod.key
                    ));
                }
            }
            let ratio = rod.diameter / rod.length;
            if ratio > SLENDER_LIMIT {
                out.push(format!(
                    "{}.diameter = {} m is {ratio:.2} of the length it stiffens ({} m): the \
                     slender-rod model (no shear, extension or cross-section deformation) is \
                     good for diameters below {SLENDER_LIMIT} of the length, its error growing \
                     like (d / L)^2",
                    rod.key, rod.diameter, rod.length
                ));
            }
        }
        for (i, t) in self.tendons.iter().enumerate() {
            let offset = t.largest_offset();
            if offset > TENDON_OFFSET_WARNING * self.length {
                out.push(format!(
                    "tendons[{i}].offset = {offset} m is {:.2} of the rod's length {} m from \
                     the backbone (millimetres meant? SI units: m)",
                    offset / self.length,
                    self.length
                ));
            }
        }
        if self.contact_radius() == 0.0 {
            if let Some(i) = self.obstacles.iter().position(|o| o.has_edges()) {
                out.push(format!(
                    "obstacles[{i}] ({}) has sharp edges and the rod no radius: where the \
                     backbone meets an edge its contact normal is not unique and the solve may \
                     not converge; give the rod its radius (\"radius\", or a round rod's \
                     \"diameter\")",
                    self.obstacles[i].shape()
                ));
            }
        }
        let loads = self.load_parameters();
        let (key, what, largest) = loads.iter().fold(
            (super::LoadKey::Named(""), "", 0.0),
            |best, (key, what, value)| {
                if *value > best.2 {
                    (*key, *what, *value)
                } else {
                    best
                }
            },
        );
        if largest > 0.0 && largest < ROUNDOFF_LOAD {
            out.push(format!(
                "{key}: the largest load parameter, {what} = {largest:.1e}, moves the rod by \
                 less than round-off (below {ROUNDOFF_LOAD:e}): check the units (SI: Pa, m, \
                 kg, N; a modulus or a load off by a factor 1e9 leaves the rod unmoved)"
            ));
        }
        out
    }
}
