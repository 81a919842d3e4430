//! A robot's drive as the inverse kinematics sees it: a vector of
//! coordinates, the set they may take, how they enter the forward solver,
//! the tip's Jacobian in them, and where a missed target is tried from. The
//! engine (`engine.rs`) asks only these questions; this file alone tells the
//! drives apart.
//!
//! | drive | coordinates | admissible set | reference (default) |
//! |---|---|---|---|
//! | muscles | `[kappa_x, kappa_y]` a section [1/m] | each section's hexagon of muscle lengths | the last answer along a path (zero) |
//! | tendons | one tension a tendon [N] | `0 <= t <= max_tension` | the pretension (zero: the least tension) |
//! | field | the uniform field, world frame [T] | `|B| <= max_field` | zero (the smallest field) |

use super::super::bounds::{BoundedStep, Bounds};
use super::super::{Drive, Muscles, Robot};
use crate::error::{Error, Result};
use crate::solver::{CoupledLinearisation, DriveParameters, Solver};
use nalgebra::{DMatrix, DVector, Matrix3xX, Vector2, Vector3};
use rand::{RngExt, SeedableRng};

/// Random starts drawn in the admissible set when a descent from the last
/// answer misses (after the drive's own starts). A descent of the example
/// tendon robot from slack stalled on 38 of 150 reachable targets, its
/// tensions pressed to 0 and `max_tension` far from the generating ones
/// (tools/reach_campaign.py); the draws reach them.
const RANDOM_STARTS: usize = 9;

/// What an inverse solve searches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ActuationSpace {
    /// The muscles' rest curvature per section (pneumatic robots).
    Curvature,
    /// The tendons' tensions.
    Tensions,
    /// The uniform external magnetic field.
    Field,
}

impl ActuationSpace {
    /// The snake_case name used by the Python API.
    pub fn name(self) -> &'static str {
        match self {
            ActuationSpace::Curvature => "curvature",
            ActuationSpace::Tensions => "tensions",
            ActuationSpace::Field => "field",
        }
    }
}

/// Where the drive's coordinates may go.
#[derive(Debug, Clone)]
enum Admissible {
    /// Linear rows block by block (muscles, tendons).
    Polytope(Bounds),
    /// The ball `|x| <= radius` (a field).
    Ball(f64),
    /// The ball on the leading coordinates and the interval `[lo, hi]` on
    /// the last (a limited field and an insertion).
    BallAndInterval(f64, [f64; 2]),
    /// Anywhere (a field without `max_field`).
    Free,
}

/// A robot's insertion as the last coordinate, `u = weight * d` (`d` the
/// insertion [m]): an insertion of the robot's length counts in the
/// least-norm choice as much as the drive's scale (a curvature of `1/L`,
/// `max_tension`, `max_field` or 1 mT).
#[derive(Debug, Clone, Copy)]
struct Insertion {
    /// The range of `d` [m].
    range: [f64; 2],
    /// The base's tangent, along which it moves, and where it is at `d = 0`.
    axis: Vector3<f64>,
    base: Vector3<f64>,
    weight: f64,
}

/// One robot's drive (see the module docs).
#[derive(Debug, Clone)]
pub(super) struct DriveSpace {
    space: ActuationSpace,
    /// The drive's own coordinates (the insertion's is after them).
    dimension: usize,
    insertion: Option<Insertion>,
    admissible: Admissible,
    /// The scale below which a coordinate's change does not count (the
    /// floor of [`DriveSpace::size`]).
    floor: f64,
    /// The drive's scale: the range of a curvature component's random
    /// draws; `max_tension`; `max_field` (0: no limit, no random draws).
    reach: f64,
    /// Robot facts the curvature starts need.
    sections: usize,
    length: f64,
    base: crate::quat::Quat,
}

