//! Python values to the core's and back: the value tree, typed arguments
//! refused by name, arrays.

use crate::value::MAX_DEPTH;
use crate::{Quat, Value};
use nalgebra::Vector3;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple, PyType};

/// Where a value sits in the caller's input, for refusals: a chain of steps on
/// the stack, rendered only for an error. Inside a dict (a scene, a robot) the
/// key path names the field as the validators do (`tip.position[1]`); inside an
/// argument the argument's name comes first, so that every refusal starts with
/// it (`target: at [1]: ...`).
pub(super) struct Path<'a> {
    step: Step<'a>,
    parent: Option<&'a Path<'a>>,
    /// Lists, dicts and arrays entered so far.
    depth: usize,
}

#[derive(Clone, Copy)]
pub(super) enum Step<'a> {
    Input(&'a str),
    Argument(&'a str),
    Key(&'a str),
    Index(usize),
    /// An array's `tolist()`: one level deeper at the same place.
    Same,
}

impl<'a> Path<'a> {
    pub(super) fn input(name: &'a str) -> Self {
        Path {
            step: Step::Input(name),
            parent: None,
            depth: 0,
        }
    }

    pub(super) fn argument(name: &'a str) -> Self {
        Path {
            step: Step::Argument(name),
            parent: None,
            depth: 0,
        }
    }

    pub(super) fn child(&'a self, step: Step<'a>) -> Path<'a> {
        Path {
            step,
            parent: Some(self),
            depth: self.depth + 1,
        }
    }

    pub(super) fn key(&'a self, key: &'a str) -> Path<'a> {
        self.child(Step::Key(key))
    }

    pub(super) fn index(&'a self, i: usize) -> Path<'a> {
        self.child(Step::Index(i))
    }

    pub(super) fn error(&self, reason: impl std::fmt::Display) -> PyErr {
        let mut steps = Vec::new();
        let mut node = Some(self);
        while let Some(p) = node {
            steps.push(p.step);
            node = p.parent;
        }
        let (mut name, mut argument, mut at) = ("", false, String::new());
        for step in steps.into_iter().rev() {
            match step {
                Step::Input(n) => name = n,
                Step::Argument(n) => (name, argument) = (n, true),
                Step::Key(k) if at.is_empty() => at.push_str(k),
                Step::Key(k) => at.push_str(&format!(".{k}")),
                Step::Index(i) => at.push_str(&format!("[{i}]")),
                Step::Same => {}
            }
        }
        PyValueError::new_err(match (at.is_empty(), argument) {
            (true, _) => format!("{name}: {reason}"),
            (false, false) => format!("{at}: {reason}"),
            (false, true) => format!("{name}: at {at}: {reason}"),
        })
    }
}

pub(super) fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map_or_else(|_| "?".to_owned(), |n| n.to_string())
}

pub(super) fn unsupported(obj: &Bound<'_, PyAny>, path: &Path) -> PyErr {
    path.error(format!("unsupported value of type {}", type_name(obj)))
}

/// NumPy's scalar types, looked up once.
pub(super) struct NumpyTypes {
    generic: Py<PyType>,
    bool_: Py<PyType>,
    integer: Py<PyType>,
    floating: Py<PyType>,
}

