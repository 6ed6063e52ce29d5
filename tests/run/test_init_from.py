"""`fieldgen train --init-from RUN`: a new run that starts from the networks another run learned, counts its
own env steps and randomness, survives being stopped before its first checkpoint, and refuses a source whose
networks it could not take before writing anything."""

from __future__ import annotations

import json
import shutil

import jax
import numpy as np
import pytest
from typer.testing import CliRunner

from fieldgen.agents import checkpoint
from fieldgen.cli import app
from fieldgen.run import evaluate, record, session, summary
from test_training import unwrapped as flat
from tiny_runs import as_if_learned

runner = CliRunner()


@pytest.fixture(scope="module")
def source(tmp_path_factory, tiny_crl_args):
    """A tiny CRL run on point_nav, trained to its end."""
    out = tmp_path_factory.mktemp("source")
    result = runner.invoke(app, ["train", "point_nav", "--out", str(out), "--no-videos", *tiny_crl_args])
    assert result.exit_code == 0, result.output
    return out / "point_nav-crl-0"


@pytest.fixture(scope="module")
def learned(tmp_path_factory, tiny_crl_args):
    """A tiny CRL run on point_nav that reads as having learned (tiny_runs.as_if_learned), untrained: all that the
    refusals below read of a source is its record and the shapes of what it learned; the slow test above starts
    from a trained one."""
    out = tmp_path_factory.mktemp("learned")
    result = runner.invoke(app, ["train", "point_nav", "--out", str(out), "--prepare", *tiny_crl_args])
    assert result.exit_code == 0, result.output
    return as_if_learned(out / "point_nav-crl-0")


@pytest.mark.slow
def test_a_run_starts_from_what_another_learned_and_trains_on(tmp_path, source, tiny_crl_args):
    prepared = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--seed", "3", "--prepare",
                                   "--init-from", str(source), *tiny_crl_args])
    assert prepared.exit_code == 0, prepared.output
    assert flat(f"starts from what {source} learned in 1,760 env steps (evaluation 2)") in flat(prepared.output)
    run = tmp_path / "point_nav-crl-3"
    assert json.loads((run / record.RUN).read_text())["init_from"] == {"run": str(source), "env_steps": 1760,
                                                                       "eval": 2, "before": 0}

    # set up but not trained (as if killed before its first checkpoint): it opens at what it starts from
    opened = session.open_run(run)
    assert opened.rows == [] and opened.init_from["run"] == str(source)
    learned, _ = checkpoint.load(source / record.LEARNER, *session.learner_template(opened))
    for a, b in zip(jax.tree.leaves(opened.state.nets), jax.tree.leaves(learned.nets)):
        np.testing.assert_array_equal(a, b)
    assert int(opened.state.env_steps[0]) == 0
    np.testing.assert_array_equal(opened.state.key[0], jax.random.PRNGKey(3))

    trained = runner.invoke(app, ["train", "--resume", str(run), "--no-videos"])
    assert trained.exit_code == 0, trained.output
    rows = [json.loads(line) for line in (run / record.METRICS).read_text().splitlines()]
    assert [r["eval"] for r in rows] == [0, 1, 2]
    assert [r["env_steps"] for r in rows] == [800, 1280, 1760]  # its own steps, the buffer's refill first
    assert (run / record.CHECKPOINT).exists()

    # a run started from this one counts the chain from nothing learned, and its summary says so
    chained = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path), "--seed", "4", "--prepare",
                                  "--init-from", str(run), *tiny_crl_args])
    assert chained.exit_code == 0, chained.output
    assert flat("learned in 1,760 env steps (evaluation 2, 3,520 from nothing learned)") in flat(chained.output)
    chain = session.open_run(tmp_path / "point_nav-crl-4", load_state=False)
    assert chain.init_from["before"] == 1760 and chain.learned_before == 3520
    judged = evaluate.Evaluation({m: np.array([0.5]) for m in summary.METRICS}, 1760, None)
    assert evaluate.summarize([chain], [judged], 8, "fieldgen eval").env_steps_before == {4: 3520}
    assert evaluate.summarize([opened], [judged], 8, "fieldgen eval").env_steps_before == {3: 1760}
    evaluated = runner.invoke(app, ["eval", str(run), "--episodes", "4", "--no-video"])
    assert evaluated.exit_code == 0, evaluated.output
    assert flat("at 1,760 env steps (3,520 from nothing learned) on point_nav") in flat(evaluated.output)
    assert json.loads((run / summary.SUMMARY).read_text())["env_steps_before"] == {"3": 1760}