impl DriveSpace {
    pub fn of(robot: &Robot) -> Result<DriveSpace> {
        let space = robot.actuation_space();
        let ls = robot.body.section_length();
        let (dimension, admissible, floor, reach) = match &robot.drive {
            Drive::Muscles(m) => (
                2 * robot.body.sections,
                Admissible::Polytope(Bounds::muscles(m, ls)),
                1.0 / robot.body.length,
                max_curvature(m, ls),
            ),
            Drive::Tendons(t) => {
                let upper = t.max_tension;
                let reach = upper.unwrap_or(0.0);
                (
                    t.routes.len(),
                    Admissible::Polytope(Bounds::tensions(upper)),
                    1e-6 * upper.unwrap_or(1.0),
                    reach,
                )
            }
            Drive::Field(f) => match f.max_field {
                Some(limit) => (3, Admissible::Ball(limit), 1e-6 * limit, limit),
                None => (3, Admissible::Free, 1e-9, 0.0),
            },
        };
        let length = robot.body.length;
        let (admissible, insertion) = match robot.insertion_range {
            None => (admissible, None),
            Some(range) => {
                let weight = match space {
                    ActuationSpace::Curvature => 1.0 / (length * length),
                    ActuationSpace::Tensions if reach > 0.0 => reach / length,
                    ActuationSpace::Tensions => 1.0 / length,
                    ActuationSpace::Field => 1e-3 / length,
                };
                let scaled = range.map(|d| d * weight);
                let admissible = match admissible {
                    Admissible::Polytope(bounds) => {
                        Admissible::Polytope(bounds.and_interval(scaled))
                    }
                    Admissible::Free => Admissible::Polytope(Bounds::none().and_interval(scaled)),
                    Admissible::Ball(radius) => Admissible::BallAndInterval(radius, scaled),
                    Admissible::BallAndInterval(..) => unreachable!("made here only"),
                };
                let insertion = Insertion {
                    range,
                    axis: robot.insertion_axis(),
                    base: robot.body.base_position,
                    weight,
                };
                (admissible, Some(insertion))
            }
        };
        Ok(DriveSpace {
            space,
            dimension,
            insertion,
            admissible,
            floor,
            reach,
            sections: robot.body.sections,
            length,
            base: robot.body.base_quaternion,
        })
    }

    /// The insertion [m] of coordinates `x` (0 without one).
    pub fn insertion(&self, x: &DVector<f64>) -> f64 {
        match (self.insertion, x.get(self.dimension)) {
            (Some(i), Some(u)) => u / i.weight,
            _ => 0.0,
        }
    }

    /// The coordinates of an answer: its drive's, then its insertion's.
    pub fn coordinates(&self, drive: Vec<f64>, insertion: f64) -> DVector<f64> {
        let mut x = drive;
        if let Some(i) = self.insertion {
            x.push(insertion * i.weight);
        }
        DVector::from_vec(x)
    }

    pub fn space(&self) -> ActuationSpace {
        self.space
    }

    /// Every coordinate: the drive's and an insertion's.
    pub fn dimension(&self) -> usize {
        self.dimension + usize::from(self.insertion.is_some())
    }

    /// The drive's own coordinates of `x`.
    fn drive_part(&self, x: &DVector<f64>) -> DVector<f64> {
        x.rows(0, self.dimension).into_owned()
    }

    /// Muscles follow a path: along a trajectory the reference is the last
    /// answer (smooth motion). Tendons and fields keep theirs (least effort).
    pub fn follows_path(&self) -> bool {
        self.space == ActuationSpace::Curvature
    }

    /// Whether the last coordinate is an insertion (it moves the base).
    pub fn has_insertion(&self) -> bool {
        self.insertion.is_some()
    }

    /// The magnitude of a change of `x` that counts: `|x|`, at least the floor.
    pub fn size(&self, x: &DVector<f64>) -> f64 {
        x.norm().max(self.floor)
    }

    /// Set the forward solver's drive to `x`.
    pub fn apply(&self, solver: &mut Solver, x: &DVector<f64>) -> Result<()> {
        let drive = self.drive_part(x);
        match self.space {
            ActuationSpace::Curvature => solver.set_rest_curvature(&pairs(&drive)),
            ActuationSpace::Tensions => solver.set_tensions(drive.as_slice()),
            ActuationSpace::Field => {
                solver.set_magnetic_field(Vector3::new(drive[0], drive[1], drive[2]))
            }
        }?;
        if let Some(i) = self.insertion {
            solver.set_base_position(i.base + self.insertion(x) * i.axis)?;
        }
        Ok(())
    }

