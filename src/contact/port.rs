//! A sliding port: a point the backbone passes through and slides through,
//! without friction or against Coulomb friction (a trocar, the exit of a
//! guide tube).
//!
//! The port is a point `p` with an axis `a`, the way the rod goes through
//! it. Where the backbone (the polygon of its nodes) crosses the port's
//! plane, `a . (c - p) = 0`, at the point `c` of its chord, the two rows
//! `b_i . (c - p) = 0` (`b_1`, `b_2` the port's frame across the axis) hold
//! it on the axis. Their multipliers `lambda_i` are the port's force in that
//! frame; since `c` slides along the chord as the rod moves, the force that
//! acts on the rod is `P^T sum lambda_i b_i` with `P = I - t a^T / (a . t)`
//! (`t` the chord): across the rod, so it does no work as the rod slides.
//! The crossing is continuous from one element to the next, and so are the
//! multipliers (a fixed frame), which a port's force then keeps.
//!
//! With friction (`solver/friction.rs`) a port also holds the rod along
//! itself while it sticks: the arc length `sigma = sigma_(k-1) + s h_k` of
//! the material in the port is held, a third row, whose gradient is
//! `-(h_k / a . t) a` at the crossing's shares (see [`Port::axial_direction`]).

use crate::error::{Error, Result};
use crate::read::{vec3, Table};
use crate::value::Value;
use nalgebra::Vector3;

/// A port the backbone slides through.
#[derive(Debug, Clone, PartialEq)]
pub struct Port {
    /// The point the backbone passes through [m], world frame.
    pub position: Vector3<f64>,
    /// The unit direction the rod goes through it (base to tip).
    pub axis: Vector3<f64>,
    /// Its Coulomb friction coefficient (`>= 0`; 0: the rod slides freely).
    /// With friction the answer depends on the loading history (see
    /// `solver/friction.rs`).
    pub friction: f64,
}

/// Where the backbone crosses a port's plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossing {
    /// The element (1..=n) whose chord crosses, between nodes `k - 1` and `k`.
    pub element: usize,
    /// The crossing's place along the chord, `0..=1`.
    pub s: f64,
    /// The crossing point [m].
    pub point: Vector3<f64>,
}

impl Port {
    /// A port at `position` with the rod going along `axis` (any length but zero).
    pub fn new(position: Vector3<f64>, axis: Vector3<f64>) -> Port {
        Port {
            position,
            axis: axis.normalize(),
            friction: 0.0,
        }
    }

    /// The same port with Coulomb friction `mu`.
    pub fn with_friction(mut self, mu: f64) -> Port {
        self.friction = mu;
        self
    }

    /// The port's frame across its axis, `(b_1, b_2)`: fixed, so that the
    /// multipliers keep their meaning as the crossing moves along the rod.
    pub fn frame(&self) -> [Vector3<f64>; 2] {
        let a = self.axis;
        // The world axis least along `a`, made orthogonal to it.
        let k = a.iamin();
        let e = Vector3::ith(k, 1.0);
        let b1 = (e - a * a[k]).normalize();
        [b1, a.cross(&b1)]
    }

    /// Where the polygon of nodes `r` crosses the port's plane going along
    /// the axis, nearest the port; `None` where it does not.
    pub fn crossing(&self, r: &[Vector3<f64>]) -> Option<Crossing> {
        let along = |x: &Vector3<f64>| self.axis.dot(&(x - self.position));
        let mut best: Option<(f64, Crossing)> = None;
        let mut before = along(&r[0]);
        for k in 1..r.len() {
            let here = along(&r[k]);
            // Through the plane forwards, the element's end on it counted once.
            if before < 0.0 && here >= 0.0 {
                let s = before / (before - here);
                let point = r[k - 1] + s * (r[k] - r[k - 1]);
                let distance = (point - self.position).norm();
                if best.is_none_or(|(d, _)| distance < d) {
                    best = Some((
                        distance,
                        Crossing {
                            element: k,
                            s,
                            point,
                        },
                    ));
                }
            }
            before = here;
        }
        best.map(|(_, c)| c)
    }

    /// The directions of the forces of the port's two multipliers on the
    /// rod where it crosses along `chord`: `P^T b_i`, across the chord.
    pub fn force_directions(&self, chord: &Vector3<f64>) -> [Vector3<f64>; 2] {
        let along = self.axis.dot(chord);
        self.frame()
            .map(|b| b - self.axis * (chord.dot(&b) / along))
    }

    /// The gradient of the arc length in the port, `sigma = sigma_(k-1) + s
    /// h`, with respect to the crossing's nodes (weighted by their shares
    /// `1 - s`, `s`) for an element of rest length `h` along `chord`:
    /// `-(h / a . t) a`. A multiplier `f` of a row of `sigma` pushes the rod
    /// by `f` times it, whose part along the chord is `-f h / |t|`.
    pub fn axial_direction(&self, chord: &Vector3<f64>, h: f64) -> Vector3<f64> {
        -self.axis * (h / self.axis.dot(chord))
    }

