"""A render pool kept across flights (sim/rendering/pool_keeper.py): another scene in the running workers renders
what a new pool would, and the keeper starts a new pool when it must."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from mpcde.config.scenario import load_scenario
from mpcde.flight.loop import prepare_run
from sim.bullet.scene import SceneSpec
from sim.camera import CameraConfig
from sim.rendering.pool import RenderPool
from sim.rendering.pool_keeper import PoolKeeper
from sim.rotations import quat_xyzw_from_yaw

CAMERA = CameraConfig(width_px=96, height_px=72)


def _forest(seed: int) -> tuple[SceneSpec, np.ndarray]:
    """forest_swarm's layout of ``seed``: its scene and the drones' starts (N, 3) [m]."""
    prepared = prepare_run(replace(load_scenario("forest_swarm"), seed=seed))
    return SceneSpec(obstacles=prepared.obstacles, n_drones=prepared.starts.shape[0]), prepared.starts


def _looking_along_x(starts: np.ndarray) -> tuple[np.ndarray, np.ndarray, list]:
    """Poses and cameras of every drone 2 m ahead of its start, level, looking along +x (into the forest)."""
    pos = starts + np.array([2.0, 0.0, 0.0])
    quat = np.stack([quat_xyzw_from_yaw(0.0) for _ in pos])
    cams = []
    for i, p in enumerate(pos):
        T = np.eye(4)
        T[:3, :3] = np.array([[0, 0, 1.0], [-1, 0, 0], [0, -1, 0]])
        T[:3, 3] = p + [0.1, 0.0, 0.0]
        cams.append((i, T))
    return pos, quat, cams


def _same(a, b) -> bool:
    return all(
        np.array_equal(x.rgb, y.rgb) and np.array_equal(x.depth_true_m, y.depth_true_m, equal_nan=True)
        and np.array_equal(x.depth_sensor_m, y.depth_sensor_m, equal_nan=True) and np.array_equal(x.drone_index_mask, y.drone_index_mask)
        for x, y in zip(a, b, strict=True)
    )  # fmt: skip


@pytest.mark.parametrize("workers", [0, 2])
def test_a_kept_pool_renders_the_next_flights_scene_as_a_new_pool_would(workers):
    (spec0, starts0), (spec1, starts1) = _forest(0), _forest(1)
    with PoolKeeper() as keeper:
        first = keeper.get(spec0, CAMERA, workers)
        pos, quat, cams = _looking_along_x(starts0)
        first.render(pos, quat, cams, sensor=(0, 3))
        first.submit(pos, quat, cams, sensor=(0, 4))  # a flight cut short with a batch in flight
        pos, quat, cams = _looking_along_x(starts1)
        kept = keeper.get(spec1, CAMERA, workers)
        assert kept is first and (keeper.started, keeper.reloaded) == (1, 1)
        assert (kept.renders, kept.render_s) == (0, 0.0)  # the new flight's counters
        got = kept.render(pos, quat, cams, sensor=(1, 3))
        assert kept.renders == len(cams)
    assert first.closed
    with RenderPool(spec1, CAMERA, workers) as fresh:
        want = fresh.render(pos, quat, cams, sensor=(1, 3))
    assert _same(got, want)
    with RenderPool(spec0, CAMERA, workers) as other:  # the first forest from the same cameras: other images
        assert not _same(other.render(pos, quat, cams, sensor=(1, 3)), want)


def test_a_keeper_starts_a_new_pool_for_another_drone_count_or_camera_and_after_a_worker_died():
    spec, _ = _forest(0)
    with PoolKeeper() as keeper:
        a = keeper.get(spec, CAMERA, 1)
        b = keeper.get(SceneSpec(obstacles=spec.obstacles, n_drones=spec.n_drones - 1), CAMERA, 1)
        assert b is not a and a.closed and (keeper.started, keeper.reloaded) == (2, 0)
        c = keeper.get(spec, CameraConfig(width_px=64, height_px=48), 1)
        assert c is not b and b.closed
        d = keeper.get(spec, CameraConfig(width_px=64, height_px=48), 0)
        assert d is not c and c.closed
        e = keeper.get(spec, CAMERA, 1)
        e._workers[0].kill()
        e._workers[0].join()
        f = keeper.get(spec, CAMERA, 1)
        assert f is not e and e.closed and not f.closed and keeper.started == 6
    assert f.closed and keeper.pool is None


def test_reload_refuses_a_scene_with_another_drone_count():
    spec, _ = _forest(0)
    with RenderPool(spec, CAMERA, 0) as pool:
        with pytest.raises(ValueError, match="drones"):
            pool.reload(SceneSpec(obstacles=spec.obstacles, n_drones=spec.n_drones + 1))


def test_a_pool_whose_collect_was_cut_short_is_replaced_not_reloaded():
    """Ctrl-C inside collect() leaves a worker's answer unread: reusing the pool would read it as the answer to the
    next request, so the keeper closes it (close() bounds its wait) and starts a new one."""
    spec, starts = _forest(0)
    pos, quat, cams = _looking_along_x(starts)
    with PoolKeeper() as keeper:
        pool = keeper.get(spec, CAMERA, 2)
        pool.submit(pos, quat, cams, sensor=(0, 1))

        def interrupted():
            raise KeyboardInterrupt

        pool._conns[1].recv = interrupted  # worker 0's answer is read, then the interrupt
        with pytest.raises(KeyboardInterrupt):
            pool.collect()
        del pool._conns[1].recv  # the pipe's own recv again (worker 1's answer is still unread)
        assert not pool.accepts(spec, CAMERA, 2)
        fresh = keeper.get(spec, CAMERA, 2)
        assert fresh is not pool and pool.closed and (keeper.started, keeper.reloaded) == (2, 0)
        assert len(fresh.render(pos, quat, cams, sensor=(0, 1))) == len(cams)