@pytest.mark.parametrize("field, changes, phrase", [
    ("point_soccer", [], "point_nav observes or acts differently from point_soccer (observation 6 against 8 values"),
    ("point_nav", ["--set", "crl.hidden=[16,16]"], "the configs differ in crl.hidden ([32, 32] there, [16, 16] here)"),
    ("point_nav", ["--seeds", "2"], "it trained 1 seeds at once, this run (crl on point_nav) 2; give --seeds 1"),
], ids=["layout", "network", "seeds"])
def test_a_source_whose_networks_do_not_fit_is_refused_before_anything_is_written(tmp_path, learned, tiny_crl_args,
                                                                                  field, changes, phrase):
    result = runner.invoke(app, ["train", field, "--out", str(tmp_path / "runs"), "--prepare", "--init-from",
                                 str(learned), *tiny_crl_args, *changes])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert flat(phrase) in flat(result.output)
    assert not (tmp_path / "runs").exists()


def test_a_damaged_source_is_said_to_be_damaged_not_to_differ(tmp_path, learned, tiny_crl_args):
    """Before: a learner.msgpack cut short read as 'its networks do not fit', the configs differing in nothing."""
    damaged = tmp_path / "source"
    shutil.copytree(learned, damaged)
    whole = (learned / record.LEARNER).read_bytes()
    (damaged / record.LEARNER).write_bytes(whole[:len(whole) // 2])
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path / "runs"), "--prepare", "--init-from",
                                 str(damaged), *tiny_crl_args])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert flat(f"--init-from {damaged}: checkpoint corrupt: {damaged / record.LEARNER} was damaged") \
        in flat(result.output)
    assert "do not fit" not in result.output and not (tmp_path / "runs").exists()


def test_a_source_of_another_algorithm_is_refused(tmp_path, learned):
    result = runner.invoke(app, ["train", "point_nav", "--algo", "sac", "--out", str(tmp_path), "--prepare",
                                 "--init-from", str(learned)])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert flat("it trained crl, this run (sac on point_nav) trains sac") in flat(result.output)


def test_init_from_names_a_run_that_has_learned(tmp_path, tiny_crl_args):
    """Each way a source is no run that learned is said as itself (before: "no learner.msgpack there" for all)."""
    (tmp_path / "notes.txt").write_text("mine")
    prepared = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path / "new"), "--prepare", *tiny_crl_args])
    assert prepared.exit_code == 0, prepared.output
    fresh = tmp_path / "new" / "point_nav-crl-0"
    for source, said in ((tmp_path / "none", f"{tmp_path / 'none'} is missing, not a run folder"),
                         (tmp_path / "notes.txt", f"{tmp_path / 'notes.txt'} is a file, not a run folder"),
                         (fresh, "it holds no learner.msgpack (written at each evaluation) nor checkpoint: it has not "
                                 f"trained yet; train it first (fieldgen train --resume {fresh})")):
        result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path / "runs"), "--init-from", str(source),
                                     *tiny_crl_args])
        assert result.exit_code == 1 and "Traceback" not in result.output
        assert flat(f"--init-from {source}: {said}") in flat(result.output), result.output
    (fresh / record.METRICS).write_text("")  # evaluated, then both weight files moved away: no --resume brings them
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path / "runs"), "--init-from", str(fresh),
                                 *tiny_crl_args])
    assert flat(f"--init-from {fresh}: it has evaluations in metrics.jsonl but neither learner.msgpack nor "
                "checkpoint.msgpack (moved or deleted): put them back, or name another run") in flat(result.output)
    (fresh / record.METRICS).unlink()
    (fresh / record.CHECKPOINT).write_bytes(b"a checkpoint")  # learned, its learner.msgpack deleted
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path / "runs"), "--init-from", str(fresh),
                                 *tiny_crl_args])
    assert flat(f"its learner.msgpack is missing; fieldgen train --resume {fresh} writes it again") in \
        flat(result.output), result.output
    (fresh / record.LEARNER).mkdir()
    result = runner.invoke(app, ["train", "point_nav", "--out", str(tmp_path / "runs"), "--init-from", str(fresh),
                                 *tiny_crl_args])
    assert flat("its learner.msgpack is a folder; make it the file fieldgen train wrote") in flat(result.output)
    assert not (tmp_path / "runs").exists()


def test_init_from_is_not_for_a_resumed_run(tmp_path, learned):
    result = runner.invoke(app, ["train", "--resume", str(learned), "--init-from", str(learned)])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert flat("--init-from sets up a new run") in flat(result.output)
