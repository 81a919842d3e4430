//! A triangle mesh as an obstacle (anatomy, a fixture): its signed distance
//! from parry3d-f64's bounding-volume tree and the angle-weighted
//! pseudo-normals that tell inside from outside (Baerentzen and Aanaes
//! 2005), so a query costs O(log triangles).
//!
//! Our vectors are nalgebra's and parry's are glam's: they meet only here,
//! as three numbers.

use super::Proximity;
use nalgebra::Vector3;
use parry3d_f64::math::Vector as ParryVector;
use parry3d_f64::query::PointQueryWithLocation;
use parry3d_f64::shape::{TriMesh, TriMeshFlags, TrianglePointLocation};
use std::sync::Arc;

/// A triangle mesh, world frame [m]. Its triangles wind counter-clockwise
/// seen from outside (their normals point out of the solid); the free
/// space is the outside, or the inside with `free_inside` (a vessel the
/// rod runs in).
#[derive(Clone)]
pub struct TriangleMesh {
    /// The search tree (shared: a robot's clones and a batch's threads
    /// query the same one).
    tree: Arc<TriMesh>,
    free_inside: bool,
}

fn ours(v: ParryVector) -> Vector3<f64> {
    Vector3::new(v.x, v.y, v.z)
}

impl TriangleMesh {
    /// Build the mesh's tree: identical vertices are merged and triangles of
    /// no area dropped (an exporter's slivers). The error says which input
    /// is wrong: a vertex not finite, an index past the vertices, no
    /// triangle left, or a closed surface wound inwards.
    pub fn new(
        vertices: &[Vector3<f64>],
        triangles: &[[u32; 3]],
        free_inside: bool,
    ) -> Result<TriangleMesh, MeshError> {
        if let Some(i) = vertices
            .iter()
            .position(|v| !v.iter().all(|x| x.is_finite()))
        {
            return Err(MeshError::Vertex(i));
        }
        if let Some(t) = triangles
            .iter()
            .position(|t| t.iter().any(|&i| i as usize >= vertices.len()))
        {
            return Err(MeshError::Index(t, vertices.len()));
        }
        let points = vertices
            .iter()
            .map(|v| ParryVector::new(v.x, v.y, v.z))
            .collect();
        // A triangle of no area has no normal to tell the sides apart.
        let kept: Vec<[u32; 3]> = triangles
            .iter()
            .filter(|t| {
                let [a, b, c] = t.map(|i| vertices[i as usize]);
                (b - a).cross(&(c - a)) != Vector3::zeros()
            })
            .copied()
            .collect();
        let flags = TriMeshFlags::ORIENTED
            | TriMeshFlags::MERGE_DUPLICATE_VERTICES
            | TriMeshFlags::DELETE_DEGENERATE_TRIANGLES;
        let tree = TriMesh::with_flags(points, kept, flags).map_err(|_| MeshError::Empty)?;
        let mesh = TriangleMesh {
            tree: Arc::new(tree),
            free_inside,
        };
        if let Some(volume) = mesh.enclosed_volume() {
            if volume < 0.0 {
                return Err(MeshError::WoundInwards(volume));
            }
        }
        Ok(mesh)
    }

    /// The vertices after merging.
    pub fn vertices(&self) -> Vec<Vector3<f64>> {
        self.tree.vertices().iter().map(|v| ours(*v)).collect()
    }

    /// The triangles kept (indices into [`TriangleMesh::vertices`]).
    pub fn triangles(&self) -> &[[u32; 3]] {
        self.tree.indices()
    }

    /// Whether the free space is the mesh's inside.
    pub fn free_inside(&self) -> bool {
        self.free_inside
    }

    /// Triangle `t`'s corners.
    fn corners(&self, t: u32) -> [Vector3<f64>; 3] {
        self.tree.indices()[t as usize].map(|i| ours(self.tree.vertices()[i as usize]))
    }

    /// Triangle `t`'s unit normal (every triangle kept has an area).
    fn face_normal(&self, t: u32) -> Vector3<f64> {
        let [a, b, c] = self.corners(t);
        (b - a).cross(&(c - a)).normalize()
    }

