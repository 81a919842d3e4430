"""Type stubs of the native module ``softspine._core`` (Rust, PyO3).

Checked against the built module by ``python -m mypy.stubtest softspine._core``
(``make test``). _Arrays are float64; quaternions are scalar-first ``[w, x, y, z]``.
"""

from collections.abc import Callable, Sequence
from enum import Enum
from os import PathLike
from typing import Any, TypeAlias, final

import numpy as np
import numpy.typing as npt

from .batch import BatchResult, IkBatchResult
from .sensitivity import Sensitivity
from .types import Method, Refine, RobotDict, SceneDict, SchemeName, Strategy

# What a robot carries: a payload mass [kg], or a dict of mass, tip_force
# [N], tip_moment [N m] (world frame) and point_loads [{s, force, moment}].
_Load: TypeAlias = float | dict[str, Any] | None

__version__: str
__all__ = [
    "Accuracy",
    "IkEnding",
    "IkResult",
    "IkSettings",
    "InverseSolver",
    "PaperSettings",
    "Robot",
    "Scene",
    "Scheme",
    "Settings",
    "Solution",
    "Solver",
    "SolverError",
    "Status",
    "__version__",
    "_calibrate",
    "_solve_batch",
    "jacobian",
    "keys",
    "read_obstacle",
    "residual",
    "solve",
    "trajectory_points",
]
# The core's named enums, generated from it at import (members and docs): a
# member is a str equal to its name and prints as it.
class Status(str, Enum):
    """How a solve ended."""

    def __new__(cls, value: str) -> Status: ...
    CONVERGED = "converged"
    NOT_CONVERGED = "not_converged"
    ITERATION_LIMIT = "iteration_limit"
    TOLERANCE_NOT_MET = "tolerance_not_met"
    UNDERRESOLVED = "underresolved"
    NUMERICAL_ERROR = "numerical_error"
    INDETERMINATE = "indeterminate"

class IkEnding(str, Enum):
    """Why an inverse solve ended."""

    def __new__(cls, value: str) -> IkEnding: ...
    REACHED = "reached"
    OUT_OF_REACH = "out_of_reach"
    BOUNDS_ACTIVE = "bounds_active"
    SOLVER_FAILURE = "solver_failure"
    ITERATION_LIMIT = "iteration_limit"
    LOAD_IGNORED = "load_ignored"

class Scheme(str, Enum):
    """How a solution's nodes were computed."""

    def __new__(cls, value: str) -> Scheme: ...
    FD2 = "fd2"
    FE4 = "fe4"
    RK4 = "rk4"

_Array: TypeAlias = npt.NDArray[np.float64]

class SolverError(Exception):
    """A solve did not converge (raised with ``check=True``)."""

@final
class Scene:
    """What is being solved; ``ValueError`` naming the key on invalid input."""

    def __new__(cls, data: SceneDict | dict[str, Any] | Scene | str | PathLike[str]) -> Scene:
        """From a dict, a Scene or the path of a ``.json`` / ``.toml`` file."""
    @staticmethod
    def from_json(text: str) -> Scene: ...
    @staticmethod
    def from_toml(text: str) -> Scene: ...
    @staticmethod
    def from_file(path: str | PathLike[str]) -> Scene:
        """Read a scene from a ``.json`` or ``.toml`` file."""
    def to_dict(self) -> dict[str, Any]: ...
    def to_json(self) -> str:
        """The scene as JSON text (``Scene.from_json`` reads it back)."""
    def to_toml(self) -> str:
        """The scene as TOML text (``Scene.from_toml`` reads it back)."""
    def save(self, path: str | PathLike[str]) -> None:
        """Write the scene to a ``.json`` or ``.toml`` file (by its suffix),
        which ``Scene.from_file`` reads back to the same scene."""
    @property
    def length(self) -> float: ...
    @property
    def stiffness(self) -> tuple[float, float, float]: ...
    @property
    def sections(self) -> int: ...
    @property
    def name(self) -> str | None: ...
    @property
    def distributed_force(self) -> _Array: ...
    def __reduce__(self) -> tuple[type[Scene], tuple[dict[str, Any]]]: ...

