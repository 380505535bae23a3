"""A setting chosen for a budget, watched while it runs: a replay chosen at 4.79 ms probed ran at p99 16.2 ms and
its summary still said "within 5 ms". Hand-worked percentiles (numpy's linear interpolation)."""
from __future__ import annotations

import numpy as np

from touchanything.app.sessions.budget_watch import BudgetWatch


def test_an_overrun_is_said_once_during_the_run_from_the_sixtieth_step_every_thirtieth():
    watch = BudgetWatch("pico/onnx-int8/all", 5.0, 4.79)
    slow = [16.2] * 120
    assert [watch.during(slow[:n]) for n in (1, 30, 59)] == [None, None, None]  # too few steps to judge
    assert watch.during(slow[:61]) is None  # between two checks
    assert watch.during(slow[:60]) == ("over budget: pico/onnx-int8/all steps at p99 16.20 ms so far, over the 5 ms it "
                                       "was chosen for (probed 4.79 ms)")
    assert watch.during(slow[:90]) is None and watch.during(slow) is None  # said once


def test_a_run_within_its_budget_says_nothing_during_and_within_after():
    watch = BudgetWatch("pico/onnx-int8/all", 100.0, 4.0)
    steps = [float(k) for k in range(1, 101)]  # p99 = 1 + 0.99 × 99 = 99.01
    assert watch.during(steps[:60]) is None and watch.during(steps[:90]) is None
    assert watch.after(float(np.percentile(steps, 99))) == (
        "budget    p99 99.01 ms per engine step in this run: within the 100 ms budget (probed 4.00 ms before the run)")
    assert BudgetWatch("x/torch-fp32/all", 99.0, 4.0).after(99.01).startswith("budget    p99 99.01 ms per engine "
                                                                                 "step in this run: OVER the 99 ms")
    assert watch.after(None) == ""
