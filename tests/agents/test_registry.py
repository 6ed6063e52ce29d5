"""The trainers' registry: its names without JAX, each trainer loaded when looked up and checked against
the config class it is listed with."""

from __future__ import annotations

import subprocess
import sys
import types
from pathlib import Path

import pytest

from fieldgen.agents import registry


def test_a_trainer_loads_only_when_it_is_looked_up():
    code = ("import sys\n"
            "from fieldgen.agents import registry\n"
            "print('jax' in sys.modules)\n"
            "registry.trainer('sac')\n"
            "print('jax' in sys.modules, 'fieldgen.agents.sac' in sys.modules, 'fieldgen.agents.ppo' in sys.modules)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["False", "True", "True", "False"]


def test_an_unknown_algorithm_is_refused_with_a_suggestion():
    from fieldgen.agents.config import ConfigError

    with pytest.raises(ConfigError) as info:
        registry.trainer("ppo2")
    assert str(info.value) == f"unknown algorithm 'ppo2'; did you mean 'ppo'? Available: {', '.join(registry.ALGORITHMS)}."
    with pytest.raises(ConfigError) as info:
        registry.trainer("nonsense")  # nothing near it: the choices alone
    assert str(info.value) == f"unknown algorithm 'nonsense'; available: {', '.join(registry.ALGORITHMS)}."


def test_the_algorithms_are_the_folders_holding_a_config_and_a_training_function():
    folders = Path(registry.__file__).parent
    assert registry.ALGORITHMS == tuple(sorted(
        f.name for f in folders.iterdir() if (f / "config.py").is_file() and (f / "train.py").is_file()))
    assert {"crl", "icrl", "ppo", "sac", "td3"} <= set(registry.ALGORITHMS) and "presets" not in registry.ALGORITHMS


def test_a_config_class_listed_under_another_algorithm_is_refused(monkeypatch):
    from fieldgen.agents.crl.config import CRLConfig

    monkeypatch.setattr(CRLConfig, "algo", "ppo")
    registry._load.cache_clear()
    try:
        with pytest.raises(TypeError, match="CRLConfig.algo is 'ppo', but the registry lists it as 'crl'"):
            registry.trainer("crl")
    finally:
        registry._load.cache_clear()


def test_a_config_module_must_define_exactly_one_config_class():
    module = types.ModuleType("fieldgen.agents.mine.config")
    with pytest.raises(TypeError, match="defines 0 config classes"):
        registry.config_class(module, "mine")
