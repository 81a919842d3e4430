//! The robot's sensitivities to its actuation, load and fields, and the
//! calibration of its fields to measured tip positions.

use super::{Actuation, Load, Robot};
use crate::batch::BatchSettings;
use crate::error::{Error, Result};
use crate::quat::Quat;
use crate::scene::Scene;
use crate::solver::{Sensitivity, Settings, Solution, Solver};
use nalgebra::{DMatrix, DVector, Vector3};
use rayon::prelude::*;

/// A parameter of the robot's forward map, by name.
enum Parameter {
    /// `rest_curvature[s][c]`.
    Curvature(usize, usize),
    /// `muscle_lengths[s][k]`.
    Length(usize, usize),
    /// `load` or `load.mass`: the payload mass [kg].
    Load,
    /// A force or moment component of the load (`load.tip_force[0]`,
    /// `load.point_loads[1].moment[2]`): its path in [`Load::to_table`].
    LoadWrench(String),
    /// `tensions[i]`: a tendon's tension [N].
    Tension(usize),
    /// `field[c]`: a component of the external magnetic field [T].
    MagneticField(usize),
    /// `insertion`: the base moved along its tangent [m].
    Insertion,
    /// A numeric field of `Robot::to_value` (`"stiffness.E"`, `"linear_density"`).
    Field(String),
}

impl Robot {
    /// The parameters named, `"rest_curvature"` and `"muscle_lengths"`
    /// standing for all of a section's components.
    fn parameters(&self, names: &[&str]) -> Result<Vec<(String, Parameter)>> {
        let mut out = Vec::new();
        for (i, &name) in names.iter().enumerate() {
            self.parameter(name, &mut out)
                .map_err(|e| e.of_parameter(i, name))?;
        }
        Ok(out)
    }

    /// `(section, column)` of a name `prefix[section][column]`, None for
    /// another prefix.
    fn section_index(
        &self,
        name: &str,
        prefix: &str,
        columns: usize,
    ) -> Result<Option<(usize, usize)>> {
        let Some(rest) = name.strip_prefix(prefix) else {
            return Ok(None);
        };
        let parsed: Vec<usize> = rest
            .split(']')
            .filter(|s| !s.is_empty())
            .map(|s| s.strip_prefix('[').and_then(|x| x.parse().ok()))
            .collect::<Option<_>>()
            .unwrap_or_default();
        match parsed[..] {
            [s, c] if s < self.body.sections && c < columns => Ok(Some((s, c))),
            _ => Err(Error::argument(
                name.to_string(),
                format!(
                    "expected {prefix}[section][0..{columns}] with fewer than {} sections",
                    self.body.sections
                ),
            )),
        }
    }

    /// Append the parameters `name` stands for to `out`.
    fn parameter(&self, name: &str, out: &mut Vec<(String, Parameter)>) -> Result<()> {
        match name {
            "rest_curvature" | "muscle_lengths" => {
                let columns = if name == "rest_curvature" { 2 } else { 3 };
                for s in 0..self.body.sections {
                    for c in 0..columns {
                        let p = if columns == 2 {
                            Parameter::Curvature(s, c)
                        } else {
                            Parameter::Length(s, c)
                        };
                        out.push((format!("{name}[{s}][{c}]"), p));
                    }
                }
            }
            "load" | "load.mass" => out.push((name.into(), Parameter::Load)),
            "insertion" => out.push((name.into(), Parameter::Insertion)),
            "tensions" => out.extend(
                (0..self.drive.tendon_routes().len())
                    .map(|i| (format!("tensions[{i}]"), Parameter::Tension(i))),
            ),
            "field" => {
                out.extend((0..3).map(|c| (format!("field[{c}]"), Parameter::MagneticField(c))))
            }
            _ => {
                if let Some(path) = name.strip_prefix("load.") {
                    return load_wrench(name, path, out);
                }
                if let Some(i) = one_index(name, "tensions", self.drive.tendon_routes().len())? {
                    out.push((name.into(), Parameter::Tension(i)));
                } else if let Some(c) = one_index(name, "field", 3)? {
                    out.push((name.into(), Parameter::MagneticField(c)));
                } else if let Some((s, c)) = self.section_index(name, "rest_curvature", 2)? {
                    out.push((name.into(), Parameter::Curvature(s, c)));
                } else if let Some((s, c)) = self.section_index(name, "muscle_lengths", 3)? {
                    out.push((name.into(), Parameter::Length(s, c)));
                } else {
                    if matches!(name, "sections" | "n_elements") {
                        return Err(Error::argument(name, "a count, not a parameter"));
                    }
                    self.to_value().number_at_mut(name)?;
                    out.push((name.into(), Parameter::Field(name.into())));
                }
            }
        }
        Ok(())
    }