pub(super) fn numpy_types(py: Python<'_>) -> PyResult<&'static NumpyTypes> {
    static TYPES: PyOnceLock<NumpyTypes> = PyOnceLock::new();
    TYPES.get_or_try_init(py, || {
        let np = py.import("numpy")?;
        let ty = |name: &str| -> PyResult<Py<PyType>> {
            Ok(np.getattr(name)?.cast_into::<PyType>()?.unbind())
        };
        Ok(NumpyTypes {
            generic: ty("generic")?,
            bool_: ty("bool_")?,
            integer: ty("integer")?,
            floating: ty("floating")?,
        })
    })
}

/// A Python int as a number; one beyond the double range is refused by path.
pub(super) fn int_number(obj: &Bound<'_, PyAny>, path: &Path) -> PyResult<Value> {
    obj.extract::<f64>()
        .map(Value::Number)
        .map_err(|_| path.error("integer too large for a double"))
}

/// A scalar (None, bool, str, int, float or a NumPy scalar) as a value, or None
/// if `obj` is not one. NumPy scalars are converted explicitly: `tolist()` of a
/// `longdouble` returns the `longdouble` itself.
pub(super) fn scalar(obj: &Bound<'_, PyAny>, path: &Path) -> PyResult<Option<Value>> {
    if obj.is_none() {
        return Ok(Some(Value::Null));
    }
    if let Ok(b) = obj.cast::<PyBool>() {
        return Ok(Some(Value::Bool(b.is_true())));
    }
    if let Ok(s) = obj.cast::<PyString>() {
        let text = s.to_cow().map_err(|_| path.error("not valid text"))?;
        return Ok(Some(Value::String(text.into_owned())));
    }
    if obj.is_instance_of::<PyInt>() {
        return int_number(obj, path).map(Some);
    }
    if obj.is_instance_of::<PyFloat>() {
        return Ok(Some(Value::Number(obj.extract()?)));
    }
    let py = obj.py();
    let np = numpy_types(py)?;
    if !obj.is_instance(np.generic.bind(py))? {
        return Ok(None);
    }
    if obj.is_instance(np.bool_.bind(py))? {
        return Ok(Some(Value::Bool(obj.is_truthy()?)));
    }
    if obj.is_instance(np.integer.bind(py))? {
        return int_number(&obj.call_method0("__index__")?, path).map(Some);
    }
    if obj.is_instance(np.floating.bind(py))? {
        let x: f64 = obj.extract()?;
        // A longdouble beyond the double range becomes inf: refuse it rather
        // than pass on an infinity the input did not hold.
        if x.is_infinite() && !obj.eq(x)? {
            return Err(path.error(format!("{} is out of the range of a double", obj.str()?)));
        }
        return Ok(Some(Value::Number(x)));
    }
    Err(unsupported(obj, path))
}

/// Python object -> value tree: dicts, lists, tuples, scalars (NumPy's too) and
/// arrays (of the array protocol, by `tolist()`, called once per level). At most
/// `MAX_DEPTH` levels deep, so that a deep or self-containing input is refused
/// instead of overflowing the stack.
pub(super) fn to_value(obj: &Bound<'_, PyAny>, path: &Path) -> PyResult<Value> {
    if let Some(v) = scalar(obj, path)? {
        return Ok(v);
    }
    if path.depth >= MAX_DEPTH {
        return Err(path.error(format!("nested deeper than {MAX_DEPTH} levels")));
    }
    if let Ok(d) = obj.cast::<PyDict>() {
        // Items first: converting runs Python code that could change the dict.
        let items: Vec<_> = d.iter().collect();
        let mut entries = Vec::with_capacity(items.len());
        for (k, v) in items {
            let key = match k.cast::<PyString>() {
                Ok(s) => s
                    .to_cow()
                    .map_err(|_| path.error("keys must be valid text"))?,
                Err(_) => {
                    return Err(path.error(format!("keys must be strings, got {}", type_name(&k))))
                }
            };
            let value = to_value(&v, &path.key(&key))?;
            entries.push((key.into_owned(), value));
        }
        return Ok(Value::Map(entries));
    }
    if let Ok(l) = obj.cast::<PyList>() {
        return l
            .iter()
            .enumerate()
            .map(|(i, x)| to_value(&x, &path.index(i)))
            .collect::<PyResult<_>>()
            .map(Value::List);
    }
    if let Ok(t) = obj.cast::<PyTuple>() {
        return t
            .iter()
            .enumerate()
            .map(|(i, x)| to_value(&x, &path.index(i)))
            .collect::<PyResult<_>>()
            .map(Value::List);
    }
    if let Some(q) = rotation(obj, path)? {
        return Ok(q);
    }
    // Arrays (NumPy's and every array library's speak its protocol), not
    // anything with a `tolist`: a memoryview of bytes became their codes.
    if (obj.hasattr("__array__")? || obj.hasattr("__array_interface__")?)
        && obj.hasattr("tolist")?
    {
        let list = obj.call_method0("tolist")?;
        return to_value(&list, &path.child(Step::Same));
    }
    // A file's path (a mesh's `file`) as its text.
    if obj.hasattr("__fspath__")? {
        let text = obj.py().import("os")?.call_method1("fspath", (obj,))?;
        return text
            .extract::<String>()
            .map(Value::String)
            .map_err(|_| path.error("a path must be text, not bytes"));
    }
    Err(unsupported(obj, path))
}

/// A SciPy `Rotation` (anything with its `as_quat()`, scalar last) as the
/// unit quaternion `[w, x, y, z]` every orientation key takes, scalar
/// first; a stack of rotations as a list of them. `None` for anything else.
fn rotation(obj: &Bound<'_, PyAny>, path: &Path) -> PyResult<Option<Value>> {
    if !obj.hasattr("as_quat")? {
        return Ok(None);
    }
    let scalar_first = |q: Value| match q {
        Value::List(mut xyzw) if xyzw.len() == 4 => {
            xyzw.rotate_right(1);
            Ok(Value::List(xyzw))
        }
        _ => Err(path.error("as_quat() did not give 4 numbers a rotation")),
    };
    let quaternions = to_value(&obj.call_method0("as_quat")?, path)?;
    match quaternions {
        Value::List(items) if items.iter().all(|q| matches!(q, Value::List(_))) => items
            .into_iter()
            .map(scalar_first)
            .collect::<PyResult<_>>()
            .map(|qs| Some(Value::List(qs))),
        single => scalar_first(single).map(Some),
    }
}

/// A string argument, refused by name (pyo3's own refusal does not name it).
pub(super) fn str_arg(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<String> {
    let path = Path::argument(name);
    match obj.cast::<PyString>() {
        Ok(s) => Ok(s
            .to_cow()
            .map_err(|_| path.error("not valid text"))?
            .into_owned()),
        Err(_) => Err(path.error(format!("expected a string, got {}", type_name(obj)))),
    }
}

/// The path of argument `name` once `obj` is known to be an int or a NumPy
/// integer (not a bool or a float); refused by name otherwise.
fn integer_arg<'a>(name: &'a str, obj: &Bound<'_, PyAny>) -> PyResult<Path<'a>> {
    let path = Path::argument(name);
    let py = obj.py();
    let integer = !obj.is_instance_of::<PyBool>()
        && (obj.is_instance_of::<PyInt>() || obj.is_instance(numpy_types(py)?.integer.bind(py))?);
    if !integer {
        return Err(path.error(format!("expected an integer, got {}", type_name(obj))));
    }
    Ok(path)
}

/// A count argument: an int or NumPy integer (not a bool or a float) that fits
/// `usize`, refused by name.
pub(super) fn int_arg(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    let path = integer_arg(name, obj)?;
    match obj.extract::<usize>() {
        Ok(n) => Ok(n),
        Err(_) if obj.lt(0)? => Err(path.error(format!("must not be negative, got {obj}"))),
        Err(_) => Err(path.error(format!("too large (at most {})", usize::MAX))),
    }
}

/// A 64-bit unsigned argument (a seed, a sample index): an int or NumPy
/// integer (not a bool) in `[0, 2**64)`, refused by name.
pub(super) fn u64_arg(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<u64> {
    let path = integer_arg(name, obj)?;
    obj.extract::<u64>()
        .map_err(|_| path.error(format!("must be an integer in [0, 2**64), got {obj}")))
}

/// A finite real argument (int, float, NumPy scalar or 0-d array), refused by name.
pub(super) fn float_arg(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    let path = Path::argument(name);
    match to_value(obj, &path)? {
        Value::Number(x) if x.is_finite() => Ok(x),
        Value::Number(x) => Err(path.error(format!("must be finite, got {x}"))),
        _ => Err(path.error(format!("expected a number, got {}", type_name(obj)))),
    }
}

pub(super) fn from_value<'py>(py: Python<'py>, v: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => PyBool::new(py, *b).to_owned().into_any(),
        Value::Number(x) => PyFloat::new(py, *x).into_any(),
        Value::String(s) => PyString::new(py, s).into_any(),
        Value::List(items) => {
            let l = PyList::empty(py);
            for x in items {
                l.append(from_value(py, x)?)?;
            }
            l.into_any()
        }
        Value::Map(entries) => {
            let d = PyDict::new(py);
            for (k, x) in entries {
                d.set_item(k, from_value(py, x)?)?;
            }
            d.into_any()
        }
    })
}

