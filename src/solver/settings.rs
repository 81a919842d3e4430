//! The settings of an equilibrium solve ([`Settings`]): every field with its
//! unit and default, read from a value tree by name (the Python `Settings` and
//! `solve`'s keywords go through [`Settings::set`]), checked by
//! [`Settings::validate`].

use crate::error::{Error, Result};
use crate::methods::paper::PaperSettings;
use crate::model::Scheme;
use crate::read::{as_argument, check_tolerance, count, finite, string, Table};
use crate::scene::{Scene, TipCondition};
use crate::value::Value;

/// The numerical method.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// The core chooses ([`Settings::method_for`]): shooting for accuracy on
    /// demand where it models the scene and no scheme is set (its error
    /// falls as `n^-4` at the cost of a second-order solve), Newton
    /// otherwise. The default.
    Auto,
    /// Damped Newton on the minimal (3 per node) update with the block-tridiagonal
    /// Jacobian: O(n) per iteration, quadratic convergence.
    Newton,
    /// Levenberg-Marquardt on the same residual, dense normal equations with faer.
    LevenbergMarquardt,
    /// The seed paper's method: PSO then LM over `[q, F]` with the unit-norm rows.
    Paper,
    /// The paper's system as printed, without the unit-norm rows (it collapses).
    PaperLiteral,
    /// Shooting: RK4 on the Kirchhoff rod equations, one step an element, and
    /// Newton on the base wrench (no guides). The baseline of the report.
    Shooting,
}

/// How a method finds the equilibrium: the one choice the driver makes on
/// the method ([`Method::engine`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Engine {
    /// On the discrete potential: a local method with the driver's coarse
    /// start, direct attempt, load continuation and fallbacks.
    Potential(Local),
    /// Shooting: the rod's equations integrated from the base, its own solver.
    Shooting,
    /// The seed paper's system over `[q, F]` (`literal`: without the
    /// unit-norm rows).
    Paper { literal: bool },
}

/// The local method of a solve on the discrete potential (and the one the
/// other engines' answers are checked with).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Local {
    Newton,
    LevenbergMarquardt,
}

impl Method {
    /// How this method finds the equilibrium.
    pub fn engine(self) -> Engine {
        match self {
            Method::Auto | Method::Newton => Engine::Potential(Local::Newton),
            Method::LevenbergMarquardt => Engine::Potential(Local::LevenbergMarquardt),
            Method::Paper => Engine::Paper { literal: false },
            Method::PaperLiteral => Engine::Paper { literal: true },
            Method::Shooting => Engine::Shooting,
        }
    }

    /// Whether it solves the discrete potential (everything a scene holds,
    /// the sensitivities): Newton and Levenberg-Marquardt.
    pub fn on_the_potential(self) -> bool {
        matches!(self.engine(), Engine::Potential(_))
    }

    /// The local method its answers are found or checked with.
    pub fn local(self) -> Local {
        match self.engine() {
            Engine::Potential(local) => local,
            Engine::Shooting => Local::Newton,
            Engine::Paper { .. } => Local::LevenbergMarquardt,
        }
    }

    /// The name [`Method::from_str`](std::str::FromStr) reads.
    pub fn name(self) -> &'static str {
        match self {
            Method::Auto => "auto",
            Method::Newton => "newton",
            Method::LevenbergMarquardt => "lm",
            Method::Paper => "paper",
            Method::PaperLiteral => "paper-literal",
            Method::Shooting => "shooting",
        }
    }
}

impl std::str::FromStr for Method {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "auto" => Ok(Method::Auto),
            "newton" => Ok(Method::Newton),
            "lm" => Ok(Method::LevenbergMarquardt),
            "paper" => Ok(Method::Paper),
            "paper-literal" => Ok(Method::PaperLiteral),
            "shooting" => Ok(Method::Shooting),
            other => Err(Error::argument(
                "method",
                format!("unknown method '{other}' (expected 'auto', 'newton', 'lm', 'paper', 'paper-literal' or 'shooting')"),
            )),
        }
    }
}

