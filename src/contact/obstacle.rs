//! Obstacle shapes, their signed gaps and normals, and their value-tree form
//! (`{shape = "sphere", centre = [...], radius = ...}`).

use super::mesh_file;
use super::triangle_mesh::TriangleMesh;
use crate::error::{Error, Result};
use crate::quat::Quat;
use crate::read::{finite, string, vec3, Table};
use crate::value::Value;
use nalgebra::{Matrix3, Vector3};

/// A rigid obstacle, world frame [m].
#[derive(Debug, Clone, PartialEq)]
pub enum Obstacle {
    /// Everything behind the plane through `point` with unit `normal`
    /// (which points into free space): a floor, a wall.
    HalfSpace {
        point: Vector3<f64>,
        normal: Vector3<f64>,
    },
    /// A solid ball.
    Sphere { centre: Vector3<f64>, radius: f64 },
    /// The points within `radius` of the segment from `a` to `b`.
    Capsule {
        a: Vector3<f64>,
        b: Vector3<f64>,
        radius: f64,
    },
    /// A solid circular cylinder with flat ends at `a` and `b`.
    Cylinder {
        a: Vector3<f64>,
        b: Vector3<f64>,
        radius: f64,
    },
    /// A solid box: `half_extents` along the axes of `orientation` about
    /// `centre`.
    Box {
        centre: Vector3<f64>,
        half_extents: Vector3<f64>,
        orientation: Quat,
    },
    /// A channel the rod runs inside (a vessel, a guide tube): the points
    /// within `radius` of its centreline, the smooth curve through the
    /// points `centreline` (a Catmull-Rom spline: each piece a cubic between
    /// two points, tangent to the chord of its neighbours, so the wall has
    /// no crease at the points), the radius one for all or one a point
    /// (linear along each piece). Free space is inside; the gap is
    /// `radius(t) - |p - c(t)|` at the nearest point `c(t)` of the
    /// centreline (a true distance where the radius is constant); its ends
    /// are closed by half-spheres.
    Lumen {
        centreline: Vec<Vector3<f64>>,
        radius: Vec<f64>,
    },
    /// A triangle mesh (anatomy from an STL or OBJ file, a fixture): the
    /// solid its outward-wound triangles enclose, or, with
    /// `free = "inside"`, the space outside it (the rod runs inside). The
    /// gap is the signed distance from the surface, so the rod's surface,
    /// `radius` off it, rounds its edges and corners.
    Mesh(TriangleMesh),
}

/// Where a point stands with respect to an obstacle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Proximity {
    /// Signed gap from the surface [m]: positive in free space.
    pub gap: f64,
    /// The gap's gradient, a unit vector into free space (the gradient's
    /// direction for a lumen of varying radius): the direction of a
    /// contact force on the rod.
    pub normal: Vector3<f64>,
}

impl Proximity {
    /// The surface point nearest `p` (exact where the gap is a distance).
    pub fn surface_point(&self, p: &Vector3<f64>) -> Vector3<f64> {
        p - self.gap * self.normal
    }
}

/// A unit vector along `v`, or `fallback` where `v` has no direction (a
/// point on an axis or at a centre, where the gap's gradient is not unique).
fn unit_or(v: Vector3<f64>, fallback: Vector3<f64>) -> Vector3<f64> {
    let norm = v.norm();
    if norm > 0.0 {
        v / norm
    } else {
        fallback
    }
}

/// A unit vector perpendicular to unit `t`.
fn perpendicular(t: &Vector3<f64>) -> Vector3<f64> {
    let other = if t.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    t.cross(&other).normalize()
}

/// The parameter in `[0, 1]` of the point of segment `a`-`b` nearest `p`.
fn segment_parameter(p: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    let ab = b - a;
    let length_squared = ab.norm_squared();
    if length_squared == 0.0 {
        0.0
    } else {
        ((p - a).dot(&ab) / length_squared).clamp(0.0, 1.0)
    }
}

