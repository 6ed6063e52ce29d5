"""The names the command line offers before JAX loads: the algorithms, the named presets, how a judged
policy acts.

An algorithm is a folder of this package holding its settings (config.py) and its training function
(train.py); its name is the folder's, read from the folder list here without importing it. The registry
(registry.py) loads an algorithm by that name; the configs read these names without importing the registry,
which imports them.
"""

from __future__ import annotations

from pathlib import Path

ALGORITHMS: tuple[str, ...] = tuple(sorted(folder.name for folder in Path(__file__).parent.iterdir()
                                           if (folder / "config.py").is_file() and (folder / "train.py").is_file()))
DEFAULT_ALGORITHM = "crl"  # what `fieldgen train` trains a field with when neither --algo nor a recipe names one
# named presets, `--preset NAME`: agents/presets/NAME.yaml, settings of every trainer sized for a kind of machine
PRESETS: tuple[str, ...] = ("cpu",)
# how a policy acts when it is judged (a run's evaluations, `eval_actions`; fieldgen eval --actions): its mean
# action, or actions drawn from it as in training, where the mean alone may do less (or more)
EVAL_ACTIONS: tuple[str, ...] = ("mean", "sampled")


def judged_on(actions: str) -> str:
    """What a figure's title adds about the actions it was judged on: nothing for the mean action."""
    return ", actions sampled from the policy" if actions == "sampled" else ""
