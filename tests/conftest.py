"""Shared fixtures: compiled environments are expensive on CPU, so build each once.

Tests also compile many identical programs (the same tiny configs through the CLI, resumes,
evaluations), so the session shares one JAX compilation cache among its workers: each such
program compiles once per session.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

import jax
import pytest

import fieldgen
from fieldgen import xla_flags
from fieldgen.schema import bundled_fields

FIELDS = sorted(bundled_fields())

from tiny_runs import TINY_CRL


def pytest_configure(config):
    """The first process of the session (the controller, or the only one) makes the cache folder; workers
    and the `fieldgen` commands tests start inherit the variable (JAX reads it on import).

    XLA_FLAGS is part of a compiled program's cache key, and every `fieldgen` command adds its defaults to
    it: they are set here, before anything compiles, so that a program compiled in a test's process, by a
    command it invokes or by a `fieldgen` process it starts is the same cache entry.

    The tests' programs run for seconds and compile for minutes: at LLVM's -O0 a tiny CRL run's programs
    compile in half the time, and agree with -O2's to float32 rounding.

    The session's own cache keeps every program, not only those JAX deems slow to compile (a second by
    default): the tests compile many small programs again and again, in other workers, in the commands they
    start, and for fields built twice from the same spec."""
    xla_flags.apply()
    if "xla_backend_optimization_level" not in os.environ["XLA_FLAGS"]:
        os.environ["XLA_FLAGS"] += " --xla_backend_optimization_level=0"
    if "JAX_COMPILATION_CACHE_DIR" in os.environ:  # the user's own cache, or the controller's
        return
    os.environ["JAX_COMPILATION_CACHE_DIR"] = tempfile.mkdtemp(prefix="fieldgen-test-jax-cache-")
    os.environ["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"] = "0"
    config.owns_jax_cache = True
    jax.config.update("jax_compilation_cache_dir", os.environ["JAX_COMPILATION_CACHE_DIR"])
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)


def pytest_unconfigure(config):
    if getattr(config, "owns_jax_cache", False):
        os.environ.pop("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", None)
        shutil.rmtree(os.environ.pop("JAX_COMPILATION_CACHE_DIR"), ignore_errors=True)


@pytest.fixture(scope="session")
def env_cache():
    cache: dict = {}

    def get(name: str, **kwargs):
        key = (name, tuple(sorted(kwargs.items())))
        if key not in cache:
            cache[key] = fieldgen.make(name, **kwargs)
        return cache[key]

    return get


@pytest.fixture
def write_spec(tmp_path: Path):
    """Write YAML text to a file in a temporary folder and return its path."""

    def write(text: str, name: str = "field.yaml") -> Path:
        path = tmp_path / name
        path.write_text(text)
        return path

    return write


@pytest.fixture(scope="session")
def tiny_crl():
    """TINY_CRL as a CRLConfig, with any of its keys changed."""
    from fieldgen.agents.crl import CRLConfig

    return lambda **changes: CRLConfig(**{**TINY_CRL, **changes})


@pytest.fixture(scope="session")
def tiny_crl_args():
    """TINY_CRL as `fieldgen train` options."""
    sets = {k: v for k, v in TINY_CRL.items() if k not in ("total_steps", "num_envs")}
    return ["--steps", str(TINY_CRL["total_steps"]), "--envs", str(TINY_CRL["num_envs"]),
            *[x for k, v in sets.items() for x in ("--set", f"crl.{k}={json.dumps(v, separators=(',', ':'))}")]]


@pytest.fixture(scope="session")
def train_point_nav(tmp_path_factory, tiny_crl_args):
    """train_point_nav(seeds) -> the folder of a tiny CRL run of that many seeds on point_nav, trained with
    `fieldgen train` once per seed count for the whole session (each costs minutes on two CPU cores)."""
    from typer.testing import CliRunner

    from fieldgen.cli import app

    trained: dict[int, Path] = {}

    def train(seeds: int) -> Path:
        if seeds not in trained:
            out = tmp_path_factory.mktemp("runs")
            result = CliRunner().invoke(app, ["train", "point_nav", "--seeds", str(seeds), "--out", str(out),
                                              "--no-videos", *tiny_crl_args])
            assert result.exit_code == 0, result.output
            trained[seeds] = out / f"point_nav-crl-0to{seeds - 1}"
        return trained[seeds]

    return train


@pytest.fixture
def interrupt_after_eval(monkeypatch):
    """interrupt_after_eval(index): from now on `fieldgen train` stops as Ctrl-C would, once evaluation `index`'s
    metrics are written; interrupt_after_eval(None) lets training run on again."""
    from fieldgen.run import record

    write_metrics = record.write_metrics

    def arm(index: int | None) -> None:
        def stop(folder, rows):
            write_metrics(folder, rows)
            if rows[-1]["eval"] == index:
                raise KeyboardInterrupt

        monkeypatch.setattr(record, "write_metrics", write_metrics if index is None else stop)

    return arm