    /// The tip's position and turn differentiated in the coordinates, at the
    /// solver's (converged) state; `None` at a bifurcation.
    pub fn tip_jacobian(&self, solver: &mut Solver) -> Option<(Matrix3xX<f64>, Matrix3xX<f64>)> {
        let (position, rotation) = self.drive_jacobian(solver)?;
        let Some(i) = self.insertion else {
            return Some((position, rotation));
        };
        // The insertion's column: the base moved along its tangent.
        let moved = solver.base_sensitivity(i.axis).ok()?;
        let k = self.dimension;
        let widen = |m: Matrix3xX<f64>, column: Vector3<f64>| {
            let mut out = m.insert_column(k, 0.0);
            out.set_column(k, &(column / i.weight));
            out
        };
        Some((
            widen(position, moved.position.column(0).into()),
            widen(rotation, moved.rotation.column(0).into()),
        ))
    }

    /// The forward solver's equations and tip linearised at its state (not
    /// necessarily an equilibrium) in the state and the drive: a coupled
    /// iteration's step (`solver/coupled.rs`), the tip's turn only if `turn`.
    /// `None` with an insertion (it
    /// moves the base, no parameter of the loading) or where the solver
    /// cannot (a singular Jacobian, a rod that is not free).
    pub fn linearise(&self, solver: &mut Solver, turn: bool) -> Option<CoupledLinearisation> {
        if self.has_insertion() {
            return None;
        }
        let parameters = match self.space {
            ActuationSpace::Curvature => DriveParameters::SectionCurvature(self.sections),
            ActuationSpace::Tensions => DriveParameters::Tensions,
            ActuationSpace::Field => DriveParameters::Field,
        };
        solver.linearise_coupled(parameters, turn).ok()
    }

    /// The drive's own columns of [`DriveSpace::tip_jacobian`].
    fn drive_jacobian(&self, solver: &mut Solver) -> Option<(Matrix3xX<f64>, Matrix3xX<f64>)> {
        let free = !solver.model().is_constrained();
        match self.space {
            ActuationSpace::Curvature => {
                let sens = solver.tip_sensitivity(self.sections).ok()?;
                Some((sens.position, sens.rotation))
            }
            // Tensions and the field enter the equations linearly: their
            // columns in closed form, one back-substitution each.
            ActuationSpace::Tensions if free => {
                let sens = solver.tension_sensitivity().ok()?;
                Some((sens.position, sens.rotation))
            }
            ActuationSpace::Field if free => {
                let sens = solver.field_sensitivity().ok()?;
                Some((sens.position, sens.rotation))
            }
            _ => {
                // The scene's own values, each through its term's derivative.
                let space = self.space;
                let scene = solver.scene().clone();
                let (names, values): (Vec<String>, Vec<f64>) = match space {
                    ActuationSpace::Tensions => scene
                        .tendons
                        .iter()
                        .enumerate()
                        .map(|(j, t)| (format!("tendons[{j}].tension"), t.tension))
                        .unzip(),
                    _ => (0..3)
                        .map(|j| (format!("magnetic_field[{j}]"), scene.magnetic_field[j]))
                        .unzip(),
                };
                let sens = solver
                    .sensitivity_of_paths(names, &values, |j, delta| {
                        let mut moved = scene.clone();
                        match space {
                            ActuationSpace::Tensions => moved.tendons[j].tension += delta,
                            _ => moved.magnetic_field[j] += delta,
                        }
                        Ok(moved)
                    })
                    .ok()?;
                Some((sens.tip_position, sens.tip_rotation))
            }
        }
    }

