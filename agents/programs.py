"""A trainer's jitted programs for one batch of seeds, each compiled on a worker thread of its own.

Compiling a run's MJX programs (its start, its chunk, its evaluation) takes most of a short run's
first minutes. Tracing needs Python's lock but XLA's compiler does not: each program is traced in
the caller's thread and compiled on a worker, so the compiles overlap one another and the tracing
of the next program, and the start runs while the chunk is still compiling. On a CPU backend the
programs compile one after another instead, the caller waiting for each: there the programs run on
the same cores, and XLA already spreads one compile over them (side by side, two test workers on two
cores ran slower: bench/results/README.md). Either way the caller waits in Python, where Ctrl-C
reaches it at once, rather than inside XLA, which takes no signal until the compile ends; so it
waits for a program's results (`computed`).
"""

from __future__ import annotations

import functools
import threading
import weakref
from concurrent.futures import Future
from typing import Callable

import jax

from ..curriculum.contract import start_sampling
from . import sharding

SIDE_BY_SIDE: bool | None = None  # compile on worker threads; None: on every backend but the CPU
COMPILE_THREAD = "compile"  # the name of each compile's thread
RUN_THREAD = "run"  # the name of the thread a program `started` runs on
_running: list[weakref.ref] = []  # a result of each program called, until it is computed (or no longer held)


def side_by_side() -> bool:
    return jax.default_backend() != "cpu" if SIDE_BY_SIDE is None else SIDE_BY_SIDE


class Compiling:
    """A jitted function lowered for the given arguments and compiled on a thread of its own; calling it
    waits for that compile (where not `side_by_side()`, so does making it). Ctrl-C meanwhile interrupts
    the wait, not the compile: XLA cannot be stopped mid-compile, and a thread killed inside it aborts
    the process, so a program stopped meanwhile either waits for `under_way()` compiles to end or leaves
    without them (os._exit, as `fieldgen train` does)."""

    def __init__(self, jitted, *args):
        self._done: Future = Future()
        lowered = jitted.lower(*args)
        self.out_info = lowered.out_info  # the shapes of what it returns
        threading.Thread(target=self._compile, args=(lowered,), name=COMPILE_THREAD).start()
        if not side_by_side():
            self._done.result()

    def _compile(self, lowered) -> None:
        try:
            self._done.set_result(lowered.compile())
        except BaseException as error:  # raised where the program is called
            self._done.set_exception(error)

    def __call__(self, *args):
        return _held(self._done.result()(*args))

    def started(self, *args) -> Future:
        """The program called on a thread of its own, its results in the Future: a call that holds its thread
        until the program ends (on a GPU, a while loop's condition is read back at each turn) leaves the
        caller free meanwhile, to write the last evaluation while this chunk trains, and to take Ctrl-C."""
        program = self._done.result()
        return on_thread(lambda: _held(program(*args)), RUN_THREAD)


def _held(results):
    """A program's results, kept track of until they are ready (`under_way`)."""
    _running[:] = [ref for ref in _running if ref() is not None and not ref().is_ready()]
    _running.extend(weakref.ref(leaf) for leaf in jax.tree.leaves(results)[:1])  # they come ready together
    return results


def computed(tree, fetch=jax.device_get):
    """fetch(tree) (jax.device_get, or sharding.to_host across processes), waited for on a thread of its own:
    the caller waits in Python, where Ctrl-C reaches it at once, while a program runs in XLA, which takes no
    signal until the program ends."""
    return on_thread(lambda: fetch(tree), "wait").result()


def on_thread(work: Callable, name: str) -> Future:
    """work() on a thread of its own called `name`, its result (or what it raised) in the Future."""
    done: Future = Future()

    def run():
        try:
            done.set_result(work())
        except BaseException as error:  # raised where the result is asked for
            done.set_exception(error)

    threading.Thread(target=run, name=name).start()
    return done


def under_way() -> bool:
    """Whether a program is still compiling, or still running: one dispatched and not yet waited for, or one a
    caller stopped waiting for (`computed`)."""
    return any(t.name in (COMPILE_THREAD, RUN_THREAD) and t.is_alive() for t in threading.enumerate()) or \
        any(ref() is not None and not ref().is_ready() for ref in _running)


