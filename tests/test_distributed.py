"""The batch calls on a local Dask cluster, a local Ray instance and a process
pool: the same results as a local batch, to the last bit."""

from __future__ import annotations

import concurrent.futures

import numpy as np
import pytest

import softspine
from softspine.batch import BatchResult

# Dask and Ray clusters start in seconds: the full tier only (make test).
pytestmark = pytest.mark.slow

LOAD = 0.03
CHUNK = 8
PART = 24  # three chunks a task


@pytest.fixture(scope="module")
def dask_client():
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    )
    client = distributed.Client(cluster)
    yield client
    client.close()
    cluster.close()


@pytest.fixture(scope="module")
def ray_module():
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


@pytest.fixture(scope="module")
def process_pool():
    # Spawned, not forked: a fork of a process that runs Ray's and Dask's
    # threads can inherit their locks held.
    import multiprocessing

    context = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(max_workers=2, mp_context=context) as pool:
        yield pool


@pytest.fixture(params=["dask", "ray", "processes"])
def executor(request):
    name = {"dask": "dask_client", "ray": "ray_module", "processes": "process_pool"}[request.param]
    return request.getfixturevalue(name)


def same(a, b):
    assert type(a) is type(b)
    for field, value in a.to_dict().items():
        other = getattr(b, field)
        if value is None:
            assert other is None, field
        else:
            np.testing.assert_array_equal(value, other, err_msg=field)


def test_a_workspace_on_a_cluster_is_the_local_workspace(executor):
    robot = softspine.Robot()
    local = robot.workspace(100, LOAD, seed=3, chunk=CHUNK, shapes=True)
    remote = robot.workspace(
        100, LOAD, seed=3, chunk=CHUNK, shapes=True, executor=executor, part=PART
    )
    assert isinstance(remote, BatchResult) and len(remote) == 100
    same(local, remote)


def test_forward_and_inverse_batches_on_a_cluster(executor):
    robot = softspine.Robot()
    ws = robot.workspace(60, LOAD, seed=5)
    path = np.linspace(ws.actuations[0], ws.actuations[1], 60)
    same(
        robot.forward_batch(path, LOAD, chunk=CHUNK),
        robot.forward_batch(path, LOAD, chunk=CHUNK, executor=executor, part=PART),
    )
    targets = ws.tip_positions[:6]
    same(
        robot.inverse_batch(targets, LOAD, chunk=2),
        robot.inverse_batch(targets, LOAD, chunk=2, executor=executor, part=4),
    )


def test_a_tendon_robots_batch_on_a_cluster(executor):
    robot = softspine.Robot.from_file("examples/robots/tendon_robot.toml")
    tensions = np.abs(np.sin(np.arange(30 * 9).reshape(30, 9))) * 10.0
    local = robot.forward_batch(tensions=tensions, load=0.01, chunk=CHUNK)
    remote = robot.forward_batch(tensions=tensions, load=0.01, chunk=CHUNK,
                                 executor=executor, part=PART)
    assert remote.tensions.shape == (30, 9) and remote.actuations is None
    same(local, remote)
    same(
        robot.workspace(30, 0.01, seed=4, chunk=CHUNK),
        robot.workspace(30, 0.01, seed=4, chunk=CHUNK, executor=executor, part=PART),
    )
    targets = local.tip_positions[:6]
    same(
        robot.inverse_batch(targets, 0.01, chunk=2),
        robot.inverse_batch(targets, 0.01, chunk=2, executor=executor, part=4),
    )


def test_solve_batch_on_a_cluster(executor):
    scenes = [
        {"length": 1, "stiffness": {"kx": 1, "ky": 1, "kz": 1}, "tip_force": [p, 0, 0]}
        for p in np.linspace(0.1, 3.0, 10)
    ]
    same(
        softspine.solve_batch(scenes, n_elements=24, chunk=2),
        softspine.solve_batch(scenes, n_elements=24, chunk=2, executor=executor, part=4),
    )


def test_progress_reaches_the_end_on_a_cluster(dask_client):
    calls = []
    softspine.Robot().workspace(
        50, chunk=5, part=10, executor=dask_client, progress=lambda d, t: calls.append((d, t))
    )
    assert calls[-1] == (50, 50)


@pytest.mark.parametrize(
    ("keywords", "message"),
    [
        ({"part": 20}, "part: must be a positive multiple of chunk"),
        ({"executor": object()}, "executor: expected a Dask Client"),
    ],
)
def test_bad_cluster_arguments_are_refused_by_name(keywords, message):
    options = {"chunk": 8, "executor": concurrent.futures.ThreadPoolExecutor(1)} | keywords
    with pytest.raises(ValueError, match=message):
        softspine.Robot().workspace(10, **options)
