"""The range of every number a person gives fieldgen, on the command line or in a sweep file, kept in one place so
that a value is checked against the same bounds wherever it is given, and before any work starts: a number
past its range is refused in one line that states the range, never left to end in a traceback, a wait
without end or memory that runs out. docs/guarantees.md lists them."""

from __future__ import annotations

import dataclasses
from decimal import Decimal, InvalidOperation

SEED_MAX = 2**32 - 1  # a random key takes 32 bits of seed: 2**32 would give seed 0's key
MAX_SEEDS = 65_536  # seeds vmapped in one run: their list is written in run.json and their keys made at once
MAX_STAGES = 1000  # stages of one curriculum, written or read
COUNT_MAX = 10**15  # a count on the command line (--steps, --envs, --episodes): far past any run's
TIME_LIMIT_SECONDS = 10**9  # a time limit, in seconds: some thirty years
MAX_DIGITS = 100  # of a number in a file or on the command line: a float's range ends at 309, any real one at far fewer
SWEEP_RUNS = 10_000  # runs one sweep plans; counted before they are, so that a sweep of millions takes no memory


@dataclasses.dataclass(frozen=True)
class Range:
    """The whole numbers (or, not `whole`, the numbers) from `low` to `high`, both included, and what they count."""

    low: int | float
    high: int | float
    what: str
    whole: bool = True

    def text(self) -> str:
        return f"{'a whole number' if self.whole else 'a number'} from {self.low:,} to {self.high:,}"

    def problem(self, value) -> str | None:
        """Why `value` is out of this range (None where it is in it)."""
        if isinstance(value, bool) or not isinstance(value, (int, float)) or value != value \
                or not self.low <= value <= self.high or (self.whole and value != int(value)):
            return f"{self.what} is {self.text()}"
        return None


LEVELS = Range(2, 64, "the automatic curriculum's levels (an easy end and the field itself at least; each is "
                      "built and simulated in every batch)")
SEED = Range(0, SEED_MAX, "a seed (a random key takes 32 bits)")
SEEDS = Range(1, MAX_SEEDS, "seeds trained at once")
STAGES = Range(2, MAX_STAGES, "a curriculum's stages, both ends included")
THEN_STAGES = Range(1, MAX_STAGES, "the stages each --then adds")
PROCESSES = Range(1, MAX_SEEDS, "the processes of one run")
PROCESS_ID = Range(0, MAX_SEEDS - 1, "a process's id (0 to --num-processes - 1)")
COORDINATOR_TIMEOUT = Range(1, 86_400, "the seconds to wait for the coordinator and the other processes (a day "
                                       "at most)")
ROLLOUT_STEPS = Range(1, 1_000_000, "the steps of a timed rollout")
SLURM_MINUTES = Range(1, 525_600, "the minutes of a SLURM task (a year at most: a run's --time-limit takes it)")
GPUS_PER_TASK = Range(0, 64, "the GPUs of one task")
CPUS_PER_TASK = Range(1, 4096, "the CPUs of one task")
MEMORY_GB = Range(1, 65_536, "the gigabytes of memory of one task")
REQUEUES = Range(0, 1000, "the times a task is requeued")
GPU_INDEX = Range(0, 1023, "a GPU's index")

assert SLURM_MINUTES.high * 60 < TIME_LIMIT_SECONDS  # a task's minutes are a run's --time-limit


def not_boolean(value):
    """A setting's number as YAML or JSON gave it, for pydantic to read (a BeforeValidator): true and false are
    refused, where pydantic would take them as 1 and 0, as numbers are not booleans (StrictBool)."""
    if isinstance(value, bool):
        raise ValueError("a boolean is not a number")
    return value


def number(text: str | int | float, whole: bool = True) -> int | float | None:
    """`text` as people write a number (40000, 2e6, 1_000) read exactly, or None where it is none, or longer
    than MAX_DIGITS (a value of thousands of digits is refused, not converted at length)."""
    cleaned = str(text).strip().replace("_", "")
    if len(cleaned) > MAX_DIGITS:
        return None
    try:
        value = Decimal(cleaned)
    except InvalidOperation:
        return None
    if not value.is_finite() or abs(value.adjusted()) > MAX_DIGITS:
        return None
    if whole:
        return int(value) if value == value.to_integral_value() else float(value)
    return float(value)

NAME_BYTES = 255  # of one file or folder name, as file systems allow
PATH_BYTES = 4096  # of a whole path (Linux's PATH_MAX)