impl Obstacle {
    /// The signed gap of `p` and its normal (see [`Proximity`]).
    pub fn proximity(&self, p: &Vector3<f64>) -> Proximity {
        match self {
            Obstacle::HalfSpace { point, normal } => Proximity {
                gap: (p - point).dot(normal),
                normal: *normal,
            },
            Obstacle::Sphere { centre, radius } => {
                let d = p - centre;
                Proximity {
                    gap: d.norm() - radius,
                    normal: unit_or(d, Vector3::z()),
                }
            }
            Obstacle::Capsule { a, b, radius } => {
                let c = a + segment_parameter(p, a, b) * (b - a);
                let d = p - c;
                let axis = unit_or(b - a, Vector3::z());
                Proximity {
                    gap: d.norm() - radius,
                    normal: unit_or(d, perpendicular(&axis)),
                }
            }
            Obstacle::Cylinder { a, b, radius } => cylinder(p, a, b, *radius),
            Obstacle::Box {
                centre,
                half_extents,
                orientation,
            } => {
                let local = orientation.inverse_rotate(p - centre);
                let (gap, normal) = box_gap(&local, half_extents);
                Proximity {
                    gap,
                    normal: orientation.rotate(normal),
                }
            }
            Obstacle::Lumen { centreline, radius } => lumen(p, centreline, radius),
            Obstacle::Mesh(mesh) => mesh.proximity(p),
        }
    }

    /// The derivative of the normal field at `p`, `dnu/dp` (the Hessian of
    /// the gap where it is a distance): in closed form for a plane, a sphere
    /// and a capsule, by central differences of step `step` [m] for the
    /// others. It turns a contact force with the surface it leans on (see
    /// `solver::contact::curvature`).
    pub fn normal_jacobian(&self, p: &Vector3<f64>, step: f64) -> Matrix3<f64> {
        // A sphere about `c` (a capsule's nearest axis point) seen from `p`,
        // with the directions `along` in which the normal does not turn.
        let round = |c: Vector3<f64>, along: Option<Vector3<f64>>| {
            let d = p - c;
            let distance = d.norm();
            if distance == 0.0 {
                return Matrix3::zeros();
            }
            let nu = d / distance;
            let mut flat = Matrix3::identity() - nu * nu.transpose();
            if let Some(t) = along {
                flat -= t * t.transpose();
            }
            flat / distance
        };
        match self {
            Obstacle::HalfSpace { .. } => Matrix3::zeros(),
            Obstacle::Sphere { centre, .. } => round(*centre, None),
            Obstacle::Capsule { a, b, .. } => {
                let t = segment_parameter(p, a, b);
                let axis = (b - a).try_normalize(0.0);
                let inside = t > 0.0 && t < 1.0;
                round(a + t * (b - a), axis.filter(|_| inside))
            }
            _ => {
                let mut jacobian = Matrix3::zeros();
                for axis in 0..3 {
                    let mut e = Vector3::zeros();
                    e[axis] = step;
                    let turn = self.proximity(&(p + e)).normal - self.proximity(&(p - e)).normal;
                    jacobian.set_column(axis, &(turn / (2.0 * step)));
                }
                jacobian
            }
        }
    }

    /// Whether its surface has sharp edges or corners (a box's, a finite
    /// cylinder's rims, a mesh's), where the gap of a point on them has no
    /// unique gradient: a rod of no radius touching one has no unique
    /// contact normal.
    pub fn has_edges(&self) -> bool {
        matches!(
            self,
            Obstacle::Box { .. } | Obstacle::Cylinder { .. } | Obstacle::Mesh(_)
        )
    }

    /// The shape's name in its value tree.
    pub fn shape(&self) -> &'static str {
        match self {
            Obstacle::HalfSpace { .. } => "half_space",
            Obstacle::Sphere { .. } => "sphere",
            Obstacle::Capsule { .. } => "capsule",
            Obstacle::Cylinder { .. } => "cylinder",
            Obstacle::Box { .. } => "box",
            Obstacle::Lumen { .. } => "lumen",
            Obstacle::Mesh(_) => "mesh",
        }
    }
}

/// A finite cylinder's gap: in its frame (axis `t` from the middle, radial
/// distance `rho`), outside the length of `(rho - R, |z| - h)` clipped at
/// zero, inside the larger of the two (the nearer face).
fn cylinder(p: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>, radius: f64) -> Proximity {
    let axis = b - a;
    let half = 0.5 * axis.norm();
    let t = unit_or(axis, Vector3::z());
    let d = p - 0.5 * (a + b);
    let z = d.dot(&t);
    let radial = d - z * t;
    let rho = radial.norm();
    let e = unit_or(radial, perpendicular(&t));
    let (dr, dz) = (rho - radius, z.abs() - half);
    let along = t * z.signum();
    if dr > 0.0 || dz > 0.0 {
        let (r, zz) = (dr.max(0.0), dz.max(0.0));
        let gap = r.hypot(zz);
        Proximity {
            gap,
            normal: (r * e + zz * along) / gap,
        }
    } else if dr >= dz {
        Proximity { gap: dr, normal: e }
    } else {
        Proximity {
            gap: dz,
            normal: along,
        }
    }
}

