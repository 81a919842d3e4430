//! Triangle meshes from files: STL (binary or ASCII) and Wavefront OBJ, the
//! formats anatomy and CAD exports come in. Only the geometry is read:
//! vertices and triangles (an OBJ's polygons cut into fans); normals,
//! texture coordinates, groups and materials are skipped (the winding gives
//! the normals).

use nalgebra::Vector3;
use std::path::Path;

/// Vertices and the triangles through them (indices, counter-clockwise
/// seen from the side their normal points to).
pub type Triangles = (Vec<Vector3<f64>>, Vec<[u32; 3]>);

/// Read `path` by its extension (`.stl` or `.obj`, any case). The error says
/// what is wrong and where (the line of a text file), without the path.
pub fn read(path: &Path) -> Result<Triangles, String> {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let bytes = || std::fs::read(path).map_err(|e| format!("cannot be read: {e}"));
    match extension.as_deref() {
        Some("stl") => stl(&bytes()?),
        Some("obj") => obj(&String::from_utf8_lossy(&bytes()?)),
        _ => Err("expected an .stl or .obj file".into()),
    }
}

/// An STL file: binary when its length is that its triangle count says
/// (some binary files also begin with "solid"), else ASCII.
pub fn stl(bytes: &[u8]) -> Result<Triangles, String> {
    if bytes.len() >= 84 {
        let count = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
        if count.checked_mul(50).and_then(|b| b.checked_add(84)) == Some(bytes.len()) {
            return Ok(binary_stl(&bytes[84..], count));
        }
    }
    let text = String::from_utf8_lossy(bytes);
    if !text.trim_start().starts_with("solid") {
        return Err(
            "is neither a binary STL (its length does not match its triangle count) \
             nor an ASCII one (it does not begin with \"solid\")"
                .into(),
        );
    }
    ascii_stl(&text)
}

/// Each record: a normal (skipped), three vertices of three `f32`, two bytes.
fn binary_stl(records: &[u8], count: usize) -> Triangles {
    let float = |b: &[u8]| f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64;
    let mut vertices = Vec::with_capacity(3 * count);
    for record in records.chunks_exact(50) {
        for corner in 0..3 {
            let at = 12 + 12 * corner;
            vertices.push(Vector3::new(
                float(&record[at..]),
                float(&record[at + 4..]),
                float(&record[at + 8..]),
            ));
        }
    }
    let triangles = (0..count as u32)
        .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
        .collect();
    (vertices, triangles)
}

/// `facet ... outer loop vertex x y z (x3) endloop endfacet`, repeated.
fn ascii_stl(text: &str) -> Result<Triangles, String> {
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    let mut facet: Vec<u32> = Vec::new();
    for (number, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("vertex") => {
                let point = coordinates(&mut words)
                    .ok_or_else(|| format!("line {}: expected \"vertex x y z\"", number + 1))?;
                facet.push(vertices.len() as u32);
                vertices.push(point);
            }
            Some("endfacet") => {
                if facet.len() < 3 {
                    return Err(format!(
                        "line {}: a facet of {} vertices",
                        number + 1,
                        facet.len()
                    ));
                }
                fan(&facet, &mut triangles);
                facet.clear();
            }
            _ => {}
        }
    }
    Ok((vertices, triangles))
}

/// Three finite numbers from `words`.
fn coordinates<'a>(words: &mut impl Iterator<Item = &'a str>) -> Option<Vector3<f64>> {
    let mut point = Vector3::zeros();
    for c in 0..3 {
        point[c] = words.next()?.parse::<f64>().ok()?;
    }
    Some(point)
}

/// A polygon's corners as the fan of triangles from its first.
fn fan(corners: &[u32], triangles: &mut Vec<[u32; 3]>) {
    for k in 1..corners.len() - 1 {
        triangles.push([corners[0], corners[k], corners[k + 1]]);
    }
}