    /// The value of a parameter at an actuation and a tip mass.
    fn parameter_value(&self, p: &Parameter, a: &Actuation, load: &Load) -> Result<f64> {
        let kappa = &a.rest_curvature;
        Ok(match p {
            Parameter::Curvature(s, c) => kappa.get(*s).map_or(0.0, |k| k[*c]),
            Parameter::Length(s, c) => self.muscle_lengths(&self.curvature_of(a))?[*s][*c],
            Parameter::Load => load.mass,
            Parameter::LoadWrench(path) => *load.to_table().number_at_mut(path).map_err(|_| {
                Error::argument(
                    format!("load.{path}"),
                    format!(
                        "not in the load, which has {} point loads",
                        load.point_loads.len()
                    ),
                )
            })?,
            Parameter::Tension(i) => a.tensions.get(*i).copied().unwrap_or(0.0),
            Parameter::MagneticField(c) => a.field[*c],
            Parameter::Insertion => a.insertion,
            Parameter::Field(path) => *self.to_value().number_at_mut(path)?,
        })
    }

    /// The actuation's rest curvature (straight when not given).
    fn curvature_of(&self, a: &Actuation) -> Vec<[f64; 2]> {
        if a.rest_curvature.is_empty() {
            vec![[0.0; 2]; self.body.sections]
        } else {
            a.rest_curvature.clone()
        }
    }

    /// The scene with a parameter moved by `delta`.
    fn scene_moved(&self, p: &Parameter, a: &Actuation, load: &Load, delta: f64) -> Result<Scene> {
        let mut moved = Actuation {
            rest_curvature: self.curvature_of(a),
            ..a.clone()
        };
        match p {
            Parameter::Curvature(s, c) => moved.rest_curvature[*s][*c] += delta,
            Parameter::Length(s, c) => {
                let mut lengths = self.muscle_lengths(&moved.rest_curvature)?;
                lengths[*s][*c] += delta;
                moved.rest_curvature = self.rest_curvature(&lengths)?;
            }
            Parameter::Load => {
                // The tip mass enters only as the tip force `(m + tool) g`,
                // linearly: a difference through zero (no payload) is as
                // exact as any, past the check that a mass is not negative.
                let mut scene = self.scene(a, load)?;
                scene.tip_force += delta * self.body.gravity;
                return Ok(scene);
            }
            Parameter::LoadWrench(path) => {
                // Linear in every force and moment: the load is rebuilt
                // through its reader (which checks only that they are finite).
                let mut v = load.to_table();
                *v.number_at_mut(path)? += delta;
                return self.scene(a, &Load::from_value(&v)?);
            }
            Parameter::Tension(i) => {
                // The equations are linear in a tension: a difference through
                // zero (a slack tendon) is as exact as any, so the scene is
                // built without the non-negativity check.
                let tension = moved.tensions.get(*i).copied().unwrap_or(0.0);
                moved.tensions = Vec::new();
                let mut scene = self.scene(&moved, load)?;
                for (k, t) in scene.tendons.iter_mut().enumerate() {
                    t.tension = a.tensions.get(k).copied().unwrap_or(0.0);
                }
                scene.tendons[*i].tension = tension + delta;
                return Ok(scene);
            }
            Parameter::MagneticField(c) => {
                // Past max_field by a difference step: built as the scene.
                let field = moved.field;
                moved.field = Vector3::zeros();
                let mut scene = self.scene(&moved, load)?;
                scene.magnetic_field = field;
                scene.magnetic_field[*c] += delta;
                return Ok(scene);
            }
            Parameter::Field(path) => {
                let mut v = self.to_value();
                *v.number_at_mut(path)? += delta;
                return Robot::from_value(&v)?.scene(a, load);
            }
            Parameter::Insertion => {
                // A difference past the stage's range is still a rod: the
                // base moved as the scene's, not checked against the range.
                let mut scene = self.scene(a, load)?;
                scene.base_position += delta * self.insertion_axis();
                return Ok(scene);
            }
        }
        self.scene(&moved, load)
    }

