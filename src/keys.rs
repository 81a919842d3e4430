//! The key reference: every key a scene or a robot is read from, with its
//! unit, default and meaning. The documentation's key page is generated
//! from these tables (`docs/hooks/keys.py`, through the extension's
//! `keys()`), and the tests check that they name exactly the keys the
//! readers (`scene.rs`, `robot/`) accept, nested ones too.

/// One key of a reader.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Key {
    /// Its path: `length`, `stiffness.E`, `point_loads[].s`.
    pub name: &'static str,
    /// SI unit, or what the value is (`[x, y, z] m`, `count`).
    pub unit: &'static str,
    /// The value when the key is absent (`required` if it must be given).
    pub default: &'static str,
    /// What it is, its range and what it interacts with.
    pub meaning: &'static str,
}

const fn key(
    name: &'static str,
    unit: &'static str,
    default: &'static str,
    meaning: &'static str,
) -> Key {
    Key {
        name,
        unit,
        default,
        meaning,
    }
}

/// The keys of a scene (`Scene::from_value`).
pub const SCENE: &[Key] = &[
    key("name", "text", "none", "Free text, shown in reports."),
    key("length", "m", "the sections' lengths' sum", "The rod's length, > 0."),
    key("stiffness", "table", "required", "Bending and torsion: {kx, ky, kz}, or a round rod's {E, G, diameter}."),
    key("stiffness.kx", "N m^2", "required with ky, kz", "Bending stiffness about the material x axis, > 0."),
    key("stiffness.ky", "N m^2", "required with kx, kz", "Bending stiffness about the material y axis, > 0."),
    key("stiffness.kz", "N m^2", "required with kx, ky", "Torsional stiffness, > 0."),
    key("stiffness.E", "Pa", "required with G, diameter", "Young's modulus (a warning outside 1 kPa to 1.2 TPa)."),
    key("stiffness.G", "Pa", "required with E, diameter", "Shear modulus: E / (2 (1 + nu))."),
    key("stiffness.diameter", "m", "required with E, G", "The round rod's diameter; its radius is the contact radius."),
    key("rest_curvature", "[[kappa_x, kappa_y], ...] 1/m", "straight", "One entry a section (equal sections unless `sections` gives lengths): the actuation."),
    key("sections", "list of tables", "one section", "A section's own properties, each key optional; lengths for all sections or none."),
    key("sections[].length", "m", "equal sections", "The section's length."),
    key("sections[].stiffness", "table", "the rod's", "As `stiffness`."),
    key("sections[].linear_density", "kg/m", "the rod's", "With `gravity`."),
    key("sections[].distributed_moment", "[mx, my, mz] N m/m", "the rod's", "Over this section, world frame."),
    key("distributed_force", "[fx, fy, fz] N/m", "[0, 0, 0]", "A dead force along the rod, world frame."),
    key("distributed_moment", "[mx, my, mz] N m/m", "[0, 0, 0]", "A dead moment along the rod, world frame."),
    key("gravity", "table", "none", "The rod's own weight."),
    key("gravity.linear_density", "kg/m", "required", "Mass per length, >= 0."),
    key("gravity.vector", "[gx, gy, gz] m/s^2", "required", "Gravity, world frame."),
    key("tip_force", "[Px, Py, Pz] N", "[0, 0, 0]", "A dead force at the tip, world frame."),
    key("tip_moment", "[Mx, My, Mz] N m", "[0, 0, 0]", "A dead moment at the tip, world frame."),
    key("tip_force_offset", "[x, y, z] m", "[0, 0, 0]", "Where `tip_force` acts, from the tip in its material frame (a tool)."),
    key("base_quaternion", "[w, x, y, z], 3x3 or Rotation", "[1, 0, 0, 0]: tangent +z", "The base frame; a quaternion within 1e-3 of unit norm."),
    key("base_position", "[x, y, z] m", "[0, 0, 0]", "The base, world frame."),
    key("tip", "table", "{type: free}", "The tip's condition."),
    key("tip.type", "free, pinned or clamped", "required", "Free (loads only), pinned (position held) or clamped (pose held)."),
    key("tip.position", "[x, y, z] m", "required when held", "Where a pinned or clamped tip is held, world frame."),
    key("tip.quaternion", "[w, x, y, z], 3x3 or Rotation", "required when clamped", "The clamped tip's frame."),
    key("guides", "list of tables", "none", "Points of the rod held in place (a node each)."),
    key("guides[].s", "m", "required", "Arc length from the base, in (0, L), on a node."),
    key("guides[].position", "[x, y, z] m", "required", "Where it is held, world frame."),
    key("point_loads", "list of tables", "none", "Dead loads on nodes."),
    key("point_loads[].s", "m", "required", "Arc length from the base, in (0, L], on a node."),
    key("point_loads[].force", "[x, y, z] N", "[0, 0, 0]", "World frame."),
    key("point_loads[].moment", "[x, y, z] N m", "[0, 0, 0]", "World frame."),
    key("tendons", "list of tables", "none", "Tendons pulling with given tensions."),
    key("tendons[].tension", "N", "required", "The tendon's tension, >= 0."),
    key("tendons[].offset", "[x, y] m, or one a section", "required", "Where it runs in the cross-section, material frame."),
    key("tendons[].twist", "rad/m, or one a section", "0", "The rate its angle turns along the rod (a helix)."),
    key("tendons[].end", "m", "L", "Arc length where it is anchored, in (0, L]."),
    key("magnetization", "[x, y, z] A m^2/m, or one a section", "none", "Magnetised material, material frame."),
    key("tip_magnet", "[x, y, z] A m^2", "[0, 0, 0]", "A magnet at the tip, material frame."),
    key("magnetic_field", "[x, y, z] T", "[0, 0, 0]", "A uniform field, world frame."),
    key("obstacles", "list of tables", "none", "Rigid obstacles (see `obstacles[].shape`), world frame."),
    key("obstacles[].shape", "text", "required", "half_space {point, normal}, sphere {centre, radius}, capsule and cylinder {a, b, radius}, box {centre, half_extents, orientation}, lumen {centreline, radius: one or one a point}, mesh {file or vertices and triangles, scale, position, orientation, free}."),
    key("obstacles[].friction", "1", "0", "Coulomb's coefficient mu, >= 0."),
    key("ports", "list of tables", "none", "Points the rod slides through."),
    key("ports[].position", "[x, y, z] m", "required", "The port, world frame."),
    key("ports[].axis", "[x, y, z]", "the base tangent", "The direction the rod passes it."),
    key("ports[].friction", "1", "0", "Coulomb's coefficient mu along the rod, >= 0."),
    key("radius", "m", "half a round rod's diameter, else 0", "The rod's radius for contact, >= 0."),
];