    /// The signed volume the triangles enclose when every edge is shared
    /// by exactly two of them in opposite directions (a closed, consistently
    /// wound surface; negative when wound inwards), else `None`.
    pub fn enclosed_volume(&self) -> Option<f64> {
        let mut edges: std::collections::HashMap<(u32, u32), i32> = Default::default();
        let mut volume = 0.0;
        for t in self.tree.indices() {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *edges.entry((a.min(b), a.max(b))).or_default() += if a < b { 1 } else { -1 };
            }
            let [a, b, c] = t.map(|i| ours(self.tree.vertices()[i as usize]));
            volume += a.dot(&b.cross(&c)) / 6.0;
        }
        // Each undirected edge once each way: its count is zero (and it
        // was seen at all).
        edges.values().all(|&n| n == 0).then_some(volume)
    }

    /// The signed distance of `p` from the surface, positive in free space,
    /// and its gradient. Measured from the feature nearest `p`, not from
    /// the projected point: from a face its plane (the normal is the
    /// face's, exactly, however near `p` is), from an edge its line, from a
    /// vertex the vertex; the side from the pseudo-normals.
    pub fn proximity(&self, p: &Vector3<f64>) -> Proximity {
        let (projection, (triangle, location)) = self
            .tree
            .project_local_point_and_get_location(ParryVector::new(p.x, p.y, p.z), false);
        let corners = self.corners(triangle);
        let face = self.face_normal(triangle);
        let outside = if projection.is_inside { -1.0 } else { 1.0 };
        // The offset from the nearest feature, signed and made a unit.
        let from_feature = |offset: Vector3<f64>| {
            let distance = offset.norm();
            if distance > 0.0 {
                (outside * distance, offset * (outside / distance))
            } else {
                (0.0, face)
            }
        };
        let (gap, normal) = match location {
            TrianglePointLocation::OnFace(..) | TrianglePointLocation::OnSolid => {
                ((p - corners[0]).dot(&face), face)
            }
            TrianglePointLocation::OnEdge(edge, _) => {
                // Parry's edges: 0 is AB, 1 is BC, 2 is AC.
                let (a, b) = match edge {
                    0 => (corners[0], corners[1]),
                    1 => (corners[1], corners[2]),
                    _ => (corners[0], corners[2]),
                };
                let along = (b - a).normalize();
                let offset = p - a;
                from_feature(offset - offset.dot(&along) * along)
            }
            TrianglePointLocation::OnVertex(k) => from_feature(p - corners[k as usize]),
        };
        let free = if self.free_inside { -1.0 } else { 1.0 };
        Proximity {
            gap: free * gap,
            normal: free * normal,
        }
    }
}

impl PartialEq for TriangleMesh {
    fn eq(&self, other: &Self) -> bool {
        self.free_inside == other.free_inside
            && self.tree.vertices() == other.tree.vertices()
            && self.tree.indices() == other.tree.indices()
    }
}

impl std::fmt::Debug for TriangleMesh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TriangleMesh")
            .field("vertices", &self.tree.vertices().len())
            .field("triangles", &self.tree.indices().len())
            .field("free_inside", &self.free_inside)
            .finish()
    }
}

/// What is wrong with a mesh's input.
#[derive(Debug, Clone, PartialEq)]
pub enum MeshError {
    /// Vertex `i` is not finite.
    Vertex(usize),
    /// Triangle `t` names a vertex past the `n` given.
    Index(usize, usize),
    /// No triangle of non-zero area.
    Empty,
    /// A closed surface whose triangles wind inwards (its signed volume).
    WoundInwards(f64),
}

