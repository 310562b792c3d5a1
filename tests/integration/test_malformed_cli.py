"""The bad-input promise through the real command line: every malformed scenario named in issue 29 gets one stderr line.

Each case runs ``python -m mpcde fly FILE --out DIR`` in a fresh process and
reads its whole stderr (file descriptor 2, where PyBullet's import banner
used to land): exactly one line ``mpcde: error: <field>=<value>: <allowed>``
naming the field, exit status 2, no ``--out`` folder and no staging folder.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

LAYOUT = "drones: {layout: antipodal, count: 2}\n"
DEEP = "a: " + "[" * 1000 + "]" * 1000 + "\n"
BOMB = "a0: &a0 [x, x, x, x, x, x, x, x, x]\n" + "".join(f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]\n" for i in range(1, 10))
MANY_DRONES = "drones:\n  layout: explicit\n  starts: [" + ", ".join(f"[{i % 30 - 15}.0, {i // 30 - 15}.0, 1.5]" for i in range(1000)) + "]\n"

CASES: dict[str, tuple[str | bytes, str]] = {
    "mixed_key_types": ("world: {arena_size_m: [10, 10], 3: x}\n" + LAYOUT, "world.3"),
    "deep_nesting": (DEEP, "levels deep"),
    "alias_bomb": (BOMB, "values in one file"),
    "huge_arena": ("world: {arena_size_m: [1.0e+300, 10]}\n" + LAYOUT, "world.arena_size_m[0]"),
    "inf_arena": ("world: {arena_size_m: [.inf, .inf]}\n" + LAYOUT, "world.arena_size_m[0]"),
    "two_km_dense": ("world: {arena_size_m: [2000, 2000], obstacle_density_per_100m2: 30}\n" + LAYOUT, "world.arena_size_m[0]"),
    "dense_within_limits": ("world: {arena_size_m: [200, 200], obstacle_density_per_100m2: 30}\n" + LAYOUT, "world.obstacle_density_per_100m2"),
    "thousand_drones": (MANY_DRONES, "drones.starts"),
    "explicit_tag": ("run: {cameras: !!bool maybe}\n" + LAYOUT, "run.cameras"),
    "int_tag": ("seed: !!int 1.5\n" + LAYOUT, "seed"),
    "huge_name": ("name: " + "x" * 2_000_000 + "\n", "scenario"),
    "long_name": ("name: " + "x" * 500 + "\n" + LAYOUT, "name"),
    "not_utf8": (b"name: caf\xe9\n" + LAYOUT.encode(), "scenario"),
    "date_name": ("name: 2020-13-45\n" + LAYOUT, "name"),
    "long_int": ("seed: " + "7" * 5000 + "\n" + LAYOUT, "seed"),
    "newline_key": ('world: {"arena\\nsize": 3}\n' + LAYOUT, "world.arena\\nsize"),
    "ansi_key": ('world: {"\\e[31mred": 3}\n' + LAYOUT, "world.\\x1b[31mred"),
    "obstacle_height": ("world:\n  obstacles:\n    - {kind: tree, center_xy: [3.0, 3.0], height_m: -1}\n" + LAYOUT, "world.obstacles[0].height_m"),
    "empty": ("", "scenario"),
    "comment_only": ("# nothing here\n", "scenario"),
    "null": ("null\n", "scenario"),
    "octal": ("seed: 017\n" + LAYOUT, "seed"),
    "sexagesimal": ("duration_s: 1:30\n" + LAYOUT, "duration_s"),
    "duplicate_keys": ("seed: 1\nseed: 2\n" + LAYOUT, "seed"),
    "box_fields_on_a_tree": ("world:\n  obstacles:\n    - {center_xy: [3.0, 3.0], half_extents_xy: [1.0, 1.0]}\n" + LAYOUT, "world.obstacles[0].half_extents_xy"),
    "count_without_layout": ("drones: {count: 6}\n", "drones.count"),
    "odd_camera_width": ("camera: {width_px: 330}\n" + LAYOUT, "camera.width_px"),
    "horizon_2_64": ("dmpc: {qp: {horizon_steps: 18446744073709551616}}\n" + LAYOUT, "dmpc.qp.horizon_steps"),
    "controller_gains_are_constants": ("physics: {gains: {pos_damping: 0.5}}\n" + LAYOUT, "physics.gains"),  # a class constant
    "negative_robot_radius": ("physics: {quadrotor: {robot_radius_m: -0.1}}\n" + LAYOUT, "physics.quadrotor.robot_radius_m"),
    "goal_outside_arena": ("drones: {layout: explicit, starts: [[0, 0, 1.5]], goals: [[500, 0, 1.5]]}\n", "drones.goals"),
    "goal_too_high": ("drones: {layout: explicit, starts: [[0, 0, 1.5]], goals: [[1, 0, 1000]]}\n", "drones.goals"),
}


def _fly(path: Path, out: Path, *extra: str, environ: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"} | (environ or {})
    return subprocess.run([sys.executable, "-m", "mpcde", "fly", str(path), "--out", str(out), "--quiet", *extra],
                          capture_output=True, text=True, timeout=120, env=env)  # fmt: skip


def _assert_one_line(r: subprocess.CompletedProcess, field: str, out: Path) -> None:
    lines = r.stderr.splitlines()
    assert r.returncode == 2, r.stderr[-2000:]
    assert len(lines) == 1 and lines[0].startswith("mpcde: error: ") and field in lines[0], r.stderr[-2000:]
    assert len(lines[0]) < 1000 and lines[0].isprintable()
    assert not out.exists() and not list(out.parent.glob(f".{out.name}.partial-*"))


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_malformed_file_is_one_line_exit_2_and_nothing_written(case, tmp_path):
    text, field = CASES[case]
    path = tmp_path / "bad.yaml"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    _assert_one_line(_fly(path, tmp_path / "run"), field, tmp_path / "run")


def test_special_files_are_refused_without_blocking(tmp_path):
    fifo = tmp_path / "scenario.fifo"
    os.mkfifo(fifo)
    for path in (fifo, Path("/dev/zero"), tmp_path):
        _assert_one_line(_fly(path, tmp_path / "run"), "not a regular file", tmp_path / "run")


def test_a_tiny_duration_option_is_refused(tmp_path):
    _assert_one_line(_fly(Path("crossing"), tmp_path / "run", "--duration", "1e-12"), "duration", tmp_path / "run")


def test_an_unknown_numerics_profile_is_refused_before_the_flight(tmp_path):
    r = _fly(Path("crossing"), tmp_path / "run", environ={"MPCDE_NUMERICS": "avx512"})
    _assert_one_line(r, "MPCDE_NUMERICS='avx512'", tmp_path / "run")


def _fly_generated(raw: bytes, tmp: Path) -> None:
    path = tmp / "generated.yaml"
    path.write_bytes(raw)
    out = tmp / "run"
    r = _fly(path, out, "--duration", "0.05")  # an accepted file flies 50 ms: what is checked is the refusal
    if r.returncode == 0:
        assert r.stderr.strip() == "", r.stderr[-2000:]
        return
    _assert_one_line(r, "", out)


def test_generated_malformed_files_keep_the_promise_through_the_real_cli(tmp_path):
    """Hypothesis's mutated and damaged built-ins (tests/scenario_strategies.py), each in a fresh process."""
    import shutil

    import scenario_strategies as gen
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    @settings(max_examples=16, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
    @given(raw=st.one_of(gen.mutated_documents().map(str.encode), gen.damaged_texts()))
    def check(raw: bytes) -> None:
        tmp = tmp_path / "case"
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir()
        _fly_generated(raw, tmp)

    check()
