"""Settings of the smallest runs the tests train, importable by name from any test module (each test folder
has its own conftest, so `from conftest import ...` would find the nearest one, not this)."""

# The smallest CRL run on point_nav that trains: 10 iterations of 8 envs x 10 steps prefill its 100 rows
# (800 env steps), then 2 evaluations of 6 iterations each. Every test that trains it, in-process or through
# `fieldgen train`, uses these very settings, so that the session compiles its programs once.
TINY_CRL = {"total_steps": 1900, "num_envs": 8, "unroll_length": 10, "batch_size": 32, "min_replay_rows": 100,
            "max_replay_rows": 400, "hidden": (32, 32), "repr_dim": 8, "num_evals": 2, "eval_envs": 8}

# The smallest self-play run on a team field, as `fieldgen train` options: a few thousand env steps, 3 evaluations
# of 10 iterations of 8 matches x 10 steps.
TINY_SELFPLAY = ["--steps", "2400", "--envs", "8", "--set", "ppo.unroll_length=10", "--set", "ppo.num_minibatches=4",
                 "--set", "ppo.hidden=[32,32]", "--set", "ppo.num_evals=3", "--set", "ppo.eval_envs=8",
                 "--set", "ppo.update_epochs=2", "--set", "ppo.pool_size=2"]


def as_if_learned(run):
    """A run folder set up with `fieldgen train --prepare` given a learner.msgpack of exactly the shapes its
    trainer learns (zeros, from the trainer's traced shapes: no program compiled or run) and an evaluation at 0
    env steps a seed, so that it reads as a run that has learned wherever only its record and the shapes of what
    it learned are read: the refusals of --init-from, export, view and eval, and what eval plays. Training the
    tiny run instead costs most of a minute on two CPU cores."""
    import jax
    import numpy as np

    from fieldgen.agents import checkpoint
    from fieldgen.files import write_atomic
    from fieldgen.run import record, session

    prepared = session.open_run(run, load_state=False)
    shapes = session.learner_template(prepared)
    write_atomic(run / record.LEARNER, checkpoint.pieces(jax.tree.map(lambda s: np.zeros(s.shape, s.dtype), shapes)))
    record.write_metrics(run, [{"eval": 0, "seed": seed, "env_steps": 0} for seed in prepared.seeds])
    return run