    /// The step `d` from `x` (admissible) that minimises
    /// `|d - r|^2 + |J d - e|^2 / c` with `x + d` admissible, and whether a
    /// limit holds it back (see `bounds.rs`). `None` if `c I + J J^T` is singular.
    pub fn step(
        &self,
        x: &DVector<f64>,
        j: &DMatrix<f64>,
        e: &DVector<f64>,
        r: &DVector<f64>,
        c: f64,
    ) -> Option<BoundedStep> {
        match &self.admissible {
            Admissible::Polytope(bounds) => bounds.step(x, j, e, r, c),
            Admissible::Ball(radius) => ball_step(x, j, e, r, c, *radius, x.len()),
            Admissible::Free => ball_step(x, j, e, r, c, f64::INFINITY, x.len()),
            Admissible::BallAndInterval(radius, range) => {
                ball_and_interval_step(x, j, e, r, c, *radius, *range)
            }
        }
    }

    /// Which coordinates of `x` are off their limits: a tension strictly
    /// between zero and `max_tension`; every coordinate of the muscles and
    /// the field (their limits mix coordinates).
    pub fn free(&self, x: &DVector<f64>) -> Vec<bool> {
        let drive = self.drive_part(x);
        let mut out: Vec<bool> = match self.space {
            ActuationSpace::Tensions => {
                let upper = if self.reach > 0.0 {
                    self.reach
                } else {
                    f64::INFINITY
                };
                drive.iter().map(|t| *t > 0.0 && *t < upper).collect()
            }
            _ => vec![true; drive.len()],
        };
        if let Some(i) = self.insertion {
            let d = self.insertion(x);
            out.push(d > i.range[0] && d < i.range[1]);
        }
        out
    }

    /// `x` brought into the admissible set (rounding only, for a step's
    /// result; the nearest point scaled in, for a start).
    pub fn clamp(&self, robot: &Robot, x: &mut DVector<f64>) {
        if let Some(i) = self.insertion {
            let k = self.dimension;
            let [lo, hi] = i.range.map(|d| d * i.weight);
            x[k] = x[k].clamp(lo, hi);
            let mut drive = self.drive_part(x);
            self.clamp_drive(robot, &mut drive);
            x.rows_mut(0, k).copy_from(&drive);
        } else {
            self.clamp_drive(robot, x);
        }
    }

    /// Whether `x` is admissible: [`DriveSpace::clamp`] leaves it as it is.
    pub fn within(&self, robot: &Robot, x: &DVector<f64>) -> bool {
        let mut clamped = x.clone();
        self.clamp(robot, &mut clamped);
        clamped == *x
    }

    /// [`DriveSpace::clamp`] of the drive's own coordinates.
    fn clamp_drive(&self, robot: &Robot, x: &mut DVector<f64>) {
        match self.space {
            ActuationSpace::Curvature => {
                if let Some(m) = robot.drive.muscles() {
                    let mut kappa = pairs(x);
                    m.clamp_to_bounds(robot.body.section_length(), &mut kappa);
                    *x = flat(&kappa);
                }
            }
            ActuationSpace::Tensions => {
                let upper = robot.drive.max_tension().unwrap_or(f64::INFINITY);
                x.apply(|t| *t = t.clamp(0.0, upper));
            }
            ActuationSpace::Field => {
                if let Admissible::Ball(radius) | Admissible::BallAndInterval(radius, _) =
                    self.admissible
                {
                    let norm = x.norm();
                    if norm > radius {
                        *x *= radius / norm;
                    }
                }
            }
        }
    }

    /// Starts that do not depend on the reference, after the last answer:
    /// the drive's own (muscles: the arc aimed at the target, then straight;
    /// tendons: the middle of the range; a field: zero), then points drawn
    /// uniformly in the admissible set, seeded by the target so that an
    /// answer depends on nothing else.
    pub fn starts(&self, target: &Vector3<f64>, last: &DVector<f64>) -> Vec<DVector<f64>> {
        let starts = self.drive_starts(target, &self.drive_part(last));
        let Some(i) = self.insertion else {
            return starts;
        };
        // The drive's starts at the last insertion, then at the middle of
        // the range.
        let (kept, middle) = (self.insertion(last), 0.5 * (i.range[0] + i.range[1]));
        let mut out = vec![last.clone()];
        for d in [kept, middle] {
            for x in &starts[1..] {
                out.push(self.coordinates(x.iter().copied().collect(), d));
            }
        }
        out
    }