    /// The forward solver of this robot (its default discretisation).
    pub(crate) fn forward_solver(&self, kappa: &[[f64; 2]], load: &Load) -> Result<Solver> {
        self.actuated_solver(
            &Actuation {
                rest_curvature: kappa.to_vec(),
                ..Actuation::default()
            },
            load,
        )
    }

    /// The forward solver of this robot under a whole actuation.
    pub(crate) fn actuated_solver(&self, a: &Actuation, load: &Load) -> Result<Solver> {
        let settings = Settings {
            n_elements: Some(self.n_elements),
            ..Settings::default()
        };
        Solver::new(&self.scene(a, load)?, settings)
    }

    /// The loaded equilibrium of an actuation and its tip's sensitivity to
    /// the named parameters: `"rest_curvature"`, `"muscle_lengths"` (or one
    /// component, `"muscle_lengths[2][0]"`), `"tensions"` (or
    /// `"tensions[i]"`), `"field"` (or `"field[c]"`), `"load"` (the tip
    /// mass), `"insertion"` (the base along its tangent) and any numeric field of the robot (`"stiffness.E"`,
    /// `"linear_density"`, `"disk_mass"`; `"inflation_rate"` has no effect
    /// on statics).
    pub fn sensitivity(
        &self,
        actuation: &Actuation,
        load: &Load,
        names: &[&str],
        initial: Option<&[Quat]>,
    ) -> Result<(Solution, Sensitivity)> {
        let parameters = self.parameters(names)?;
        let mut solver = self.actuated_solver(actuation, load)?;
        let sol = solver.solve_warm_or_cold(initial)?;
        if !sol.converged() {
            return Err(Error::NotConverged {
                status: sol.status,
                iterations: sol.iterations,
                residual: sol.residual_norm,
                reason: format!("the forward solve: {}", sol.message),
            });
        }
        let values = parameters
            .iter()
            .map(|(_, p)| self.parameter_value(p, actuation, load))
            .collect::<Result<Vec<_>>>()?;
        let names = parameters.iter().map(|(n, _)| n.clone()).collect();
        let sens = solver.sensitivity_with(names, &values, |j, delta| {
            self.scene_moved(&parameters[j].1, actuation, load, delta)
        })?;
        Ok((sol, sens))
    }
}

/// The parameters of a load's wrench named `name` (`path` after `load.`):
/// a component (`tip_force[0]`, `point_loads[1].moment[2]`), or a vector
/// (`tip_force`, `point_loads[1].force`) standing for its three. A point
/// load's arc length is refused: it snaps to a node, not a smooth parameter.
fn load_wrench(name: &str, path: &str, out: &mut Vec<(String, Parameter)>) -> Result<()> {
    let field = path.rsplit('.').next().unwrap_or(path);
    let vector = field.split('[').next().unwrap_or(field);
    if !matches!(vector, "tip_force" | "tip_moment" | "force" | "moment")
        || (matches!(vector, "force" | "moment") && !path.starts_with("point_loads["))
    {
        return Err(Error::argument(
            name,
            "expected load.mass, load.tip_force, load.tip_moment or \
             load.point_loads[j].force / .moment (each [i] for one component)",
        ));
    }
    if let Some(index) = field.strip_prefix(vector).filter(|i| !i.is_empty()) {
        if !matches!(index, "[0]" | "[1]" | "[2]") {
            return Err(Error::argument(
                name,
                "a component is [0], [1] or [2] (world frame)",
            ));
        }
        out.push((name.into(), Parameter::LoadWrench(path.into())));
    } else {
        out.extend((0..3).map(|i| {
            (
                format!("{name}[{i}]"),
                Parameter::LoadWrench(format!("{path}[{i}]")),
            )
        }));
    }
    Ok(())
}