pub(super) fn vec3_array<'py>(py: Python<'py>, v: &Vector3<f64>) -> Bound<'py, PyArray1<f64>> {
    vec![v.x, v.y, v.z].into_pyarray(py)
}

pub(super) fn rows3<'py>(py: Python<'py>, vs: &[Vector3<f64>]) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((vs.len(), 3), |(i, c)| vs[i][c]).into_pyarray(py)
}

pub(super) fn rows4<'py>(py: Python<'py>, qs: &[Quat]) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((qs.len(), 4), |(i, c)| qs[i].to_array()[c]).into_pyarray(py)
}

/// An optional argument that was given (Python's None means "the default").
pub(super) fn given<'py>(x: Option<&Bound<'py, PyAny>>) -> Option<Bound<'py, PyAny>> {
    x.filter(|o| !o.is_none()).cloned()
}

pub(super) fn rows_n<'py, const N: usize>(
    py: Python<'py>,
    rows: &[[f64; N]],
) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((rows.len(), N), |(i, c)| rows[i][c]).into_pyarray(py)
}

/// An (m, N) float argument. A float64 array of that shape is read as it is;
/// anything else (lists, other dtypes such as longdouble or object, junk) goes
/// through `to_value`, converted or refused by the rules of a scene's values.
pub(super) fn rows_arg<const N: usize>(
    name: &str,
    obj: &Bound<'_, PyAny>,
) -> PyResult<Vec<[f64; N]>> {
    let rows = rows_of::<N>(name, obj)?;
    let path = Path::argument(name);
    for (i, row) in rows.iter().enumerate() {
        for (j, x) in row.iter().enumerate() {
            if !x.is_finite() {
                return Err(path
                    .index(i)
                    .index(j)
                    .error(format!("must be finite, got {x}")));
            }
        }
    }
    Ok(rows)
}

