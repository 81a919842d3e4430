//! A robot's batches: forward statics of many actuations or drives, inverse
//! kinematics of many targets, its workspace, on the generic chunked runner
//! of [`crate::batch`] (see there for chunking, warm starts and threads).

use super::{
    Actuation, ActuationSpace, IkEnding, IkOptions, IkResult, InverseSolver, Load, Robot, Strategy,
};
use crate::batch::{check_batch_size, run_chunks, BatchControl, BatchSettings, ResultSize, Sample};
use crate::error::{Error, Result};
use crate::quat::Quat;
use crate::solver::{Solution, Solver};
use nalgebra::Vector3;

/// One inverse solve of a batch.
#[derive(Debug, Clone, PartialEq)]
pub struct IkSample {
    pub ending: IkEnding,
    pub reached: bool,
    pub rest_curvature: Vec<[f64; 2]>,
    /// The tensions found [N] (a tendon robot's; empty otherwise).
    pub tensions: Vec<f64>,
    /// The field found [T] (a magnetic robot's; zero otherwise).
    pub field: Vector3<f64>,
    /// The insertion found [m] (a robot with an insertion range; zero otherwise).
    pub insertion: f64,
    pub tip_position: Vector3<f64>,
    pub tip_miss: f64,
    pub iterations: usize,
}

impl IkSample {
    pub(crate) fn of(r: IkResult) -> IkSample {
        IkSample {
            ending: r.ending,
            reached: r.reached,
            rest_curvature: r.rest_curvature,
            tensions: r.tensions,
            field: r.field,
            insertion: r.insertion,
            tip_position: r.tip_position,
            tip_miss: r.tip_miss,
            iterations: r.iterations,
        }
    }
}

/// Largest change of a section's rest turn (curvature times section length)
/// [rad] from the last sample for which a warm start pays. Measured on the
/// default robot (`cargo bench --bench batch`): from a random earlier sample
/// a warm start cost 1.2 times a cold one; along a slow sweep of the
/// actuation warm starts within this bound save a fifth of the time.
pub const WARM_TURN: f64 = 0.5;

/// The last equilibrium of a chunk's solver and the actuation it had.
#[derive(Default)]
struct Last {
    q: Option<Vec<Quat>>,
    kappa: Vec<[f64; 2]>,
}

impl Last {
    /// Whether a warm start from here pays for `kappa` over sections of `length`.
    fn near(&self, kappa: &[[f64; 2]], length: f64) -> bool {
        self.q.is_some()
            && self.kappa.len() == kappa.len()
            && self.kappa.iter().zip(kappa).all(|(a, b)| {
                let d = [a[0] - b[0], a[1] - b[1]];
                length * d[0].hypot(d[1]) < WARM_TURN
            })
    }
}

/// A solve from the chunk's last equilibrium where it is near (and warm
/// starts are on), redone from the straight rod if that does not end
/// converged and stable; else from the straight rod.
fn solve_warm(
    solver: &mut Solver,
    last: &mut Last,
    kappa: &[[f64; 2]],
    section_length: f64,
    warm: bool,
) -> Result<Solution> {
    let start = if warm && last.near(kappa, section_length) {
        last.q.as_deref()
    } else {
        None
    };
    let sol = solver.solve_warm_or_cold(start)?;
    if warm && sol.converged() && sol.stable {
        last.q = Some(sol.quaternions.clone());
        last.kappa = kappa.to_vec();
    }
    Ok(sol)
}

/// A chunk's forward solver and its last equilibrium.
type ChunkState = (Solver, Last);