/// A box's gap in its own frame: outside the length of the excess over the
/// half extents, inside the largest (negative) one, along its axis.
fn box_gap(local: &Vector3<f64>, half: &Vector3<f64>) -> (f64, Vector3<f64>) {
    let excess = local.abs() - half;
    let sign = local.map(|x| if x < 0.0 { -1.0 } else { 1.0 });
    let outside = excess.map(|x| x.max(0.0));
    let gap = outside.norm();
    if gap > 0.0 {
        return (gap, outside.component_mul(&sign) / gap);
    }
    let k = excess.imax();
    let mut normal = Vector3::zeros();
    normal[k] = sign[k];
    (excess[k], normal)
}

/// The Catmull-Rom centreline through `points` at the global parameter
/// `t` in `[0, pieces]` (piece `i` from point `i` to `i + 1`): its point and
/// first and second derivatives in `t`. End tangents one-sided.
fn spline(points: &[Vector3<f64>], t: f64) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
    let pieces = points.len() - 1;
    let i = (t.floor() as usize).min(pieces - 1);
    let u = t - i as f64;
    let tangent = |k: usize| -> Vector3<f64> {
        match k {
            0 => points[1] - points[0],
            k if k == pieces => points[pieces] - points[pieces - 1],
            k => 0.5 * (points[k + 1] - points[k - 1]),
        }
    };
    let (p0, p1, m0, m1) = (points[i], points[i + 1], tangent(i), tangent(i + 1));
    let (u2, u3) = (u * u, u * u * u);
    let point = (2.0 * u3 - 3.0 * u2 + 1.0) * p0
        + (u3 - 2.0 * u2 + u) * m0
        + (-2.0 * u3 + 3.0 * u2) * p1
        + (u3 - u2) * m1;
    let first = (6.0 * u2 - 6.0 * u) * p0
        + (3.0 * u2 - 4.0 * u + 1.0) * m0
        + (-6.0 * u2 + 6.0 * u) * p1
        + (3.0 * u2 - 2.0 * u) * m1;
    let second = (12.0 * u - 6.0) * p0
        + (6.0 * u - 4.0) * m0
        + (-12.0 * u + 6.0) * p1
        + (6.0 * u - 2.0) * m1;
    (point, first, second)
}

/// Newton steps for a lumen's nearest centreline point.
const NEAREST_STEPS: usize = 30;

/// A lumen's gap at the nearest point of its centreline (see
/// [`Obstacle::Lumen`]): from the nearest point of the polyline through its
/// points, Newton on `(c(t) - p) . c'(t) = 0` (clamped to the ends). The
/// gradient of the gap is `-u + r'(t) grad t`, `u` the unit vector from
/// `c(t)` to `p` and `grad t = c' / (|c'|^2 - (p - c) . c'')`.
fn lumen(p: &Vector3<f64>, centreline: &[Vector3<f64>], radius: &[f64]) -> Proximity {
    let radius_at = |i: usize| radius[if radius.len() == 1 { 0 } else { i }];
    let pieces = centreline.len() - 1;
    let mut best: Option<(f64, usize, f64)> = None;
    for (i, w) in centreline.windows(2).enumerate() {
        let s = segment_parameter(p, &w[0], &w[1]);
        let distance = (p - (w[0] + s * (w[1] - w[0]))).norm();
        if best.is_none_or(|(d, _, _)| distance < d) {
            best = Some((distance, i, s));
        }
    }
    let (_, i, s) = best.expect("a lumen has a segment (checked when read)");
    let mut t = i as f64 + s;
    for _ in 0..NEAREST_STEPS {
        let (c, d1, d2) = spline(centreline, t);
        let f = (c - p).dot(&d1);
        let slope = d1.norm_squared() + (c - p).dot(&d2);
        let step = if slope > 0.0 {
            -f / slope
        } else {
            -f.signum() * 0.25
        };
        let next = (t + step.clamp(-0.5, 0.5)).clamp(0.0, pieces as f64);
        let done = (next - t).abs() <= 1e-15 * (1.0 + t.abs());
        t = next;
        if done {
            break;
        }
    }
    let (c, d1, d2) = spline(centreline, t);
    let k = (t.floor() as usize).min(pieces - 1);
    let u = t - k as f64;
    let (ra, rb) = (radius_at(k), radius_at(k + 1));
    let r = ra + u * (rb - ra);
    let offset = p - c;
    let distance = offset.norm();
    let axis = unit_or(d1, Vector3::z());
    let away = unit_or(offset, perpendicular(&axis));
    // The radius's change moves the gap along the centreline only inside.
    let inside = t > 0.0 && t < pieces as f64;
    let slope = d1.norm_squared() - offset.dot(&d2);
    let radius_gradient = if inside && slope > 0.0 {
        (rb - ra) * d1 / slope
    } else {
        Vector3::zeros()
    };
    Proximity {
        gap: r - distance,
        normal: unit_or(radius_gradient - away, -away),
    }
}