/// The rows of an (m, N) array by `rows_arg`'s rules, finite or not (a
/// stored state may hold the overflow that ended its solve).
pub(super) fn rows_of<const N: usize>(
    name: &str,
    obj: &Bound<'_, PyAny>,
) -> PyResult<Vec<[f64; N]>> {
    let path = Path::argument(name);
    Ok(match obj.extract::<PyReadonlyArray2<f64>>() {
        Ok(a) if a.as_array().ncols() == N => a
            .as_array()
            .rows()
            .into_iter()
            .map(|r| std::array::from_fn(|c| r[c]))
            .collect(),
        _ => match to_value(obj, &path)? {
            Value::List(items) => items
                .iter()
                .enumerate()
                .map(|(i, row)| numbers::<N>(row, &path.index(i)))
                .collect::<PyResult<_>>()?,
            other => {
                return Err(path.error(format!(
                    "expected an array of shape (m, {N}), got {}",
                    other.kind()
                )))
            }
        },
    })
}

/// A real argument that may be infinite or NaN (a stored residual), refused by name.
pub(super) fn number_or_infinite(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<f64> {
    let path = Path::argument(name);
    match to_value(obj, &path)? {
        Value::Number(x) => Ok(x),
        _ => Err(path.error(format!("expected a number, got {}", type_name(obj)))),
    }
}

/// A bool argument (not an int), refused by name.
pub(super) fn bool_arg(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<bool> {
    match obj.cast::<PyBool>() {
        Ok(b) => Ok(b.is_true()),
        Err(_) => {
            Err(Path::argument(name).error(format!("expected a bool, got {}", type_name(obj))))
        }
    }
}

/// Python's spelling of a bool, for a `repr`.
pub(super) fn python_bool(b: bool) -> &'static str {
    if b {
        "True"
    } else {
        "False"
    }
}

/// The fields of a dict that stores a result (`Solution.to_dict()`), read by
/// name: a missing key is refused as `owner.key`.
pub(super) struct Fields<'py> {
    owner: &'static str,
    dict: Bound<'py, PyDict>,
}

