//! Many solves at once, on every core: forward statics of many actuations or
//! scenes, inverse kinematics of many targets, a robot's workspace.
//!
//! The samples are cut into chunks of [`BatchSettings::chunk`]; each chunk is
//! solved in order by one worker with one reusable solver (its workspace
//! allocated once), each solve warm-started from the last equilibrium of the
//! chunk when [`BatchSettings::warm_start`] is set. Chunks run on rayon's
//! threads. The results depend on the chunking, never on the number of
//! threads: a batch cut at multiples of `chunk` (a distributed engine's
//! partitions) gives the same answers to the last bit.
//!
//! A caller that can be interrupted (Python's Ctrl-C) or wants progress
//! passes a [`BatchControl`]: every worker polls its stop flag through
//! [`crate::interrupt`], and `done` counts the finished samples.

use crate::error::{Error, Result};
use crate::quat::Quat;
use crate::scene::Scene;
use crate::solver::{Settings, Solution, Status};
use nalgebra::Vector3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

/// How a batch runs.
#[derive(Debug, Clone, PartialEq)]
pub struct BatchSettings {
    /// Worker threads; `None`: rayon's global pool (every core).
    pub threads: Option<usize>,
    /// Samples a worker solves in order with one solver (the unit of work,
    /// and the run of warm starts).
    pub chunk: usize,
    /// Start a solve from the chunk's last equilibrium where its actuation is
    /// near (every section's rest turn within [`WARM_TURN`]; a warm start that
    /// does not end converged and stable is redone from the straight rod);
    /// when false every solve is cold.
    pub warm_start: bool,
    /// Keep every equilibrium's node positions and quaternions.
    pub shapes: bool,
}

impl Default for BatchSettings {
    fn default() -> Self {
        BatchSettings {
            threads: None,
            chunk: DEFAULT_CHUNK,
            warm_start: true,
            shapes: false,
        }
    }
}

/// Chunks a task on a cluster takes by default: a few thousand samples of the
/// robot, about 0.1 s of work, large against a task's overhead on Ray or Dask
/// (milliseconds).
pub const PART_CHUNKS: usize = 32;

/// Samples a worker takes at a time: large enough that a chunk's set-up (a
/// solver, its workspace) is amortised and warm starts have a run, small
/// enough that two cores share a batch of a few hundred evenly.
pub const DEFAULT_CHUNK: usize = 64;

impl BatchSettings {
    pub fn validate(&self) -> Result<()> {
        if self.chunk == 0 {
            return Err(Error::argument("chunk", "must be at least 1"));
        }
        if self.threads == Some(0) {
            return Err(Error::argument(
                "threads",
                "must be at least 1 (or None: every core)",
            ));
        }
        let most = max_threads();
        if let Some(t) = self.threads.filter(|t| *t > most) {
            return Err(Error::argument(
                "threads",
                format!(
                    "{t} is more than {most} ({THREADS_PER_CORE} for each of this machine's {} \
                     cores): threads beyond the cores only take turns on them (None: every core)",
                    cores()
                ),
            ));
        }
        Ok(())
    }

    /// The samples of one task when a batch is cut into tasks (on a
    /// cluster): `part`, or [`PART_CHUNKS`] chunks by default. Refused unless
    /// a positive multiple of `chunk`: only then is every part solved as the
    /// same samples of a local batch (the same answers, to the bit).
    pub fn part(&self, part: Option<usize>) -> Result<usize> {
        let part = part.unwrap_or(PART_CHUNKS * self.chunk);
        if part == 0 || part % self.chunk != 0 {
            return Err(Error::argument(
                "part",
                format!(
                    "must be a positive multiple of chunk ({}) for the results to be those of \
                     a local batch, got {part}",
                    self.chunk
                ),
            ));
        }
        Ok(part)
    }

