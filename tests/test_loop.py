"""Several seeds under vmap, the pure train(key), and one run sharded over two (CPU) devices."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import jax
import numpy as np
import pytest

from agents import crl, loop, ppo


def tiny_crl():
    return crl.CRLConfig(total_steps=1900, num_envs=8, unroll_length=10, batch_size=32, min_replay_rows=100,
                         max_replay_rows=400, hidden=(32, 32), repr_dim=8, num_evals=2, eval_envs=8)


def test_vmapped_seeds_match_seeds_run_alone(env_cache):
    algo = crl.make_train(tiny_crl(), env_cache("point_nav"))
    both, rows = loop.run(algo, [0, 1], 2)
    alone, alone_rows = loop.run(algo, [1], 2)
    for a, b in zip(jax.tree.leaves(loop.seed_slice(both.actor, 1)), jax.tree.leaves(loop.seed_slice(alone.actor, 0))):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-4, atol=1e-5)
    assert {r["seed"] for r in rows} == {0, 1} and len(rows) == 6
    ours = [r for r in rows if r["seed"] == 1]
    for a, b in zip(ours, alone_rows):
        assert a["critic_loss" if a["eval"] else "success_any"] == pytest.approx(
            b["critic_loss" if b["eval"] else "success_any"], rel=1e-4)


def test_pure_train_is_the_stepwise_run(env_cache):
    config = ppo.PPOConfig(total_steps=2 * 8 * 20, num_envs=8, unroll_length=20, num_minibatches=4, update_epochs=2,
                           hidden=(32, 32), num_evals=2, eval_envs=8)
    algo = ppo.make_train(config, env_cache("point_nav"))
    state, metrics = jax.jit(jax.vmap(loop.pure_train(algo, 2)))(jax.random.PRNGKey(3)[None])
    _, rows = loop.run(algo, [3], 2)
    np.testing.assert_allclose(np.asarray(metrics["policy_loss"][0]), [r["policy_loss"] for r in rows[1:]],
                               rtol=1e-4)
    np.testing.assert_allclose(np.asarray(metrics["time_at_goal"][0]), [r["time_at_goal"] for r in rows[1:]])
    assert metrics["term_success"].shape == (1, 2) if "term_success" in metrics else True


TWO_DEVICES = """
import json, sys
import jax
import fieldgen
from agents import crl, loop
assert len(jax.local_devices()) == {devices}
config = crl.CRLConfig(total_steps=1900, num_envs=8, unroll_length=10, batch_size=32, min_replay_rows=100,
                       max_replay_rows=400, hidden=(32, 32), repr_dim=8, num_evals=2, eval_envs=8)
state, rows = loop.run(crl.make_train(config, fieldgen.make("point_nav")), [0], 2)
shards = len(state.buffer.data["state"].sharding.device_set)
print(json.dumps({{"rows": rows, "buffer_devices": shards}}))
"""


@pytest.mark.slow
@pytest.mark.parametrize("devices", [1, 2])
def test_two_devices_match_one(devices, tmp_path):
    """The same CRL run on one and on two host devices: the environments and the buffer are split
    across the two, and the metrics agree within float32 reduction-order tolerance."""
    results = {}
    for n in (1, devices):
        env = {**os.environ, "XLA_FLAGS": f"--xla_force_host_platform_device_count={n}", "JAX_PLATFORMS": "cpu"}
        proc = subprocess.run([sys.executable, "-c", TWO_DEVICES.format(devices=n)], env=env, capture_output=True,
                              text=True, cwd=Path(__file__).parent.parent, timeout=600)
        assert proc.returncode == 0, proc.stderr[-3000:]
        results[n] = json.loads(proc.stdout.strip().splitlines()[-1])
    assert results[devices]["buffer_devices"] == devices
    for one, many in zip(results[1]["rows"], results[devices]["rows"]):
        for name in ("success_any", "time_at_goal", "critic_loss", "actor_loss"):
            if name in one:
                assert many[name] == pytest.approx(one[name], rel=2e-3, abs=1e-3), name
