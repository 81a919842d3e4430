//! Batches: `solve_batch` here, `Robot.forward_batch`, `inverse_batch` and
//! `workspace` in `robot.rs`. The results become the dataclasses of
//! `softspine.batch` (arrays, one row a sample).

use super::convert::*;
use super::detach::detach_batch;
use super::scene::scene_arg;
use super::solve::settings_with;
use crate::robot::{Actuation, DriveColumns};
use crate::{BatchControl, BatchSettings, IkSample, Sample, Status};
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// The batch keywords every batch call takes, read into the core's settings.
pub(super) fn batch_settings(
    threads: Option<&Bound<'_, PyAny>>,
    chunk: Option<&Bound<'_, PyAny>>,
    warm_start: Option<&Bound<'_, PyAny>>,
    shapes: Option<&Bound<'_, PyAny>>,
) -> PyResult<BatchSettings> {
    let mut s = BatchSettings::default();
    if let Some(t) = given(threads) {
        s.threads = Some(int_arg("threads", &t)?);
    }
    if let Some(c) = given(chunk) {
        s.chunk = int_arg("chunk", &c)?;
    }
    if let Some(w) = given(warm_start) {
        s.warm_start = bool_arg("warm_start", &w)?;
    }
    if let Some(x) = given(shapes) {
        s.shapes = bool_arg("shapes", &x)?;
    }
    s.validate()?;
    Ok(s)
}

/// `progress`: None or a callable `progress(done, total)`; `softspine.batch`
/// turns the user's None, True or False into one before the call.
fn progress_arg<'py>(progress: Option<&Bound<'py, PyAny>>) -> PyResult<Option<Bound<'py, PyAny>>> {
    match given(progress) {
        None => Ok(None),
        Some(p) if p.is_callable() => Ok(Some(p)),
        Some(p) => Err(Path::argument("progress").error(format!(
            "expected a callable progress(done, total), got {}",
            type_name(&p)
        ))),
    }
}

/// A batch call that runs here (`None`) or, with `plan=True`, only reads
/// its arguments as the batch would and returns how a cluster cuts it:
/// `(chunk, part)`, the samples of a worker's run and of a task
/// (`softspine.distributed` calls it so before it cuts the batch).
pub(super) fn cluster_plan<'py>(
    py: Python<'py>,
    plan: Option<&Bound<'py, PyAny>>,
    part: Option<&Bound<'py, PyAny>>,
    settings: &BatchSettings,
) -> PyResult<Option<Bound<'py, PyAny>>> {
    let part = given(part).map(|p| int_arg("part", &p)).transpose()?;
    let planned = given(plan).map(|p| bool_arg("plan", &p)).transpose()?;
    if planned != Some(true) {
        return match part {
            Some(_) => Err(Path::argument("part").error(
                "the samples of one task on a cluster: give it with executor= (a local batch is \
                 cut into chunk= samples a worker)",
            )),
            None => Ok(None),
        };
    }
    let part = settings.part(part)?;
    Ok(Some((settings.chunk, part).into_pyobject(py)?.into_any()))
}

/// Run `work` with a fresh [`BatchControl`] (see `detach_batch`).
pub(super) fn run_batch<T: Send>(
    py: Python<'_>,
    total: usize,
    progress: Option<&Bound<'_, PyAny>>,
    work: impl FnOnce(&BatchControl) -> crate::Result<T> + Send,
) -> PyResult<T> {
    let progress = progress_arg(progress)?;
    let control = BatchControl::default();
    detach_batch(py, &control, total, progress.as_ref(), || work(&control))
}

/// An array of names (`numpy.str_`) from the core's names.
fn names<'py>(py: Python<'py>, names: Vec<&'static str>) -> PyResult<Bound<'py, PyAny>> {
    py.import("numpy")?
        .call_method1("asarray", (PyList::new(py, names)?, "U"))
}

/// The drives of a robot's batch: each sample's actuation, and which of its
/// drives the result reports (the core's [`crate::robot::DriveColumns`]).
pub(super) struct Drives<'a> {
    pub(super) actuations: Vec<&'a Actuation>,
    pub(super) columns: DriveColumns,
    pub(super) sections: usize,
    pub(super) tendons: usize,
}