/// Solver settings; every field has a documented default.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Number of elements `n`, a multiple of the number of sections. `None`
    /// (the default): [`default_elements`] of the scene's sections, the
    /// smallest multiple of them that is at least [`DEFAULT_ELEMENTS`].
    pub n_elements: Option<usize>,
    /// The numerical method (default [`Method::Auto`]: the core chooses,
    /// see [`Settings::method_for`]).
    pub method: Method,
    /// The discretisation of the backbone. `None` (the default): chosen by
    /// [`Settings::scheme_for`], the faster for the accuracy asked (measured:
    /// `fe4` for accuracy on demand below [`FOURTH_ORDER_TOL`], or
    /// [`FOURTH_ORDER_TOL_HELD`] on a scene with held points, `fd2`
    /// otherwise). The paper's method and shooting have their own
    /// discretisation and take only `None` or `fd2`.
    pub scheme: Option<Scheme>,
    /// Convergence tolerance on the relative residual: the largest torque
    /// imbalance of a row over its own scale `k_c / L` (default 1e-10, within
    /// [`RESIDUAL_TOL_RANGE`]). The tolerance in effect is never below the
    /// round-off floor of the residual (see [`RodModel::roundoff_floor`]), so
    /// that it cannot be defeated at large n.
    pub residual_tol: f64,
    /// Iteration budget of a solve (default 500), shared by the coarse rod of
    /// nested iteration (at most three quarters of it), the direct attempt (at most 60),
    /// every load-continuation step (at most 25 each) and the
    /// Levenberg-Marquardt fallback: `Solution::iterations` never exceeds it.
    pub max_iterations: usize,
    /// Smallest load-continuation step before giving up, as a fraction of
    /// the load (default 1e-6, in (0, 1)).
    pub min_continuation_step: f64,
    /// Settings of the paper's method (swarm, Gauss-Newton, LM).
    pub paper: PaperSettings,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            n_elements: None,
            method: Method::Auto,
            scheme: None,
            residual_tol: 1e-10,
            max_iterations: 500,
            min_continuation_step: 1e-6,
            paper: PaperSettings::default(),
        }
    }
}

/// Accuracy on demand below this tolerance (relative to `L`) uses the
/// fourth-order scheme when the scheme is not set: measured on the report's
/// five scenes (from Python, README "Accuracy on demand"), `fe4` meets 1e-6 L
/// in 0.15 to 1.0 times and 1e-8 L in 0.1 to 0.25 times the time of `fd2`
/// (which misses 1e-8 L on two of them within 10 240 elements). Issue 30's
/// race scenes (cantilevers at alpha = 3 and 10, a precurved rod under its
/// weight; `tol=` from Python, 2026-11-27, once `fe4`'s passes no longer
/// started a thread): at 1e-5 L `fe4` takes 0.5 to 0.7 times `fd2`'s time,
/// at 1e-4 L 0.9 to 1.6 times, at 1e-3 L 1.3 to 3.5 times: the switch
/// between the last two.
pub const FOURTH_ORDER_TOL: f64 = 3e-5;

/// [`FOURTH_ORDER_TOL`] of a scene with held points: on the pinned and
/// clamped rods of the tests (tests/test_held_references.py), `fe4` is even
/// with `fd2` at 1e-6 L and 3.5 to 4 times faster at 1e-8 L.
pub const FOURTH_ORDER_TOL_HELD: f64 = 1e-6;

/// The fewest elements of a solve by default (see [`default_elements`]).
pub const DEFAULT_ELEMENTS: usize = 20;

/// The default discretisation of a scene: the smallest n of
/// [`Scene::node_multiple`] (one that puts every located input on a node)
/// that is at least [`DEFAULT_ELEMENTS`]; if there is none, the sections'
/// default, which the scene's own check then refuses by key.
pub fn default_elements_of(scene: &Scene) -> usize {
    match scene.node_multiple(MAX_ELEMENTS) {
        Ok(g) => DEFAULT_ELEMENTS.div_ceil(g) * g,
        Err(_) => default_elements(scene.sections()),
    }
}

/// The default number of elements of a rod of `sections` sections: the
/// smallest multiple of them that is at least [`DEFAULT_ELEMENTS`] (every
/// section gets the same whole number of elements).
pub fn default_elements(sections: usize) -> usize {
    let sections = sections.max(1);
    DEFAULT_ELEMENTS.div_ceil(sections) * sections
}

/// Largest `n_elements` of the O(n) Newton solver: about 0.5 KB a node of
/// workspace, so 4 000 000 elements take about 2 GB.
pub const MAX_ELEMENTS: usize = 4_000_000;

/// Largest `n_elements` of the dense methods (`lm`: matrices of `(3n)^2`
/// entries and O(n^3) work an iteration).
pub const MAX_DENSE_ELEMENTS: usize = 1_000;

/// Largest `n_elements` of the paper's method (dense, over `[q, F]`, and a
/// swarm of particles in `7n` dimensions).
pub const MAX_PAPER_ELEMENTS: usize = 400;

/// Range of `residual_tol`: below 1e-14 is below what double precision
/// resolves; above 1e-4 a "converged" state is visibly off equilibrium.
pub const RESIDUAL_TOL_RANGE: (f64, f64) = (1e-14, 1e-4);

/// Smallest discretisations of which one pass may outlast an interrupt poll
/// ([`Settings::has_long_passes`]): a sweep over 20 000 elements takes about
/// 2 ms, a dense factorisation of 100 elements' `(3n)^2` matrix about as long.
const LONG_PASS_ELEMENTS: usize = 20_000;
const LONG_DENSE_PASS_ELEMENTS: usize = 100;