    /// [`DriveSpace::starts`] in the drive's own coordinates.
    fn drive_starts(&self, target: &Vector3<f64>, last: &DVector<f64>) -> Vec<DVector<f64>> {
        let k = self.dimension;
        let mut out = vec![last.clone()];
        match self.space {
            ActuationSpace::Curvature => {
                out.push(self.arc_toward(target));
                out.push(DVector::zeros(k));
            }
            ActuationSpace::Tensions if self.reach > 0.0 => {
                out.push(DVector::from_element(k, 0.5 * self.reach))
            }
            ActuationSpace::Tensions => {}
            ActuationSpace::Field => out.push(DVector::zeros(k)),
        }
        if self.reach > 0.0 {
            let seed = target.iter().fold(0x9e37_79b9_7f4a_7c15u64, |h, x| {
                h.rotate_left(17) ^ x.to_bits()
            });
            let mut rng = rand::rngs::SmallRng::seed_from_u64(seed);
            for _ in 0..RANDOM_STARTS {
                out.push(match self.space {
                    ActuationSpace::Curvature => {
                        DVector::from_fn(k, |_, _| self.reach * (2.0 * rng.random::<f64>() - 1.0))
                    }
                    ActuationSpace::Tensions => {
                        DVector::from_fn(k, |_, _| self.reach * rng.random::<f64>())
                    }
                    ActuationSpace::Field => {
                        // Uniform in the ball: a direction and radius^(1/3).
                        let v = Vector3::from_fn(|_, _| rng.random::<f64>() * 2.0 - 1.0);
                        let radius = self.reach * rng.random::<f64>().cbrt();
                        DVector::from_column_slice((v.normalize() * radius).as_slice())
                    }
                });
            }
        }
        out
    }

    /// Constant curvature in the plane of the base axis and the target, of
    /// the arc from the base through the target (weight ignored): the chord
    /// of an arc turning by `theta` leaves the tangent at `theta / 2`.
    fn arc_toward(&self, target: &Vector3<f64>) -> DVector<f64> {
        let local = self.base.inverse_rotate(*target);
        let lateral = Vector2::new(local.x, local.y);
        let u = lateral.try_normalize(1e-12).unwrap_or(Vector2::x());
        let kappa = 2.0 * lateral.norm().atan2(local.z) / self.length;
        // Bending toward u: (kappa_y, -kappa_x) = kappa u.
        flat(&vec![[-kappa * u.y, kappa * u.x]; self.sections])
    }

    /// The answer's actuation in every form a result carries: rest curvature,
    /// tensions, field.
    pub fn actuation(&self, x: &DVector<f64>) -> (Vec<[f64; 2]>, Vec<f64>, Vector3<f64>) {
        let x = &self.drive_part(x);
        let straight = vec![[0.0; 2]; self.sections];
        match self.space {
            ActuationSpace::Curvature => (pairs(x), Vec::new(), Vector3::zeros()),
            ActuationSpace::Tensions => (straight, x.iter().copied().collect(), Vector3::zeros()),
            ActuationSpace::Field => (straight, Vec::new(), Vector3::new(x[0], x[1], x[2])),
        }
    }

    /// The reference or pretension of a solve, checked, in the coordinates
    /// (`None`: the drive's default, zero).
    pub fn reference(
        &self,
        robot: &Robot,
        curvature: Option<&[[f64; 2]]>,
        pretension: Option<&[f64]>,
    ) -> Result<Option<Vec<f64>>> {
        let given = self.drive_reference(robot, curvature, pretension)?;
        // The least insertion (zero: where the body puts the base) unless
        // a reference says otherwise.
        Ok(given.map(|r| self.coordinates(r, 0.0).as_slice().to_vec()))
    }

