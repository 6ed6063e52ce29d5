"""The statistics over seeds: the interquartile mean and its stratified bootstrap interval, on numbers whose
answers are worked out by hand, and the summary record."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
import scipy.stats

from fieldgen.run.summary import MetricSummary, SeedSummary, interval, iqm, summarize


@pytest.mark.parametrize("values,expected", [
    ([0.7], 0.7),  # one seed: its value
    ([0.2, 0.6], 0.4),  # up to three seeds a quarter of a run is cut from neither end: the mean
    ([0.0, 0.3, 0.9], 0.4),
    ([0.9, 0.1, 0.5, 0.3], 0.4),  # four: 0.1 and 0.9 cut, the mean of 0.3 and 0.5
    ([0.0, 1.0, 0.2, 0.4, 0.9], 0.5),  # five: one cut from each end (int(5 / 4)), the mean of 0.2, 0.4, 0.9
    ([0.5, 0.5, 0.5, 1.0], 0.5),  # ties: one 0.5 and the 1.0 cut
    ([100.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, -100.0], 0.5),  # eight: the outliers and a 0 and a 1 cut
])
def test_iqm_is_the_mean_of_the_middle_half(values, expected):
    assert iqm(values) == pytest.approx(expected, abs=1e-12)
    assert iqm(values) == pytest.approx(scipy.stats.trim_mean(values, 0.25))  # rliable's aggregate_iqm


def test_iqm_of_several_tasks_is_over_every_run_of_every_task():
    assert iqm([1.0, 2.0], [3.0, 4.0]) == 2.5  # four runs: 1 and 4 cut
    assert iqm([0.0, 0.0, 0.0], [9.0]) == 0.0  # 0 and 9 cut: the outlier of a task of one seed goes too
    assert iqm([0.0, 0.0], [9.0]) == 3.0  # three runs: the mean


def test_no_values_is_refused():
    with pytest.raises(ValueError, match="at least one value"):
        iqm([])
    with pytest.raises(ValueError, match="at least one value"):
        interval([0.5], [])


@pytest.mark.parametrize("call,phrase", [
    (lambda: iqm([0.5, None, 0.7]), "not all finite numbers: [[0.5, nan, 0.7]]"),  # None reads as NaN
    (lambda: interval([0.1, float("inf")]), "not all finite numbers"),
    (lambda: MetricSummary.of({0: float("nan"), 1: 0.3}), "not all finite numbers"),
    (lambda: interval([0.1, 0.5, 0.9], confidence=95), "confidence=95: a share between 0 and 1"),
    (lambda: interval([0.1, 0.5, 0.9], resamples=0), "resamples=0: a whole number of bootstrap resamples"),
    (lambda: interval([0.1, 0.5, 0.9], seed=-1), "seed=-1: a whole number, 0 or more"),
    (lambda: MetricSummary.of([0.1, 0.2]), "takes each seed's value, {seed: value}, not list"),
    (lambda: MetricSummary.of({"a": 0.1}), "seeds are whole numbers, not [\"'a'\"]"),
    (lambda: iqm(["a"]), "takes numbers, one per seed"),
])
def test_what_would_give_nan_or_a_library_error_is_refused_in_words(call, phrase):
    with pytest.raises(ValueError, match=re.escape(phrase)):
        call()


@pytest.mark.parametrize("tasks,expected", [
    ([[0.3]], (0.3, 0.3)),  # one seed: the interval is the value
    ([[0.5, 0.5, 0.5]], (0.5, 0.5)),  # ties: every resample is the same
    ([[0.0, 1.0]], (0.0, 1.0)),  # resamples 0, 0.5 or 1, a quarter of them at each end
    # stratified: every resample keeps four 5s and two of {0, 1}; of the six a run is cut from each end:
    # mean(0, 5, 5, 5) = 3.75 where both are 0 (a quarter of resamples), else mean(1, 5, 5, 5) = 4
    ([[5.0, 5.0, 5.0, 5.0], [0.0, 1.0]], (3.75, 4.0)),
    # a task of one seed resamples to itself: 0.5 and two of {0, 1}, the mean of three
    ([[0.5], [0.0, 1.0]], (0.5 / 3, 2.5 / 3)),
    # five seeds, one success: resamples with 0 or 1 successes have an IQM of 0; 2 of 5 (p 0.20) give 1/3,
    # 3 (p 0.05) 2/3, 4 or 5 (p 0.007, under the top 2.5%) 1
    ([[0.0, 0.0, 0.0, 0.0, 1.0]], (0.0, 2 / 3)),
])
def test_interval_on_numbers_worked_out_by_hand(tasks, expected):
    assert interval(*tasks) == pytest.approx(expected, abs=1e-12)


def test_the_interval_is_reproducible_and_stratified():
    values = [0.1, 0.35, 0.4, 0.55, 0.9]
    low, high = interval(values)
    assert interval(values) == (low, high)  # a generator of a fixed seed
    assert min(values) <= low < iqm(values) < high <= max(values)
    assert interval(values, seed=1) != (low, high)
    assert interval(values, confidence=0.5)[0] > low  # a narrower interval at a lower confidence
    # pooled, the same six values could resample to six 0s or six 5s; stratified they cannot
    assert interval([5.0] * 4, [0.0, 1.0]) != interval([5.0] * 4 + [0.0, 1.0])


def test_a_summary_round_trips_through_json():
    summary = summarize(["point_nav"], "crl", ["runs/point_nav-crl-0to2"], 8, {0: 1760, 1: 1760, 2: 1760},
                        {"success_any": {0: 0.25, 1: 0.5, 2: 1.0}, "time_at_goal": {0: 3.0, 1: 4.5, 2: 9.0}},
                        "fieldgen eval runs/point_nav-crl-0to2 --episodes 8")
    assert summary.success_any.iqm == pytest.approx(1.75 / 3) and summary.time_at_goal.iqm == pytest.approx(5.5)
    assert (summary.success_any.low, summary.success_any.high) == pytest.approx(interval([0.25, 0.5, 1.0]))
    assert summary.seeds == [0, 1, 2] and summary.label == "IQM (3 seeds)" and summary.confidence == 0.95
    written = json.loads(summary.model_dump_json())
    assert written["success_any"]["per_seed"] == {"0": 0.25, "1": 0.5, "2": 1.0}  # JSON keys are text
    assert SeedSummary.model_validate(written) == summary


def test_one_seed_says_so():
    summary = MetricSummary.of({4: 0.625})
    assert (summary.iqm, summary.low, summary.high) == (0.625, 0.625, 0.625)
    assert summary.text(2) == "0.62 [0.62, 0.62]"
    one = summarize(["point_nav"], "crl", ["r"], 8, {4: 800}, {"success_any": {4: 0.5}, "time_at_goal": {4: 2.0}}, "")
    assert one.label == "IQM (one seed)"
    assert np.isclose(one.time_at_goal.low, 2.0) and np.isclose(one.time_at_goal.high, 2.0)


def test_a_summary_records_how_its_episodes_acted():
    """mean unless told; each way a run can be judged (registry.EVAL_ACTIONS) is accepted, any other refused."""
    from fieldgen.agents.registry import EVAL_ACTIONS

    one = summarize(["point_nav"], "crl", ["r"], 8, {4: 800}, {"success_any": {4: 0.5}, "time_at_goal": {4: 2.0}}, "")
    assert one.actions == "mean"
    for actions in EVAL_ACTIONS:
        assert SeedSummary.model_validate({**one.model_dump(), "actions": actions}).actions == actions
    with pytest.raises(ValueError):
        SeedSummary.model_validate({**one.model_dump(), "actions": "random"})


POINT_NAV = "a" * 64  # a field's digest, as fieldgen eval records it


def one_seed_each(tmp_path, **changes):
    """summary.json files of seeds 0-4 of one recipe, each judged on its own, written as fieldgen eval does."""
    from fieldgen.run.summary import write

    success, at_goal = [0.0, 1.0, 0.2, 0.4, 0.9], [1.0, 9.0, 2.0, 4.0, 8.0]
    paths = []
    for s in range(5):
        one = summarize(["point_nav"], "crl", [f"runs/point_nav-crl-{s}"], 8, {s: 1760 + s},
                        {"success_any": {s: success[s]}, "time_at_goal": {s: at_goal[s]}}, "fieldgen eval",
                        **{"field_digests": [POINT_NAV], **(changes if s == 4 else {})})
        paths.append(tmp_path / f"s{s}" / "summary.json")
        paths[-1].parent.mkdir()
        write(one, paths[-1])
    return paths, success, at_goal


def test_summaries_of_seeds_judged_apart_pool_into_the_summary_of_all_of_them(tmp_path):
    from fieldgen.run.summary import pooled, read

    paths, success, at_goal = one_seed_each(tmp_path)
    pool = pooled([(p, read(p)) for p in paths], "fieldgen aggregate")
    together = summarize(["point_nav"], "crl", [f"runs/point_nav-crl-{s}" for s in range(5)], 8,
                         {s: 1760 + s for s in range(5)}, {"success_any": dict(enumerate(success)),
                                                           "time_at_goal": dict(enumerate(at_goal))}, "fieldgen aggregate",
                         field_digests=[POINT_NAV])
    assert pool == together and pool.success_any.iqm == pytest.approx(0.5) and pool.label == "IQM (5 seeds)"


@pytest.mark.parametrize("changes,phrase", [
    ({"actions": "sampled"}, "differ in actions (sampled against mean): pooled seeds must be judged alike"),
    ({"env_steps_before": {4: 10}}, None),  # a chain of runs pools as any other
    ({"field_digests": ["b" * 64]}, "differ in field (the digest of its spec, though names may agree) (point_nav "
                                    "bbbbbbbbbbbb against point_nav aaaaaaaaaaaa): pooled seeds must be judged alike"),
])
def test_summaries_judged_otherwise_are_refused_in_one_line(tmp_path, changes, phrase):
    from fieldgen.run.summary import SummaryError, pooled, read

    paths, _, _ = one_seed_each(tmp_path, **changes)
    read_all = [(p, read(p)) for p in paths]
    if phrase is None:
        assert pooled(read_all, "").env_steps_before == {4: 10}
        return
    with pytest.raises(SummaryError, match=rf"^{paths[4]} and {paths[0]} {re.escape(phrase)}$"):
        pooled(read_all, "")
    with pytest.raises(SummaryError, match=rf"^{paths[0]} is named twice: each summary's seeds are pooled once; "
                                           "name it once$"):
        pooled([read_all[0], read_all[0]], "")


def test_aggregate_prints_and_writes_the_pooled_seeds_and_says_what_is_wrong_in_one_line(tmp_path):
    from typer.testing import CliRunner

    from fieldgen.cli import app
    from fieldgen.run.summary import read

    runner = CliRunner()
    paths, _, _ = one_seed_each(tmp_path)
    out = tmp_path / "all.json"
    result = runner.invoke(app, ["aggregate", *map(str, paths), "--summary", str(out)])
    assert result.exit_code == 0, result.output
    said = " ".join(result.output.split())  # the console breaks lines at its width
    assert "IQM (5 seeds): success_any 0.500 [" in said and all(f"│ {s} " in result.output for s in range(5)), said
    assert read(out).seeds == [0, 1, 2, 3, 4] and "fieldgen aggregate" in read(out).command
    (tmp_path / "bad.json").write_text("{}")
    (tmp_path / "empty.json").write_text("\n")
    for args, phrase in (([str(tmp_path / "none.json")], "none.json is missing"),
                       ([str(tmp_path / "empty.json")], "empty.json is empty, not a summary of fieldgen eval"),
                       ([str(tmp_path / "bad.json")], "bad.json is not a summary of fieldgen eval: it has no key "
                                                       "'fields' (fieldgen eval --summary writes one)"),
                       ([str(tmp_path)], "is a folder"),
                       ([str(paths[0]), "--summary", str(tmp_path / "no" / "x.json")], "there is no folder"),
                       ([str(paths[0]), "--summary", str(tmp_path / "x.txt")], "give the file the .json ending")):
        result = runner.invoke(app, ["aggregate", *args])
        message = " ".join(result.output.split())  # the console breaks long paths over lines
        assert result.exit_code == 1 and phrase in message and "Traceback" not in message, result.output
        assert message.startswith("error:") and message.count("error:") == 1


@pytest.mark.parametrize("metric", ["success_any", "time_at_goal"])
def test_a_summary_whose_seeds_do_not_line_up_is_refused_naming_the_file(tmp_path, metric):
    """Before: seed 4's value missing from one metric was a KeyError traceback in fieldgen aggregate."""
    from fieldgen.run.summary import SummaryError, read

    paths, _, _ = one_seed_each(tmp_path)
    saved = json.loads(paths[4].read_text())
    saved[metric]["per_seed"] = {"3": 0.5}
    paths[4].write_text(json.dumps(saved))
    with pytest.raises(SummaryError, match=rf"^{paths[4]} is not a summary of fieldgen eval: {metric}.per_seed holds "
                                           r"seeds 3 where env_steps holds 4: every seed has a value of each$"):
        read(paths[4])


