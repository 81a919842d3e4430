//! Readers of value trees (JSON, TOML, a Python dict), shared by the scene, the
//! robot and the solver settings: each refuses a wrong kind, shape or range
//! with an error that names the key ([`Error::InvalidScene`]; the settings
//! turn it into [`Error::InvalidArgument`]).

use crate::error::{Error, Result};
use crate::quat::Quat;
use crate::value::Value;
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

/// A map with the path of its key, for error messages.
pub(crate) struct Table<'a> {
    pub(crate) entries: &'a [(String, Value)],
    path: String,
}

impl<'a> Table<'a> {
    pub(crate) fn new(v: &'a Value, path: &str) -> Result<Self> {
        match v {
            Value::Map(entries) => Ok(Table {
                entries,
                path: path.to_string(),
            }),
            other => Err(Error::scene(
                path,
                format!("expected a table, got {}", other.kind()),
            )),
        }
    }

    /// The table at the top of an input (a scene, the settings): its keys are
    /// named bare, `what` only names the input when it is not a table.
    pub(crate) fn top(v: &'a Value, what: &str) -> Result<Self> {
        let mut table = Table::new(v, what)?;
        table.path.clear();
        Ok(table)
    }

    /// The table's own path (`tendons[2]`).
    pub(crate) fn path(&self) -> &str {
        &self.path
    }

    pub(crate) fn key(&self, k: &str) -> String {
        if self.path.is_empty() {
            k.to_string()
        } else {
            format!("{}.{k}", self.path)
        }
    }

    /// The positive number at `k` (its key formatted for an error only).
    pub(crate) fn positive(&self, k: &str) -> Result<f64> {
        match self.require(k)? {
            Value::Number(x) if x.is_finite() && *x > 0.0 => Ok(*x),
            v => positive(v, &self.key(k)),
        }
    }

    pub(crate) fn get(&self, k: &str) -> Option<&'a Value> {
        self.entries
            .iter()
            .find(|(key, _)| key == k)
            .map(|(_, v)| v)
    }

    pub(crate) fn require(&self, k: &str) -> Result<&'a Value> {
        self.get(k)
            .ok_or_else(|| Error::scene(self.key(k), "missing"))
    }

    pub(crate) fn only(&self, allowed: &[&str]) -> Result<()> {
        for (k, _) in self.entries {
            if !allowed.contains(&k.as_str()) {
                return Err(Error::scene(
                    self.key(k),
                    format!("unknown key (expected one of: {})", allowed.join(", ")),
                ));
            }
        }
        Ok(())
    }
}

/// A finite number at `key`.
pub(crate) fn finite(v: &Value, key: &str) -> Result<f64> {
    match v {
        Value::Number(x) if x.is_finite() => Ok(*x),
        Value::Number(x) => Err(Error::scene(key, format!("must be finite, got {x}"))),
        other => Err(Error::scene(
            key,
            format!("expected a number, got {}", other.kind()),
        )),
    }
}

pub(crate) fn positive(v: &Value, key: &str) -> Result<f64> {
    let x = finite(v, key)?;
    if x <= 0.0 {
        return Err(Error::scene(key, format!("must be positive, got {x}")));
    }
    Ok(x)
}

pub(crate) fn numbers<const N: usize>(v: &Value, key: &str) -> Result<[f64; N]> {
    let items = match v {
        Value::List(items) => items,
        other => {
            return Err(Error::scene(
                key,
                format!("expected a list of {N} numbers, got {}", other.kind()),
            ))
        }
    };
    if items.len() != N {
        return Err(Error::scene(
            key,
            format!(
                "expected a list of {N} numbers, got {} entries",
                items.len()
            ),
        ));
    }
    let mut out = [0.0; N];
    for (i, item) in items.iter().enumerate() {
        // The entry's key is formatted for an error only.
        out[i] = match item {
            Value::Number(x) if x.is_finite() => *x,
            _ => finite(item, &format!("{key}[{i}]"))?,
        };
    }
    Ok(out)
}

pub(crate) fn vec3(v: &Value, key: &str) -> Result<Vector3<f64>> {
    Ok(Vector3::from(numbers::<3>(v, key)?))
}

/// A number as given: integers in full, large magnitudes in exponent form.
pub(crate) fn shown(x: f64) -> String {
    if x.abs() >= 1e16 {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// A count (sections, elements) read as an integer in `[1, max]`, checked
/// before anything is allocated for it.
pub(crate) fn count(v: &Value, key: &str, max: usize) -> Result<usize> {
    let x = finite(v, key)?;
    if x >= 1.0 && x <= max as f64 && x.fract() == 0.0 {
        Ok(x as usize)
    } else {
        Err(Error::scene(
            key,
            format!("must be an integer in [1, {max}], got {}", shown(x)),
        ))
    }
}

/// A string at `key`.
pub(crate) fn string<'a>(v: &'a Value, key: &str) -> Result<&'a str> {
    match v {
        Value::String(s) => Ok(s),
        other => Err(Error::scene(
            key,
            format!("expected a string, got {}", other.kind()),
        )),
    }
}