    /// [`DriveSpace::reference`] in the drive's own coordinates.
    fn drive_reference(
        &self,
        robot: &Robot,
        curvature: Option<&[[f64; 2]]>,
        pretension: Option<&[f64]>,
    ) -> Result<Option<Vec<f64>>> {
        let space = self.space;
        match (space, curvature, pretension) {
            (ActuationSpace::Curvature, _, Some(_)) => Err(Error::argument(
                "pretension",
                "the robot has no tendons (its actuation is the muscles' curvature)",
            )),
            (ActuationSpace::Curvature, Some(r), None) => {
                let m = self.sections;
                if r.len() != m {
                    return Err(Error::argument(
                        "reference",
                        format!("expected {m} sections, got {}", r.len()),
                    ));
                }
                Ok(Some(r.iter().flatten().copied().collect()))
            }
            (_, Some(_), _) => Err(Error::argument(
                "reference",
                format!(
                    "a curvature reference steers muscles; this robot's actuation is its {} (use pretension for tendons)",
                    space.name()
                ),
            )),
            (ActuationSpace::Field, None, Some(_)) => Err(Error::argument(
                "pretension",
                "a magnetic robot has no tendons to pretension",
            )),
            (ActuationSpace::Tensions, None, Some(p)) => {
                robot
                    .check_actuation(p, Vector3::zeros())
                    .map_err(|e| match e {
                        Error::InvalidArgument { name, reason } => {
                            Error::argument(name.replacen("tensions", "pretension", 1), reason)
                        }
                        other => other,
                    })?;
                if p.len() != self.dimension {
                    return Err(Error::argument(
                        "pretension",
                        format!(
                            "expected {} tensions, one a tendon, got {}",
                            self.dimension,
                            p.len()
                        ),
                    ));
                }
                Ok(Some(p.to_vec()))
            }
            (_, None, None) => Ok(None),
        }
    }

    /// A warm start's actuation, checked, in the coordinates (`None`: it gives none).
    pub fn warm(&self, robot: &Robot, start: &super::IkStart) -> Result<Option<DVector<f64>>> {
        let drive = self.warm_drive(robot, start)?;
        if let Some(d) = start.insertion {
            robot.check_insertion(d)?;
        }
        let insertion = start.insertion.unwrap_or(0.0);
        Ok(drive.map(|x| self.coordinates(x.iter().copied().collect(), insertion)))
    }

    /// [`DriveSpace::warm`] in the drive's own coordinates.
    fn warm_drive(&self, robot: &Robot, start: &super::IkStart) -> Result<Option<DVector<f64>>> {
        if self.space == ActuationSpace::Curvature {
            return Ok(start.rest_curvature.as_deref().map(flat));
        }
        let Some(x) = &start.actuation else {
            return Ok(None);
        };
        if x.len() != self.dimension {
            return Err(Error::argument(
                "initial",
                format!(
                    "has {} actuation values, the robot's {} space {}",
                    x.len(),
                    self.space.name(),
                    self.dimension
                ),
            ));
        }
        match self.space {
            ActuationSpace::Tensions => robot.check_actuation(x, Vector3::zeros())?,
            _ => robot.check_actuation(&[], Vector3::new(x[0], x[1], x[2]))?,
        }
        Ok(Some(DVector::from_column_slice(x)))
    }

    /// What holds a tip back when a limit does.
    pub fn limit(&self) -> &'static str {
        match self.space {
            ActuationSpace::Curvature => {
                "the muscles' length range limits the actuation, muscles at their length limits"
            }
            ActuationSpace::Tensions => "tendons at zero tension or at max_tension hold it back",
            ActuationSpace::Field => "the field is at max_field",
        }
    }

    /// How much of the drive an answer uses, for its message.
    pub fn describe(&self, x: &DVector<f64>) -> String {
        let drive = self.drive_part(x);
        let mut out = match self.space {
            ActuationSpace::Curvature => String::new(),
            ActuationSpace::Tensions => format!(" with tensions of {:.6} N in all", drive.sum()),
            ActuationSpace::Field => format!(" with a field of {:.6} T", drive.norm()),
        };
        if self.insertion.is_some() {
            out += &format!(" at an insertion of {:.6} m", self.insertion(x));
        }
        out
    }
}