impl Settings {
    /// Whether one pass of this solve (a sweep over the rod, a dense
    /// factorisation) may take longer than [`crate::interrupt::POLL_INTERVAL`]:
    /// a caller that must answer Ctrl-C at once then runs it
    /// [`crate::interrupt::on_worker`]. The solvers poll between passes.
    /// (Settings [`resolved`](Settings::resolved) for the scene: the default
    /// n counts as [`DEFAULT_ELEMENTS`].)
    pub fn has_long_passes(&self) -> bool {
        let n = self.n_elements.unwrap_or(DEFAULT_ELEMENTS);
        match self.method {
            // A fourth-order element costs about eight second-order ones.
            Method::Auto | Method::Newton if self.scheme == Some(Scheme::Fe4) => {
                n >= LONG_PASS_ELEMENTS / 8
            }
            Method::Auto | Method::Newton | Method::Shooting => n >= LONG_PASS_ELEMENTS,
            _ => n >= LONG_DENSE_PASS_ELEMENTS,
        }
    }

    /// The order of convergence of the nodes as `n` grows: the scheme's,
    /// or 4 for shooting (RK4).
    pub fn order(&self) -> i32 {
        match self.method {
            Method::Shooting => 4,
            _ => self.scheme.unwrap_or_default().order(),
        }
    }

    /// The scheme of a solve of `scene`, to `accuracy` (relative to `L`) with
    /// accuracy on demand: the setting, or the faster for that accuracy when
    /// it is `None` (see [`Settings::scheme`]).
    pub fn scheme_for(&self, scene: &Scene, accuracy: Option<f64>) -> Scheme {
        self.scheme.unwrap_or_else(|| {
            let held = !scene.guides.is_empty() || scene.tip != TipCondition::Free;
            let threshold = if held {
                FOURTH_ORDER_TOL_HELD
            } else {
                FOURTH_ORDER_TOL
            };
            let fine = accuracy.is_some_and(|tol| tol < threshold);
            // Contact is solved on the second-order scheme's chords so far.
            let newton = matches!(self.method, Method::Auto | Method::Newton);
            if fine && newton && !scene.has_contact() {
                Scheme::Fe4
            } else {
                Scheme::Fd2
            }
        })
    }

    /// The number of elements of a solve of `scene`: `n_elements`, or
    /// [`default_elements`] of its sections.
    pub fn elements_for(&self, scene: &Scene) -> usize {
        self.n_elements
            .unwrap_or_else(|| default_elements_of(scene))
    }

    /// The method of a solve of `scene`, to `accuracy` (relative to `L`)
    /// with accuracy on demand: the setting, or for [`Method::Auto`]
    /// shooting where accuracy is asked, no scheme is set, the tip is free
    /// and shooting models the scene ([`shooting_models`]), Newton
    /// otherwise. (Shooting's RK4 meets a tolerance with fewer elements
    /// than the fourth-order scheme, at about the cost of a second-order one
    /// each: the fastest setting of the crate at 13 of 15 of the race's
    /// points. With a held tip its Newton on the six base unknowns rarely
    /// converges from the rigid estimate, and its load path took 4 to 6
    /// times Newton's time on a pinned cantilever, measured. Tendons too stay
    /// on Newton: each RK4 stage under tendons solves for its curvature, and
    /// on the tendon robot (9 tendons) a shot took 5 times the fourth-order
    /// scheme's time for the same accuracy.)
    pub fn method_for(&self, scene: &Scene, accuracy: Option<f64>) -> Method {
        let shooting_fits = self.scheme.is_none()
            && scene.tip == TipCondition::Free
            && scene.tendons.is_empty()
            && shooting_models(scene);
        match self.method {
            Method::Auto if accuracy.is_some() && shooting_fits => Method::Shooting,
            Method::Auto => Method::Newton,
            method => method,
        }
    }

    /// These settings with the number of elements for `scene` filled in and
    /// the method chosen for a solve at that number ([`Settings::method_for`]).
    pub fn resolved(&self, scene: &Scene) -> Settings {
        Settings {
            n_elements: Some(self.elements_for(scene)),
            method: self.method_for(scene, None),
            ..self.clone()
        }
    }