def reserve_worlds(trainer, seeds: int) -> None:
    """Size the trainer's environment for every environment one of its programs steps at once (over seeds and
    environments, training's or evaluation's), before the programs are traced (Environment.reserve_worlds)."""
    trainer.env.reserve_worlds(seeds * max(trainer.config.num_envs, trainer.config.eval_envs))


def started(trainer, keys: jax.Array) -> tuple[Callable, object]:
    """The vmapped start of a batch of seeds and the shapes of the training state it makes, traced once per
    trainer and seed count: a run's checkpoint and learner are read through these shapes and its programs
    placed by them, and the start program jitted from the same function reuses the trace. The environment is
    sized for the batch first, so that a run resumed from its checkpoint is placed as one started afresh."""
    kept = ("started", keys.shape[0])
    if kept not in trainer.compiled:
        reserve_worlds(trainer, keys.shape[0])
        start = jax.vmap(trainer.start)
        trainer.compiled[kept] = start, jax.eval_shape(start, keys)
    return trainer.compiled[kept]


def sampling_of(state):
    """The sampling a (seeds stacked) training state's environments draw by now (curriculum.contract.start_sampling)."""
    return start_sampling(state.env_state)


class Programs:
    """start(keys), refill(learned), chunk_started(state), evaluate(learned, eval_keys),
    adapt(state, sampling, variants) and sampling(state) of one trainer, vmapped over seeds and placed over
    the devices (agents.sharding). Each compiles once asked for, by `prepare` or by its first call."""

    def __init__(self, trainer, keys: jax.Array, film: Callable | None, evaluate: Callable, adapt: Callable):
        start, shapes = started(trainer, keys)  # one function for both: JAX reuses the shapes' trace to compile it
        self.placement = sharding.training_shardings(shapes, sharding.device_mesh(), trainer.env_axes)
        self._state = jax.tree.map(lambda s, p: jax.ShapeDtypeStruct(s.shape, s.dtype, sharding=p),
                                   shapes, self.placement)
        self._learned = trainer.learned
        self._jobs = {
            "start": lambda: Compiling(jax.jit(start, out_shardings=self.placement), keys),
            "refill": lambda: Compiling(jax.jit(jax.vmap(trainer.refill), out_shardings=self.placement),
                                        trainer.learned(shapes)),
            "chunk": lambda: Compiling(jax.jit(jax.vmap(trainer.chunk), in_shardings=(self.placement,),
                                               out_shardings=(self.placement, None)), self._state),
            "evaluate": lambda: Compiling(jax.jit(jax.vmap(functools.partial(evaluate, trainer, film=film))),
                                          self._learned(self._state), keys),
            "adapt": lambda: Compiling(jax.jit(jax.vmap(functools.partial(adapt, trainer)),
                                               in_shardings=(self.placement, None, None),
                                               out_shardings=(self.placement, None, None)),
                                       self._state, jax.eval_shape(sampling_of, self._state), self._variants),
            "sampling": lambda: Compiling(jax.jit(sampling_of), self._state),
        }
        self._compiling: dict[str, Compiling] = {}

    @property
    def _variants(self):
        """The shapes of an evaluation's results per variant, what `adapt` reads."""
        return self._program("evaluate").out_info[0]["variants"]

    def prepare(self, *names: str) -> None:
        """Start compiling these programs, in this order, unless they already are."""
        for name in names:
            if name not in self._compiling:
                self._compiling[name] = self._jobs[name]()

    def compiled(self) -> None:
        """Wait until every program asked for so far has compiled."""
        for program in self._compiling.values():
            program._done.result()

    def _program(self, name: str) -> Compiling:
        self.prepare(name)
        return self._compiling[name]

    def start(self, keys: jax.Array):
        return self._program("start")(keys)

    def refill(self, learned):
        return self._program("refill")(learned)

    def chunk_started(self, state) -> Future:
        """`chunk` on a thread of its own (`Compiling.started`)."""
        return self._program("chunk").started(state)

    def evaluate(self, state, eval_keys: jax.Array):
        """Evaluation reads only what the state has learned, so a state of another stage, whose field has
        other bodies and geoms, is judged here too (a curriculum's last stage while it trains an earlier one)."""
        return self._program("evaluate")(self._learned(state), eval_keys)

    def adapt(self, state, sampling, variants):
        return self._program("adapt")(state, sampling, variants)

    def sampling(self, state):
        """The sampling the state's environments draw by now: where a run starts, or moves to another stage."""
        return self._program("sampling")(state)