    /// Bytes one sample's result holds while a batch returns it (the core's
    /// [`Sample`] with its shape of `nodes` nodes if kept, and `drive_values`
    /// numbers of its drives), twice: the parts and the joined results, or
    /// the results and the caller's copy (Python's arrays), live at once.
    pub fn sample_bytes(&self, nodes: usize, drive_values: usize) -> usize {
        let shape = match self.shapes {
            true => nodes.saturating_mul(std::mem::size_of::<(Vector3<f64>, Quat)>()),
            false => 0,
        };
        std::mem::size_of::<Sample>()
            .saturating_add(shape)
            .saturating_add(drive_values.saturating_mul(8))
            .saturating_mul(2)
    }
}

/// Most worker threads a batch may ask for, per core: a solve is pure
/// computation, so threads beyond the cores only take turns on them, and
/// thousands of them load the machine for nothing (2 000 drove its load
/// average above 600).
pub const THREADS_PER_CORE: usize = 4;

/// The cores this process may use.
fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Largest `threads` of a batch: [`THREADS_PER_CORE`] for each core.
pub fn max_threads() -> usize {
    THREADS_PER_CORE * cores()
}

/// Refuse a batch of `count` results of `bytes_each` bytes that cannot fit
/// in the memory the machine has free (or whose size overflows), naming the
/// argument `name` that sets the count, before anything is allocated: a
/// failed allocation of the results would abort the process. A batch that
/// fits may still fail to allocate: that is [`Error::OutOfMemory`].
pub fn check_batch_size(name: &str, count: usize, bytes_each: usize) -> Result<()> {
    let free = free_memory();
    let bytes = count.checked_mul(bytes_each);
    match (bytes, free) {
        (Some(b), Some(free)) if b <= free => Ok(()),
        (Some(b), None) if b <= isize::MAX as usize => Ok(()),
        (bytes, free) => Err(Error::argument(
            name,
            format!(
                "{count} samples need {} for their results, more than {}: run the batch in parts",
                bytes.map_or_else(|| "more bytes than an address space holds".into(), in_bytes),
                free.map_or_else(
                    || "an address space holds".into(),
                    |f| format!("the {} free on this machine", in_bytes(f))
                ),
            ),
        )),
    }
}

/// A byte count for a person: `1.5 GB`.
fn in_bytes(b: usize) -> String {
    let b = b as f64;
    match b {
        b if b >= 1e12 => format!("{:.1} TB", b / 1e12),
        b if b >= 1e9 => format!("{:.1} GB", b / 1e9),
        b if b >= 1e6 => format!("{:.1} MB", b / 1e6),
        b => format!("{b:.0} bytes"),
    }
}

/// The memory available to new allocations [bytes] (Linux: `MemAvailable`
/// of `/proc/meminfo`); None where the system does not say.
fn free_memory() -> Option<usize> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: usize = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// Progress and interruption of a running batch, shared with its caller.
#[derive(Debug, Default)]
pub struct BatchControl {
    /// Samples finished so far.
    pub done: AtomicUsize,
    /// Set by the caller to stop: the workers wind down and the batch
    /// returns [`Error::Interrupted`] (shared: a solve's interrupt check
    /// holds it).
    pub stop: Arc<AtomicBool>,
}

/// One forward solve of a batch: how it ended and the tip (the shape if asked).
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    pub status: Status,
    pub stable: bool,
    pub iterations: usize,
    pub residual_norm: f64,
    pub tip_position: Vector3<f64>,
    /// Scalar first.
    pub tip_quaternion: Quat,
    /// Node positions and quaternions, with [`BatchSettings::shapes`].
    pub shape: Option<(Vec<Vector3<f64>>, Vec<Quat>)>,
}

impl Sample {
    pub(crate) fn of(sol: &Solution, shapes: bool) -> Sample {
        Sample {
            status: sol.status,
            stable: sol.stable,
            iterations: sol.iterations,
            residual_norm: sol.residual_norm,
            tip_position: sol.tip_position(),
            tip_quaternion: *sol.quaternions.last().expect("n + 1 nodes"),
            shape: shapes.then(|| (sol.positions.clone(), sol.quaternions.clone())),
        }
    }

    pub fn converged(&self) -> bool {
        self.status == Status::Converged
    }
}