@final
class Solution:
    """An equilibrium (or the best state reached) with its status."""

    @property
    def n_elements(self) -> int: ...
    @property
    def scheme(self) -> Scheme: ...
    @property
    def length(self) -> float: ...
    @property
    def arc_length(self) -> _Array: ...
    @property
    def positions(self) -> _Array: ...
    @property
    def quaternions(self) -> _Array: ...
    def positions_at(self, s: npt.ArrayLike) -> _Array:
        """Positions at the arc lengths ``s`` (any array in ``[0, L]``), shape
        ``s.shape + (3,)``: between the nodes at the scheme's order."""
    def rotations_at(self, s: npt.ArrayLike) -> _Array:
        """Unit quaternions at the arc lengths ``s``, shape ``s.shape + (4,)``:
        between the nodes at the scheme's order, normalised."""
    @property
    def rotation_matrices(self) -> _Array: ...
    @property
    def forces(self) -> _Array: ...
    @property
    def moments(self) -> _Array: ...
    @property
    def curvatures(self) -> _Array: ...
    @property
    def tip_position(self) -> _Array: ...
    @property
    def tip_quaternion(self) -> _Array: ...
    @property
    def tip_reaction_force(self) -> _Array | None: ...
    @property
    def tip_reaction_moment(self) -> _Array | None: ...
    @property
    def guide_reactions(self) -> _Array: ...
    @property
    def contacts(self) -> dict[str, _Array]: ...
    @property
    def ports(self) -> dict[str, _Array]: ...
    @property
    def converged(self) -> bool: ...
    @property
    def status(self) -> Status: ...
    @property
    def iterations(self) -> int: ...
    @property
    def continuation_steps(self) -> int: ...
    @property
    def residual_norm(self) -> float: ...
    @property
    def energy(self) -> float: ...
    @property
    def stable(self) -> bool: ...
    @property
    def message(self) -> str: ...
    @property
    def error_estimate(self) -> float | None: ...
    @property
    def extrapolated(self) -> bool: ...
    @property
    def solve_time(self) -> float: ...
    def to_dict(self) -> dict[str, Any]: ...
    @staticmethod
    def from_dict(data: dict[str, Any]) -> Solution: ...
    def __reduce__(self) -> tuple[Any, tuple[dict[str, Any]]]: ...
    def save(self, path: str | PathLike[str]) -> None:
        """Write every field of ``to_dict()`` to ``path``: NPZ (``.npz``) or
        JSON (``.json``), by its suffix."""
    @staticmethod
    def load(path: str | PathLike[str]) -> Solution:
        """The solution that ``save`` wrote to ``path`` (NPZ or JSON)."""
    def to_json(self) -> str:
        """Every field of ``to_dict()`` as JSON text (arrays as nested lists,
        floats exactly); ``json.dumps(to_dict())`` cannot write the arrays."""
    @staticmethod
    def from_json(text: str) -> Solution:
        """The solution that ``to_json()`` wrote."""

@final
class IkResult:
    """The actuation of one inverse solve in every space, with its equilibrium."""

    @property
    def rest_curvature(self) -> _Array: ...
    @property
    def muscle_lengths(self) -> _Array: ...
    @property
    def inflation_times(self) -> _Array: ...
    @property
    def tensions(self) -> _Array:
        """Tendon tensions, N (a tendon-driven robot; empty otherwise)."""
    @property
    def field(self) -> _Array:
        """The uniform magnetic field, world frame, T (a magnetic robot; zero otherwise)."""
    @property
    def insertion(self) -> float:
        """How far the base was moved along its tangent, m (a robot with an
        ``insertion_range``, whose inverse kinematics chooses it; zero otherwise)."""
    @property
    def solution(self) -> Solution: ...
    @property
    def tip_position(self) -> _Array:
        """The point aimed at the target: the tool's (``tool_offset`` from the
        tip), or the tip without a tool."""
    @property
    def tip_miss(self) -> float: ...
    @property
    def reached(self) -> bool: ...
    @property
    def ending(self) -> IkEnding: ...
    @property
    def starts(self) -> int: ...
    @property
    def message(self) -> str: ...
    @property
    def iterations(self) -> int: ...
    @property
    def time(self) -> float: ...
    def to_dict(self) -> dict[str, Any]: ...
    @staticmethod
    def from_dict(data: dict[str, Any]) -> IkResult: ...
    def save(self, path: str | PathLike[str]) -> None:
        """Write every field of ``to_dict()`` to ``path``: NPZ (``.npz``; the
        solution's fields under ``"solution/..."``) or JSON (``.json``)."""
    @staticmethod
    def load(path: str | PathLike[str]) -> IkResult:
        """The result that ``IkResult.save`` wrote to ``path``."""
    def to_json(self) -> str:
        """Every field of ``to_dict()`` as JSON text (its solution's nested)."""
    @staticmethod
    def from_json(text: str) -> IkResult:
        """The result that ``to_json()`` wrote."""
    def __reduce__(self) -> tuple[Any, tuple[dict[str, Any]]]: ...

