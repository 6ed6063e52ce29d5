"""Results over seeds as Agarwal et al. ("Deep RL at the Edge of the Statistical Precipice", NeurIPS 2021)
report them: the interquartile mean of the seeds' values with a 95% stratified percentile-bootstrap interval,
because a single seed, or a mean and range over a few, says little about how an algorithm does.

The interquartile mean is rliable's (`aggregate_iqm`: scipy.stats.trim_mean over every run of every task,
a quarter cut from each end): whole runs are cut, so with up to three seeds it is their mean and with
five the mean of the middle three. rliable itself is not used: it brings pandas, seaborn, statsmodels
and arch, none of them among fieldgen's pinned requirements. The bootstrap draws from a generator of a
fixed seed, so the same values always give the same interval.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Literal, Sequence

import numpy as np
import scipy.stats
from pydantic import BaseModel, Field, ValidationError, model_validator

from fieldgen.agents.registry import EVAL_ACTIONS
from fieldgen.files import EVAL, Output, named_twice, write_file
from fieldgen.limits import MAX_SEEDS
from fieldgen.run.record import metric_problem
from fieldgen.schema.errors import shown_text

SUMMARY = "summary.json"
METRICS = ("success_any", "time_at_goal")  # what a summary holds, per seed and over them
CONFIDENCE, RESAMPLES, BOOTSTRAP_SEED = 0.95, 2000, 0  # rliable's default count of bootstrap resamples
RESAMPLED_AT_ONCE = 2**22  # values of a bootstrap batch: memory stays a few tens of MB whatever the seed count
MAX_SUMMARY_BYTES = 32 * 2**20  # a summary of MAX_SEEDS seeds takes a few MB


def _tasks(tasks: Sequence[Sequence[float]]) -> list[np.ndarray]:
    try:
        arrays = [np.asarray(t, dtype=float).ravel() for t in tasks]
    except (TypeError, ValueError):
        raise ValueError(f"an interquartile mean takes numbers, one per seed for each task, not {list(tasks)!r}") \
            from None
    if not arrays or any(a.size == 0 for a in arrays):
        raise ValueError("an interquartile mean needs at least one value of every task")
    if not all(np.isfinite(a).all() for a in arrays):  # None reads as NaN, and NaN would be the answer unsaid
        raise ValueError("an interquartile mean of values that are not all finite numbers: "
                         f"{[a.tolist() for a in arrays]}")
    return arrays


def _trimmed(values: np.ndarray, axis: int = -1) -> np.ndarray:
    return scipy.stats.trim_mean(values, 0.25, axis=axis)


def iqm(*tasks: Sequence[float]) -> float:
    """The interquartile mean of every value of every task (each task: one value per seed)."""
    return float(_trimmed(np.concatenate(_tasks(tasks))))


def interval(*tasks: Sequence[float], confidence: float = CONFIDENCE, resamples: int = RESAMPLES,
             seed: int = BOOTSTRAP_SEED) -> tuple[float, float]:
    """(low, high): the percentile-bootstrap interval of `iqm(*tasks)`, each task's seeds resampled on their
    own (stratified), so that every resample holds as many runs of each task as the data. A task of one
    seed resamples to itself: with one seed in all, the interval is the value."""
    if not 0 < confidence < 1:
        raise ValueError(f"confidence={confidence!r}: a share between 0 and 1 (0.95 for a 95% interval)")
    if not isinstance(resamples, int) or resamples < 1:
        raise ValueError(f"resamples={resamples!r}: a whole number of bootstrap resamples, 1 or more ({RESAMPLES} "
                         "by default)")
    if not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed={seed!r}: a whole number, 0 or more, that seeds the bootstrap")
    arrays = _tasks(tasks)
    varied = [a for a in arrays if a.size > 1]
    if not varied:
        value = iqm(*arrays)
        return value, value
    fixed = np.concatenate([a for a in arrays if a.size == 1] or [np.empty(0)])

    def statistic(*samples: np.ndarray, axis: int) -> np.ndarray:
        constant = np.broadcast_to(fixed, samples[0].shape[:-1] + fixed.shape)
        return _trimmed(np.concatenate([*samples, constant], axis=-1))

    batch = max(1, RESAMPLED_AT_ONCE // sum(a.size for a in arrays))
    result = scipy.stats.bootstrap(varied, statistic, n_resamples=resamples, confidence_level=confidence,
                                   method="percentile", vectorized=True, axis=-1, rng=np.random.default_rng(seed),
                                   batch=batch)
    low, high = result.confidence_interval
    return float(low), float(high)


class MetricSummary(BaseModel):
    """One metric over seeds: each seed's value, their interquartile mean and its interval."""

    per_seed: dict[int, float]  # seed -> value
    iqm: float
    low: float
    high: float

    @classmethod
    def of(cls, per_seed: dict[int, float]) -> MetricSummary:
        if not isinstance(per_seed, dict):
            raise ValueError("MetricSummary.of takes each seed's value, {seed: value}, not "
                             f"{type(per_seed).__name__}")
        if not all(isinstance(seed, int) and not isinstance(seed, bool) for seed in per_seed):
            raise ValueError(f"MetricSummary.of: seeds are whole numbers, not {sorted(map(repr, per_seed))}")
        values = list(per_seed.values())
        low, high = interval(values)
        return cls(per_seed=per_seed, iqm=iqm(values), low=low, high=high)

    def text(self, digits: int) -> str:
        """'IQM [low, high]', as the tables print it."""
        return f"{self.iqm:.{digits}f} [{self.low:.{digits}f}, {self.high:.{digits}f}]"


