"""Settings objects mirrored from the core (issue 11, item 6): defaults, field
names and checks are the core's; the Python classes only convert."""

from __future__ import annotations

import inspect
import pickle

import numpy as np
import pytest

import softspine
from softspine import Accuracy, IkSettings, PaperSettings, Settings

CANTILEVER = {"length": 1.0, "stiffness": {"kx": 1, "ky": 1, "kz": 1}, "tip_force": [3, 0, 0]}


def test_defaults_are_the_cores_with_counts_as_ints():
    d = Settings().to_dict()
    assert d["n_elements"] is None and d["method"] == "auto"
    assert d["residual_tol"] == 1e-10 and d["max_iterations"] == 500
    assert isinstance(d["max_iterations"], int)
    assert d["paper"]["particles"] == 40 and isinstance(d["paper"]["seed"], int)
    assert Settings(**d) == Settings()
    assert Accuracy(1e-6).to_dict() == {"tol": 1e-6, "refine": None, "max_elements": 10240}


def test_fields_are_checked_when_set_and_ranges_when_validated():
    s = Settings()
    with pytest.raises(ValueError, match="^method: unknown method 'fast'"):
        s.method = "fast"
    with pytest.raises(ValueError, match="^residual_tol: expected a number, got a string"):
        s.residual_tol = "small"
    s.residual_tol = 1.0  # the kind is right; the range is validate()'s
    with pytest.raises(ValueError, match=r"^residual_tol: must lie in \[1e-14, 1e-4\]"):
        s.validate()
    with pytest.raises(ValueError, match="^residual_tol: must lie in"):
        softspine.solve(CANTILEVER, s)
    with pytest.raises(ValueError, match="^bogus: unknown setting"):
        Settings(bogus=1)
    with pytest.raises(ValueError, match="^paper.chi: expected a number"):
        Settings(paper={"chi": "x"})


def test_keywords_override_the_settings():
    s = Settings(n_elements=40, residual_tol=1e-12)
    assert softspine.solve(CANTILEVER, s).n_elements == 40
    assert softspine.solve(CANTILEVER, s, n_elements=20).n_elements == 20
    assert softspine.solve(CANTILEVER, {"n_elements": 24}).n_elements == 24
    assert s.n_elements == 40  # the object is not changed by a keyword


def test_paper_settings_are_shared_with_their_settings():
    s = Settings(method="paper", n_elements=5)
    s.paper.particles = 12
    s.paper.iterations = 5
    assert s.to_dict()["paper"]["particles"] == 12
    s.paper = {"seed": 3}  # a dict applies over the current paper settings
    assert s.paper.particles == 12 and s.paper.seed == 3
    a = softspine.solve(CANTILEVER, s)
    b = softspine.solve(CANTILEVER, method="paper", n_elements=5,
                        paper=PaperSettings(particles=12, iterations=5, seed=3))
    assert np.array_equal(a.positions, b.positions)


def test_accuracy_object_and_keywords_agree():
    by_object = softspine.solve(CANTILEVER, accuracy=Accuracy(1e-5, refine="richardson"))
    by_keywords = softspine.solve(CANTILEVER, tol=1e-5, refine="richardson")
    assert by_object.n_elements == by_keywords.n_elements and by_object.extrapolated
    assert np.array_equal(by_object.tip_position, by_keywords.tip_position)
    # tol overrides the object's.
    overridden = softspine.solve(CANTILEVER, accuracy=Accuracy(1e-2), tol=1e-5)
    assert overridden.error_estimate <= 1e-5
    assert softspine.solve(CANTILEVER, tol=1e-2, method="newton").error_estimate > 1e-5
    with pytest.raises(ValueError, match="^refine: needs tol"):
        softspine.solve(CANTILEVER, refine="richardson")
    with pytest.raises(ValueError, match="^settings: expected a Settings or a dict"):
        softspine.solve(CANTILEVER, 40)


@pytest.mark.parametrize("obj", [Settings(n_elements=30, method="lm"),
                                 PaperSettings(particles=7), Accuracy(1e-4, max_elements=640),
                                 IkSettings(strategy="geometric", tol=1e-8)])
def test_settings_pickle_and_print(obj):
    copy = pickle.loads(pickle.dumps(obj))
    assert copy == obj and copy is not obj
    assert repr(copy) == repr(obj) and repr(obj).startswith(type(obj).__name__ + "(")


def test_constructors_show_their_signatures():
    assert str(inspect.signature(Settings)) == "(**fields)"
    assert str(inspect.signature(Accuracy)) == "(tol, refine=None, max_elements=10240)"


def test_ik_settings_drive_inverse_track_and_the_inverse_solver():
    robot = softspine.Robot()
    target = [0.2, 0.0, -0.88]
    loose = IkSettings(tol=1e-6, max_iterations=40)
    assert IkSettings().to_dict() == {"strategy": "equilibrium", "tol": 1e-9,
                                      "max_iterations": 60}
    by_object = robot.inverse(target, 0.03, settings=loose)
    by_keywords = robot.inverse(target, 0.03, tol=1e-6, max_iterations=40)
    assert by_object.reached and np.array_equal(by_object.rest_curvature,
                                                 by_keywords.rest_curvature)
    # A keyword overrides the object's field; None is the default.
    geometric = robot.inverse(target, 0.03, settings=loose, strategy="geometric")
    assert geometric.ending == "load_ignored"
    assert robot.inverse(target, 0.03, strategy=None).reached
    solver = robot.inverse_solver(0.03)
    assert solver.solve(target, settings={"tol": 1e-6}).reached
    track = robot.track([target, [0.21, 0.0, -0.88]], 0.03, settings=loose)
    assert all(r.reached for r in track)