@final
class IkSettings:
    """Settings of inverse kinematics."""

    def __new__(cls, **fields: Any) -> IkSettings: ...
    def validate(self) -> None: ...
    def to_dict(self) -> dict[str, Any]: ...
    @property
    def strategy(self) -> Strategy: ...
    @strategy.setter
    def strategy(self, value: Strategy) -> None: ...
    tol: float
    max_iterations: int
    def __setstate__(self, state: dict[str, Any]) -> None: ...
    def __reduce__(self) -> tuple[Any, tuple[()], dict[str, Any]]: ...

@final
class InverseSolver:
    """Inverse kinematics of one robot under one tip mass, warm from its last answer."""

    def solve(
        self,
        target: npt.ArrayLike,
        reference: npt.ArrayLike | None = None,
        direction: npt.ArrayLike | None = None,
        settings: IkSettings | dict[str, Any] | None = None,
        *,
        tol: float | None = None,
        max_iterations: int | None = None,
        pretension: npt.ArrayLike | None = None,
        orientation: Any = None,
    ) -> IkResult: ...

@final
class Robot:
    """A continuum robot: a body (sections, stiffness, mass, base pose, tool)
    and one drive: pneumatic muscles (three a section, the default), tendons
    routed along its sections, or magnetised material in an external field.
    Its inverse kinematics searches the drive's coordinates: the muscles'
    curvature, the tendons' tensions or the field."""

    def __new__(cls, data: RobotDict | dict[str, Any] | None = None) -> Robot: ...
    @staticmethod
    def from_json(text: str) -> Robot: ...
    @staticmethod
    def from_toml(text: str) -> Robot: ...
    @staticmethod
    def from_file(path: str | PathLike[str]) -> Robot: ...
    @property
    def actuation_space(self) -> str:
        """What the inverse kinematics searches: "tensions", "field" or "curvature"."""
    @property
    def sections(self) -> int: ...
    @property
    def length(self) -> float: ...
    @property
    def n_elements(self) -> int: ...
    @property
    def muscle_length_range(self) -> tuple[float, float] | None: ...
    def to_dict(self) -> dict[str, Any]: ...
    def to_json(self) -> str:
        """The robot as JSON text (``Robot.from_json`` reads it back)."""
    def to_toml(self) -> str:
        """The robot as TOML text (``Robot.from_toml`` reads it back)."""
    def save(self, path: str | PathLike[str]) -> None:
        """Write the robot to a ``.json`` or ``.toml`` file (by its suffix),
        which ``Robot.from_file`` reads back to the same robot."""
    def scene(
        self,
        rest_curvature: npt.ArrayLike | None = None,
        load: _Load = None,
        *,
        tensions: npt.ArrayLike | None = None,
        field: npt.ArrayLike | None = None,
        insertion: float | None = None,
    ) -> Scene:
        """The Scene of this robot with an actuation (rest curvature (m, 2),
        default straight; one tension a tendon, N; a uniform field, T; the
        base moved by ``insertion`` m along its tangent) and a tip mass (kg)."""
    def muscle_lengths(self, rest_curvature: npt.ArrayLike) -> _Array: ...
    def rest_curvature(self, muscle_lengths: npt.ArrayLike) -> _Array: ...
    def inflation_times(self, muscle_lengths: npt.ArrayLike) -> _Array: ...
    def muscle_lengths_from_times(self, times: npt.ArrayLike) -> _Array: ...
    def within_bounds(self, rest_curvature: npt.ArrayLike) -> bool: ...
    def forward(
        self,
        rest_curvature: npt.ArrayLike | None = None,
        load: _Load = None,
        initial: Solution | npt.ArrayLike | None = None,
        *,
        tensions: npt.ArrayLike | None = None,
        field: npt.ArrayLike | None = None,
        insertion: float | None = None,
    ) -> Solution:
        """The loaded equilibrium of an actuation under a tip mass (kg): the
        muscles' rest curvature (m, 2) (default straight), the tendons'
        ``tensions`` (N, one a tendon, each >= 0 and at most ``max_tension``),
        a uniform ``field`` (T, world frame, at most ``max_field``) and the
        ``insertion`` (m, default 0: the base moved along its tangent, within
        ``insertion_range``; through the robot's ``ports``); from
        the straight rod or warm from ``initial`` (a Solution of this robot or
        its quaternions (n + 1, 4); with friction a Solution is the last step
        of the history, the robot starting where it stood, at its insertion
        then)."""
    def sensitivity(
        self,
        rest_curvature: npt.ArrayLike | None = None,
        load: _Load = None,
        parameters: str | Sequence[str] | None = None,
        initial: Solution | npt.ArrayLike | None = None,
        *,
        tensions: npt.ArrayLike | None = None,
        field: npt.ArrayLike | None = None,
        insertion: float | None = None,
    ) -> Sensitivity:
        """The loaded equilibrium of an actuation (``.solution``) and its tip's
        sensitivity to the named parameters: ``"rest_curvature"``,
        ``"muscle_lengths"`` (or one component, ``"muscle_lengths[2][0]"``),
        ``"tensions"`` (or ``"tensions[i]"``), ``"field"`` (or
        ``"field[c]"``), the load's ``"load.mass"``, ``"load.tip_force"``,
        ``"load.tip_moment"``, ``"load.point_loads[j].force"`` / ``".moment"``
        (three columns each, or one with ``[i]``), ``"insertion"`` (the base
        along its tangent, at the ``insertion`` given) and any numeric field of
        ``to_dict()`` (``"stiffness.E"``, ``"linear_density"``,
        ``"disk_mass"``). Default: the robot's actuation space."""
    def forward_batch(
        self,
        actuations: npt.ArrayLike | None = None,
        load: _Load = None,
        *,
        tensions: npt.ArrayLike | None = None,
        field: npt.ArrayLike | None = None,
        insertion: npt.ArrayLike | None = None,
        shapes: bool | None = None,
        warm_start: bool | None = None,
        threads: int | None = None,
        chunk: int | None = None,
        progress: bool | Callable[[int, int], object] | None = None,
        executor: Any = None,
        part: int | None = None,
    ) -> BatchResult:
        """Forward statics of many actuations (samples, m, 2) under one tip
        mass, in Rust on every core without the GIL. A tendon-driven or
        magnetic robot takes ``tensions`` (samples, tendons) in N and ``field``
        (samples, 3) in T, each checked against the drives' limits (the
        rest curvature is then optional); the result keeps them.

        ``shapes``: keep every node's position and quaternion (default False).
        ``warm_start``: start a solve from the last equilibrium of its chunk
        where the actuation is near (default True; random samples are solved
        cold). ``threads``: worker threads (default every core; at most 4 a
        core). ``chunk``:
        samples a worker solves in order (default 64; the answers depend on
        it, never on the thread count). ``progress``: None (a bar on a
        terminal after 2 s), True, False or ``progress(done, total)``.
        Ctrl-C stops the batch (KeyboardInterrupt). ``executor``: a Dask
        ``Client``, the ``ray`` module or a ``concurrent.futures`` executor
        runs the batch in tasks of ``part`` samples (a multiple of ``chunk``;
        default 32 chunks), with the results of a local run (see
        ``softspine.distributed``)."""
    def workspace(
        self,
        samples: int,
        load: _Load = None,
        *,
        seed: int = 0,
        first: int = 0,
        shapes: bool | None = None,
        threads: int | None = None,
        chunk: int | None = None,
        progress: bool | Callable[[int, int], object] | None = None,
        executor: Any = None,
        part: int | None = None,
    ) -> BatchResult:
        """The equilibria of ``samples`` random actuations (each muscle's
        length uniform over its range, seeded) under a tip mass: a
        ``BatchResult`` with ``actuations``; a tendon-driven robot's draws
        each tension over ``[0, max_tension]`` (``tensions``), a magnetic
        one's the field in the ball ``|B| <= max_field`` (``field``). Sample
        ``i`` is drawn from the seed and ``first + i`` (a part of a larger
        workspace draws what the whole would). Keywords as ``forward_batch``."""
    def inverse_batch(
        self,
        targets: npt.ArrayLike,
        load: _Load = None,
        reference: npt.ArrayLike | None = None,
        direction: npt.ArrayLike | None = None,
        settings: IkSettings | dict[str, Any] | None = None,
        *,
        pretension: npt.ArrayLike | None = None,
        orientation: Any = None,
        threads: int | None = None,
        chunk: int | None = None,
        progress: bool | Callable[[int, int], object] | None = None,
        executor: Any = None,
        part: int | None = None,
    ) -> IkBatchResult:
        """Load-aware inverse kinematics of many targets (samples, 3), each on
        its own (as ``inverse``), on every core; a tendon-driven or magnetic
        robot's in its tensions (closest to ``pretension``) or field, kept in
        the result's ``tensions`` or ``field``. Keywords as ``forward_batch``."""
    # The raw batches and sensitivity, each the fields of its result (the
    # methods above, written in softspine.batch and softspine.sensitivity);
    # with plan=True a batch only reads its arguments and returns (chunk,
    # part), the cut of a cluster's batch.
    def _forward_batch(
        self,
        actuations: npt.ArrayLike | None = None,
        load: _Load = None,
        *,
        tensions: npt.ArrayLike | None = None,
        field: npt.ArrayLike | None = None,
        insertion: npt.ArrayLike | None = None,
        shapes: bool | None = None,
        warm_start: bool | None = None,
        threads: int | None = None,
        chunk: int | None = None,
        progress: Callable[[int, int], object] | None = None,
        part: int | None = None,
        plan: bool | None = None,
    ) -> Any: ...
    def _workspace(
        self,
        samples: int,
        load: _Load = None,
        *,
        seed: int = 0,
        first: int = 0,
        shapes: bool | None = None,
        threads: int | None = None,
        chunk: int | None = None,
        progress: Callable[[int, int], object] | None = None,
        part: int | None = None,
        plan: bool | None = None,
    ) -> Any: ...
    def _inverse_batch(
        self,
        targets: npt.ArrayLike,
        load: _Load = None,
        reference: npt.ArrayLike | None = None,
        direction: npt.ArrayLike | None = None,
        settings: IkSettings | dict[str, Any] | None = None,
        *,
        pretension: npt.ArrayLike | None = None,
        orientation: Any = None,
        threads: int | None = None,
        chunk: int | None = None,
        progress: Callable[[int, int], object] | None = None,
        part: int | None = None,
        plan: bool | None = None,
    ) -> Any: ...
    def _sensitivity(
        self,
        rest_curvature: npt.ArrayLike | None = None,
        load: _Load = None,
        parameters: str | Sequence[str] | None = None,
        initial: Solution | npt.ArrayLike | None = None,
        *,
        tensions: npt.ArrayLike | None = None,
        field: npt.ArrayLike | None = None,
        insertion: float | None = None,
    ) -> dict[str, Any]: ...
    def inverse_solver(self, load: _Load = None) -> InverseSolver: ...
    def inverse(
        self,
        target: npt.ArrayLike,
        load: _Load = None,
        reference: npt.ArrayLike | None = None,
        direction: npt.ArrayLike | None = None,
        settings: IkSettings | dict[str, Any] | None = None,
        *,
        strategy: Strategy | None = None,
        tol: float | None = None,
        max_iterations: int | None = None,
        initial: IkResult | Solution | npt.ArrayLike | None = None,
        pretension: npt.ArrayLike | None = None,
        orientation: Any = None,
    ) -> IkResult:
        """Load-aware inverse kinematics of one target, in the robot's
        actuation space. Muscles: the curvature closest to ``reference``.
        Tendons: the non-negative tensions (at most ``max_tension``) closest
        in norm to ``pretension`` (default zero) among those that reach the
        target, a local minimum (its KKT conditions hold). Field: the
        smallest field (at most ``max_field``) that puts the tip closest to
        the target. ``initial``: a warm start, an earlier IkResult or
        Solution (its equilibrium; its actuation is the reference unless one
        is given) or quaternions (n + 1, 4)."""
    def track(
        self,
        points: npt.ArrayLike,
        load: _Load = None,
        reference: npt.ArrayLike | None = None,
        direction: npt.ArrayLike | None = None,
        settings: IkSettings | dict[str, Any] | None = None,
        *,
        strategy: Strategy | None = None,
        tol: float | None = None,
        max_iterations: int | None = None,
        pretension: npt.ArrayLike | None = None,
        orientation: Any = None,
    ) -> list[IkResult]: ...
    def __reduce__(self) -> tuple[type[Robot], tuple[dict[str, Any]]]: ...