impl<'py> Fields<'py> {
    /// The fields of `data`, every key of which is one of `keys` (a key
    /// that `to_dict()` never writes is a mistake, not something to drop).
    pub(super) fn new(
        owner: &'static str,
        data: &Bound<'py, PyAny>,
        keys: &[&str],
    ) -> PyResult<Self> {
        let dict = data.cast::<PyDict>().map_err(|_| {
            Path::input(owner).error(format!(
                "expected a dict (from to_dict()), got {}",
                type_name(data)
            ))
        })?;
        for key in dict.keys() {
            let known = key
                .cast::<PyString>()
                .ok()
                .and_then(|k| k.to_str().ok().map(|k| keys.contains(&k)));
            if known != Some(true) {
                return Err(Path::input(owner).error(format!(
                    "unknown key {} (expected the keys of to_dict(): {})",
                    key.repr()?,
                    keys.join(", ")
                )));
            }
        }
        // What `np.load` gives back for a scalar (a 0-d array) is read as
        // the scalar: a dict saved by `np.savez(**to_dict())` loads again.
        let unwrapped = PyDict::new(dict.py());
        for (key, value) in dict.iter() {
            let scalar = value
                .cast::<numpy::PyUntypedArray>()
                .is_ok_and(|a| numpy::PyUntypedArrayMethods::ndim(a) == 0);
            if scalar {
                unwrapped.set_item(key, value.call_method0("item")?)?;
            } else {
                unwrapped.set_item(key, value)?;
            }
        }
        Ok(Fields {
            owner,
            dict: unwrapped,
        })
    }

    fn name(&self, key: &str) -> String {
        format!("{}.{key}", self.owner)
    }

    pub(super) fn get(&self, key: &str) -> PyResult<Bound<'py, PyAny>> {
        self.dict.get_item(key)?.ok_or_else(|| {
            PyValueError::new_err(format!(
                "{}: missing (every key of to_dict() is needed)",
                self.name(key)
            ))
        })
    }

    pub(super) fn rows<const N: usize>(&self, key: &str) -> PyResult<Vec<[f64; N]>> {
        rows_of::<N>(&self.name(key), &self.get(key)?)
    }

    pub(super) fn vectors(&self, key: &str) -> PyResult<Vec<Vector3<f64>>> {
        Ok(self
            .rows::<3>(key)?
            .into_iter()
            .map(Vector3::from)
            .collect())
    }

    pub(super) fn vector(&self, key: &str) -> PyResult<Vector3<f64>> {
        vector_of(&self.name(key), &self.get(key)?)
    }

    pub(super) fn floats(&self, key: &str) -> PyResult<Vec<f64>> {
        floats_arg(&self.name(key), &self.get(key)?)
    }

    /// A key that the dicts of earlier versions lack: empty when absent or None.
    pub(super) fn floats_or_empty(&self, key: &str) -> PyResult<Vec<f64>> {
        match self.dict.get_item(key)? {
            Some(v) if !v.is_none() => floats_arg(&self.name(key), &v),
            _ => Ok(Vec::new()),
        }
    }

    /// A key that the dicts of earlier versions lack: None when absent or None.
    /// A number that the dicts of earlier versions lack: `default` when
    /// absent or None.
    pub(super) fn float_or(&self, key: &str, default: f64) -> PyResult<f64> {
        match self.dict.get_item(key)? {
            Some(v) if !v.is_none() => float_arg(&self.name(key), &v),
            _ => Ok(default),
        }
    }

    pub(super) fn floats_if_given(&self, key: &str) -> PyResult<Option<Vec<f64>>> {
        match self.dict.get_item(key)? {
            Some(v) if !v.is_none() => floats_arg(&self.name(key), &v).map(Some),
            _ => Ok(None),
        }
    }

    /// Rows of a key that the dicts of earlier versions lack: empty when
    /// absent or None.
    /// Booleans (one a row) that the dicts of earlier versions lack: empty
    /// when absent or None.
    pub(super) fn bools_or_empty(&self, key: &str) -> PyResult<Vec<bool>> {
        match self.dict.get_item(key)? {
            Some(v) if !v.is_none() => v.extract::<Vec<bool>>().map_err(|_| {
                crate::error::Error::argument(self.name(key), "expected a list of booleans").into()
            }),
            _ => Ok(Vec::new()),
        }
    }

    pub(super) fn rows_or_empty<const N: usize>(&self, key: &str) -> PyResult<Vec<[f64; N]>> {
        match self.dict.get_item(key)? {
            Some(v) if !v.is_none() => rows_of::<N>(&self.name(key), &v),
            _ => Ok(Vec::new()),
        }
    }

    /// A field that may be None: left out (as `np.savez` must leave out a
    /// None) it is None.
    pub(super) fn optional(&self, key: &str) -> PyResult<Option<Bound<'py, PyAny>>> {
        Ok(given(self.dict.get_item(key)?.as_ref()))
    }

    pub(super) fn optional_vector(&self, key: &str) -> PyResult<Option<Vector3<f64>>> {
        self.optional(key)?
            .map(|v| vector_of(&self.name(key), &v))
            .transpose()
    }
}