impl Robot {
    /// What makes a chunk's state: a forward solver of this robot (its
    /// default discretisation) under `load`.
    fn chunk_solver(&self, load: &Load) -> Result<impl Fn() -> Result<ChunkState> + Sync + '_> {
        let zero = vec![[0.0; 2]; self.body.sections];
        self.scene(&Actuation::muscles(zero.clone()), load)?;
        let load = load.clone();
        Ok(move || Ok((self.forward_solver(&zero, &load)?, Last::default())))
    }

    /// One forward sample of a chunk.
    fn forward_sample(
        &self,
        (solver, last): &mut ChunkState,
        kappa: &[[f64; 2]],
        settings: &BatchSettings,
    ) -> Result<Sample> {
        solver.set_rest_curvature(kappa)?;
        let sol = solve_warm(
            solver,
            last,
            kappa,
            self.body.section_length(),
            settings.warm_start,
        )?;
        Ok(Sample::of(&sol, settings.shapes))
    }

    /// The actuations of a batch given by drive, each `None` or a row a
    /// sample: the muscles' rest curvature (`sections` rows a sample, sample
    /// after sample), the tensions [N], the field [T], the insertion [m].
    /// Refused by name when nothing is given or the counts of samples
    /// disagree.
    pub fn batch_actuations(
        &self,
        rest_curvature: Option<&[[f64; 2]]>,
        tensions: Option<&[Vec<f64>]>,
        field: Option<&[[f64; 3]]>,
        insertion: Option<&[f64]>,
    ) -> Result<Vec<Actuation>> {
        let m = self.body.sections.max(1);
        if rest_curvature.is_some_and(|k| k.len() % m != 0) {
            return Err(Error::argument(
                "actuations",
                format!("rows are not whole samples of {m} sections"),
            ));
        }
        let counts = [
            ("actuations", rest_curvature.map(|k| k.len() / m)),
            ("tensions", tensions.map(<[_]>::len)),
            ("field", field.map(<[_]>::len)),
            ("insertion", insertion.map(<[_]>::len)),
        ];
        let mut given = counts.iter().filter_map(|(name, c)| c.map(|c| (*name, c)));
        let Some((first, count)) = given.next() else {
            return Err(match self.actuation_space() {
                ActuationSpace::Curvature => {
                    Error::argument("actuations", "missing (the rest curvature of each sample)")
                }
                _ => Error::argument(
                    "tensions",
                    "missing (give the tensions, the field or the actuations of each sample)",
                ),
            });
        };
        if let Some((name, other)) = given.find(|(_, c)| *c != count) {
            return Err(Error::argument(
                name,
                format!("{other} samples, but {first} has {count}"),
            ));
        }
        Ok((0..count)
            .map(|i| Actuation {
                rest_curvature: rest_curvature
                    .map_or(Vec::new(), |k| k[i * m..(i + 1) * m].to_vec()),
                tensions: tensions.map_or(Vec::new(), |t| t[i].clone()),
                field: field.map_or(Vector3::zeros(), |b| Vector3::from(b[i])),
                insertion: insertion.map_or(0.0, |d| d[i]),
            })
            .collect())
    }

    /// Forward statics of many actuations under one load, every drive of
    /// the robot (muscles, tendons, field) in each: see [`Robot::scene`].
    /// Each actuation is checked first (the drives' limits included), an
    /// error naming its sample. A chunk's solver starts warm from its last
    /// equilibrium where the actuation is near (within [`WARM_TURN`]).
    pub fn forward_batch(
        &self,
        actuations: &[Actuation],
        load: &Load,
        settings: &BatchSettings,
        control: &BatchControl,
    ) -> Result<Vec<Sample>> {
        let m = self.body.sections;
        let muscles_only = self.actuation_space() == ActuationSpace::Curvature
            && actuations.iter().all(|a| {
                a.tensions.is_empty() && a.field == Vector3::zeros() && a.insertion == 0.0
            });
        if !muscles_only {
            return self.drive_batch(actuations, load, settings, control);
        }
        // The muscles' own path: one scene whose rest curvature changes.
        let mut k = Vec::new();
        k.try_reserve_exact(actuations.len() * m)
            .map_err(|_| Error::OutOfMemory {
                what: "actuations".into(),
                bytes: actuations.len() * m * 16,
            })?;
        for (i, a) in actuations.iter().enumerate() {
            match a.rest_curvature.len() {
                0 => k.extend(std::iter::repeat_n([0.0; 2], m)),
                rows if rows == m => k.extend_from_slice(&a.rest_curvature),
                rows => {
                    return Err(Error::argument(
                        "actuations",
                        format!("sample {i} has {rows} sections, the robot {m}"),
                    ))
                }
            }
        }
        self.muscle_batch(&k, load, settings, control)
    }

    /// Forward statics of many muscle actuations: `actuations` holds
    /// `[kappa_x, kappa_y]` per section, sample after sample (`sections` rows
    /// a sample).
    fn muscle_batch(
        &self,
        actuations: &[[f64; 2]],
        load: &Load,
        settings: &BatchSettings,
        control: &BatchControl,
    ) -> Result<Vec<Sample>> {
        let m = self.body.sections;
        if actuations.len() % m != 0 {
            return Err(Error::argument(
                "actuations",
                format!(
                    "{} rows are not whole samples of {m} sections",
                    actuations.len()
                ),
            ));
        }
        if actuations.iter().flatten().any(|k| !k.is_finite()) {
            let row = actuations
                .iter()
                .position(|k| !k.iter().all(|v| v.is_finite()));
            return Err(Error::argument(
                "actuations",
                format!("must be finite (sample {})", row.unwrap_or(0) / m),
            ));
        }
        let start = self.chunk_solver(load)?;
        run_chunks(
            actuations.len() / m,
            self.result_size("actuations", settings),
            settings,
            control,
            start,
            |state, i| self.forward_sample(state, &actuations[i * m..(i + 1) * m], settings),
        )
    }

    /// Inverse kinematics of many targets [m], each on its own (the
    /// reference, direction and settings of `options` apply to every one);
    /// a chunk reuses one inverse solver, warm from its last answer.
    pub fn inverse_batch(
        &self,
        targets: &[Vector3<f64>],
        options: &IkOptions,
        settings: &BatchSettings,
        control: &BatchControl,
    ) -> Result<Vec<IkSample>> {
        options.settings.validate()?;
        if let Some(i) = targets
            .iter()
            .position(|t| !t.iter().all(|v| v.is_finite()))
        {
            return Err(Error::argument(
                "targets",
                format!("must be finite (target {i})"),
            ));
        }
        let ik = &options.settings;
        let aim = options.aim()?;
        // Checked once, before any chunk runs.
        let reference = self.ik_reference(options)?;
        run_chunks(
            targets.len(),
            self.result_size("targets", settings),
            settings,
            control,
            || match ik.strategy {
                Strategy::Equilibrium => Ok(Some(InverseSolver::new(self, &options.load)?)),
                Strategy::Geometric => Ok(None),
            },
            |solver, i| {
                let target = targets[i];
                let r = match solver {
                    Some(solver) => {
                        // With friction each target's history starts at rest,
                        // whatever the chunk solved before it.
                        solver.stand_at_rest();
                        solver.solve(
                            target,
                            aim,
                            reference.as_deref(),
                            ik.tol,
                            ik.max_iterations,
                        )?
                    }
                    None => self.inverse(target, options)?,
                };
                Ok(IkSample::of(r))
            },
        )
    }
}