/// `prefix[i]` with `i < count`, or `None` for another name.
fn one_index(name: &str, prefix: &str, count: usize) -> Result<Option<usize>> {
    let Some(rest) = name.strip_prefix(prefix) else {
        return Ok(None);
    };
    if !rest.starts_with('[') {
        return Ok(None);
    }
    match rest
        .strip_prefix('[')
        .and_then(|r| r.strip_suffix(']'))
        .and_then(|i| i.parse::<usize>().ok())
    {
        Some(i) if i < count => Ok(Some(i)),
        _ => Err(Error::argument(
            name.to_string(),
            format!("expected {prefix}[0..{count}]"),
        )),
    }
}

/// How a calibration iterates.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationSettings {
    /// Gauss-Newton iterations at most.
    pub max_iterations: usize,
    /// Converged when no parameter moves by more than this fraction of its
    /// scale (the magnitude of its starting value).
    pub step_tol: f64,
    /// How the forward solves of an iteration are spread over the cores.
    pub batch: BatchSettings,
}

impl Default for CalibrationSettings {
    fn default() -> Self {
        CalibrationSettings {
            max_iterations: 30,
            step_tol: 1e-9,
            batch: BatchSettings::default(),
        }
    }
}

/// Fitted robot parameters.
#[derive(Debug, Clone)]
pub struct Calibration {
    pub parameters: Vec<String>,
    /// Least-squares estimates.
    pub estimates: Vec<f64>,
    /// Their standard errors, from the residual variance and `(J^T J)^-1`.
    pub standard_errors: Vec<f64>,
    /// Covariance of the estimates, row-major `k x k`.
    pub covariance: Vec<f64>,
    /// `measured - model` tip per sample at the estimates [m].
    pub residuals: Vec<Vector3<f64>>,
    /// Root mean square of the residual components [m].
    pub rms: f64,
    pub iterations: usize,
    pub converged: bool,
    /// The robot with the estimates.
    pub robot: Robot,
    pub message: String,
}

impl Robot {
    /// With the fields named set to `values`.
    fn with_fields(&self, names: &[String], values: &[f64]) -> Result<Robot> {
        let mut v = self.to_value();
        for (name, x) in names.iter().zip(values) {
            *v.number_at_mut(name)? = *x;
        }
        Robot::from_value(&v)
    }