/// The N numbers of a list (finiteness is the caller's check).
pub(super) fn numbers<const N: usize>(v: &Value, path: &Path) -> PyResult<[f64; N]> {
    let items = match v {
        Value::List(items) if items.len() == N => items,
        Value::List(items) => {
            return Err(path.error(format!("expected {N} numbers, got {}", items.len())))
        }
        other => return Err(path.error(format!("expected {N} numbers, got {}", other.kind()))),
    };
    let mut out = [0.0; N];
    for (i, item) in items.iter().enumerate() {
        out[i] = match item {
            Value::Number(x) => *x,
            other => {
                return Err(path
                    .index(i)
                    .error(format!("expected a number, got {}", other.kind())))
            }
        };
    }
    Ok(out)
}

/// A 3-vector argument: a row of `rows_arg`'s rules.
pub(super) fn vec3_arg(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Vector3<f64>> {
    let v = vector_of(name, obj)?;
    for (i, x) in v.iter().enumerate() {
        if !x.is_finite() {
            return Err(Path::argument(name)
                .index(i)
                .error(format!("must be finite, got {x}")));
        }
    }
    Ok(v)
}

/// An orientation, world frame: a unit quaternion `[w, x, y, z]` (scalar
/// first, normalised here) or anything with SciPy's `Rotation.as_quat()`
/// (scalar last). The core refuses a zero or non-finite one by name.
pub(super) fn orientation_arg(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<crate::quat::Quat> {
    let path = Path::argument(name);
    if let Some(q) = rotation(obj, &path)? {
        let [w, x, y, z] =
            numbers::<4>(&q, &path).map_err(|_| path.error("expected a single rotation"))?;
        return Ok(crate::quat::Quat::new(w, x, y, z));
    }
    let q = floats_arg(name, obj)?;
    match q[..] {
        [w, x, y, z] => Ok(crate::quat::Quat::new(w, x, y, z)),
        _ => Err(Path::argument(name).error(format!(
            "expected a quaternion [w, x, y, z] or a scipy Rotation, got {} values",
            q.len()
        ))),
    }
}

/// A 3-vector by `vec3_arg`'s rules, finite or not.
pub(super) fn vector_of(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Vector3<f64>> {
    let path = Path::argument(name);
    let v: [f64; 3] = match obj.extract::<PyReadonlyArray1<f64>>() {
        Ok(a) if a.as_array().len() == 3 => std::array::from_fn(|i| a.as_array()[i]),
        _ => numbers::<3>(&to_value(obj, &path)?, &path)?,
    };
    Ok(Vector3::from(v))
}

/// A flat sequence of numbers (a list or a 1-D array), finite or not (the
/// core checks the values and names the entry).
pub(super) fn floats_arg(name: &str, obj: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    if let Ok(a) = obj.extract::<PyReadonlyArray1<f64>>() {
        return Ok(a.as_array().to_vec());
    }
    let path = Path::argument(name);
    let Value::List(items) = to_value(obj, &path)? else {
        return Err(path.error(format!(
            "expected a sequence of numbers, got {}",
            type_name(obj)
        )));
    };
    items
        .iter()
        .enumerate()
        .map(|(i, item)| match item {
            Value::Number(x) => Ok(*x),
            other => Err(path
                .index(i)
                .error(format!("expected a number, got {}", other.kind()))),
        })
        .collect()
}

// `#[pyo3(from_py_with = ...)]` takes a function path: one converter a name.
/// What a robot carries: a payload mass [kg], or a dict of
/// `crate::robot::Load::KEYS` (read by the core).
pub(super) fn load_arg(obj: &Bound<'_, PyAny>) -> PyResult<Option<crate::robot::Load>> {
    let path = Path::argument("load");
    if obj.is_none() {
        return Ok(None);
    }
    match to_value(obj, &path)? {
        Value::Number(x) if !x.is_finite() => Err(path.error(format!("must be finite, got {x}"))),
        v @ (Value::Number(_) | Value::Map(_)) => Ok(Some(crate::robot::Load::from_value(&v)?)),
        _ => Err(path.error(format!(
            "expected a mass [kg] or a dict of {{{}}}, got {}",
            crate::robot::Load::KEYS.join(", "),
            type_name(obj)
        ))),
    }
}

pub(super) fn points_arg(obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    int_arg("points", obj)
}

pub(super) fn samples_count(obj: &Bound<'_, PyAny>) -> PyResult<usize> {
    int_arg("samples", obj)
}

pub(super) fn seed_arg(obj: &Bound<'_, PyAny>) -> PyResult<u64> {
    u64_arg("seed", obj)
}

pub(super) fn first_arg(obj: &Bound<'_, PyAny>) -> PyResult<u64> {
    u64_arg("first", obj)
}

pub(super) fn check_arg(obj: &Bound<'_, PyAny>) -> PyResult<bool> {
    bool_arg("check", obj)
}

pub(super) fn text_arg(obj: &Bound<'_, PyAny>) -> PyResult<String> {
    str_arg("text", obj)
}

/// A file's path: a string or an `os.PathLike`, refused by name.
pub(super) fn path_arg(obj: &Bound<'_, PyAny>) -> PyResult<std::path::PathBuf> {
    let path = Path::argument("path");
    let text = obj
        .py()
        .import("os")?
        .call_method1("fspath", (obj,))
        .map_err(|_| path.error(format!("expected a path, got {}", type_name(obj))))?;
    Ok(std::path::PathBuf::from(str_arg("path", &text)?))
}

/// Show each of the core's warnings about the caller's input (see
/// `Scene::warnings`) as a `UserWarning` at the caller's line: the first
/// frame outside the package (a batch's Python layer calls the core).
pub(super) fn warn_user(py: Python<'_>, messages: &[String]) -> PyResult<()> {
    if messages.is_empty() {
        return Ok(());
    }
    let category = py.get_type::<pyo3::exceptions::PyUserWarning>();
    let level = user_stack_level(py)?;
    for m in messages {
        let text = std::ffi::CString::new(m.replace('\0', " ")).expect("no interior NUL left");
        PyErr::warn(py, &category, &text, level)?;
    }
    Ok(())
}

/// The `stacklevel` of the innermost frame whose module is not the package.
fn user_stack_level(py: Python<'_>) -> PyResult<i32> {
    let mut frame = py.import("sys")?.call_method1("_getframe", (0,))?;
    let mut level = 1;
    while !frame.is_none() {
        let module: String = frame
            .getattr("f_globals")?
            .get_item("__name__")
            .and_then(|n| n.extract())
            .unwrap_or_default();
        if module != "softspine" && !module.starts_with("softspine.") {
            break;
        }
        level += 1;
        frame = frame.getattr("f_back")?;
    }
    Ok(level)
}

/// A core error about what an argument holds (text that does not parse, a
/// file that cannot be read), said as that argument's: `text: invalid JSON: ...`.
pub(super) fn of_argument(name: &str, e: crate::Error) -> PyErr {
    match e {
        crate::Error::Parse(reason) => PyValueError::new_err(format!("{name}: {reason}")),
        other => other.into(),
    }
}

/// An array-like as a NumPy array of float64 and its shape. What is not an
/// array (lists, tuples) is read as a value first, so that junk inside it
/// (bytes, sets) is refused where it sits rather than converted by NumPy.
fn float_array<'py>(
    name: &str,
    obj: &Bound<'py, PyAny>,
) -> PyResult<(Bound<'py, PyAny>, Vec<usize>)> {
    let py = obj.py();
    let path = Path::argument(name);
    if !(obj.hasattr("__array__")? || obj.hasattr("__array_interface__")?) {
        to_value(obj, &path)?;
    }
    let np = py.import("numpy")?;
    let given = np.call_method1("asarray", (obj,)).map_err(|e| {
        PyValueError::new_err(format!("{name}: not an array of numbers ({})", e.value(py)))
    })?;
    // Real numbers only: NumPy casts complex to real with a mere warning,
    // and booleans, strings and objects to numbers they never were.
    let kind: String = given.getattr("dtype")?.getattr("kind")?.extract()?;
    if !matches!(kind.as_str(), "i" | "u" | "f") {
        let dtype = given.getattr("dtype")?.str()?;
        return Err(path.error(format!("expected real numbers, got an array of {dtype}")));
    }
    let array = np
        .call_method1("asarray", (given, "float64"))
        .map_err(|e| {
            PyValueError::new_err(format!("{name}: not an array of numbers ({})", e.value(py)))
        })?;
    let shape: Vec<usize> = array.getattr("shape")?.extract()?;
    Ok((array, shape))
}

/// Arc lengths `s`: any array-like of numbers (a scalar too), flattened,
/// and its shape (the core checks the values and names the entry).
pub(super) fn stations_arg(obj: &Bound<'_, PyAny>) -> PyResult<(Vec<f64>, Vec<usize>)> {
    let (array, shape) = float_array("s", obj)?;
    let flat = array.call_method0("ravel")?;
    let values = flat.extract::<PyReadonlyArray1<f64>>()?.as_array().to_vec();
    Ok((values, shape))
}

/// `data` (rows of `width` numbers, one a station) as an array of shape
/// `shape + (width,)`.
pub(super) fn shaped<'py>(
    py: Python<'py>,
    data: Vec<f64>,
    mut shape: Vec<usize>,
    width: usize,
) -> PyResult<Bound<'py, PyAny>> {
    shape.push(width);
    let shape = pyo3::types::PyTuple::new(py, shape)?;
    data.into_pyarray(py).call_method1("reshape", (shape,))
}

/// A batch of samples, each `per` rows of `N` numbers: an array-like of
/// shape (count, per, N), as the rows of all samples, one after the other.
pub(super) fn samples_arg<const N: usize>(
    name: &str,
    obj: &Bound<'_, PyAny>,
    per: usize,
) -> PyResult<Vec<[f64; N]>> {
    let (array, shape) = float_array(name, obj)?;
    if shape.len() != 3 || shape[1] != per || shape[2] != N {
        return Err(PyValueError::new_err(format!(
            "{name}: expected shape (samples, {per}, {N}), got {shape:?}"
        )));
    }
    rows_of::<N>(
        name,
        &array.call_method1("reshape", ((shape[0] * per) as i64, N as i64))?,
    )
}

/// A (samples, `width`) array of numbers, one row a sample.
pub(super) fn sample_rows(
    name: &str,
    obj: &Bound<'_, PyAny>,
    width: usize,
) -> PyResult<Vec<Vec<f64>>> {
    let (array, shape) = float_array(name, obj)?;
    if shape.len() != 2 || shape[1] != width {
        return Err(PyValueError::new_err(format!(
            "{name}: expected shape (samples, {width}), got {shape:?}"
        )));
    }
    array.call_method0("tolist")?.extract()
}