/// The keys of each shape.
const SHAPES: [(&str, &[&str]); 7] = [
    ("half_space", &["point", "normal"]),
    ("sphere", &["centre", "radius"]),
    ("capsule", &["a", "b", "radius"]),
    ("cylinder", &["a", "b", "radius"]),
    ("box", &["centre", "half_extents", "orientation"]),
    ("lumen", &["centreline", "radius"]),
    (
        "mesh",
        &[
            "file",
            "vertices",
            "triangles",
            "scale",
            "position",
            "orientation",
            "free",
        ],
    ),
];

fn positive(key: &str, x: f64) -> Result<f64> {
    if x > 0.0 {
        Ok(x)
    } else {
        Err(Error::scene(key, format!("must be positive, got {x}")))
    }
}

impl Obstacle {
    /// Read `{shape = ..., ...}` at `path` (`obstacles[2]`): each shape's
    /// keys as [`Obstacle`]'s fields (`orientation` of a box optional, as
    /// `[w, x, y, z]`), lengths positive, a half-space's normal non-zero
    /// (made unit), a lumen of at least two points with one radius or one a
    /// point.
    pub fn from_value(v: &Value, path: &str) -> Result<Obstacle> {
        let t = Table::new(v, path)?;
        let shape = string(t.require("shape")?, &t.key("shape"))?;
        let Some((_, keys)) = SHAPES.iter().find(|(name, _)| *name == shape) else {
            let names: Vec<&str> = SHAPES.iter().map(|(name, _)| *name).collect();
            return Err(Error::scene(
                t.key("shape"),
                format!(
                    "unknown shape {shape:?} (expected one of: {})",
                    names.join(", ")
                ),
            ));
        };
        // `friction` is the scene's (`scene::obstacle_friction`).
        let allowed: Vec<&str> = ["shape", "friction"]
            .into_iter()
            .chain(keys.iter().copied())
            .collect();
        t.only(&allowed)?;
        let point = |k: &str| vec3(t.require(k)?, &t.key(k));
        let length = |k: &str| positive(&t.key(k), finite(t.require(k)?, &t.key(k))?);
        Ok(match shape {
            "half_space" => {
                let normal = point("normal")?;
                let norm = normal.norm();
                if norm == 0.0 {
                    return Err(Error::scene(t.key("normal"), "must not be zero"));
                }
                Obstacle::HalfSpace {
                    point: point("point")?,
                    // A unit normal as written back is kept to the last bit.
                    normal: if (norm - 1.0).abs() <= 4.0 * f64::EPSILON {
                        normal
                    } else {
                        normal / norm
                    },
                }
            }
            "sphere" => Obstacle::Sphere {
                centre: point("centre")?,
                radius: length("radius")?,
            },
            "capsule" | "cylinder" => {
                let (a, b, radius) = (point("a")?, point("b")?, length("radius")?);
                if shape == "cylinder" && a == b {
                    return Err(Error::scene(
                        t.key("b"),
                        "must differ from a (the cylinder's axis)",
                    ));
                }
                match shape {
                    "capsule" => Obstacle::Capsule { a, b, radius },
                    _ => Obstacle::Cylinder { a, b, radius },
                }
            }
            "box" => {
                let half_extents = point("half_extents")?;
                for c in 0..3 {
                    positive(&format!("{}[{c}]", t.key("half_extents")), half_extents[c])?;
                }
                Obstacle::Box {
                    centre: point("centre")?,
                    half_extents,
                    orientation: match t.get("orientation") {
                        Some(q) => crate::read::orientation(q, &t.key("orientation"))?,
                        None => Quat::IDENTITY,
                    },
                }
            }
            "mesh" => mesh(&t)?,
            _ => {
                let key = t.key("centreline");
                let centreline = match t.require("centreline")? {
                    v @ Value::List(items) if items.len() >= 2 => points(v, &key)?,
                    _ => {
                        return Err(Error::scene(
                            key,
                            "expected a list of at least two [x, y, z] points",
                        ))
                    }
                };
                let radius_key = t.key("radius");
                let radius: Vec<f64> = match t.require("radius")? {
                    Value::List(items) if items.len() == centreline.len() => items
                        .iter()
                        .enumerate()
                        .map(|(i, x)| {
                            let k = format!("{radius_key}[{i}]");
                            positive(&k, finite(x, &k)?)
                        })
                        .collect::<Result<_>>()?,
                    Value::List(items) => {
                        return Err(Error::scene(
                            radius_key,
                            format!(
                                "expected one radius or one a centreline point ({}), got {}",
                                centreline.len(),
                                items.len()
                            ),
                        ))
                    }
                    x => vec![positive(&radius_key, finite(x, &radius_key)?)?],
                };
                Obstacle::Lumen { centreline, radius }
            }
        })
    }