/// The last equilibrium of a chunk's solver and the whole actuation it had.
#[derive(Default)]
struct LastActuated {
    q: Option<Vec<Quat>>,
    actuation: Actuation,
}

impl Robot {
    /// How far apart two actuations are: an estimate of the largest change
    /// of a section's turn [rad] between them, to compare with
    /// [`WARM_TURN`]. The rest curvature turns a section by `kappa l_s`; a
    /// tension `tau` at offset `r` bends by its moment `tau r`, a field `B`
    /// by `|m| |B|` a length (and a tip magnet's `|mu| |B|`), each over the
    /// softest stiffness `k` along the section `l_s`.
    fn actuation_turn(&self, a: &Actuation, b: &Actuation, k: f64) -> f64 {
        let ls = self.body.section_length();
        let curvature = a
            .rest_curvature
            .iter()
            .zip(&b.rest_curvature)
            .map(|(x, y)| ls * (x[0] - y[0]).hypot(x[1] - y[1]))
            .fold(0.0, f64::max);
        let arms = self.drive.tendon_routes().iter().map(|t| {
            std::iter::once(&t.offset)
                .chain(t.reroutes.iter().map(|r| &r.offset))
                .map(|o| o[0].hypot(o[1]))
                .fold(0.0, f64::max)
        });
        let tension: f64 = a
            .tensions
            .iter()
            .zip(&b.tensions)
            .zip(arms)
            .map(|((x, y), r)| (x - y).abs() * r)
            .sum();
        let magnet = self.drive.magnets().map_or(0.0, |f| {
            f.magnetization
                .iter()
                .map(|m| m.norm() * ls)
                .fold(f.tip_magnet.norm(), f64::max)
        });
        let field = (a.field - b.field).norm() * magnet;
        curvature.max((tension * ls + field) / k)
    }

