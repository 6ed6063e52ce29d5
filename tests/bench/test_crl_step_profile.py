"""bench/crl_step_profile.py: kernels summarised per iteration and per gradient step, the loop of gradient
steps found in compiled HLO, and the whole script on a CPU, tiny."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "bench" / "crl_step_profile.py"
sys.path.insert(0, str(ROOT / "bench"))
import crl_step_profile as profile  # noqa: E402

sys.path.remove(str(ROOT / "bench"))


def kernel(name: str, ts: float, dur: float) -> dict:
    return {"ph": "X", "pid": 1, "tid": 7, "ts": ts, "dur": dur, "name": name}


def test_a_gradient_step_is_the_difference_of_two_iterations_per_extra_step():
    # two traced iterations each: 3 gradient steps' kernels, then 5 (numbered apart, as two programs number them)
    def iteration(steps, offset, number):
        collect = [kernel("loop_step_fusion_1", offset, 40)]
        update = [k for i in range(steps) for k in (kernel(f"gemm_fusion_dot_{number}", offset + 50 + 10 * i, 6),
                                                    kernel(f"loop_adam_fusion_{number}", offset + 56 + 10 * i, 2))]
        return collect + update

    fewer = profile.summary(iteration(3, 0, 4) + iteration(3, 1000, 4), 2, small_us=5)
    more = profile.summary(iteration(5, 0, 9) + iteration(5, 1000, 9), 2, small_us=5)
    assert fewer["kernels"] == 7 and fewer["kernel_us"] == 40 + 3 * 8 and fewer["small_kernels"] == 3
    assert fewer["busy_us"] == 40 + 3 * 8
    step = profile.per_step(fewer, more, 2)
    assert step["kernels"] == 2 and step["kernel_us"] == 8 and step["small_kernels"] == 1
    assert step["small_kernel_us"] == 2
    rows = profile.top_rows(step["by_kind"], step["kernel_us"], 10)
    assert [(r["name"], r["us"], r["share"]) for r in rows] == [("gemm_fusion_dot", 6, 0.75),
                                                                 ("loop_adam_fusion", 2, 0.25)]


def test_fusions_are_counted_in_compiled_hlo():
    text = """
  %fusion.3 = f32[4,4]{1,0} fusion(f32[4]{0} %p), kind=kLoop, calls=%fused_computation.3
  %loop_add_fusion = (f32[4]{0}, s32[]) fusion(%a, %b), kind=kLoop, calls=%fused_add
  %custom-call.1 = f32[4,4]{1,0} custom-call(%x), custom_call_target="__cublas$gemm"
  ROOT %fusion = f32[] fusion(%c), kind=kInput, calls=%fused_reduce
"""
    assert profile.fusion_count(text) == 3


def chunk_hlo(update_trips: int) -> str:
    """A compiled chunk's text: a loop of 10 collect steps, then the loop of gradient steps, whose body calls a
    computation of its own."""
    return f"""
