"""bars: the plot of a results page whose answer is a table of numbers."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "bench"))
import bars  # noqa: E402

sys.path.remove(str(ROOT / "bench"))


def test_a_bar_reads_its_group_label_and_value_with_thousands_separators():
    assert bars.bar("one seed:width 256=56,900") == ("one seed", "width 256", 56900.0)
    assert bars.bar("a=b=1.5") == ("", "a=b", 1.5)  # the value is after the last '='
    for wrong in ("no value", "=3", "x=fast"):
        with pytest.raises(argparse.ArgumentTypeError):
            bars.bar(wrong)


def test_the_plot_is_written_and_a_reference_that_names_no_bar_is_refused(tmp_path):
    given = [bars.bar("before=36049"), bars.bar("after=147038")]
    bars.draw(given, tmp_path / "b.png", "title", "env steps/s", reference="before")
    assert (tmp_path / "b.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(SystemExit, match="names no bar; the bars are: before, after"):
        bars.draw(given, tmp_path / "c.png", "title", "env steps/s", reference="during")
    assert not (tmp_path / "c.png").exists()