    /// Forward statics of many whole actuations (rest curvature, tensions
    /// and field: a tendon-driven or magnetic robot's, muscles too). A warm
    /// start is taken where [`Robot::actuation_turn`] from the chunk's last
    /// equilibrium is within [`WARM_TURN`].
    fn drive_batch(
        &self,
        actuations: &[Actuation],
        load: &Load,
        settings: &BatchSettings,
        control: &BatchControl,
    ) -> Result<Vec<Sample>> {
        let straight = vec![[0.0; 2]; self.body.sections];
        let whole = |a: &Actuation| Actuation {
            rest_curvature: match a.rest_curvature.is_empty() {
                true => straight.clone(),
                false => a.rest_curvature.clone(),
            },
            tensions: match a.tensions.is_empty() {
                true => vec![0.0; self.drive.tendon_routes().len()],
                false => a.tensions.clone(),
            },
            field: a.field,
            insertion: a.insertion,
        };
        let actuations: Vec<Actuation> = actuations.iter().map(whole).collect();
        // The robot and the load once, each sample's drives (named).
        let (start, stiffness) = self.actuated_chunk(load)?;
        for (i, a) in actuations.iter().enumerate() {
            self.check_sample_drives(&a.rest_curvature, &a.tensions, a.field)
                .and_then(|()| self.check_insertion(a.insertion))
                .map_err(|e| match e {
                    Error::InvalidArgument { name, reason } => {
                        Error::argument(name, format!("{reason} (sample {i})"))
                    }
                    other => other,
                })?;
        }
        run_chunks(
            actuations.len(),
            self.result_size("actuations", settings),
            settings,
            control,
            start,
            |state, i| self.actuated_sample(state, &actuations[i], stiffness, settings),
        )
    }

    /// What makes a chunk's state for whole actuations (a forward solver
    /// of this robot under `load`), and the softest stiffness (the
    /// warm starts' scale).
    fn actuated_chunk(
        &self,
        load: &Load,
    ) -> Result<(impl Fn() -> Result<ActuatedChunk> + Sync + '_, f64)> {
        let rest = Actuation {
            rest_curvature: vec![[0.0; 2]; self.body.sections],
            tensions: vec![0.0; self.drive.tendon_routes().len()],
            field: Vector3::zeros(),
            insertion: 0.0,
        };
        let stiffness = self.scene(&rest, load)?.stiffness().min();
        let load = load.clone();
        let start = move || Ok((self.actuated_solver(&rest, &load)?, LastActuated::default()));
        Ok((start, stiffness))
    }