@final
class Solver:
    """A reusable solver of one scene (its workspace allocated once): set the
    actuation or the tip load, solve warm from the last equilibrium.

    Safe to share between threads: one solve runs at a time. A ``set_*`` and
    the ``solve`` that uses it belong to one thread: another thread's
    ``set_*`` or ``solve`` in between raises ``RuntimeError``; threads that
    share a solver pass the drives to ``solve`` (one call)."""

    def __new__(
        cls,
        scene: Scene | SceneDict | dict[str, Any],
        settings: Settings | dict[str, Any] | None = None,
        *,
        n_elements: int | None = None,
        method: Method | None = None,
        scheme: SchemeName | Scheme | None = None,
        residual_tol: float | None = None,
        max_iterations: int | None = None,
    ) -> Solver: ...
    def solve(
        self,
        initial: Solution | npt.ArrayLike | None = None,
        *,
        warm: bool = True,
        check: bool = False,
        rest_curvature: npt.ArrayLike | None = None,
        tip_force: npt.ArrayLike | None = None,
        tip_moment: npt.ArrayLike | None = None,
        tensions: npt.ArrayLike | None = None,
        field: npt.ArrayLike | None = None,
    ) -> Solution:
        """Solve from ``initial`` (a Solution or quaternions (n + 1, 4)) or,
        without it, from the last converged, stable equilibrium of this solver
        (``warm=True``; the straight rod before there is one) or the straight
        rod (``warm=False``). ``check=True`` raises ``SolverError`` unless the
        solve converged. ``rest_curvature``, ``tip_force``, ``tip_moment``,
        ``tensions`` and ``field``, where given, are set first as by their
        ``set_*``, in the same call."""
    def set_rest_curvature(self, rest_curvature: npt.ArrayLike) -> None:
        """The actuation, ``[kappa_x, kappa_y]`` per section (m, 2), 1/m."""
    def set_tip_force(self, force: npt.ArrayLike) -> None:
        """The dead force at the tip, world frame, N."""
    def set_tip_moment(self, moment: npt.ArrayLike) -> None:
        """The dead moment at the tip, world frame, N m."""
    def set_tensions(self, tensions: npt.ArrayLike) -> None:
        """The tendons' tensions, N (one a tendon, in the scene's order, >= 0)."""
    def set_magnetic_field(self, field: npt.ArrayLike) -> None:
        """The uniform magnetic field, world frame, T."""
    def sensitivity(self, parameters: str | Sequence[str]) -> Sensitivity:
        """Sensitivity of the last solve's equilibrium (solve first) to named
        parameters: paths in the scene's dict (``"tip_force[0]"``,
        ``"stiffness.kx"``, ``"gravity.linear_density"``,
        ``"rest_curvature[2][1]"``), ``"rest_curvature"`` (every section) or
        ``"tip_wrench"`` (the tip force and moment: the 6x6 tip compliance is
        ``.pose``). Free, pinned and clamped tips; by the implicit function
        theorem on the factored equilibrium system."""
    def _sensitivity(self, parameters: str | Sequence[str]) -> dict[str, Any]: ...
    def reset(self) -> None:
        """Forget the last equilibrium (the next solve starts straight) and
        which thread changed the scene last."""
    @property
    def scene(self) -> Scene: ...
    @property
    def n_elements(self) -> int: ...
    @property
    def tip_force(self) -> _Array: ...

