//! The seed's three trajectories for the default (hanging, 1 m) robot, each of
//! 60 points by default: a pentagram, a circle and a space spiral. Sizes are
//! chosen inside what the default robot reaches with 60 g at the tip.

use nalgebra::Vector3;
use std::f64::consts::PI;

/// Height of the planar trajectories' plane below the base [m].
const PLANE_Z: f64 = -0.88;
const RADIUS: f64 = 0.22;

/// A circle of radius 0.22 m in the plane z = -0.88 m, centred on the base axis.
pub fn circle(points: usize) -> Vec<Vector3<f64>> {
    (0..points)
        .map(|i| {
            let t = 2.0 * PI * i as f64 / points as f64;
            Vector3::new(RADIUS * t.cos(), RADIUS * t.sin(), PLANE_Z)
        })
        .collect()
}

/// A five-pointed star {5/2} inscribed in the circle, walked edge by edge.
pub fn pentagram(points: usize) -> Vec<Vector3<f64>> {
    let vertex = |k: usize| {
        let t = PI / 2.0 + 2.0 * PI * (2 * k % 5) as f64 / 5.0;
        Vector3::new(RADIUS * t.cos(), RADIUS * t.sin(), PLANE_Z)
    };
    (0..points)
        .map(|i| {
            let u = 5.0 * i as f64 / points as f64;
            let edge = u.floor() as usize;
            let f = u - edge as f64;
            vertex(edge) * (1.0 - f) + vertex(edge + 1) * f
        })
        .collect()
}

/// A space spiral: two turns, radius 0.08 to 0.22 m, rising from z = -0.93 to -0.83 m.
pub fn spiral(points: usize) -> Vec<Vector3<f64>> {
    (0..points)
        .map(|i| {
            let u = i as f64 / (points.max(2) - 1) as f64;
            let t = 4.0 * PI * u;
            let r = 0.08 + (RADIUS - 0.08) * u;
            Vector3::new(r * t.cos(), r * t.sin(), -0.93 + 0.10 * u)
        })
        .collect()
}

/// A trajectory by name: "pentagram", "circle" or "spiral".
pub fn by_name(name: &str, points: usize) -> Option<Vec<Vector3<f64>>> {
    match name {
        "pentagram" => Some(pentagram(points)),
        "circle" => Some(circle(points)),
        "spiral" => Some(spiral(points)),
        _ => None,
    }
}