/// A whole number in `[0, max]` at `key` (an iteration count, a seed).
pub(crate) fn whole(v: &Value, key: &str, max: f64) -> Result<f64> {
    let x = finite(v, key)?;
    if x >= 0.0 && x <= max && x.fract() == 0.0 {
        Ok(x)
    } else {
        Err(Error::scene(
            key,
            format!(
                "must be a whole number in [0, {}], got {}",
                shown(max),
                shown(x)
            ),
        ))
    }
}

/// A reader's refusal of a setting is an invalid argument (it names the key).
pub(crate) fn as_argument(e: Error) -> Error {
    match e {
        Error::InvalidScene { key, reason } => Error::InvalidArgument { name: key, reason },
        other => other,
    }
}

/// A list of tables under `key` (`key[i]` each), each holding only the keys
/// `allowed` and read by `item`; `about` follows the list's description in
/// the error for anything but a list (", one a section").
pub(crate) fn table_list<T>(
    v: &Value,
    key: &str,
    allowed: &[&str],
    about: &str,
    item: impl Fn(&Table) -> Result<T>,
) -> Result<Vec<T>> {
    let Value::List(items) = v else {
        return Err(Error::scene(
            key,
            format!(
                "expected a list of {{{}}} tables{about}, got {}",
                allowed.join(", "),
                v.kind()
            ),
        ));
    };
    items
        .iter()
        .enumerate()
        .map(|(i, x)| {
            let t = Table::new(x, &format!("{key}[{i}]"))?;
            t.only(allowed)?;
            item(&t)
        })
        .collect()
}

/// Refuse a tolerance outside `[min, max]` (or not finite), naming it.
pub(crate) fn check_tolerance(name: &str, value: f64, (min, max): (f64, f64)) -> Result<()> {
    if value.is_finite() && (min..=max).contains(&value) {
        return Ok(());
    }
    Err(Error::argument(
        name,
        format!("must lie in [{min:e}, {max:e}], got {value:e}"),
    ))
}

/// How far from unit norm a given quaternion may be (it is normalised): four
/// printed digits, `[0.924, 0, 0.383, 0]` for a turn of 45 degrees, are 2e-4 off.
pub const QUATERNION_NORM_TOL: f64 = 1e-3;

/// How far from orthonormal a given rotation matrix may be, `|R^T R - I|`
/// entrywise, and its determinant from 1.
pub const ROTATION_MATRIX_TOL: f64 = 1e-6;

/// An orientation: a quaternion `[w, x, y, z]` (scalar first; SciPy's
/// `Rotation.as_quat()` is scalar last) within [`QUATERNION_NORM_TOL`] of unit
/// norm, or a 3x3 rotation matrix `[[..], [..], [..]]` whose columns are the
/// material axes in the world frame (`Rotation.as_matrix()`). Normalised.
pub(crate) fn orientation(v: &Value, key: &str) -> Result<Quat> {
    if let Value::List(rows) = v {
        if rows.len() == 3 && rows.iter().all(|r| matches!(r, Value::List(_))) {
            let mut m = Matrix3::zeros();
            for (i, row) in rows.iter().enumerate() {
                let r = numbers::<3>(row, &format!("{key}[{i}]"))?;
                for (j, x) in r.iter().enumerate() {
                    m[(i, j)] = *x;
                }
            }
            return rotation_matrix(m, key);
        }
    }
    let q = Quat::from_array(numbers::<4>(v, key).map_err(|_| {
        Error::scene(
            key,
            "expected a quaternion [w, x, y, z] (scalar first), a 3x3 rotation matrix or a scipy Rotation",
        )
    })?);
    let norm = q.norm();
    if (norm - 1.0).abs() > QUATERNION_NORM_TOL {
        return Err(Error::scene(
            key,
            format!(
                "must be a unit quaternion [w, x, y, z] (scalar first; SciPy's as_quat() is \
                 scalar last), within {QUATERNION_NORM_TOL} of norm 1: its norm is {norm}"
            ),
        ));
    }
    Ok(q.normalized())
}

/// The quaternion of a proper rotation matrix (checked).
fn rotation_matrix(m: Matrix3<f64>, key: &str) -> Result<Quat> {
    let off = (m.transpose() * m - Matrix3::identity()).amax();
    let det = m.determinant();
    if !(off <= ROTATION_MATRIX_TOL && (det - 1.0).abs() <= ROTATION_MATRIX_TOL) {
        return Err(Error::scene(
            key,
            format!(
                "must be a rotation matrix (orthonormal, determinant 1, to \
                 {ROTATION_MATRIX_TOL}): |R^T R - I| = {off:.2e}, det R = {det}"
            ),
        ));
    }
    let r = Rotation3::from_matrix_unchecked(m);
    let q = UnitQuaternion::from_rotation_matrix(&r);
    Ok(Quat::new(q.w, q.i, q.j, q.k).normalized())
}