Count = Annotated[int, Field(ge=1)]

# how an evaluation acted (fieldgen.agents.registry.EVAL_ACTIONS)
Actions = Literal[EVAL_ACTIONS]


class SeedSummary(BaseModel):
    """What summary.json (and each algorithm of compare.json) holds: success_any and time_at_goal of every
    seed of one algorithm on its fields, over the seeds, and how they were measured."""

    fields: list[str]
    # each field's fieldgen.compile.artifact.field_digest: what seeds are pooled by, since two fields may share a
    # name; empty in summaries written before it was kept, which are not pooled
    field_digests: list[str] = []
    algo: str
    runs: list[str]  # the run folders the seeds come from
    episodes: Count  # evaluation episodes per seed
    env_steps: dict[int, Annotated[int, Field(ge=0)]]  # seed -> env steps its checkpoint had trained
    # seed -> env steps its networks had trained before its run began (--init-from, and the runs before that):
    # with env_steps, what a chain of runs took from nothing learned; empty where every run started from nothing
    env_steps_before: dict[int, Annotated[int, Field(ge=0)]] = {}
    success_any: MetricSummary
    time_at_goal: MetricSummary
    # the actions the episodes took: the policy's mean ("mean"), or drawn from it as in training ("sampled")
    actions: Actions = "mean"
    confidence: Annotated[float, Field(gt=0, lt=1)] = CONFIDENCE
    command: str  # the command line that produced it

    @model_validator(mode="after")
    def _measured(self):
        """Every seed's value can be what it claims (a success rate in [0, 1], a finite time at the goal), and every
        seed has one of each, so that no interval is computed over a damaged, unmeasured or missing one."""
        for metric in METRICS:
            for seed, value in getattr(self, metric).per_seed.items():
                if (said := metric_problem(metric, value)) is not None:
                    raise ValueError(f"seed {seed}'s {said}")
        seeds = sorted(self.env_steps)
        if len(seeds) > MAX_SEEDS:
            raise ValueError(f"it holds {len(seeds):,} seeds, more than the {MAX_SEEDS:,} one run trains at most")
        if not seeds:  # fieldgen eval judges one seed at least; an interval over none has no value
            raise ValueError("it holds no seed (env_steps is empty), and fieldgen eval writes one for every seed it "
                             "judged")
        for metric in METRICS:
            if sorted(per_seed := getattr(self, metric).per_seed) != seeds:
                raise ValueError(f"{metric}.per_seed holds seeds {_seed_list(per_seed)} where env_steps holds "
                                 f"{_seed_list(self.env_steps)}: every seed has a value of each")
        if stray := sorted(set(self.env_steps_before) - set(seeds)):
            raise ValueError(f"env_steps_before holds seed {stray[0]}, which env_steps does not: it records the "
                             "seeds judged, and what each had trained before")
        if self.field_digests and len(self.field_digests) != len(self.fields):
            raise ValueError(f"field_digests holds {len(self.field_digests)} digests for {len(self.fields)} fields")
        return self

    @property
    def seeds(self) -> list[int]:
        return list(self.success_any.per_seed)

    @property
    def label(self) -> str:
        """'IQM (K seeds)', or a word that a single seed's interval is the value alone."""
        count = len(self.seeds)
        return "IQM (one seed)" if count == 1 else f"IQM ({count} seeds)"


def _seed_list(per_seed: dict) -> str:
    seeds = sorted(per_seed)
    return shown_text(", ".join(map(str, seeds))) if seeds else "none"


class SummaryError(ValueError):
    """Summaries that cannot be read, pooled or computed, said in one line naming the file."""


def summarize(fields: list[str], algo: str, runs: list[Path], episodes: int, env_steps: dict[int, int],
              per_seed: dict[str, dict[int, float]], command: str,
              env_steps_before: dict[int, int] | None = None, actions: str = "mean",
              field_digests: list[str] | None = None) -> SeedSummary:
    """A SeedSummary of `per_seed` (metric -> seed -> value, for each of METRICS); SummaryError naming the seed
    where a value cannot be what it claims (a success rate of 7.5, NaN where nothing was measured)."""
    for metric in METRICS:
        for seed, value in per_seed[metric].items():
            if (said := metric_problem(metric, value)) is not None:
                raise SummaryError(f"no summary of {', '.join(map(str, runs))}: seed {seed}'s {said}; a figure is "
                                   "computed only over values that can be what they claim: evaluate the run again "
                                   "(fieldgen eval), or restore its metrics.jsonl from a copy")
    return SeedSummary(fields=fields, field_digests=field_digests or [], algo=algo, runs=[str(r) for r in runs],
                       episodes=episodes, env_steps=env_steps, command=command, env_steps_before=env_steps_before or {},
                       actions=actions, **{metric: MetricSummary.of(per_seed[metric]) for metric in METRICS})