    /// The obstacle as a value tree (`Obstacle::from_value` of it is the same).
    pub fn to_value(&self) -> Value {
        let num = Value::Number;
        let list = |xs: &[f64]| Value::List(xs.iter().map(|x| num(*x)).collect());
        let point = |v: &Vector3<f64>| list(v.as_slice());
        let mut entries = vec![("shape".to_string(), Value::String(self.shape().into()))];
        let mut add = |k: &str, v: Value| entries.push((k.to_string(), v));
        match self {
            Obstacle::HalfSpace { point: p, normal } => {
                add("point", point(p));
                add("normal", point(normal));
            }
            Obstacle::Sphere { centre, radius } => {
                add("centre", point(centre));
                add("radius", num(*radius));
            }
            Obstacle::Capsule { a, b, radius } | Obstacle::Cylinder { a, b, radius } => {
                add("a", point(a));
                add("b", point(b));
                add("radius", num(*radius));
            }
            Obstacle::Box {
                centre,
                half_extents,
                orientation,
            } => {
                add("centre", point(centre));
                add("half_extents", point(half_extents));
                add("orientation", list(&orientation.to_array()));
            }
            Obstacle::Lumen { centreline, radius } => {
                add(
                    "centreline",
                    Value::List(centreline.iter().map(point).collect()),
                );
                add(
                    "radius",
                    match radius.as_slice() {
                        [one] => num(*one),
                        many => list(many),
                    },
                );
            }
            Obstacle::Mesh(mesh) => {
                add(
                    "vertices",
                    Value::List(mesh.vertices().iter().map(point).collect()),
                );
                let index = |i: &u32| num(f64::from(*i));
                add(
                    "triangles",
                    Value::List(
                        mesh.triangles()
                            .iter()
                            .map(|t| Value::List(t.iter().map(index).collect()))
                            .collect(),
                    ),
                );
                if mesh.free_inside() {
                    add("free", Value::String("inside".into()));
                }
            }
        }
        Value::Map(entries)
    }
}

/// A mesh's entry: its triangles from `file` (an STL or OBJ path, relative
/// to the working directory, or to a scene file's folder) or from `vertices` and `triangles` (indices
/// from 0), placed in the world as `position + orientation * (scale * v)`
/// (`scale` 0.001 for a file in millimetres), the free side `"outside"`
/// (the default) or `"inside"`.
fn mesh(t: &Table) -> Result<Obstacle> {
    let (vertices, triangles) = match (t.get("file"), t.get("vertices"), t.get("triangles")) {
        (Some(file), None, None) => {
            let path = string(file, &t.key("file"))?;
            mesh_file::read(std::path::Path::new(path))
                .map_err(|reason| Error::scene(t.key("file"), format!("{path:?} {reason}")))?
        }
        (None, Some(vertices), Some(triangles)) => (
            points(vertices, &t.key("vertices"))?,
            indices(triangles, &t.key("triangles"))?,
        ),
        (Some(_), _, _) => {
            return Err(Error::scene(
                t.key("file"),
                "give a file or vertices and triangles, not both",
            ))
        }
        (None, None, _) => {
            return Err(Error::scene(
                t.key("file"),
                "missing (or vertices and triangles)",
            ))
        }
        (None, Some(_), None) => return Err(Error::scene(t.key("triangles"), "missing")),
    };
    let scale = match t.get("scale") {
        Some(s) => positive(&t.key("scale"), finite(s, &t.key("scale"))?)?,
        None => 1.0,
    };
    let position = match t.get("position") {
        Some(p) => vec3(p, &t.key("position"))?,
        None => Vector3::zeros(),
    };
    let orientation = match t.get("orientation") {
        Some(q) => crate::read::orientation(q, &t.key("orientation"))?,
        None => Quat::IDENTITY,
    };
    let free_inside = match t.get("free") {
        None => false,
        Some(v) => match string(v, &t.key("free"))? {
            "outside" => false,
            "inside" => true,
            other => {
                return Err(Error::scene(
                    t.key("free"),
                    format!("expected \"outside\" or \"inside\", got {other:?}"),
                ))
            }
        },
    };
    // Placed only when asked, so that a mesh written back reads the same.
    let placed: Vec<Vector3<f64>> =
        if scale == 1.0 && position == Vector3::zeros() && orientation == Quat::IDENTITY {
            vertices
        } else {
            vertices
                .iter()
                .map(|v| position + orientation.rotate(scale * v))
                .collect()
        };
    let key = match t.get("file") {
        Some(_) => t.key("file"),
        None => t.key("triangles"),
    };
    TriangleMesh::new(&placed, &triangles, free_inside)
        .map(Obstacle::Mesh)
        .map_err(|e| Error::scene(key, e.to_string()))
}