/// The keys of a robot (`Robot::from_value`): its body, then one drive's.
pub const ROBOT: &[Key] = &[
    key("length", "m", "1", "The backbone's length."),
    key("stiffness", "table", "{E: 200e9, G: 77e9, diameter: 0.003}", "As a scene's: {kx, ky, kz} N m^2 or {E, G, diameter}."),
    key("linear_density", "kg/m", "0.2", "The body's mass per length (muscles and tubing)."),
    key("sections", "count", "10", "Equal sections unless `section_properties` gives lengths."),
    key("disk_mass", "kg", "0.01", "A disk at each section end."),
    key("gravity", "[gx, gy, gz] m/s^2", "[0, 0, -9.81]", "World frame."),
    key("base_quaternion", "[w, x, y, z], 3x3 or Rotation", "[0, 1, 0, 0]: hanging, tangent -z", "The base frame."),
    key("base_position", "[x, y, z] m", "[0, 0, 0]", "World frame."),
    key("section_properties", "list of tables", "none", "One {length, stiffness, linear_density, disk_mass} a section, each optional."),
    key("tool_mass", "kg", "0", "A tool at the tip."),
    key("tool_offset", "[x, y, z] m", "[0, 0, 0]", "Where the tool and the payload act, from the tip in its frame; the IK aims this point."),
    key("radius", "m", "the drive's reach off the backbone", "The body's radius for contact."),
    key("n_elements", "count", "20", "Elements of its solves, a multiple of the sections."),
    key("obstacles", "list of tables", "none", "As a scene's."),
    key("ports", "list of tables", "none", "As a scene's."),
    key("insertion_range", "[min, max] m", "none: the base stays", "A stage feeding the base along its tangent; the IK chooses the insertion."),
    key("muscle_radius", "m", "0.02", "The muscles' distance from the backbone."),
    key("muscle_angles", "[a1, a2, a3] degrees", "[90, 210, 330]", "The three muscles' angles in the cross-section."),
    key("muscle_rest_length", "m", "the section length", "A muscle's length at zero inflation time."),
    key("inflation_rate", "m/s", "-0.01", "length = rest_length + rate * time (inflation shortens)."),
    key("muscle_length_range", "[min, max] m", "0.8 and 1.05 rest lengths", "The muscles' lengths the IK keeps within."),
    key("tendons", "list of tables", "none", "Each {offset [x, y] m (or one a section it runs through), twist rad/m, section}: anchored at that section's end; tendons replace the muscles."),
    key("max_tension", "N", "unbounded", "The most a tendon's drive pulls."),
    key("magnetization", "[x, y, z] A m^2/m, or one a section", "none", "Magnetised material, material frame; magnets replace the muscles."),
    key("tip_magnet", "[x, y, z] A m^2", "none", "A magnet at the tip, material frame."),
    key("max_field", "T", "unbounded", "The largest |B| the field's drive makes."),
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_key_is_listed_once() {
        for table in [SCENE, ROBOT] {
            let mut names: Vec<_> = table.iter().map(|k| k.name).collect();
            let all = names.len();
            names.sort_unstable();
            names.dedup();
            assert_eq!(names.len(), all);
            assert!(table
                .iter()
                .all(|k| !k.unit.is_empty() && !k.meaning.is_empty()));
        }
    }
}