    /// One forward sample of a whole actuation (every part given).
    fn actuated_sample(
        &self,
        (solver, last): &mut ActuatedChunk,
        a: &Actuation,
        stiffness: f64,
        settings: &BatchSettings,
    ) -> Result<Sample> {
        solver.set_drives(&a.rest_curvature, &a.tensions, a.field)?;
        solver.set_base_position(self.base_at(a.insertion))?;
        let near =
            last.q.is_some() && self.actuation_turn(&last.actuation, a, stiffness) < WARM_TURN;
        let from = if settings.warm_start && near {
            last.q.as_deref()
        } else {
            None
        };
        let sol = solver.solve_warm_or_cold(from)?;
        if settings.warm_start && sol.converged() && sol.stable {
            last.q = Some(sol.quaternions.clone());
            last.actuation = a.clone();
        }
        Ok(Sample::of(&sol, settings.shapes))
    }

    /// Sample `index` of the seeded random drives, in the robot's drive:
    /// every muscle's length uniform over its range, each tension uniform
    /// over `[0, max_tension]` (the muscles straight), or the field uniform in
    /// the ball `|B| <= max_field`; with an insertion range, the insertion
    /// uniform over it. Each sample has its own stream (from the
    /// seed and its index), so a batch draws its samples in its workers, in
    /// any order, and a part of a batch draws the same samples as the whole.
    pub fn random_drive(&self, seed: u64, index: u64) -> Result<Actuation> {
        use rand::rngs::SmallRng;
        use rand::{RngExt, SeedableRng};
        let mut rng = SmallRng::seed_from_u64(seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let mut drives = Actuation {
            rest_curvature: vec![[0.0; 2]; self.body.sections],
            tensions: vec![0.0; self.drive.tendon_routes().len()],
            field: Vector3::zeros(),
            insertion: 0.0,
        };
        match self.actuation_space() {
            ActuationSpace::Tensions => {
                let most = self.drive.max_tension().ok_or_else(|| {
                    Error::argument(
                        "max_tension",
                        "missing: the workspace samples each tension over [0, max_tension]",
                    )
                })?;
                for t in &mut drives.tensions {
                    *t = rng.random_range(0.0..=most);
                }
            }
            ActuationSpace::Field => {
                let most = self.drive.max_field().ok_or_else(|| {
                    Error::argument(
                        "max_field",
                        "missing: the workspace samples the field in the ball |B| <= max_field",
                    )
                })?;
                // Uniform in the ball: rejection from its cube.
                drives.field = loop {
                    let b = Vector3::from_fn(|_, _| rng.random_range(-1.0..=1.0));
                    if b.norm_squared() <= 1.0 {
                        break most * b;
                    }
                };
            }
            ActuationSpace::Curvature => {
                drives.rest_curvature = self.random_curvature(seed, index)?;
            }
        }
        // After the drive's draws (which stay those of the robot without).
        if let Some([lo, hi]) = self.insertion_range {
            drives.insertion = lo + (hi - lo) * rng.random::<f64>();
        }
        Ok(drives)
    }

    /// The workspace: the equilibria of `samples` random drives
    /// ([`Robot::random_drive`], drawn by the workers) under `load`; the
    /// drives and their samples.
    ///
    /// `first` is the index of the first sample: a part of a larger
    /// workspace (a distributed engine's task) draws the samples the whole
    /// would have drawn there.
    pub fn workspace(
        &self,
        samples: usize,
        first: u64,
        load: &Load,
        seed: u64,
        settings: &BatchSettings,
        control: &BatchControl,
    ) -> Result<(Vec<Actuation>, Vec<Sample>)> {
        // An insertion is one more drive: each sample's drawn over its range.
        if self.actuation_space() != ActuationSpace::Curvature || self.insertion_range.is_some() {
            return self.drive_workspace(samples, first, load, seed, settings, control);
        }
        self.muscle_workspace(samples, first, load, seed, settings, control)
    }

    /// The workspace of a tendon-driven or magnetic robot.
    fn drive_workspace(
        &self,
        samples: usize,
        first: u64,
        load: &Load,
        seed: u64,
        settings: &BatchSettings,
        control: &BatchControl,
    ) -> Result<(Vec<Actuation>, Vec<Sample>)> {
        self.validate()?;
        self.random_drive(seed, first)?;
        self.check_workspace(samples, first, settings)?;
        let (start, stiffness) = self.actuated_chunk(load)?;
        let out = self.drawn_samples(
            (samples, first),
            (settings, control),
            start,
            |index| self.random_drive(seed, index),
            |state, drives| self.actuated_sample(state, drives, stiffness, settings),
        )?;
        Ok(out.into_iter().unzip())
    }

    /// The samples `first..first + samples` of a workspace: each drawn by
    /// `draw(index)` in the workers and solved by `solve` with its chunk's
    /// state, with what it was drawn.
    fn drawn_samples<S, D: Send>(
        &self,
        (samples, first): (usize, u64),
        (settings, control): (&BatchSettings, &BatchControl),
        start: impl Fn() -> Result<S> + Sync,
        draw: impl Fn(u64) -> Result<D> + Sync,
        solve: impl Fn(&mut S, &D) -> Result<Sample> + Sync,
    ) -> Result<Vec<(D, Sample)>> {
        run_chunks(
            samples,
            self.result_size("samples", settings),
            settings,
            control,
            start,
            |state, i| {
                let drawn = draw(first + i as u64)?;
                let sample = solve(state, &drawn)?;
                Ok((drawn, sample))
            },
        )
    }
}

impl Robot {
    /// Refuse a workspace of `samples` from index `first` that cannot be
    /// drawn (its indices run past the last) or whose results cannot fit
    /// in memory ([`check_batch_size`]): before anything is allocated, on
    /// one machine or before a cluster's parts are cut.
    pub fn check_workspace(
        &self,
        samples: usize,
        first: u64,
        settings: &BatchSettings,
    ) -> Result<()> {
        if first.checked_add(samples as u64).is_none() {
            return Err(Error::argument(
                "first",
                format!(
                    "{first} + {samples} samples runs past the last sample index {}",
                    u64::MAX
                ),
            ));
        }
        settings.validate()?;
        check_batch_size("samples", samples, self.sample_bytes(settings))
    }