/// Make each mesh's relative `file` in the `obstacles` of a scene or robot
/// read from a file relative to that file's folder `dir` (where a user
/// keeps the meshes a scene file names), not to the working directory.
pub(crate) fn files_beside(value: &mut Value, dir: &std::path::Path) {
    let Value::Map(entries) = value else { return };
    let Some((_, Value::List(obstacles))) = entries.iter_mut().find(|(k, _)| k == "obstacles")
    else {
        return;
    };
    for obstacle in obstacles {
        let Value::Map(keys) = obstacle else { continue };
        let is_mesh = keys
            .iter()
            .any(|(k, v)| k == "shape" && *v == Value::String("mesh".into()));
        for (k, v) in keys.iter_mut() {
            if let (true, "file", Value::String(file)) = (is_mesh, k.as_str(), &mut *v) {
                if std::path::Path::new(file.as_str()).is_relative() {
                    *file = dir.join(&*file).to_string_lossy().into_owned();
                }
            }
        }
    }
}

/// A list of `[x, y, z]` points at `key`.
fn points(v: &Value, key: &str) -> Result<Vec<Vector3<f64>>> {
    match v {
        Value::List(items) => items
            .iter()
            .enumerate()
            .map(|(i, x)| vec3(x, &format!("{key}[{i}]")))
            .collect(),
        other => Err(Error::scene(
            key,
            format!("expected a list of [x, y, z] points, got {}", other.kind()),
        )),
    }
}