@final
class PaperSettings:
    """Settings of the paper's method (``method="paper"``)."""

    def __new__(cls, **fields: Any) -> PaperSettings: ...
    def validate(self) -> None: ...
    def to_dict(self) -> dict[str, Any]: ...
    particles: int
    iterations: int
    chi: float
    inertia: float
    c1: float
    c2: float
    seed: int
    gauss_newton_iterations: int
    lm_iterations: int
    tol: float
    def __setstate__(self, state: dict[str, Any]) -> None: ...
    def __reduce__(self) -> tuple[Any, tuple[()], dict[str, Any]]: ...

@final
class Settings:
    """Settings of an equilibrium solve."""

    def __new__(cls, **fields: Any) -> Settings: ...
    def validate(self) -> None: ...
    def to_dict(self) -> dict[str, Any]: ...
    @property
    def n_elements(self) -> int | None: ...
    @n_elements.setter
    def n_elements(self, value: int | None) -> None: ...
    @property
    def method(self) -> Method: ...
    @method.setter
    def method(self, value: Method) -> None: ...
    @property
    def scheme(self) -> SchemeName | None: ...
    @scheme.setter
    def scheme(self, value: SchemeName | Scheme | None) -> None: ...
    residual_tol: float
    max_iterations: int
    min_continuation_step: float
    @property
    def paper(self) -> PaperSettings: ...
    @paper.setter
    def paper(self, value: PaperSettings | dict[str, Any]) -> None: ...
    def __setstate__(self, state: dict[str, Any]) -> None: ...
    def __reduce__(self) -> tuple[Any, tuple[()], dict[str, Any]]: ...

