//! The core's named enums (`Status`, `IkEnding`, `Scheme`) as Python string
//! enums, generated from the core at import: their members and docs are the
//! core's, not a hand-kept mirror. A member is a `str` (`sol.status ==
//! "converged"` holds, it prints and serialises as its name) and an `Enum`
//! (`is` compares, `Status("converged")` reads a name, it pickles by name).

use crate::status::NamedEnum;
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyList, PyString, PyTuple, PyType};

/// The Python classes, created once by [`add_enums`].
static STATUS: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static IK_ENDING: PyOnceLock<Py<PyType>> = PyOnceLock::new();
static SCHEME: PyOnceLock<Py<PyType>> = PyOnceLock::new();

/// A `str` enum named `name` (of the module `softspine`, where the package
/// exports it) with the core enum's members, named in upper case.
fn string_enum<'py, E: NamedEnum>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyType>> {
    let members = E::VARIANTS
        .iter()
        .map(|v| (v.name().to_uppercase(), v.name()))
        .collect::<Vec<_>>();
    let kwargs = PyDict::new(py);
    kwargs.set_item("module", "softspine")?;
    kwargs.set_item("type", py.get_type::<PyString>())?;
    let class = py
        .import("enum")?
        .getattr("Enum")?
        .call((name, PyList::new(py, members)?), Some(&kwargs))?
        .cast_into::<PyType>()?;
    // A member prints and formats as its name, as `enum.StrEnum` (3.11+) does.
    let str_type = py.get_type::<PyString>();
    class.setattr("__str__", str_type.getattr("__str__")?)?;
    class.setattr("__format__", str_type.getattr("__format__")?)?;
    class.setattr(
        "__doc__",
        E::DOC.lines().map(str::trim).collect::<Vec<_>>().join(" "),
    )?;
    for v in E::VARIANTS {
        let member = class.getattr(v.name().to_uppercase())?;
        member.setattr("__doc__", v.description())?;
    }
    Ok(class)
}

/// Create the enums and add them to the module.
pub(super) fn add_enums(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    let classes = [
        (&STATUS, string_enum::<crate::Status>(py, "Status")?),
        (&IK_ENDING, string_enum::<crate::IkEnding>(py, "IkEnding")?),
        (&SCHEME, string_enum::<crate::disc::Scheme>(py, "Scheme")?),
    ];
    for (lock, class) in classes {
        m.add(class.name()?, &class)?;
        // A second import of the module (a subinterpreter) keeps the first.
        let _ = lock.set(py, class.unbind());
    }
    Ok(())
}

/// The Python member of a core enum value.
fn member<'py, E: NamedEnum>(
    py: Python<'py>,
    lock: &PyOnceLock<Py<PyType>>,
    value: E,
) -> PyResult<Bound<'py, PyAny>> {
    let class = lock.get(py).ok_or_else(|| {
        pyo3::exceptions::PyRuntimeError::new_err("softspine._core not initialised")
    })?;
    class.bind(py).call1(PyTuple::new(py, [value.name()])?)
}

/// `Solution.status`.
pub(super) fn status(py: Python<'_>, s: crate::Status) -> PyResult<Bound<'_, PyAny>> {
    member(py, &STATUS, s)
}

/// `IkResult.ending`.
pub(super) fn ik_ending(py: Python<'_>, e: crate::IkEnding) -> PyResult<Bound<'_, PyAny>> {
    member(py, &IK_ENDING, e)
}

/// `Solution.scheme`.
pub(super) fn scheme(py: Python<'_>, s: crate::disc::Scheme) -> PyResult<Bound<'_, PyAny>> {
    member(py, &SCHEME, s)
}