/// A list of `[i, j, k]` vertex indices at `key`.
fn indices(v: &Value, key: &str) -> Result<Vec<[u32; 3]>> {
    let Value::List(items) = v else {
        return Err(Error::scene(
            key,
            format!(
                "expected a list of [i, j, k] vertex indices, got {}",
                v.kind()
            ),
        ));
    };
    items
        .iter()
        .enumerate()
        .map(|(t, x)| {
            let k = format!("{key}[{t}]");
            let [a, b, c] = crate::read::numbers::<3>(x, &k)?;
            let mut out = [0u32; 3];
            for (o, (i, value)) in out.iter_mut().zip([a, b, c].into_iter().enumerate()) {
                *o = crate::read::whole(
                    &Value::Number(value),
                    &format!("{k}[{i}]"),
                    f64::from(u32::MAX),
                )? as u32;
            }
            Ok(out)
        })
        .collect()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// One of each shape.
    pub(crate) fn shapes() -> Vec<Obstacle> {
        let text = r#"[
            {"shape": "half_space", "point": [0, 0, -0.5], "normal": [0, 0.3, 1]},
            {"shape": "sphere", "centre": [0.2, 0.1, -0.3], "radius": 0.15},
            {"shape": "capsule", "a": [0, 0, 0], "b": [0.3, 0.1, -0.2], "radius": 0.05},
            {"shape": "cylinder", "a": [0.1, 0, 0], "b": [0.1, 0.2, -0.1], "radius": 0.08},
            {"shape": "box", "centre": [0, 0.1, 0], "half_extents": [0.1, 0.05, 0.2],
             "orientation": [0.9238795, 0.3826834, 0, 0]},
            {"shape": "lumen", "centreline": [[0, 0, 0], [0, 0, -0.3], [0.1, 0, -0.5]],
             "radius": [0.02, 0.025, 0.015]},
            {"shape": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
             "triangles": [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
             "scale": 0.3, "position": [-0.1, 0, -0.3],
             "orientation": [0.9238795, 0, 0.3826834, 0]}
        ]"#;
        match Value::from_json_str(text).unwrap() {
            Value::List(items) => items
                .iter()
                .enumerate()
                .map(|(i, v)| Obstacle::from_value(v, &format!("obstacles[{i}]")).unwrap())
                .collect(),
            _ => unreachable!(),
        }
    }

    /// Points spread around the shapes (a fixed generator).
    pub(crate) fn points() -> Vec<Vector3<f64>> {
        let mut state = 12345u64;
        let mut uniform = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        (0..400)
            .map(|_| Vector3::new(uniform(), uniform(), uniform() - 0.2))
            .collect()
    }

    #[test]
    fn the_normal_is_the_gaps_gradient() {
        // Central differences of the gap against its normal, away from where
        // the gradient jumps (the difference then straddles two faces).
        let h = 1e-7;
        for shape in shapes() {
            let mut checked = 0;
            for p in points() {
                let at = shape.proximity(&p);
                let gradient = Vector3::from_fn(|c, _| {
                    let d = Vector3::ith(c, h);
                    (shape.proximity(&(p + d)).gap - shape.proximity(&(p - d)).gap) / (2.0 * h)
                });
                let smooth = (0..3).all(|c| {
                    let d = Vector3::ith(c, 1e-4);
                    (shape.proximity(&(p + d)).normal - at.normal).norm() < 1e-2
                        && (shape.proximity(&(p - d)).normal - at.normal).norm() < 1e-2
                });
                if smooth {
                    // The lumen of varying radius: the normal is the
                    // gradient's direction (its gap is no distance).
                    let direction = match shape {
                        Obstacle::Lumen { .. } => gradient.normalize(),
                        _ => gradient,
                    };
                    assert!(
                        (direction - at.normal).norm() < 1e-6,
                        "{}: at {p}, gradient {gradient} against normal {}",
                        shape.shape(),
                        at.normal
                    );
                    checked += 1;
                }
            }
            assert!(checked > 300, "{}: {checked} smooth points", shape.shape());
        }
    }

    #[test]
    fn the_normals_closed_form_derivative_is_its_difference() {
        // A plane's, a sphere's and a capsule's `normal_jacobian` in closed
        // form against central differences of the normal (the others' are
        // those differences).
        let h = 1e-6;
        for shape in shapes().into_iter().take(3) {
            for p in points() {
                let exact = shape.normal_jacobian(&p, h);
                let differenced = Matrix3::from_fn(|r, c| {
                    let d = Vector3::ith(c, h);
                    (shape.proximity(&(p + d)).normal[r] - shape.proximity(&(p - d)).normal[r])
                        / (2.0 * h)
                });
                let scale = 1.0 + differenced.norm();
                assert!(
                    (exact - differenced).norm() < 1e-6 * scale,
                    "{}: at {p}, {exact} against {differenced}",
                    shape.shape()
                );
            }
        }
    }

    #[test]
    fn a_lumens_wall_has_no_crease_at_its_points() {
        // A right-angled bend through three points: inside the bend, where
        // the distance to the polyline has a crease on the bisector, the
        // spline's normal turns smoothly (and the gap stays a distance).
        let lumen = Obstacle::Lumen {
            centreline: vec![
                Vector3::zeros(),
                Vector3::new(1.0, 0.0, 0.0),
                Vector3::new(1.0, 1.0, 0.0),
            ],
            radius: vec![0.1],
        };
        let on_bisector = Vector3::new(0.95, 0.05, 0.0);
        let h = 1e-6;
        let across = Vector3::new(1.0, -1.0, 0.0).normalize() * h;
        let (a, b) = (
            lumen.proximity(&(on_bisector + across)),
            lumen.proximity(&(on_bisector - across)),
        );
        assert!((a.normal - b.normal).norm() < 1e-4, "{a:?} {b:?}");
        assert!(
            (a.gap - b.gap).abs() < 2.0 * h * (1.0 + 1e-6),
            "{} {}",
            a.gap,
            b.gap
        );
    }

    #[test]
    fn the_gap_is_the_signed_distance_to_the_surface() {
        // Every shape of constant size: the surface point is on the surface
        // (gap zero there) and the gap is its distance, signed by the side.
        let known = [
            (
                Obstacle::Sphere {
                    centre: Vector3::zeros(),
                    radius: 1.0,
                },
                Vector3::new(0.0, 3.0, 4.0),
                4.0,
            ),
            (
                Obstacle::Capsule {
                    a: Vector3::zeros(),
                    b: Vector3::new(0.0, 0.0, 2.0),
                    radius: 0.5,
                },
                Vector3::new(0.3, 0.4, 1.0),
                0.0,
            ),
            (
                Obstacle::Cylinder {
                    a: Vector3::zeros(),
                    b: Vector3::new(0.0, 0.0, 2.0),
                    radius: 1.0,
                },
                Vector3::new(4.0, 0.0, 6.0),
                5.0,
            ),
            (
                Obstacle::Box {
                    centre: Vector3::zeros(),
                    half_extents: Vector3::new(1.0, 2.0, 3.0),
                    orientation: Quat::IDENTITY,
                },
                Vector3::new(0.5, -1.5, 0.0),
                -0.5,
            ),
            (
                Obstacle::Lumen {
                    centreline: vec![Vector3::zeros(), Vector3::new(0.0, 0.0, -1.0)],
                    radius: vec![0.1],
                },
                Vector3::new(0.03, 0.04, -0.5),
                0.05,
            ),
        ];
        for (shape, p, gap) in &known {
            assert!((shape.proximity(p).gap - gap).abs() < 1e-15, "{shape:?}");
        }
        for shape in shapes() {
            if matches!(shape, Obstacle::Lumen { .. }) {
                continue; // its radius varies: not a distance
            }
            for p in points() {
                let at = shape.proximity(&p);
                let surface = at.surface_point(&p);
                assert!(
                    shape.proximity(&surface).gap.abs() < 1e-12,
                    "{shape:?} at {p}"
                );
                assert!((at.normal.norm() - 1.0).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn obstacles_round_trip_and_bad_ones_are_refused_by_key() {
        for shape in shapes() {
            let again = Obstacle::from_value(&shape.to_value(), "o").unwrap();
            assert_eq!(again, shape);
        }
        let refused = |text: &str| match Obstacle::from_value(
            &Value::from_json_str(text).unwrap(),
            "obstacles[0]",
        ) {
            Err(Error::InvalidScene { key, .. }) => key,
            other => panic!("{text}: {other:?}"),
        };
        let cases = [
            (r#"{"shape": "cone"}"#, "obstacles[0].shape"),
            (r#"{"radius": 1}"#, "obstacles[0].shape"),
            (
                r#"{"shape": "sphere", "centre": [0, 0, 0]}"#,
                "obstacles[0].radius",
            ),
            (
                r#"{"shape": "sphere", "centre": [0, 0, 0], "radius": -1}"#,
                "obstacles[0].radius",
            ),
            (
                r#"{"shape": "sphere", "centre": [0, 0], "radius": 1}"#,
                "obstacles[0].centre",
            ),
            (
                r#"{"shape": "sphere", "centre": [0, 0, 0], "radius": 1, "a": [0, 0, 0]}"#,
                "obstacles[0].a",
            ),
            (
                r#"{"shape": "half_space", "point": [0, 0, 0], "normal": [0, 0, 0]}"#,
                "obstacles[0].normal",
            ),
            (
                r#"{"shape": "cylinder", "a": [0, 0, 0], "b": [0, 0, 0], "radius": 1}"#,
                "obstacles[0].b",
            ),
            (
                r#"{"shape": "box", "centre": [0, 0, 0], "half_extents": [1, 0, 1]}"#,
                "obstacles[0].half_extents[1]",
            ),
            (
                r#"{"shape": "lumen", "centreline": [[0, 0, 0]], "radius": 1}"#,
                "obstacles[0].centreline",
            ),
            (
                r#"{"shape": "lumen", "centreline": [[0, 0, 0], [0, 0, 1]], "radius": [1, 2, 3]}"#,
                "obstacles[0].radius",
            ),
            (
                r#"{"shape": "lumen", "centreline": [[0, 0, 0], [0, 0, 1]], "radius": [1, 0]}"#,
                "obstacles[0].radius[1]",
            ),
            (r#"{"shape": "mesh"}"#, "obstacles[0].file"),
            (
                r#"{"shape": "mesh", "file": "no such file.stl"}"#,
                "obstacles[0].file",
            ),
            (
                r#"{"shape": "mesh", "file": "a.stl", "vertices": [], "triangles": []}"#,
                "obstacles[0].file",
            ),
            (
                r#"{"shape": "mesh", "vertices": [[0, 0, 0]]}"#,
                "obstacles[0].triangles",
            ),
            (
                r#"{"shape": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [[0, 1, 2.5]]}"#,
                "obstacles[0].triangles[0][2]",
            ),
            (
                r#"{"shape": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [[0, 1, 3]]}"#,
                "obstacles[0].triangles",
            ),
            (
                r#"{"shape": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [[0, 1, 2]], "free": "both"}"#,
                "obstacles[0].free",
            ),
            (
                r#"{"shape": "mesh", "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0]], "triangles": [[0, 1, 2]], "scale": 0}"#,
                "obstacles[0].scale",
            ),
        ];
        for (text, key) in cases {
            assert_eq!(refused(text), key, "{text}");
        }
    }
}
