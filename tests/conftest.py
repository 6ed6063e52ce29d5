"""Shared fixtures: compiled environments are expensive on CPU, so build each once.

Tests also compile many identical programs (the same tiny configs through the CLI, resumes,
evaluations), so the session shares one JAX compilation cache among its workers: each such
program compiles once per session.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import jax
import pytest

import fieldgen
from fieldgen.schema import bundled_fields

FIELDS = sorted(bundled_fields())


def pytest_configure(config):
    """The first process of the session (the controller, or the only one) makes the cache folder; workers
    and the `fieldgen` commands tests start inherit the variable (JAX reads it on import)."""
    if "JAX_COMPILATION_CACHE_DIR" in os.environ:  # the user's own cache, or the controller's
        return
    os.environ["JAX_COMPILATION_CACHE_DIR"] = tempfile.mkdtemp(prefix="fieldgen-test-jax-cache-")
    config.owns_jax_cache = True
    jax.config.update("jax_compilation_cache_dir", os.environ["JAX_COMPILATION_CACHE_DIR"])


def pytest_unconfigure(config):
    if getattr(config, "owns_jax_cache", False):
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