%collect_body (arg.1: (s32[], f32[4])) -> (s32[], f32[4]) {{
  %cosine_fusion = f32[4]{{0}} fusion(%gte.1), kind=kLoop, calls=%fused_cos
}}
%adam (param.9: f32[4]) -> f32[4] {{
  ROOT %adam_fusion.2 = f32[4]{{0}} fusion(%param.9), kind=kLoop, calls=%fused_adam
}}
%update_body (arg.2: (s32[], f32[4])) -> (s32[], f32[4]) {{
  %dot.7 = f32[4]{{0}} dot(%gte.2, %gte.2)
  %call.3 = f32[4]{{0}} call(%dot.7), to_apply=%adam
}}
ENTRY %main.1 (x.1: f32[4]) -> f32[4] {{
  %while.1 = (s32[], f32[4]{{0}}) while(%t.1), condition=%c1, body=%collect_body, backend_config={{"known_trip_count":{{"n":"10"}}}}
  ROOT %while.2 = (s32[], f32[4]{{0}}) while(%t.2), condition=%c2, body=%update_body, backend_config={{"known_trip_count":{{"n":"{update_trips}"}}}}
}}
"""


def test_the_loop_of_gradient_steps_is_the_one_whose_trip_count_changed():
    loops, other = profile.hlo_loops(chunk_hlo(6)), profile.hlo_loops(chunk_hlo(12))
    assert [(trips, sorted(names)) for trips, names in loops] == [
        (10, ["cosine_fusion"]), (6, ["adam_fusion.2", "call.3", "dot.7"])]
    # 13 and 25 gradient steps, two a loop iteration: the body runs 12 of the 13
    assert profile.update_loop(loops, other, 13, 25) == ({"adam_fusion.2", "call.3", "dot.7"}, 12)
    # a loop the other chunk has once more (the physics steps of each variant, say) is no gradient step
    assert profile.update_loop([(5, {"step"}), (6, {"dot.7"})], [(5, set()), (5, set()), (12, set())], 12, 25) == (
        {"dot.7"}, 12)
    assert profile.update_loop(loops, loops, 13, 13) is None  # nothing changed
    assert profile.update_loop(profile.hlo_loops(chunk_hlo(10)), other, 20, 25) is None  # two loops of 10


@pytest.mark.parametrize("options, message", [
    (["--field", "no_such_field"], "no_such_field: neither a file nor a bundled field"),
    (["--field", "point_nav", "--set", "crl.batch_size=100000"], "hold fewer transitions than one batch"),
    (["--traced", "0"], "--envs, --traced, --top and --windows are positive"),
])
def test_bad_input_is_one_clear_line(monkeypatch, capsys, options, message):
    monkeypatch.setattr(sys, "argv", ["crl_step_profile.py", *options])
    with pytest.raises(SystemExit) as stopped:
        profile.main()
    assert stopped.value.code != 0 and message in str(stopped.value.code) + capsys.readouterr().err


@pytest.mark.slow
def test_the_script_profiles_a_tiny_run_on_cpu(tmp_path):
    out = tmp_path / "rows.jsonl"
    result = subprocess.run(
        [sys.executable, str(SCRIPT), "--field", "point_nav", "--envs", "4", "--traced", "1", "--top", "3",
         "--set", "crl.hidden=[16,16]", "--set", "crl.repr_dim=8", "--set", "crl.batch_size=32",
         "--set", "crl.unroll_length=10", "--set", "crl.min_replay_rows=20", "--set", "crl.max_replay_rows=100",
         "--profile", str(tmp_path / "traces"), "--json", str(out)],
        capture_output=True, text=True, cwd=tmp_path, timeout=900)
    assert result.returncode == 0, result.stderr[-2000:]
    assert "backend: cpu" in result.stdout and "profiled: CPU host operations" in result.stdout
    iteration, step = (json.loads(line) for line in out.read_text().splitlines())
    assert iteration["part"] == "iteration" and step["part"] == "gradient_step"
    assert iteration["kernels"] > 0 and iteration["kernel_us"] > 0 and iteration["fusions"] > 0
    assert iteration["gradient_steps"] >= 1 and iteration["flops"] > 0 and 1 <= len(iteration["top"]) <= 3
    assert step["gradient_steps"][1] > step["gradient_steps"][0] == iteration["gradient_steps"]
    # a CPU's trace names each operation's HLO instruction: the gradient step is the loop's body, not a difference
    assert step["method"].startswith("the kernels of the compiled loop of gradient steps")
    assert 0 < step["kernels"] < iteration["kernels"] and 0 < step["kernel_us"] < iteration["kernel_us"]
    assert step["windows"][1] == 2 * step["windows"][0]
    assert sorted(p.name for p in (tmp_path / "traces").iterdir()) == ["iteration", f"windows_{step['windows'][1]}"]