impl std::fmt::Display for MeshError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MeshError::Vertex(i) => write!(f, "vertex {i} is not finite"),
            MeshError::Index(t, n) => {
                write!(f, "triangle {t} names a vertex past the {n} given")
            }
            MeshError::Empty => write!(f, "has no triangle of non-zero area"),
            MeshError::WoundInwards(v) => write!(
                f,
                "is a closed surface wound inwards (signed volume {v:.3e} m^3): its \
                 triangles must turn counter-clockwise seen from outside; reverse each \
                 triangle (for a channel the rod runs inside, keep them outward and set \
                 free = \"inside\")"
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A box's surface as 12 triangles, wound outwards.
    pub(crate) fn box_mesh(half: Vector3<f64>) -> (Vec<Vector3<f64>>, Vec<[u32; 3]>) {
        let vertices = (0..8)
            .map(|i| {
                Vector3::new(
                    if i & 1 == 0 { -half.x } else { half.x },
                    if i & 2 == 0 { -half.y } else { half.y },
                    if i & 4 == 0 { -half.z } else { half.z },
                )
            })
            .collect();
        // Each face's corners counter-clockwise seen from outside.
        let faces = [
            [0, 2, 3, 1], // -z
            [4, 5, 7, 6], // +z
            [0, 1, 5, 4], // -y
            [2, 6, 7, 3], // +y
            [0, 4, 6, 2], // -x
            [1, 3, 7, 5], // +x
        ];
        let triangles = faces
            .iter()
            .flat_map(|f| [[f[0], f[1], f[2]], [f[0], f[2], f[3]]])
            .collect();
        (vertices, triangles)
    }

    #[test]
    fn a_box_mesh_has_the_boxs_signed_distance() {
        let half = Vector3::new(0.1, 0.2, 0.3);
        let (vertices, triangles) = box_mesh(half);
        let mesh = TriangleMesh::new(&vertices, &triangles, false).unwrap();
        assert!((mesh.enclosed_volume().unwrap() - 8.0 * half.product()).abs() < 1e-15);
        let solid = super::super::Obstacle::Box {
            centre: Vector3::zeros(),
            half_extents: half,
            orientation: crate::quat::Quat::IDENTITY,
        };
        for p in super::super::obstacle::tests::points() {
            let (a, b) = (mesh.proximity(&p), solid.proximity(&p));
            assert!((a.gap - b.gap).abs() < 1e-14, "at {p}: {a:?} {b:?}");
            assert!((a.normal - b.normal).norm() < 1e-12, "at {p}: {a:?} {b:?}");
        }
        // Free inside: the same surface, the other side.
        let channel = TriangleMesh::new(&vertices, &triangles, true).unwrap();
        let p = Vector3::new(0.05, 0.0, 0.0);
        let at = channel.proximity(&p);
        assert!(
            (at.gap - 0.05).abs() < 1e-15
                && (at.normal - Vector3::new(-1.0, 0.0, 0.0)).norm() < 1e-15
        );
    }

    #[test]
    fn bad_meshes_are_refused_with_the_reason() {
        let (mut vertices, mut triangles) = box_mesh(Vector3::new(1.0, 1.0, 1.0));
        let inwards: Vec<[u32; 3]> = triangles.iter().map(|[a, b, c]| [*a, *c, *b]).collect();
        assert!(matches!(
            TriangleMesh::new(&vertices, &inwards, false),
            Err(MeshError::WoundInwards(v)) if (v + 8.0).abs() < 1e-12
        ));
        // An open surface (a box without its lid) is taken as it is wound.
        let open = TriangleMesh::new(&vertices, &triangles[2..], false).unwrap();
        assert_eq!(open.enclosed_volume(), None);
        triangles.push([0, 1, 8]);
        assert_eq!(
            TriangleMesh::new(&vertices, &triangles, false).unwrap_err(),
            MeshError::Index(12, 8)
        );
        vertices[3].y = f64::NAN;
        assert_eq!(
            TriangleMesh::new(&vertices, &triangles, false).unwrap_err(),
            MeshError::Vertex(3)
        );
        let flat = [Vector3::zeros(), Vector3::x(), 2.0 * Vector3::x()];
        assert_eq!(
            TriangleMesh::new(&flat, &[[0, 1, 2]], false).unwrap_err(),
            MeshError::Empty
        );
    }
}
