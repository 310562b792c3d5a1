"""The numerics profile (mpcde/numerics.py): which variables it sets, when, and what a process reports."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from mpcde import numerics
from mpcde.errors import ConfigError

ROOT = Path(__file__).resolve().parents[3]


V3_CPU = "processor\t: 0\nflags\t\t: fpu sse4_2 avx avx2 fma bmi1 bmi2 f16c movbe\n"


def test_portable_sets_every_pin_only_where_unset_and_only_on_an_x86_64_v3_cpu():
    env = {"ATEN_CPU_CAPABILITY": "default"}  # a pin the user chose stays theirs
    assert numerics.apply(env, machine="x86_64", cpuinfo=V3_CPU)
    assert env["ATEN_CPU_CAPABILITY"] == "default"
    assert {k: env[k] for k in numerics.X86_V3 if k != "ATEN_CPU_CAPABILITY"} == {k: v for k, v in numerics.X86_V3.items() if k != "ATEN_CPU_CAPABILITY"}
    arm: dict[str, str] = {}
    assert not numerics.apply(arm, machine="aarch64", cpuinfo=V3_CPU) and arm == {}
    old: dict[str, str] = {}  # an AVX-only CPU would fault on numba's and OpenBLAS's Haswell code
    assert not numerics.apply(old, machine="x86_64", cpuinfo="flags\t\t: fpu sse4_2 avx\n") and old == {}


@pytest.mark.parametrize("value", ["native", "fast", ""])
def test_native_or_an_invalid_value_sets_nothing(value):
    env = {numerics.VARIABLE: value}
    assert not numerics.apply(env, machine="x86_64", cpuinfo=V3_CPU)
    assert env == {numerics.VARIABLE: value}


def test_requested_names_the_variable_the_value_and_the_choices():
    assert numerics.requested({}) == "portable" == numerics.DEFAULT
    assert numerics.requested({numerics.VARIABLE: "native"}) == "native"
    with pytest.raises(ConfigError, match=r"^MPCDE_NUMERICS='avx512': allowed 'portable' or 'native'"):
        numerics.requested({numerics.VARIABLE: "avx512"})


def _describe_in_child(**env: str) -> dict:
    code = ("import mpcde, numpy, torch, json; from mpcde.numerics import describe; "
            "print(json.dumps({**describe(), 'torch_cpu': torch.backends.cpu.get_cpu_capability()}))")  # fmt: skip
    clean = {k: v for k, v in os.environ.items() if k not in numerics.X86_V3 and k != numerics.VARIABLE}
    out = subprocess.run([sys.executable, "-c", code], env={**clean, **env, "PYTHONPATH": str(ROOT)}, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(os.uname().machine != "x86_64" or not numerics._has_x86_64_v3(), reason="the profile is defined for x86-64-v3")
def test_a_process_that_imports_mpcde_first_computes_at_x86_64_v3():
    got = _describe_in_child()
    assert got["profile"] == "portable" and got["effective"] == "portable"
    assert got["numpy_v4"] is False and got["openblas_core"] == "Haswell"  # the locked numpy wheel's OpenBLAS
    assert got["pins"] == numerics.X86_V3 and got["torch_cpu"] in ("AVX2", "DEFAULT")


def _has_avx512() -> bool:
    return "avx512f" in numerics.cpu_flags()


@pytest.mark.skipif(not _has_avx512(), reason="native and portable are the same kernels on a CPU without AVX-512")
def test_native_keeps_the_cpus_own_kernels():
    got = _describe_in_child(MPCDE_NUMERICS="native")
    assert got["profile"] == "native" and got["effective"] == "native"
    assert got["numpy_v4"] is True and got["torch_cpu"].startswith("AVX512")
    assert got["pins"] == dict.fromkeys(numerics.X86_V3)


def test_this_test_process_is_portable_because_conftest_imports_mpcde_first():
    if numerics.requested() != "portable" or os.uname().machine != "x86_64":
        pytest.skip("run under MPCDE_NUMERICS=native or off x86-64")
    assert numerics.describe()["numpy_v4"] in (False, None)


def test_a_mismatch_is_named_only_where_portable_was_asked_on_x86_64_and_did_not_hold():
    base = {"profile": "portable", "machine": "x86_64", "effective": "mixed", "numpy_v4": True, "openblas_core": "SkylakeX", "pins": {}}
    why = numerics.mismatch(base, cpuinfo=V3_CPU)
    assert why is not None and "numpy loaded before `import mpcde`" in why and "\n" not in why
    assert numerics.mismatch({**base, "effective": "portable"}, cpuinfo=V3_CPU) is None
    assert numerics.mismatch({**base, "profile": "native"}, cpuinfo=V3_CPU) is None
    assert numerics.mismatch({**base, "machine": "aarch64"}, cpuinfo=V3_CPU) is None
    assert numerics.mismatch(base, cpuinfo="flags\t\t: fpu sse4_2 avx\n") is None  # nothing could be set there


@pytest.mark.skipif(not _has_avx512(), reason="numpy's own kernels are x86-64-v3 on this CPU: nothing to tell apart")
def test_a_process_that_loaded_numpy_first_says_so():
    code = "import numpy, mpcde, json; from mpcde.numerics import describe, mismatch; print(json.dumps([describe()['effective'], mismatch()]))"
    clean = {k: v for k, v in os.environ.items() if k not in numerics.X86_V3 and k != numerics.VARIABLE}
    out = subprocess.run([sys.executable, "-c", code], env={**clean, "PYTHONPATH": str(ROOT)}, capture_output=True, text=True, check=True)
    effective, why = json.loads(out.stdout.strip().splitlines()[-1])
    assert effective == "mixed" and why is not None


def test_the_python_api_refuses_an_unknown_profile_before_flying(monkeypatch):
    import mpcde as api

    monkeypatch.setenv(numerics.VARIABLE, "turbo")
    with pytest.raises(ConfigError, match="^MPCDE_NUMERICS='turbo'"):
        api.fly("crossing", duration_s=0.1)