    /// What one sample of this robot's batch holds (see
    /// [`BatchSettings::sample_bytes`]), `name` the argument that counts
    /// the samples.
    fn result_size<'a>(&self, name: &'a str, settings: &BatchSettings) -> ResultSize<'a> {
        ResultSize {
            name,
            bytes_each: self.sample_bytes(settings),
        }
    }

    /// Bytes one sample of this robot's batches holds: its result, its
    /// shape if kept, its drives (see [`BatchSettings::sample_bytes`]).
    pub fn sample_bytes(&self, settings: &BatchSettings) -> usize {
        let nodes = self.n_elements + 1;
        let drives = 2 * self.body.sections + self.drive.tendon_routes().len() + 3;
        settings.sample_bytes(nodes, drives)
    }
}

/// A chunk's forward solver of whole actuations and its last equilibrium.
type ActuatedChunk = (Solver, LastActuated);

impl Robot {
    /// The muscles' part of [`Robot::random_drive`]: every muscle's length
    /// uniform over its range, as `[kappa_x, kappa_y]` per section.
    fn random_curvature(&self, seed: u64, index: u64) -> Result<Vec<[f64; 2]>> {
        use rand::rngs::SmallRng;
        use rand::{RngExt, SeedableRng};
        let [lo, hi] = self.muscles("actuations")?.length_range;
        // Distinct streams for distinct (seed, index) pairs.
        let mut rng = SmallRng::seed_from_u64(seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let lengths: Vec<[f64; 3]> = (0..self.body.sections)
            .map(|_| std::array::from_fn(|_| rng.random_range(lo..=hi)))
            .collect();
        self.rest_curvature(&lengths)
    }

    /// `samples` random drives ([`Robot::random_drive`] of indices
    /// `0..samples`).
    pub fn random_drives(&self, samples: usize, seed: u64) -> Result<Vec<Actuation>> {
        self.validate()?;
        (0..samples as u64)
            .map(|i| self.random_drive(seed, i))
            .collect()
    }

    /// The workspace of a muscle-driven robot.
    fn muscle_workspace(
        &self,
        samples: usize,
        first: u64,
        load: &Load,
        seed: u64,
        settings: &BatchSettings,
        control: &BatchControl,
    ) -> Result<(Vec<Actuation>, Vec<Sample>)> {
        self.check_workspace(samples, first, settings)?;
        let start = self.chunk_solver(load)?;
        let out = self.drawn_samples(
            (samples, first),
            (settings, control),
            start,
            |index| self.random_curvature(seed, index),
            |state, kappa| self.forward_sample(state, kappa, settings),
        )?;
        Ok(out
            .into_iter()
            .map(|(kappa, sample)| (Actuation::muscles(kappa), sample))
            .unzip())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::batch::max_threads;
    use crate::solver::Settings;
    use std::sync::atomic::Ordering;

    fn actuations(robot: &Robot, samples: usize) -> Vec<Actuation> {
        let m = robot.body.sections;
        (0..samples)
            .map(|j| {
                Actuation::muscles(
                    (j * m..(j + 1) * m)
                        .map(|i| {
                            let phi = 0.37 * i as f64;
                            [2.0 * phi.cos(), 2.0 * (1.3 * phi).sin()]
                        })
                        .collect(),
                )
            })
            .collect()
    }

    #[test]
    fn a_forward_batch_is_the_one_by_one_forward_solve() {
        let robot = Robot::default();
        let k = actuations(&robot, 10);
        let cold = BatchSettings {
            warm_start: false,
            chunk: 3,
            ..BatchSettings::default()
        };
        let batch = robot
            .forward_batch(
                &k,
                &crate::robot::Load::from(0.03),
                &cold,
                &BatchControl::default(),
            )
            .unwrap();
        for (sample, a) in batch.iter().zip(&k) {
            let scene = robot.scene(a, &crate::robot::Load::from(0.03)).unwrap();
            let settings = Settings {
                n_elements: Some(robot.n_elements),
                ..Settings::default()
            };
            let one = crate::solve(&scene, settings, None).unwrap();
            assert!(sample.converged() && sample.stable);
            assert_eq!(sample.tip_position, one.tip_position());
        }
        // Warm starts land on the same equilibria within the tolerance.
        let warm = robot
            .forward_batch(
                &k,
                &crate::robot::Load::from(0.03),
                &BatchSettings::default(),
                &BatchControl::default(),
            )
            .unwrap();
        for (a, b) in warm.iter().zip(&batch) {
            assert!((a.tip_position - b.tip_position).norm() < 1e-9);
        }
    }

    #[test]
    fn a_workspace_beyond_memory_is_refused_by_name_before_allocating() {
        let robot = Robot::default();
        let settings = BatchSettings::default();
        let control = BatchControl::default();
        for samples in [1usize << 40, usize::MAX] {
            match robot.workspace(
                samples,
                0,
                &crate::robot::Load::from(0.0),
                0,
                &settings,
                &control,
            ) {
                Err(Error::InvalidArgument { name, .. }) => assert_eq!(name, "samples"),
                other => panic!("{samples}: {:?}", other.map(|r| r.1.len())),
            }
        }
        match robot.workspace(
            4,
            u64::MAX - 1,
            &crate::robot::Load::from(0.0),
            0,
            &settings,
            &control,
        ) {
            Err(Error::InvalidArgument { name, .. }) => assert_eq!(name, "first"),
            other => panic!("{:?}", other.map(|r| r.1.len())),
        }
    }

    #[test]
    fn thread_counts_beyond_the_cores_are_refused() {
        let at_most = |threads| BatchSettings {
            threads: Some(threads),
            ..BatchSettings::default()
        };
        assert!(at_most(max_threads()).validate().is_ok());
        assert!(matches!(
            at_most(max_threads() + 1).validate(),
            Err(Error::InvalidArgument { name, .. }) if name == "threads"
        ));
    }

    #[test]
    fn the_answers_do_not_depend_on_the_number_of_threads() {
        let robot = Robot::default();
        let k = actuations(&robot, 40);
        let run = |threads| {
            let settings = BatchSettings {
                threads: Some(threads),
                chunk: 7,
                ..BatchSettings::default()
            };
            robot
                .forward_batch(
                    &k,
                    &crate::robot::Load::from(0.0),
                    &settings,
                    &BatchControl::default(),
                )
                .unwrap()
        };
        assert_eq!(run(1), run(2));
    }

    #[test]
    fn bad_batches_are_refused_by_name() {
        let robot = Robot::default();
        let control = BatchControl::default();
        let mut k = actuations(&robot, 2);
        k[0].rest_curvature.pop();
        let e = robot
            .forward_batch(
                &k,
                &crate::robot::Load::from(0.0),
                &BatchSettings::default(),
                &control,
            )
            .unwrap_err();
        assert!(
            e.to_string().contains("actuations") && e.to_string().contains("sample 0"),
            "{e}"
        );
        k[0].rest_curvature.push([0.0; 2]);
        k[1].rest_curvature[1][0] = f64::NAN;
        let e = robot
            .forward_batch(
                &k,
                &crate::robot::Load::from(0.0),
                &BatchSettings::default(),
                &control,
            )
            .unwrap_err();
        assert!(e.to_string().contains("sample 1"), "{e}");
        let zero = BatchSettings {
            chunk: 0,
            ..BatchSettings::default()
        };
        let e = robot.forward_batch(&k[..1], &crate::robot::Load::from(0.0), &zero, &control);
        assert!(e.unwrap_err().to_string().contains("chunk"));
    }

    #[test]
    fn a_batch_of_tensions_is_the_one_by_one_forward_solve() {
        let robot =
            Robot::from_toml_str(include_str!("../../examples/robots/tendon_robot.toml")).unwrap();
        let drives: Vec<Actuation> = (0..6)
            .map(|i| Actuation {
                tensions: (0..9)
                    .map(|j| ((i * 9 + j) as f64).sin().abs() * 8.0)
                    .collect(),
                ..Actuation::default()
            })
            .collect();
        let cold = BatchSettings {
            warm_start: false,
            chunk: 4,
            ..BatchSettings::default()
        };
        let control = BatchControl::default();
        let batch = robot
            .forward_batch(&drives, &crate::robot::Load::from(0.02), &cold, &control)
            .unwrap();
        let warm = BatchSettings::default();
        let warmed = robot
            .forward_batch(&drives, &crate::robot::Load::from(0.02), &warm, &control)
            .unwrap();
        for ((sample, again), a) in batch.iter().zip(&warmed).zip(&drives) {
            let one = robot
                .actuated_solver(a, &crate::robot::Load::from(0.02))
                .unwrap()
                .solve(None)
                .unwrap();
            assert!(sample.converged() && sample.stable);
            assert_eq!(sample.tip_position, one.tip_position());
            assert!((again.tip_position - one.tip_position()).norm() < 1e-9);
        }
        // Over the drive's limit: refused, naming the sample.
        let mut over = drives.clone();
        over[4].tensions[2] = 100.0;
        let e = robot
            .forward_batch(&over, &crate::robot::Load::from(0.02), &cold, &control)
            .unwrap_err();
        assert!(e.to_string().contains("tensions[2]") && e.to_string().contains("sample 4"));
    }

    #[test]
    fn a_stopped_batch_is_interrupted() {
        let robot = Robot::default();
        let k = actuations(&robot, 20);
        let control = BatchControl::default();
        control.stop.store(true, Ordering::Relaxed);
        let e = robot.forward_batch(
            &k,
            &crate::robot::Load::from(0.0),
            &BatchSettings::default(),
            &control,
        );
        assert!(matches!(e, Err(Error::Interrupted)));
    }
}
