//! `Scene`: the core's scene, built from a dict or a file's text.

use super::convert::*;
use crate::value::Format;
use crate::Scene;
use numpy::PyArray1;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// What is being solved: a rod or robot backbone, its loads and boundary conditions.
///
/// Build it from a dict (``Scene({...})``), a JSON or TOML file
/// (``Scene.from_file(path)``); invalid input raises ``ValueError`` naming the key.
#[pyclass(
    name = "Scene",
    module = "softspine._core",
    frozen,
    skip_from_py_object
)]
#[derive(Clone)]
pub struct PyScene {
    pub(super) inner: Scene,
}

#[pymethods]
impl PyScene {
    #[new]
    #[pyo3(text_signature = "(data)")]
    fn new(data: &Bound<'_, PyAny>) -> PyResult<Self> {
        if let Ok(s) = data.cast::<PyScene>() {
            return Ok(s.get().clone());
        }
        if data.is_instance_of::<PyDict>() {
            let inner = Scene::from_value(&to_value(data, &Path::input("scene"))?)?;
            warn_user(data.py(), &inner.warnings())?;
            return Ok(PyScene { inner });
        }
        // (A dict first: importing `os` for the path test costs as much as
        // reading a small scene.)
        let os = data.py().import("os")?;
        if data.is_instance_of::<pyo3::types::PyString>()
            || data.is_instance(&os.getattr("PathLike")?)?
        {
            let path: String = os.call_method1("fspath", (data,))?.extract()?;
            let inner = Scene::from_file(std::path::Path::new(&path))
                .map_err(|e| of_argument("scene", e))?;
            warn_user(data.py(), &inner.warnings())?;
            return Ok(PyScene { inner });
        }
        Err(PyValueError::new_err(format!(
            "scene: expected a Scene, a dict or a file's path, got {}",
            data.get_type().name()?
        )))
    }

    /// Read a scene from a JSON string.
    #[staticmethod]
    fn from_json(#[pyo3(from_py_with = text_arg)] text: String) -> PyResult<Self> {
        Ok(PyScene {
            inner: Scene::from_json_str(&text).map_err(|e| of_argument("text", e))?,
        })
    }

    /// Read a scene from a TOML string.
    #[staticmethod]
    fn from_toml(#[pyo3(from_py_with = text_arg)] text: String) -> PyResult<Self> {
        Ok(PyScene {
            inner: Scene::from_toml_str(&text).map_err(|e| of_argument("text", e))?,
        })
    }

    /// Read a scene from a ``.json`` or ``.toml`` file.
    #[staticmethod]
    fn from_file(#[pyo3(from_py_with = path_arg)] path: std::path::PathBuf) -> PyResult<Self> {
        Ok(PyScene {
            inner: Scene::from_file(&path).map_err(|e| of_argument("path", e))?,
        })
    }

    /// The scene as JSON text (``Scene.from_json`` reads it back).
    fn to_json(&self) -> PyResult<String> {
        Ok(self.inner.to_text(Format::Json)?)
    }

    /// The scene as TOML text (``Scene.from_toml`` reads it back).
    fn to_toml(&self) -> PyResult<String> {
        Ok(self.inner.to_text(Format::Toml)?)
    }

    /// Write the scene to a ``.json`` or ``.toml`` file (by its suffix),
    /// which ``Scene.from_file`` reads back to the same scene.
    fn save(&self, #[pyo3(from_py_with = path_arg)] path: std::path::PathBuf) -> PyResult<()> {
        self.inner
            .write_file(&path)
            .map_err(|e| of_argument("path", e))
    }

    /// Pickling goes through ``to_dict``.
    fn __reduce__<'py>(
        slf: &Bound<'py, Self>,
    ) -> PyResult<(Bound<'py, PyAny>, (Bound<'py, PyAny>,))> {
        Ok((slf.get_type().into_any(), (slf.get().to_dict(slf.py())?,)))
    }

    /// The scene as a plain dict (round-trips through ``Scene(d)``).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        from_value(py, &self.inner.to_value())
    }

    /// Length of the rod, m.
    #[getter]
    fn length(&self) -> f64 {
        self.inner.length
    }

    /// ``(kx, ky, kz)`` in N m^2.
    #[getter]
    fn stiffness(&self) -> (f64, f64, f64) {
        let k = self.inner.stiffness();
        (k.x, k.y, k.z)
    }

    /// Number of equal sections (of the rest curvature).
    #[getter]
    fn sections(&self) -> usize {
        self.inner.sections()
    }

    /// The scene's name, if it has one.
    #[getter]
    fn name(&self) -> Option<String> {
        self.inner.name.clone()
    }

    /// Total distributed force, gravity included (N/m).
    #[getter]
    fn distributed_force<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        vec3_array(py, &self.inner.distributed_force())
    }

    fn __repr__(&self) -> String {
        let k = self.inner.stiffness();
        format!(
            "Scene(name={:?}, length={}, stiffness=({:.4e}, {:.4e}, {:.4e}), sections={})",
            self.inner.name.as_deref().unwrap_or(""),
            self.inner.length,
            k.x,
            k.y,
            k.z,
            self.inner.sections()
        )
    }
}

/// A scene: a Scene, a dict or the path of a `.json` / `.toml` file.
pub(super) fn scene_arg(scene: &Bound<'_, PyAny>) -> PyResult<Scene> {
    Ok(PyScene::new(scene)?.inner)
}

/// An obstacle as the core reads it: checked, a mesh's ``file`` read and
/// placed (its ``vertices`` and ``triangles`` in the world frame), as a
/// dict. Invalid input raises ``ValueError`` naming the key.
#[pyfunction]
pub(super) fn read_obstacle<'py>(obstacle: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    let value = to_value(obstacle, &Path::argument("obstacle"))?;
    let read = crate::contact::Obstacle::from_value(&value, "obstacle")?;
    from_value(obstacle.py(), &read.to_value())
}

/// The key reference: ``{"scene": [...], "robot": [...]}``, each key a dict
/// of its ``name`` (``stiffness.E``, ``point_loads[].s``), ``unit``,
/// ``default`` and ``meaning``, as the core documents what its readers take.
#[pyfunction]
pub(super) fn keys(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let out = PyDict::new(py);
    for (kind, table) in [("scene", crate::keys::SCENE), ("robot", crate::keys::ROBOT)] {
        let rows = pyo3::types::PyList::empty(py);
        for k in table {
            let row = PyDict::new(py);
            row.set_item("name", k.name)?;
            row.set_item("unit", k.unit)?;
            row.set_item("default", k.default)?;
            row.set_item("meaning", k.meaning)?;
            rows.append(row)?;
        }
        out.set_item(kind, rows)?;
    }
    Ok(out)
}
