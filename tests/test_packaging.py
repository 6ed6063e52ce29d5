"""An installed fieldgen, not the checkout: a wheel built from the repository, installed into a fresh
virtual environment outside it, carries its bundled fields and its trainers under the fieldgen name."""

from __future__ import annotations

import os
import subprocess
import sys
import sysconfig
import textwrap
from pathlib import Path

from fieldgen.agents.registry import ALGORITHMS


ROOT = Path(__file__).resolve().parents[1]


def run(*args, cwd: Path, env: dict | None = None) -> str:
    done = subprocess.run([str(a) for a in args], cwd=cwd, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, f"{args} failed:\n{done.stdout}\n{done.stderr}"
    return done.stdout


def test_a_built_wheel_installed_elsewhere_has_its_fields_and_trainers(tmp_path):
    # setuptools builds inside the source folder unless told otherwise: its work folders go under tmp_path
    settings = tmp_path / "setuptools.cfg"
    settings.write_text(f"[build]\nbuild_base = {tmp_path / 'build'}\n[bdist_wheel]\nbdist_dir = {tmp_path / 'bdist'}\n")
    checkout_had_build = (ROOT / "build").exists()
    run(sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", tmp_path / "dist", ROOT, cwd=tmp_path,
        env={**os.environ, "DIST_EXTRA_CONFIG": str(settings)})
    assert checkout_had_build or not (ROOT / "build").exists()
    wheel = next((tmp_path / "dist").glob("fieldgen-*.whl"))
    venv = tmp_path / "venv"
    run(sys.executable, "-m", "venv", "--without-pip", venv, cwd=tmp_path)
    python = venv / "bin" / "python"
    site = Path(run(python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])", cwd=tmp_path).strip())
    # the dependencies come from the test's own environment: a path line, so its .pth files (among them
    # the editable install's finder, which would serve the checkout) are not run
    (site / "dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    run(sys.executable, "-m", "pip", "--python", python, "install", "-q", "--no-deps", wheel, cwd=tmp_path)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    work = tmp_path / "elsewhere"
    (work / "mine").mkdir(parents=True)
    (work / "mine" / "wide.yaml").write_text("extends: soccer_v2\nname: wide\nobstacles:\n  goalie: {width: 3.0}\n")
    (work / "agents").mkdir()  # a user's own agents/ folder must not shadow the trainers
    (work / "agents" / "__init__.py").write_text("raise ImportError('the user agents package was imported')\n")

    built = run(venv / "bin" / "fieldgen", "build", "soccer_v2", "--out", work / "build", "--no-preview", cwd=work,
                env=env)
    assert "soccer_v2" in built and (work / "build" / "soccer_v2" / "scene.xml").exists()
    check = textwrap.dedent(f"""
        import fieldgen, fieldgen.agents.crl, fieldgen.sweep.plan
        from fieldgen.schema import load_spec
        assert fieldgen.__file__.startswith({str(site)!r}), fieldgen.__file__
        assert fieldgen.agents.crl.__file__.startswith({str(site)!r}), fieldgen.agents.crl.__file__
        env = fieldgen.make("soccer_v2")
        assert env.spec.goal.distance == 20
        wide = load_spec("mine/wide.yaml")
        assert wide.obstacles["goalie"].width == 3.0 and wide.goal.distance == 20
        from fieldgen.agents.crl import CRLConfig
        assert CRLConfig.layered(agent="ant").layer_norm  # the bundled preset came with the wheel
        from fieldgen.agents import registry
        assert registry.ALGORITHMS == {ALGORITHMS!r}, registry.ALGORITHMS  # every algorithm's folder came along
        for name in registry.ALGORITHMS:
            entry = registry.trainer(name)
            assert entry.config.algo == name and entry.make_train.__module__ == f"fieldgen.agents.{{name}}.train"
        print("installed ok", env.observation_size)
    """)
    assert "installed ok 33" in run(python, "-c", check, cwd=work, env=env)