def test_a_summary_that_does_not_record_its_fields_digest_is_not_pooled(tmp_path):
    """Two fields may share a name (the bundled point_nav and one of your own): a summary without its field's
    digest cannot say which it judged, so it is evaluated again rather than pooled by name."""
    from fieldgen.run.summary import SummaryError, pooled, read

    paths, _, _ = one_seed_each(tmp_path, field_digests=[])
    with pytest.raises(SummaryError, match=rf"^{paths[4]} does not record its field's digest .*evaluate its run "
                                           "again with fieldgen eval, then pool$"):
        pooled([(p, read(p)) for p in paths], "")


@pytest.mark.parametrize("value,phrase", [
    ("7.5", "seed 4's success_any is 7.5, outside its range (from 0 to 1)"),
    ("NaN", "seed 4's success_any is NaN: it was not measured"),
    ("-1.0", "seed 4's success_any is -1.0, outside its range (from 0 to 1)"),
])
def test_aggregate_refuses_a_seed_whose_success_cannot_be_a_rate_rather_than_average_it(tmp_path, value, phrase):
    from typer.testing import CliRunner

    from fieldgen.cli import app

    paths, _, _ = one_seed_each(tmp_path)
    edited = json.loads(paths[4].read_text())
    edited["success_any"]["per_seed"]["4"] = "@"
    paths[4].write_text(json.dumps(edited).replace('"@"', value))
    out = tmp_path / "all.json"
    result = CliRunner().invoke(app, ["aggregate", *map(str, paths), "--summary", str(out)])
    message = " ".join(result.output.split())
    assert result.exit_code == 1 and message.startswith(f"error: {paths[4]} is not a summary of fieldgen eval: "
                                                        f"{phrase}"), result.output
    assert "Traceback" not in message and not out.exists()