    pub fn validate(&self) -> Result<()> {
        let limit = match self.method {
            Method::Auto | Method::Newton | Method::Shooting => MAX_ELEMENTS,
            Method::LevenbergMarquardt => MAX_DENSE_ELEMENTS,
            Method::Paper | Method::PaperLiteral => MAX_PAPER_ELEMENTS,
        };
        if let Some(n) = self.n_elements {
            if n == 0 || n > limit {
                return Err(Error::argument(
                    "n_elements",
                    format!(
                        "must lie in [1, {limit}] for method {:?}, got {n}",
                        self.method
                    ),
                ));
            }
        }
        if self.scheme == Some(Scheme::Fe4)
            && matches!(
                self.method,
                Method::Paper | Method::PaperLiteral | Method::Shooting
            )
        {
            return Err(Error::argument(
                "scheme",
                format!(
                    "method '{}' has its own discretisation; only 'fd2' (or None) applies",
                    self.method.name()
                ),
            ));
        }
        check_tolerance("residual_tol", self.residual_tol, RESIDUAL_TOL_RANGE)?;
        if self.max_iterations == 0 {
            return Err(Error::argument("max_iterations", "must be positive"));
        }
        if !(self.min_continuation_step > 0.0 && self.min_continuation_step < 1.0) {
            return Err(Error::argument(
                "min_continuation_step",
                format!("must lie in (0, 1), got {}", self.min_continuation_step),
            ));
        }
        if matches!(self.method, Method::Paper | Method::PaperLiteral) {
            self.paper.validate()?;
        }
        Ok(())
    }
}

/// Whether shooting models everything in `scene`: no guides, nothing only
/// the discrete potential models ([`Scene::beyond_shooting`]).
pub fn shooting_models(scene: &Scene) -> bool {
    scene.guides.is_empty() && scene.beyond_shooting().is_none()
}

/// Largest iteration budget a setting accepts.
const MAX_ITERATION_SETTING: usize = 1_000_000_000;

impl Settings {
    /// Every key of [`Settings::set`], in the order of the fields.
    pub const KEYS: [&'static str; 7] = [
        "n_elements",
        "method",
        "scheme",
        "residual_tol",
        "max_iterations",
        "min_continuation_step",
        "paper",
    ];

    /// Set the field `key` from a value: `n_elements` a count or null (the
    /// default), `method` a name, `paper` a table of [`PaperSettings::set`]'s
    /// keys applied to the current paper settings. Refuses an unknown key or
    /// a value of the wrong kind, naming the key; ranges are
    /// [`validate`](Settings::validate)'s.
    pub fn set(&mut self, key: &str, value: &Value) -> Result<()> {
        self.set_field(key, value).map_err(as_argument)
    }

    fn set_field(&mut self, key: &str, value: &Value) -> Result<()> {
        match key {
            "n_elements" => {
                self.n_elements = match value {
                    Value::Null => None,
                    v => Some(count(v, key, MAX_ELEMENTS)?),
                }
            }
            "method" => self.method = string(value, key)?.parse()?,
            "scheme" => {
                self.scheme = match value {
                    Value::Null => None,
                    v => Some(string(v, key)?.parse()?),
                }
            }
            "residual_tol" => self.residual_tol = finite(value, key)?,
            "max_iterations" => self.max_iterations = count(value, key, MAX_ITERATION_SETTING)?,
            "min_continuation_step" => self.min_continuation_step = finite(value, key)?,
            "paper" => {
                let table = Table::new(value, key)?;
                for (k, v) in table.entries {
                    self.paper.set(k, v).map_err(|e| prefixed("paper", e))?;
                }
            }
            other => {
                return Err(Error::argument(
                    other,
                    format!(
                        "unknown setting (expected one of: {})",
                        Self::KEYS.join(", ")
                    ),
                ))
            }
        }
        Ok(())
    }

    /// Settings from a table of [`Settings::set`]'s keys over the defaults, validated.
    pub fn from_value(v: &Value) -> Result<Settings> {
        let mut settings = Settings::default();
        for (k, x) in Table::top(v, "settings").map_err(as_argument)?.entries {
            settings.set(k, x)?;
        }
        settings.validate()?;
        Ok(settings)
    }

    /// Every field as a table ([`Settings::from_value`] reads it back).
    pub fn to_value(&self) -> Value {
        Value::Map(vec![
            (
                "n_elements".into(),
                self.n_elements
                    .map_or(Value::Null, |n| Value::Number(n as f64)),
            ),
            ("method".into(), Value::String(self.method.name().into())),
            (
                "scheme".into(),
                self.scheme
                    .map_or(Value::Null, |s| Value::String(s.name().into())),
            ),
            ("residual_tol".into(), Value::Number(self.residual_tol)),
            (
                "max_iterations".into(),
                Value::Number(self.max_iterations as f64),
            ),
            (
                "min_continuation_step".into(),
                Value::Number(self.min_continuation_step),
            ),
            ("paper".into(), self.paper.to_value()),
        ])
    }
}

/// An error of a nested table's key, named from its parent (`paper.chi`).
pub(crate) fn prefixed(parent: &str, e: Error) -> Error {
    match e {
        Error::InvalidArgument { name, reason } if !name.starts_with(parent) => {
            Error::InvalidArgument {
                name: format!("{parent}.{name}"),
                reason,
            }
        }
        other => other,
    }
}