/// Curvature scale of the random starts: twice the range across the first
/// two muscles (the starts are clamped into range).
fn max_curvature(muscles: &Muscles, section_length: f64) -> f64 {
    let lever = muscles.lever(section_length);
    let [lo, hi] = muscles.length_range;
    let per = (lever[0][0] - lever[1][0]).hypot(lever[0][1] - lever[1][1]);
    2.0 * (hi - lo) / per.max(f64::MIN_POSITIVE)
}

fn pairs(x: &DVector<f64>) -> Vec<[f64; 2]> {
    x.as_slice().chunks(2).map(|c| [c[0], c[1]]).collect()
}

fn flat(k: &[[f64; 2]]) -> DVector<f64> {
    DVector::from_iterator(2 * k.len(), k.iter().flat_map(|x| x.iter().copied()))
}

/// [`DriveSpace::step`] in the ball `|x_b + d_b| <= radius` over the first
/// `ball` coordinates (the others free): the free minimiser `d = r + J^T (c
/// I + J J^T)^{-1} (e - J r)` if it stays inside, else the minimiser with
/// `nu |x_b + d_b|^2` added, `nu` the smallest that keeps it on the sphere
/// (by bisection): `(D + J^T J / c) d = v + J^T e / c`, `v = r - nu x_b`,
/// `D` the identity with `1 + nu` on the ball's coordinates, applied by the
/// Woodbury identity, `d = D^-1 v + D^-1 J^T (c I + J D^-1 J^T)^-1 (e - J
/// D^-1 v)`, so that it stays exact as `c -> 0`.
fn ball_step(
    x: &DVector<f64>,
    j: &DMatrix<f64>,
    e: &DVector<f64>,
    r: &DVector<f64>,
    c: f64,
    radius: f64,
    ball: usize,
) -> Option<BoundedStep> {
    let rows = j.nrows();
    let within = |d: &DVector<f64>| (x + d).rows(0, ball).norm();
    let solve = |nu: f64| -> Option<DVector<f64>> {
        let inverse = DVector::from_fn(
            x.len(),
            |i, _| if i < ball { 1.0 / (1.0 + nu) } else { 1.0 },
        );
        let mut v = r.clone();
        v.rows_mut(0, ball).axpy(-nu, &x.rows(0, ball), 1.0);
        let dv = v.component_mul(&inverse);
        let scaled = j * DMatrix::from_diagonal(&inverse);
        let g = (&scaled * j.transpose() + DMatrix::identity(rows, rows) * c).cholesky()?;
        Some(&dv + scaled.transpose() * g.solve(&(e - j * &dv)))
    };
    let free = solve(0.0)?;
    if within(&free) <= radius {
        return Some(BoundedStep {
            step: free,
            blocking: 0,
        });
    }
    let (mut lo, mut hi) = (0.0, 1.0);
    while within(&solve(hi)?) > radius && hi < 1e300 {
        hi *= 4.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if within(&solve(mid)?) > radius {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-12 * hi {
            break;
        }
    }
    let mut d = solve(hi)?;
    // On the sphere to round-off, never outside it.
    let shrink = (radius / within(&d)).min(1.0);
    let moved = (x.rows(0, ball) + d.rows(0, ball)) * shrink - x.rows(0, ball);
    d.rows_mut(0, ball).copy_from(&moved);
    Some(BoundedStep {
        step: d,
        blocking: 1,
    })
}

/// [`DriveSpace::step`] in the ball over all but the last coordinate and
/// the interval `[lo, hi]` on the last. The problem is convex: where the
/// step within the ball alone leaves the interval, the step with both
/// holds the last coordinate at the bound it crossed, and the others are
/// the ball's step with that column's move taken into the miss.
fn ball_and_interval_step(
    x: &DVector<f64>,
    j: &DMatrix<f64>,
    e: &DVector<f64>,
    r: &DVector<f64>,
    c: f64,
    radius: f64,
    [lo, hi]: [f64; 2],
) -> Option<BoundedStep> {
    let k = x.len() - 1;
    let free = ball_step(x, j, e, r, c, radius, k)?;
    let last = x[k] + free.step[k];
    if (lo..=hi).contains(&last) {
        return Some(free);
    }
    let held = last.clamp(lo, hi) - x[k];
    let rest = |v: &DVector<f64>| v.rows(0, k).into_owned();
    let moved = e - j.column(k) * held;
    let step = ball_step(
        &rest(x),
        &j.columns(0, k).into_owned(),
        &moved,
        &rest(r),
        c,
        radius,
        k,
    )?;
    let mut d = DVector::zeros(k + 1);
    d.rows_mut(0, k).copy_from(&step.step);
    d[k] = held;
    Some(BoundedStep {
        step: d,
        blocking: step.blocking + 1,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ball_step_is_the_free_step_inside_and_on_the_sphere_beyond() {
        let j = DMatrix::identity(3, 3);
        let x = DVector::zeros(3);
        let r = DVector::zeros(3);
        let small = DVector::from_row_slice(&[0.3, 0.4, 0.0]);
        let free = ball_step(&x, &j, &small, &r, 1e-14, 1.0, 3).unwrap();
        assert_eq!(free.blocking, 0);
        assert!((free.step - &small).norm() < 1e-12);
        let large = small * 10.0;
        let held = ball_step(&x, &j, &large, &r, 1e-14, 1.0, 3).unwrap();
        assert_eq!(held.blocking, 1);
        assert!((held.step.norm() - 1.0).abs() < 1e-12);
        assert!((held.step - DVector::from_row_slice(&[0.6, 0.8, 0.0])).norm() < 1e-9);
    }

    #[test]
    fn the_ball_and_interval_step_holds_each_limit_it_crosses() {
        // A field (3) in the unit ball and an insertion (1) in [0, 0.2].
        let j = DMatrix::identity(4, 4);
        let (x, r) = (DVector::zeros(4), DVector::zeros(4));
        let both = |e: [f64; 4]| {
            ball_and_interval_step(
                &x,
                &j,
                &DVector::from_row_slice(&e),
                &r,
                1e-14,
                1.0,
                [0.0, 0.2],
            )
            .unwrap()
        };
        // The insertion past its range: held at 0.2, the field free.
        let s = both([0.3, 0.4, 0.0, 0.5]);
        assert_eq!(s.blocking, 1);
        assert!((s.step - DVector::from_row_slice(&[0.3, 0.4, 0.0, 0.2])).norm() < 1e-9);
        // The field past its ball: on the sphere, the insertion free.
        let s = both([3.0, 4.0, 0.0, 0.1]);
        assert_eq!(s.blocking, 1);
        assert!((s.step - DVector::from_row_slice(&[0.6, 0.8, 0.0, 0.1])).norm() < 1e-9);
        // Both.
        let s = both([3.0, 4.0, 0.0, -0.1]);
        assert_eq!(s.blocking, 2);
        assert!((s.step - DVector::from_row_slice(&[0.6, 0.8, 0.0, 0.0])).norm() < 1e-9);
    }

    #[test]
    fn the_tension_box_step_keeps_the_bounds_and_gives_the_least_norm() {
        // Two tendons pull one way, one the other: J t = b with t >= 0. The
        // minimum-norm solution is J^T (J J^T)^-1 b restricted to the positive
        // columns: t = [1, 2, 0] * 2 / 5.
        let j = DMatrix::from_row_slice(1, 3, &[1.0, 2.0, -1.0]);
        let b = DVector::from_element(1, 2.0);
        let x = DVector::zeros(3);
        let free = Bounds::tensions(None);
        let t = free.step(&x, &j, &b, &x, 1e-14).unwrap().step;
        assert!((t - DVector::from_row_slice(&[0.4, 0.8, 0.0])).norm() < 1e-9);
        // With an upper bound of 0.7, the second tendon saturates and the
        // first makes up the rest: t1 + 2 (0.7) = 2.
        let boxed = Bounds::tensions(Some(0.7));
        let held = boxed.step(&x, &j, &b, &x, 1e-14).unwrap();
        let t = held.step;
        assert!((&j * &t - &b).norm() < 1e-9);
        assert!((t[1] - 0.7).abs() < 1e-12 && t[2] == 0.0 && (t[0] - 0.6).abs() < 1e-9);
        assert!(held.blocking > 0);
    }
}