/// Set the drive columns (`actuations` or `rest_curvature`, `tensions`,
/// `field`) of a result's fields, a row a sample (an empty part of an
/// actuation is its zero: straight, slack).
fn set_drives(d: &Bound<'_, PyDict>, drives: &Drives<'_>, curvature_key: &str) -> PyResult<()> {
    let py = d.py();
    let a = &drives.actuations;
    let count = a.len();
    let (m, t) = (drives.sections, drives.tendons);
    if drives.columns.rest_curvature {
        let k = Array3::from_shape_fn((count, m, 2), |(i, s, c)| {
            a[i].rest_curvature.get(s).map_or(0.0, |k| k[c])
        });
        d.set_item(curvature_key, k.into_pyarray(py))?;
    }
    if drives.columns.tensions {
        let x = Array2::from_shape_fn((count, t), |(i, j)| {
            a[i].tensions.get(j).copied().unwrap_or(0.0)
        });
        d.set_item("tensions", x.into_pyarray(py))?;
    }
    if drives.columns.field {
        let b = Array2::from_shape_fn((count, 3), |(i, c)| a[i].field[c]);
        d.set_item("field", b.into_pyarray(py))?;
    }
    if drives.columns.insertion {
        let x = Array1::from_iter(a.iter().map(|a| a.insertion));
        d.set_item("insertion", x.into_pyarray(py))?;
    }
    Ok(())
}

/// The fields of a `softspine.batch.BatchResult` of forward samples, with
/// the drives of a robot's batch.
pub(super) fn batch_result<'py>(
    py: Python<'py>,
    samples: &[Sample],
    drives: Option<&Drives<'_>>,
) -> PyResult<Bound<'py, PyDict>> {
    let count = samples.len();
    let d = PyDict::new(py);
    if let Some(drives) = drives {
        set_drives(&d, drives, "actuations")?;
    }
    let tips = Array2::from_shape_fn((count, 3), |(i, c)| samples[i].tip_position[c]);
    let quats = Array2::from_shape_fn((count, 4), |(i, c)| samples[i].tip_quaternion.to_array()[c]);
    d.set_item("tip_positions", tips.into_pyarray(py))?;
    d.set_item("tip_quaternions", quats.into_pyarray(py))?;
    let status: Vec<&'static str> = samples.iter().map(|s| Status::name(s.status)).collect();
    d.set_item("status", names(py, status)?)?;
    let stable = Array1::from_iter(samples.iter().map(|s| s.stable));
    d.set_item("stable", stable.into_pyarray(py))?;
    let iterations = Array1::from_iter(samples.iter().map(|s| s.iterations as i64));
    d.set_item("iterations", iterations.into_pyarray(py))?;
    let residuals = Array1::from_iter(samples.iter().map(|s| s.residual_norm));
    d.set_item("residual_norms", residuals.into_pyarray(py))?;
    let shapes: Option<Vec<&(Vec<_>, Vec<_>)>> = samples.iter().map(|s| s.shape.as_ref()).collect();
    // Every sample's shape, if they all have the same number of nodes.
    if let Some(shapes) = shapes.filter(|s| !s.is_empty()) {
        let nodes = shapes[0].0.len();
        if shapes.iter().all(|s| s.0.len() == nodes) {
            let p = Array3::from_shape_fn((count, nodes, 3), |(i, j, c)| shapes[i].0[j][c]);
            let q =
                Array3::from_shape_fn((count, nodes, 4), |(i, j, c)| shapes[i].1[j].to_array()[c]);
            d.set_item("positions", p.into_pyarray(py))?;
            d.set_item("quaternions", q.into_pyarray(py))?;
        }
    }
    Ok(d)
}