/// `v x y z` and `f a b c ...` lines (a corner `a`, `a/t` or `a/t/n`, counted
/// from 1, or from the end when negative).
pub fn obj(text: &str) -> Result<Triangles, String> {
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    let mut corners = Vec::new();
    for (number, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => vertices.push(
                coordinates(&mut words)
                    .ok_or_else(|| format!("line {}: expected \"v x y z\"", number + 1))?,
            ),
            Some("f") => {
                corners.clear();
                for word in words {
                    let index = word.split('/').next().unwrap_or_default();
                    let corner = index
                        .parse::<i64>()
                        .ok()
                        .and_then(|i| match i {
                            i if i > 0 => Some(i - 1),
                            i if i < 0 => Some(vertices.len() as i64 + i),
                            _ => None,
                        })
                        .filter(|&i| i >= 0 && (i as usize) < vertices.len())
                        .ok_or_else(|| {
                            format!(
                                "line {}: {word:?} is not a vertex (there are {} so far)",
                                number + 1,
                                vertices.len()
                            )
                        })?;
                    corners.push(corner as u32);
                }
                if corners.len() < 3 {
                    return Err(format!(
                        "line {}: a face of {} vertices",
                        number + 1,
                        corners.len()
                    ));
                }
                fan(&corners, &mut triangles);
            }
            _ => {}
        }
    }
    Ok((vertices, triangles))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit square in z = 0 as two triangles, facing +z.
    const SQUARE: [[f32; 3]; 6] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];

    fn corners((vertices, triangles): &Triangles) -> Vec<[f64; 3]> {
        triangles
            .iter()
            .flatten()
            .map(|&i| {
                let v = vertices[i as usize];
                [v.x, v.y, v.z]
            })
            .collect()
    }

    fn expected() -> Vec<[f64; 3]> {
        SQUARE.iter().map(|c| c.map(f64::from)).collect()
    }

    #[test]
    fn binary_and_ascii_stl_give_the_same_triangles() {
        // A binary file whose header begins with "solid", as some exporters write.
        let mut binary = b"solid exported".to_vec();
        binary.resize(80, b' ');
        binary.extend(2u32.to_le_bytes());
        for triangle in SQUARE.chunks(3) {
            binary.extend([0u8; 12]);
            for corner in triangle {
                for x in corner {
                    binary.extend(x.to_le_bytes());
                }
            }
            binary.extend([0u8; 2]);
        }
        assert_eq!(corners(&stl(&binary).unwrap()), expected());
        let mut ascii = String::from("solid square\n");
        for triangle in SQUARE.chunks(3) {
            ascii += "  facet normal 0 0 1\n    outer loop\n";
            for c in triangle {
                ascii += &format!("      vertex {} {} {}\n", c[0], c[1], c[2]);
            }
            ascii += "    endloop\n  endfacet\n";
        }
        ascii += "endsolid square\n";
        assert_eq!(corners(&stl(ascii.as_bytes()).unwrap()), expected());
        assert!(stl(b"not a mesh").is_err());
        let broken = ascii.replace("vertex 1 1 0", "vertex 1 one 0");
        assert!(stl(broken.as_bytes()).unwrap_err().starts_with("line 6"));
    }

    #[test]
    fn obj_polygons_become_fans_and_indices_may_count_from_the_end() {
        let text =
            "# a square\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1 4//1\n";
        assert_eq!(corners(&obj(text).unwrap()), expected());
        let relative = text.replace("f 1//1 2//1 3//1 4//1", "f -4/1 -3/2 -2/3 -1/4");
        assert_eq!(corners(&obj(&relative).unwrap()), expected());
        let refused = obj(&text.replace("f 1//1", "f 9//1")).unwrap_err();
        assert!(refused.starts_with("line 7: \"9//1\""), "{refused}");
        assert!(obj("v 0 0 0\nv 1 0 0\nf 1 2\n").is_err());
    }
}