@pytest.mark.parametrize("metric,value", [("success_any", 7.5), ("success_any", float("nan")),
                                          ("time_at_goal", float("inf")), ("time_at_goal", -2.0)])
def test_no_summary_is_computed_over_a_value_that_cannot_be_what_it_claims(metric, value):
    from fieldgen.run.summary import SummaryError

    per_seed = {"success_any": {0: 0.5, 1: 0.25}, "time_at_goal": {0: 2.0, 1: 3.0}}
    per_seed[metric][1] = value
    with pytest.raises(SummaryError, match=rf"^no summary of runs/a: seed 1's {metric} is "):
        summarize(["point_nav"], "crl", ["runs/a"], 8, {0: 800, 1: 800}, per_seed, "")


def test_aggregate_refuses_a_summary_of_no_seeds_naming_it(tmp_path):
    """Before: a summary.json edited down to no seeds was read, and pooling it alone ended in a ValueError traceback
    from the interquartile mean."""
    from typer.testing import CliRunner

    from fieldgen.cli import app

    paths, _, _ = one_seed_each(tmp_path)
    emptied = json.loads(paths[0].read_text())
    emptied["env_steps"], emptied["success_any"]["per_seed"], emptied["time_at_goal"]["per_seed"] = {}, {}, {}
    paths[0].write_text(json.dumps(emptied))
    result = CliRunner().invoke(app, ["aggregate", str(paths[0])])
    assert result.exit_code == 1 and "Traceback" not in result.output, result.output
    assert " ".join(result.output.split()) == (f"error: {paths[0]} is not a summary of fieldgen eval: it holds no seed "
                                               "(env_steps is empty), and fieldgen eval writes one for every seed it "
                                               "judged")


