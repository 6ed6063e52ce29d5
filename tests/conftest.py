"""Shared fixtures: compiled environments are expensive on CPU, so build each once."""

from __future__ import annotations

from pathlib import Path

import pytest

import fieldgen
from fieldgen.schema import bundled_fields

FIELDS = sorted(bundled_fields())


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