@final
class Accuracy:
    """Accuracy on demand: the n whose backbone's error is below ``tol * L``."""

    def __new__(
        cls, tol: float, refine: Refine | None = None, max_elements: int = 10240
    ) -> Accuracy: ...
    def validate(self) -> None: ...
    def to_dict(self) -> dict[str, Any]: ...
    tol: float
    @property
    def refine(self) -> Refine | None: ...
    @refine.setter
    def refine(self, value: Refine | None) -> None: ...
    max_elements: int
    def __setstate__(self, state: dict[str, Any]) -> None: ...
    def __reduce__(self) -> tuple[Any, tuple[float], dict[str, Any]]: ...

def solve(
    scene: Scene | SceneDict | dict[str, Any] | str | PathLike[str],
    settings: Settings | dict[str, Any] | None = None,
    *,
    n_elements: int | None = None,
    method: Method | None = None,
    scheme: SchemeName | Scheme | None = None,
    initial: Solution | npt.ArrayLike | None = None,
    accuracy: Accuracy | dict[str, Any] | None = None,
    tol: float | None = None,
    refine: Refine | None = None,
    residual_tol: float | None = None,
    max_iterations: int | None = None,
    check: bool = False,
    paper: PaperSettings | dict[str, Any] | None = None,
) -> Solution: ...
# The raw batch and fit: the fields of a BatchResult (or with plan=True the
# cut of a cluster's batch) and of a Calibration (``softspine.solve_batch``
# and ``softspine.calibrate`` build them).
def _solve_batch(
    scenes: Sequence[Scene | SceneDict | dict[str, Any]],
    settings: Settings | dict[str, Any] | None = None,
    *,
    n_elements: int | None = None,
    method: Method | None = None,
    scheme: SchemeName | Scheme | None = None,
    residual_tol: float | None = None,
    max_iterations: int | None = None,
    shapes: bool | None = None,
    threads: int | None = None,
    chunk: int | None = None,
    progress: Callable[[int, int], object] | None = None,
    part: int | None = None,
    plan: bool | None = None,
) -> Any: ...
def _calibrate(
    robot: Robot,
    actuations: npt.ArrayLike,
    measured_tips: npt.ArrayLike,
    parameters: str | Sequence[str],
    load: _Load = None,
    *,
    max_iterations: int | None = None,
    threads: int | None = None,
) -> dict[str, Any]: ...
def residual(scene: Scene | SceneDict | dict[str, Any], quaternions: npt.ArrayLike) -> _Array: ...
def jacobian(scene: Scene | SceneDict | dict[str, Any], quaternions: npt.ArrayLike) -> _Array: ...
def trajectory_points(name: str, points: int = 60, robot: Robot | None = None) -> _Array: ...
def read_obstacle(obstacle: dict[str, Any]) -> dict[str, Any]: ...
def keys() -> dict[str, list[dict[str, str]]]:
    """The key reference: every key of a scene and a robot with its unit,
    default and meaning (``{"scene": [...], "robot": [...]}``)."""