    /// Fit the named fields of the robot (any numeric field of
    /// [`Robot::to_value`], e.g. `"stiffness.E"`, `"linear_density"`,
    /// `"disk_mass"`, `"muscle_radius"`; `"load"` is the tip mass, the same
    /// for every sample) to tip positions measured at known actuations
    /// (`actuations`: `sections` rows a sample), by Gauss-Newton with the
    /// sensitivities of every sample (on every core) and a step halved
    /// until the squared residual drops.
    pub fn calibrate(
        &self,
        actuations: &[[f64; 2]],
        measured_tips: &[Vector3<f64>],
        load: &Load,
        names: &[&str],
        settings: &CalibrationSettings,
    ) -> Result<Calibration> {
        settings.batch.validate()?;
        let m = self.body.sections;
        let measured = measured_tips;
        if actuations.len() != measured.len() * m {
            return Err(Error::argument(
                "measured_tips",
                format!(
                    "{} tips for {} samples of actuations",
                    measured.len(),
                    actuations.len() / m.max(1)
                ),
            ));
        }
        if let Some(i) = actuations
            .iter()
            .position(|k| !k.iter().all(|x| x.is_finite()))
        {
            return Err(Error::argument(
                format!("actuations[{}][{}]", i / m, i % m),
                "must be finite",
            ));
        }
        if let Some(i) = measured
            .iter()
            .position(|t| !t.iter().all(|x| x.is_finite()))
        {
            return Err(Error::argument(
                format!("measured_tips[{i}]"),
                "must be finite",
            ));
        }
        let parameters = self.parameters(names)?;
        let fields: Vec<String> = parameters
            .iter()
            .map(|(name, p)| match p {
                Parameter::Field(_) | Parameter::Load | Parameter::LoadWrench(_) => {
                    Ok(name.clone())
                }
                _ => Err(Error::argument(
                    name.clone(),
                    "the actuation is known: fit robot fields or the load",
                )),
            })
            .collect::<Result<_>>()?;
        let k = fields.len();
        if k == 0 || 3 * measured.len() <= k {
            return Err(Error::argument(
                "parameters",
                format!("{k} parameters need more than {k} / 3 measured tips"),
            ));
        }
        let start: Vec<f64> = parameters
            .iter()
            .map(|(_, p)| {
                let first = Actuation {
                    rest_curvature: actuations[..m].to_vec(),
                    ..Actuation::default()
                };
                self.parameter_value(p, &first, load)
            })
            .collect::<Result<_>>()?;
        // A wrench that starts at zero (an unknown tip force) is scaled by
        // the robot's weight, and its moment by the weight times the length.
        let weight = self.body.own_mass() * self.body.gravity.norm();
        let scale: Vec<f64> = start
            .iter()
            .zip(&parameters)
            .map(|(x, (_, p))| {
                let natural = match p {
                    Parameter::LoadWrench(path) if path.contains("moment") => {
                        weight * self.body.length
                    }
                    Parameter::LoadWrench(_) => weight,
                    _ => 0.0,
                };
                x.abs().max(natural).max(1e-12)
            })
            .collect();
        // The robot and load of a parameter vector.
        let split = |p: &[f64]| -> Result<(Robot, Load)> {
            let mut mass = load.mass;
            let mut wrench = load.to_table();
            let mut field_names = Vec::new();
            let mut field_values = Vec::new();
            for ((name, kind), x) in parameters.iter().zip(p) {
                match kind {
                    Parameter::Load => mass = *x,
                    Parameter::LoadWrench(path) => *wrench.number_at_mut(path)? = *x,
                    _ => {
                        field_names.push(name.clone());
                        field_values.push(*x);
                    }
                }
            }
            Ok((
                self.with_fields(&field_names, &field_values)?,
                Load::from_value(&wrench)?.with_mass(mass),
            ))
        };
        let samples: Vec<&[[f64; 2]]> = actuations.chunks(m).collect();
        // Built once: the evaluations of every iteration and line search share it.
        let threads = crate::batch::Threads::new(settings.batch.threads)?;
        let mut warm: Vec<Option<Vec<Quat>>> = vec![None; samples.len()];
        // Residuals (measured - model) and the Jacobian of the model's tips.
        let evaluate = |p: &[f64],
                        warm: &mut Vec<Option<Vec<Quat>>>,
                        jacobian: bool|
         -> Result<(DVector<f64>, Option<DMatrix<f64>>)> {
            let (robot, carried) = split(p)?;
            let names: Vec<&str> = fields.iter().map(|s| s.as_str()).collect();
            let work = |warm: &mut Vec<Option<Vec<Quat>>>| {
                samples
                    .par_iter()
                    .zip(warm.par_iter_mut())
                    .map(
                        |(kappa, q)| -> Result<(Vector3<f64>, Option<Sensitivity>)> {
                            let (sol, sens) = if jacobian {
                                let (sol, sens) = robot.sensitivity(
                                    &Actuation {
                                        rest_curvature: kappa.to_vec(),
                                        ..Actuation::default()
                                    },
                                    &carried,
                                    &names,
                                    q.as_deref(),
                                )?;
                                (sol, Some(sens))
                            } else {
                                let mut solver = robot.forward_solver(kappa, &carried)?;
                                (solver.solve_warm_or_cold(q.as_deref())?, None)
                            };
                            if !sol.converged() {
                                return Err(Error::NotConverged {
                                    status: sol.status,
                                    iterations: sol.iterations,
                                    residual: sol.residual_norm,
                                    reason: format!("a forward solve: {}", sol.message),
                                });
                            }
                            *q = Some(sol.quaternions.clone());
                            Ok((sol.tip_position(), sens))
                        },
                    )
                    .collect::<Result<Vec<_>>>()
            };
            let results = threads.run(|| work(warm))?;
            let mut r = DVector::zeros(3 * samples.len());
            let mut jac = jacobian.then(|| DMatrix::zeros(3 * samples.len(), k));
            for (i, (tip, sens)) in results.iter().enumerate() {
                for c in 0..3 {
                    r[3 * i + c] = measured[i][c] - tip[c];
                }
                if let (Some(j), Some(s)) = (jac.as_mut(), sens) {
                    for c in 0..3 {
                        for col in 0..k {
                            // d(model tip)/dp in scaled parameters.
                            j[(3 * i + c, col)] = s.tip_position[(c, col)] * scale[col];
                        }
                    }
                }
            }
            Ok((r, jac))
        };
        let mut p = start.clone();
        let (mut r, mut jac) = evaluate(&p, &mut warm, true)?;
        let mut cost = r.norm_squared();
        let mut converged = false;
        let mut iterations = 0;
        let mut message = String::from("iteration limit reached");
        while iterations < settings.max_iterations {
            iterations += 1;
            let j = jac.as_ref().expect("evaluated with the Jacobian");
            // Gauss-Newton in scaled parameters: J dx = r (the model moves
            // towards the measurements), by SVD for rank-deficient fits.
            let Ok(svd) = j.clone().svd(true, true).solve(&r, 1e-12) else {
                message = "the least-squares step failed".into();
                break;
            };
            let mut t = 1.0;
            let mut accepted = false;
            for _ in 0..30 {
                let trial: Vec<f64> = (0..k).map(|c| p[c] + t * svd[c] * scale[c]).collect();
                match evaluate(&trial, &mut warm, false) {
                    Ok((r_trial, _)) if r_trial.norm_squared() <= cost => {
                        p = trial;
                        accepted = true;
                        break;
                    }
                    _ => t *= 0.5,
                }
            }
            let moved = t * svd.amax();
            if !accepted {
                // No step lowers the residual: at the minimum to round-off.
                converged = moved < 1e-6;
                message = if converged {
                    "converged (no step lowers the residual)".into()
                } else {
                    "the line search failed".into()
                };
                break;
            }
            (r, jac) = evaluate(&p, &mut warm, true)?;
            cost = r.norm_squared();
            if moved < settings.step_tol {
                converged = true;
                message = "converged".into();
                break;
            }
        }
        let j = jac.expect("evaluated with the Jacobian");
        let dof = (r.len() - k) as f64;
        let variance = cost / dof;
        let jtj = j.transpose() * &j;
        let covariance_scaled = jtj
            .clone()
            .pseudo_inverse(1e-14 * jtj.norm())
            .map_err(|e| Error::argument("parameters", e.to_string()))?;
        let mut covariance = vec![0.0; k * k];
        for a in 0..k {
            for b in 0..k {
                covariance[a * k + b] = variance * covariance_scaled[(a, b)] * scale[a] * scale[b];
            }
        }
        let standard_errors = (0..k).map(|a| covariance[a * k + a].sqrt()).collect();
        let residuals = (0..measured.len())
            .map(|i| Vector3::new(r[3 * i], r[3 * i + 1], r[3 * i + 2]))
            .collect();
        let (robot, _) = split(&p)?;
        Ok(Calibration {
            parameters: fields,
            estimates: p,
            standard_errors,
            covariance,
            residuals,
            rms: (cost / r.len() as f64).sqrt(),
            iterations,
            converged,
            robot,
            message,
        })
    }
}