/// What a batch's results hold: the argument that sets their count (named
/// when the batch is refused) and the bytes of one.
#[derive(Clone, Copy)]
pub(crate) struct ResultSize<'a> {
    pub(crate) name: &'a str,
    pub(crate) bytes_each: usize,
}

/// Run `work` over the items `0..count` in chunks (see the module's
/// documentation), once their results are known to fit
/// ([`check_batch_size`]). `start` makes a chunk's state (its solver);
/// `work` solves one item, by its index.
pub(crate) fn run_chunks<S, R>(
    count: usize,
    size: ResultSize,
    settings: &BatchSettings,
    control: &BatchControl,
    start: impl Fn() -> Result<S> + Sync,
    work: impl Fn(&mut S, usize) -> Result<R> + Sync,
) -> Result<Vec<R>>
where
    R: Send,
{
    settings.validate()?;
    check_batch_size(size.name, count, size.bytes_each)?;
    // Before any work: a batch that cannot hold its results fails at once.
    let mut joined = Vec::new();
    joined
        .try_reserve_exact(count)
        .map_err(|_| Error::OutOfMemory {
            what: format!("{}: the results", size.name),
            bytes: count.saturating_mul(std::mem::size_of::<R>()),
        })?;
    let chunk = settings.chunk;
    let chunks = || -> Result<Vec<Vec<R>>> {
        (0..count.div_ceil(chunk))
            .into_par_iter()
            .map(|c| {
                let items = c * chunk..count.min((c + 1) * chunk);
                let stop = Arc::clone(&control.stop);
                crate::interrupt::with_check(
                    move || stop.load(Ordering::Relaxed),
                    || {
                        let mut state = start()?;
                        let mut out = Vec::with_capacity(items.len());
                        for item in items {
                            // Between samples directly (the interrupt check
                            // inside a solve polls only every 20 ms).
                            if control.stop.load(Ordering::Relaxed) {
                                return Err(Error::Interrupted);
                            }
                            out.push(work(&mut state, item)?);
                            control.done.fetch_add(1, Ordering::Relaxed);
                        }
                        Ok(out)
                    },
                )
            })
            .collect()
    };
    let parts = Threads::new(settings.threads)?.run(chunks)?;
    if control.stop.load(Ordering::Relaxed) {
        return Err(Error::Interrupted);
    }
    for part in parts {
        joined.extend(part);
    }
    Ok(joined)
}

/// Where parallel work runs: rayon's global pool (every core) or a pool of
/// the threads asked for, built once.
pub(crate) struct Threads(Option<rayon::ThreadPool>);

impl Threads {
    pub(crate) fn new(threads: Option<usize>) -> Result<Self> {
        threads
            .map(|t| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(t)
                    .build()
                    .map_err(|e| Error::argument("threads", format!("no thread pool: {e}")))
            })
            .transpose()
            .map(Threads)
    }

    pub(crate) fn run<R: Send>(&self, work: impl FnOnce() -> R + Send) -> R {
        match &self.0 {
            Some(pool) => pool.install(work),
            None => work(),
        }
    }
}

/// Forward statics of many scenes, each with `solver_settings` (cold
/// solves: the scenes may differ in anything, their discretisation too).
pub fn solve_batch(
    scenes: &[Scene],
    solver_settings: &Settings,
    settings: &BatchSettings,
    control: &BatchControl,
) -> Result<Vec<Sample>> {
    solver_settings.validate()?;
    // The finest scene's shape for every sample: a bound, not a sum.
    let nodes = scenes
        .iter()
        .map(|s| solver_settings.elements_for(s) + 1)
        .max()
        .unwrap_or(0);
    run_chunks(
        scenes.len(),
        ResultSize {
            name: "scenes",
            bytes_each: settings.sample_bytes(nodes, 0),
        },
        settings,
        control,
        || Ok(()),
        |_, i| {
            let sol = crate::solve(&scenes[i], solver_settings.clone(), None)?;
            Ok(Sample::of(&sol, settings.shapes))
        },
    )
}