def test_a_summary_key_of_any_length_is_quoted_by_its_start(tmp_path):
    """Before: a seed key of thousands of digits was quoted whole in the one-line refusal."""
    from fieldgen.run.summary import SummaryError, read

    paths, _, _ = one_seed_each(tmp_path)
    edited = json.loads(paths[0].read_text())
    edited["success_any"]["per_seed"] = {"1" * 5000: 0.5}
    paths[0].write_text(json.dumps(edited))
    with pytest.raises(SummaryError) as caught:
        read(paths[0])
    assert "success_any.per_seed.111" in str(caught.value) and "(5,027 characters)" in str(caught.value)
    assert len(str(caught.value)) < 300 + len(str(paths[0]))


@pytest.mark.parametrize("edit,phrase", [
    (lambda d: d["env_steps"].update({"4": -5}), "env_steps.4: Input should be greater than or equal to 0"),
    (lambda d: d.update(confidence=2), "confidence: Input should be less than 1"),
    (lambda d: d.update(env_steps_before={"9": 10}), "env_steps_before holds seed 9, which env_steps does not"),
])
def test_a_summary_edited_past_what_eval_writes_is_refused_at_its_key(tmp_path, edit, phrase):
    """Before: a negative env_steps, a confidence of 2 and the env steps before a seed the summary lacks were read
    and pooled."""
    from fieldgen.run.summary import SummaryError, read

    paths, _, _ = one_seed_each(tmp_path)
    edited = json.loads(paths[4].read_text())
    edit(edited)
    paths[4].write_text(json.dumps(edited))
    with pytest.raises(SummaryError, match=re.escape(f"{paths[4]} is not a summary of fieldgen eval: {phrase}")):
        read(paths[4])