def read(path: Path) -> SeedSummary:
    """A summary.json that `fieldgen eval` wrote, or SummaryError naming the file and what is wrong."""
    try:
        if path.is_file() and (size := path.stat().st_size) > MAX_SUMMARY_BYTES:
            raise SummaryError(f"{path} holds {size:,} bytes, more than a summary of fieldgen eval ever does "
                               f"({MAX_SUMMARY_BYTES:,}); name the summary.json that fieldgen eval --summary wrote")
        text = path.read_bytes()
        if not text.strip():
            raise SummaryError(f"{path} is empty, not a summary of fieldgen eval; name the summary.json that "
                               "fieldgen eval --summary wrote, or evaluate the runs again")
        return SeedSummary.model_validate_json(text)
    except FileNotFoundError:
        raise SummaryError(f"{path} is missing; name a summary.json that fieldgen eval wrote") from None
    except IsADirectoryError:
        raise SummaryError(f"{path} is a folder; name the summary.json in it that fieldgen eval wrote") from None
    except ValidationError as exc:
        raise SummaryError(f"{path} is not a summary of fieldgen eval: {_first_problem(exc)}") from None


def _first_problem(exc: ValidationError) -> str:
    error = exc.errors()[0]
    where = shown_text(".".join(str(p) for p in error["loc"]))  # a key may be a text of any length
    if error["type"] == "missing":
        return f"it has no key '{where}' (fieldgen eval --summary writes one)"
    said = error["msg"].removeprefix("Value error, ")
    return f"{where}: {said}" if where else said


# what summaries pooled into one must share, and the word for it in an error: fields by their digests, since two
# fields may share a name
POOLED_ALIKE = {"field_digests": "field (the digest of its spec, though names may agree)", "fields": "field names",
                "algo": "algorithm", "actions": "actions", "episodes": "episodes per seed"}


def _shown(one: SeedSummary, key: str) -> str:
    """A value summaries must share, as an error shows it: a field by its name and its digest's start."""
    if key == "field_digests":
        return ", ".join(f"{name} {digest[:12]}" for name, digest in zip(one.fields, one.field_digests))
    return str(getattr(one, key))


def pooled(summaries: Sequence[tuple[Path, SeedSummary]], command: str) -> SeedSummary:
    """One summary over the seeds of several, each judged on its own (one seed per machine, or runs evaluated
    apart): their per-seed values, the IQM and interval over all of them. The summaries must be of one field
    and algorithm, judged on as many episodes a seed with the same actions, each seed in one of them; else
    SummaryError naming the two files."""
    if twice := named_twice(path for path, _ in summaries):
        raise SummaryError(f"{twice}: each summary's seeds are pooled once; name it once")
    (first_path, first), owners = summaries[0], {}
    for path, one in summaries:
        if not one.field_digests:
            raise SummaryError(f"{path} does not record its field's digest (an earlier fieldgen wrote it), so "
                               "seeds of two fields of one name could be pooled: evaluate its run again with "
                               "fieldgen eval, then pool")
        for key, word in POOLED_ALIKE.items():
            if getattr(one, key) != getattr(first, key):
                raise SummaryError(f"{path} and {first_path} differ in {word} ({_shown(one, key)} against "
                                   f"{_shown(first, key)}): pooled seeds must be judged alike")
        for seed in one.seeds:
            if seed in owners:
                raise SummaryError(f"seed {seed} is in both {owners[seed]} and {path}; pool each seed once")
            owners[seed] = path
    if len(owners) > MAX_SEEDS:
        raise SummaryError(f"these summaries hold {len(owners):,} seeds in all, more than the {MAX_SEEDS:,} a pooled "
                           "summary holds; pool fewer at once")
    merged = lambda key: {s: v for _, one in summaries for s, v in getattr(one, key).items()}  # noqa: E731
    per_seed = {metric: {s: v for _, one in summaries for s, v in getattr(one, metric).per_seed.items()}
                for metric in METRICS}
    return summarize(first.fields, first.algo, [r for _, one in summaries for r in one.runs], first.episodes,
                     merged("env_steps"), per_seed, command, merged("env_steps_before"), first.actions,
                     first.field_digests)


def write(summary: SeedSummary, path: Path, output: Output = EVAL) -> None:
    """summary.json as `output.command` (eval, aggregate) writes it: refused (files.NotOurs) over a file it did not
    write, such as a run's run.json or a sweep's summary.json."""
    write_file(path, (json.dumps(summary.model_dump(mode="json"), indent=1) + "\n").encode(), output)
