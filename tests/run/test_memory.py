"""Command-line values past what the machine holds: refused in a sentence with the memory they would take,
before anything is allocated or written, and no number overflows on its way to the device."""

from __future__ import annotations

import jax
import numpy as np
import pytest
from typer.testing import CliRunner

from fieldgen.agents import loop, memory
from fieldgen.cli import app

runner = CliRunner()
GB = 10**9


@pytest.fixture
def machine_of(monkeypatch):
    """machine_of(gigabytes): the memory the checks see, whatever this machine has."""
    def set_memory(gigabytes: float) -> None:
        monkeypatch.setattr(memory, "available", lambda: (int(gigabytes * GB), "this machine"))
    return set_memory


def refused(tmp_path, *args: str) -> str:
    """`fieldgen train point_nav ARGS` into tmp_path: refused in one paragraph, nothing written."""
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--no-videos", *args])
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    assert list(tmp_path.iterdir()) == []
    return " ".join(result.output.split())


@pytest.mark.parametrize("args,phrase", [
    (["--envs", "10000000000", "--steps", "1e14"], "--steps 100,000,000,000,000 with 10,000,000,000 envs x unroll "
     "62 per iteration: a run counts its env steps in 32-bit integers, which reach 2,147,483,647"),
    (["--steps", "3G"], "--steps 3,000,000,000 with 1,024 envs x unroll 62 per iteration"),
    (["--seed", "4294967000", "--seeds", "1000"], "--seed 4294967000 with --seeds 1,000 runs past seed 4,294,967,295, "
     "the largest a random key takes; train fewer --seeds or start from a lower --seed"),
    (["--seed", "4294967296"], "--seed 4294967296: a seed (a random key takes 32 bits) is a whole number from 0 to 4,294,967,295"),
    (["--seed", "4294967295", "--seeds", "2"], "runs past seed 4,294,967,295"),
    (["--seeds", "1000000"], "--seeds 1000000: seeds trained at once is a whole number from 1 to 65,536"),
], ids=["envs", "steps", "seeds", "seed", "seed_range", "many_seeds"])
def test_counts_past_what_the_device_counts_are_refused(tmp_path, args, phrase):
    """Before: an OverflowError traceback (and a run folder) for --envs, a run whose step counter would wrap
    for --steps, a MemoryError listing the seeds, and seeds past 2**32 given seed 0's random key."""
    assert phrase in refused(tmp_path, *args)


@pytest.mark.parametrize("args,phrase", [
    (["--envs", "100000", "--steps", "1G"], "training 1 seed of crl with 100,000 envs needs about 28.8 GB (replay "
     "buffer 28 GB, update batch 560 MB, episodes 197 MB, networks and optimizers 3.03 MB) of memory, more than the "
     "16 GB of this machine; lower --envs or crl.max_replay_rows"),
    (["--envs", "8", "--set", "crl.hidden=[100000,100000]"], "networks and optimizers 360 GB, replay buffer 2.24 MB, "
     "update batch 44.8 kB, episodes 15.7 kB) of memory, more than the 16 GB of this machine; lower crl.hidden"),
    (["--envs", "8", "--set", "crl.max_replay_rows=100000000"], "needs about 22.4 GB (replay buffer 22.4 GB"),
    (["--envs", "1024", "--seeds", "1000"], "training 1,000 seeds of crl with 1,024 envs needs about 297 GB"),
    (["--envs", "10000", "--steps", "1G", "--set", "crl.windows_per_env=1000"], "(update batch 56 GB, replay buffer "
     "2.8 GB, episodes 19.7 MB, networks and optimizers 3.03 MB) of memory, more than the 16 GB of this machine; lower "
     "crl.windows_per_env or --envs"),
    (["--algo", "ppo", "--envs", "10000000", "--steps", "1.9G", "--set", "ppo.num_evals=5"],
     "training 1 seed of ppo with 10,000,000 envs needs about"),
], ids=["envs", "network", "buffer", "seeds", "windows", "ppo"])
def test_a_run_the_machine_cannot_hold_is_refused_with_its_estimate(tmp_path, machine_of, args, phrase):
    machine_of(16)
    assert phrase in refused(tmp_path, *args)


def test_a_run_prepared_to_train_elsewhere_is_written_with_a_note(tmp_path, machine_of):
    """--prepare is for a run that trains on another machine (a GPU's): its memory is checked where it resumes,
    and here it is only said."""
    machine_of(16)
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--prepare", "--envs", "100000",
                                 "--steps", "1G"])
    message = " ".join(result.output.split())
    assert result.exit_code == 0 and (tmp_path / "point_nav-crl-0" / "run.json").exists(), result.output
    assert "note: training 1 seed of crl with 100,000 envs needs about 28.8 GB" in message
    assert message.endswith("more than the 16 GB of this machine; lower --envs or crl.max_replay_rows; resume it on a "
                            "machine that holds it")


def test_a_prepared_run_too_large_for_this_machine_is_refused_before_it_loads(tmp_path, machine_of, tiny_crl_args):
    """Prepared on a larger machine (--prepare, to train elsewhere), then resumed here."""
    prepared = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--prepare", *tiny_crl_args])
    assert prepared.exit_code == 0, prepared.output
    machine_of(0.0001)
    result = runner.invoke(app, ["train", "--resume", str(tmp_path / "point_nav-crl-0")])
    message = " ".join(result.output.split())
    assert result.exit_code == 1 and "Traceback" not in message, result.output
    assert "training 1 seed of crl with 8 envs needs about" in message and "more than the 100 kB" in message


def test_the_estimate_of_a_training_state_is_what_it_allocates(env_cache, tiny_crl):
    from fieldgen.agents import crl

    trainer = crl.make_train(tiny_crl(), env_cache("point_nav"))
    estimate = memory.training(trainer, 2)
    state = jax.vmap(trainer.init)(loop.seed_keys([0, 1]))
    held = sum(np.asarray(x).nbytes for x in jax.tree.leaves(state))
    assert estimate.total - estimate.parts[memory.BATCH] == held
    assert estimate.parts[memory.BUFFER] == sum(np.asarray(x).nbytes for x in jax.tree.leaves(state.buffer))


@pytest.mark.parametrize("args,phrase", [
    (["--envs", "1e11"], "benchmarking 100,000,000,000 envs needs about 197 TB (episodes 197 TB) of memory, more "
     "than the 16 GB of this machine; lower --envs"),
    (["--envs", "0"], "'0' is not a positive whole count"),
    (["--envs", "-3"], "'-3' is not a positive whole count"),
    (["--steps", "0"], "--steps 0: the steps of a timed rollout is a whole number from 1 to 1,000,000"),
], ids=["envs", "zero", "negative", "steps"])
def test_bench_counts_are_checked(machine_of, args, phrase):
    """Before: --envs -3 was a traceback from XLA, --envs 0 a row of zeros, --envs 1e11 an allocation failure."""
    machine_of(16)
    result = runner.invoke(app, ["bench", "point_nav", *args])
    assert result.exit_code in (1, 2) and "Traceback" not in result.output
    assert phrase in " ".join(result.output.split())