    /// Read a port (`ports[i]`): `position`, `axis` (default: the base's
    /// tangent, `default_axis`) and `friction` (default 0).
    pub fn from_value(v: &Value, path: &str, default_axis: Vector3<f64>) -> Result<Port> {
        let t = Table::new(v, path)?;
        t.only(&["position", "axis", "friction"])?;
        let position = vec3(t.require("position")?, &t.key("position"))?;
        let axis = match t.get("axis") {
            None => default_axis,
            Some(v) => vec3(v, &t.key("axis"))?,
        };
        if axis.norm() == 0.0 {
            return Err(Error::scene(t.key("axis"), "must not be zero"));
        }
        let friction = match t.get("friction") {
            None => 0.0,
            Some(v) => {
                let key = t.key("friction");
                super::check_friction(crate::read::finite(v, &key)?, &key)?
            }
        };
        Ok(Port::new(position, axis).with_friction(friction))
    }

    pub fn to_value(&self) -> Value {
        let point = |v: &Vector3<f64>| Value::List(v.iter().map(|x| Value::Number(*x)).collect());
        let mut entries = vec![
            ("position".into(), point(&self.position)),
            ("axis".into(), point(&self.axis)),
        ];
        if self.friction != 0.0 {
            entries.push(("friction".into(), Value::Number(self.friction)));
        }
        Value::Map(entries)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_frame_is_orthonormal_and_across_the_axis() {
        for axis in [
            Vector3::x(),
            Vector3::new(0.3, -2.0, 0.7),
            Vector3::new(0.0, 0.0, -1.0),
        ] {
            let port = Port::new(Vector3::zeros(), axis);
            let [b1, b2] = port.frame();
            for (x, y) in [(b1, port.axis), (b2, port.axis), (b1, b2)] {
                assert!(x.dot(&y).abs() < 1e-15);
            }
            assert!((b1.norm() - 1.0).abs() < 1e-15 && (b2.norm() - 1.0).abs() < 1e-15);
        }
    }

    #[test]
    fn the_crossing_is_the_chord_through_the_plane_and_its_forces_are_across_it() {
        let port = Port::new(Vector3::new(0.25, 0.0, 0.0), Vector3::x());
        let r: Vec<Vector3<f64>> = (0..=4)
            .map(|k| Vector3::new(0.1 * k as f64, 0.02 * (k * k) as f64, 0.0))
            .collect();
        let c = port.crossing(&r).unwrap();
        assert_eq!(c.element, 3);
        assert!((c.s - 0.5).abs() < 1e-12);
        assert!((c.point.x - 0.25).abs() < 1e-15);
        let chord = r[3] - r[2];
        for d in port.force_directions(&chord) {
            assert!(d.dot(&chord).abs() < 1e-15);
        }
        // A rod that stops short of the plane does not cross it.
        assert!(port.crossing(&r[..3]).is_none());
    }

    #[test]
    fn the_axial_direction_is_the_gradient_of_the_arc_length_in_the_port() {
        // sigma = (k - 1 + s) h: its differences over either node of the
        // crossing chord, against the direction weighted by the node's share.
        let port = Port::new(
            Vector3::new(0.25, 0.01, -0.02),
            Vector3::new(1.0, 0.2, -0.1),
        );
        let h = 0.1;
        let r: Vec<Vector3<f64>> = (0..=4)
            .map(|k| Vector3::new(0.1 * k as f64, 0.02 * (k * k) as f64, -0.01 * k as f64))
            .collect();
        let arc = |r: &[Vector3<f64>]| {
            let c = port.crossing(r).unwrap();
            ((c.element - 1) as f64 + c.s) * h
        };
        let c = port.crossing(&r).unwrap();
        let g = port.axial_direction(&(r[c.element] - r[c.element - 1]), h);
        let step = 1e-7;
        for (node, share) in [(c.element - 1, 1.0 - c.s), (c.element, c.s)] {
            for axis in 0..3 {
                let mut plus = r.clone();
                let mut minus = r.clone();
                plus[node][axis] += step;
                minus[node][axis] -= step;
                let difference = (arc(&plus) - arc(&minus)) / (2.0 * step);
                assert!(
                    (difference - share * g[axis]).abs() < 1e-8,
                    "{difference} {g}"
                );
            }
        }
        // Its part along the chord is -h / |t|.
        let chord = r[c.element] - r[c.element - 1];
        assert!((g.dot(&chord) / chord.norm() + h / chord.norm()).abs() < 1e-14);
    }
}