def test_a_summary_of_more_seeds_than_a_run_trains_is_refused_before_any_bootstrap(tmp_path):
    """Before: a summary.json of 200,000 seeds (9 MB) was read and bootstrapped in gigabytes of memory for minutes."""
    from fieldgen.limits import MAX_SEEDS
    from fieldgen.run.summary import SummaryError, read

    paths, _, _ = one_seed_each(tmp_path)
    edited = json.loads(paths[0].read_text())
    many = {str(s): 0.5 for s in range(MAX_SEEDS + 1)}
    edited["env_steps"] = {s: 800 for s in many}
    edited["success_any"]["per_seed"], edited["time_at_goal"]["per_seed"] = many, many
    paths[0].write_text(json.dumps(edited))
    with pytest.raises(SummaryError, match=re.escape(f"{paths[0]} is not a summary of fieldgen eval: it holds "
                                                     "65,537 seeds, more than the 65,536 one run trains at most")):
        read(paths[0])
    paths[1].write_bytes(b" " * (33 * 2**20))
    with pytest.raises(SummaryError, match=re.escape(f"{paths[1]} holds 34,603,008 bytes, more than a summary")):
        read(paths[1])


def test_the_bootstrap_of_many_seeds_is_drawn_in_batches_with_the_same_answer(monkeypatch):
    """Every resample at once held resamples x seeds values: 65,536 seeds took gigabytes. Batches bound it."""
    import fieldgen.run.summary as summary

    values = np.random.default_rng(3).random(40)
    whole = interval(values)
    monkeypatch.setattr(summary, "RESAMPLED_AT_ONCE", 40 * 7)  # seven resamples a batch
    assert interval(values) == pytest.approx(whole)


def test_summaries_of_one_digest_under_two_names_are_not_pooled(tmp_path):
    """Before: a summary edited to another field name was pooled, the result carrying the first's name alone."""
    from fieldgen.run.summary import SummaryError, pooled, read

    paths, _, _ = one_seed_each(tmp_path)
    edited = json.loads(paths[4].read_text())
    edited["fields"] = ["point_far"]
    paths[4].write_text(json.dumps(edited))
    with pytest.raises(SummaryError, match=re.escape(f"{paths[4]} and {paths[0]} differ in field names (['point_far'] "
                                                     "against ['point_nav']): pooled seeds must be judged alike")):
        pooled([(p, read(p)) for p in paths], "")