/// The fields of a `softspine.batch.IkBatchResult` of inverse samples of
/// `robot` (the drives found: the rest curvature, and the tensions or the
/// field of a robot that has them).
pub(super) fn ik_batch_result<'py>(
    py: Python<'py>,
    samples: &[IkSample],
    robot: &crate::Robot,
) -> PyResult<Bound<'py, PyDict>> {
    let count = samples.len();
    let d = PyDict::new(py);
    let found: Vec<Actuation> = samples
        .iter()
        .map(|s| Actuation {
            rest_curvature: s.rest_curvature.clone(),
            tensions: s.tensions.clone(),
            field: s.field,
            insertion: s.insertion,
        })
        .collect();
    let drives = Drives {
        actuations: found.iter().collect(),
        columns: robot.drive_columns(true),
        sections: robot.body.sections,
        tendons: robot.drive.tendon_routes().len(),
    };
    set_drives(&d, &drives, "rest_curvature")?;
    let tips = Array2::from_shape_fn((count, 3), |(i, c)| samples[i].tip_position[c]);
    d.set_item("tip_positions", tips.into_pyarray(py))?;
    let miss = Array1::from_iter(samples.iter().map(|s| s.tip_miss));
    d.set_item("tip_miss", miss.into_pyarray(py))?;
    let reached = Array1::from_iter(samples.iter().map(|s| s.reached));
    d.set_item("reached", reached.into_pyarray(py))?;
    let endings: Vec<&'static str> = samples.iter().map(|s| s.ending.name()).collect();
    d.set_item("ending", names(py, endings)?)?;
    let iterations = Array1::from_iter(samples.iter().map(|s| s.iterations as i64));
    d.set_item("iterations", iterations.into_pyarray(py))?;
    Ok(d)
}

/// Solve many scenes on every core: the fields of a ``BatchResult`` (or,
/// with ``plan=True``, the cut of a cluster's batch: see [`cluster_plan`]). See
/// ``softspine.solve_batch``, which calls it.
#[pyfunction(name = "_solve_batch")]
#[pyo3(signature = (scenes, settings=None, *, n_elements=None, method=None, scheme=None, residual_tol=None, max_iterations=None, shapes=None, threads=None, chunk=None, progress=None, part=None, plan=None))]
#[allow(clippy::too_many_arguments)]
pub(super) fn solve_batch<'py>(
    py: Python<'py>,
    scenes: &Bound<'py, PyAny>,
    settings: Option<&Bound<'py, PyAny>>,
    n_elements: Option<&Bound<'py, PyAny>>,
    method: Option<&Bound<'py, PyAny>>,
    scheme: Option<&Bound<'py, PyAny>>,
    residual_tol: Option<&Bound<'py, PyAny>>,
    max_iterations: Option<&Bound<'py, PyAny>>,
    shapes: Option<&Bound<'py, PyAny>>,
    threads: Option<&Bound<'py, PyAny>>,
    chunk: Option<&Bound<'py, PyAny>>,
    progress: Option<&Bound<'py, PyAny>>,
    part: Option<&Bound<'py, PyAny>>,
    plan: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let text = scenes.is_instance_of::<pyo3::types::PyString>()
        || scenes.is_instance_of::<pyo3::types::PyBytes>();
    let scenes: Vec<crate::Scene> = (!text)
        .then(|| scenes.try_iter().ok())
        .flatten()
        .ok_or_else(|| {
            Path::argument("scenes").error(format!(
                "expected a sequence of Scene or dict, got {}",
                type_name(scenes)
            ))
        })?
        .enumerate()
        .map(|(i, s)| {
            scene_arg(&s?).map_err(|e| {
                pyo3::exceptions::PyValueError::new_err(format!("scenes[{i}]: {}", e.value(py)))
            })
        })
        .collect::<PyResult<_>>()?;
    let solver_settings = settings_with(
        py,
        settings,
        &[
            ("n_elements", n_elements),
            ("method", method),
            ("scheme", scheme),
            ("residual_tol", residual_tol),
            ("max_iterations", max_iterations),
        ],
    )?;
    let batch = batch_settings(threads, chunk, None, shapes)?;
    if let Some(cut) = cluster_plan(py, plan, part, &batch)? {
        return Ok(cut);
    }
    let samples = run_batch(py, scenes.len(), progress, |control| {
        crate::solve_batch(&scenes, &solver_settings, &batch, control)
    })?;
    Ok(batch_result(py, &samples, None)?.into_any())
}
