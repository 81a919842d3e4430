//! The seed's three trajectories for the default (hanging, 1 m) robot, each of
//! 60 points by default: a pentagram, a circle and a space spiral. Sizes are
//! chosen inside what the default robot reaches with 60 g at the tip.

use super::Robot;
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

/// A trajectory of the default robot placed at another robot: scaled by its
/// length (the default robot is 1 m long) and carried from the default base
/// pose (at the origin, hanging) to its base pose. For the default robot,
/// the points themselves.
pub fn placed(points: &[Vector3<f64>], robot: &Robot) -> Vec<Vector3<f64>> {
    let default = Robot::default();
    let scale = robot.body.length / default.body.length;
    // World from base of the robot, times base from world of the default.
    let turn = robot.body.base_quaternion.normalized() * default.body.base_quaternion.conj();
    points
        .iter()
        .map(|p| robot.body.base_position + turn.rotate((p - default.body.base_position) * scale))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quat::Quat;

    #[test]
    fn a_placed_trajectory_keeps_its_place_relative_to_the_base() {
        let points = circle(8);
        assert_eq!(placed(&points, &Robot::default()), points);
        // A 0.3 m robot pointing up from (0, 0, 1): the circle 0.264 m above it.
        let mut up = Robot::default();
        up.body.length = 0.3;
        up.body.base_quaternion = Quat::IDENTITY;
        up.body.base_position = Vector3::new(0.0, 0.0, 1.0);
        for (p, q) in points.iter().zip(placed(&points, &up)) {
            assert!((q.z - (1.0 + 0.3 * 0.88)).abs() < 1e-12);
            assert!(((q - up.body.base_position).xy().norm() - 0.3 * RADIUS).abs() < 1e-12);
            assert!((p.xy().norm() - RADIUS).abs() < 1e-12);
        }
    }
}
