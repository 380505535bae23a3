"""Bootstrap intervals against hand-worked and textbook expectations, and the intervals and paired comparisons of
a bench run's rows."""
from __future__ import annotations

import math

import numpy as np
import pytest

from touchanything.inference.evaluation.bench_intervals import add_intervals, align_rows, paired_comparisons
from touchanything.inference.evaluation.bench_report import markdown
from touchanything.inference.evaluation.bootstrap import Resampler, thin_strata


def test_two_trajectories_give_the_whole_range():
    """Means of draws of {0, 1}: 0 (1/4), 0.5 (1/2), 1 (1/4) — the 2.5th and 97.5th percentiles are 0 and 1."""
    assert Resampler(["s", "s"]).interval([0.0, 1.0]) == (0.5, 0.0, 1.0)


def test_identical_values_have_no_width():
    assert Resampler(["s"] * 10).interval([0.2] * 10) == pytest.approx((0.2, 0.2, 0.2))


def test_draws_stay_within_their_split():
    """One unseen trajectory of value 1 beside two seen ones of 0: every draw holds exactly one unseen trajectory,
    so every mean is 1/3. Drawn without strata the mean would range over 0…1."""
    assert Resampler(["seen", "seen", "unseen"]).interval([0.0, 0.0, 1.0]) == pytest.approx((1 / 3, 1 / 3, 1 / 3))


def test_the_interval_matches_the_normal_approximation_for_many_trajectories():
    """100 values of spread σ: the 95 % interval's half width is close to 1.96 σ / √n (textbook, not this code)."""
    values = np.random.default_rng(5).uniform(0, 1, 100)
    mean, low, high = Resampler(["s"] * 100).interval(values)
    expected = 1.96 * values.std() / math.sqrt(100)
    assert mean == pytest.approx(values.mean())
    assert (high - low) / 2 == pytest.approx(expected, rel=0.15)
    assert low < mean < high


def test_a_paired_difference_cancels_what_two_settings_share():
    """b = a − 0.1 on every trajectory: the paired difference is exactly 0.1, though each mean alone is uncertain."""
    a = np.random.default_rng(1).uniform(0.2, 0.9, 40)
    resampler = Resampler(["s"] * 40)
    diff = resampler.difference(a, a - 0.1)
    assert diff == pytest.approx((0.1, 0.1, 0.1))
    _, low, high = resampler.interval(a)
    assert high - low > 0.1  # unpaired, the intervals of a and a − 0.1 would overlap


def test_nan_trajectories_are_left_out_as_the_official_mean_does():
    resampler = Resampler(["s"] * 3)
    assert resampler.interval([0.5, math.nan, 0.5]) == pytest.approx((0.5, 0.5, 0.5))
    mean, low, high = resampler.interval([math.nan] * 3)
    assert math.isnan(mean) and math.isnan(low) and math.isnan(high)
    with pytest.raises(ValueError, match="expected 3"):
        resampler.interval([0.1, 0.2])


def test_draws_are_the_same_for_the_same_strata():
    assert np.array_equal(Resampler(["a", "b", "b"]).indices, Resampler(["a", "b", "b"]).indices)


def bench_row(setting: str, viou: list[float], ciou: list[float]) -> dict:
    model = setting.split("/")[0]
    return {"setting": setting, "model": model, "per_trajectory": {"volumetric_iou": viou, "contact_iou": ciou}}


def test_rows_get_intervals_per_split_and_paired_comparisons():
    trajectories = [{"name": "a", "split": "test_seen"}, {"name": "b", "split": "test_seen"},
                    {"name": "c", "split": "test_unseen"}]
    rows = [bench_row("nano/torch-fp32/all", [0.5, 0.5, 0.2], [0.6, 0.6, 0.3]),
            bench_row("nano/onnx-int8/all", [0.5, 0.5, 0.1], [0.6, 0.6, 0.3]),
            bench_row("tiny/torch-fp32/all", [0.7, 0.7, 0.4], [0.6, 0.6, 0.3]),
            {"setting": "paper/torch-fp32/all", "model": "paper"}]
    add_intervals(rows, trajectories)
    nano = rows[0]
    assert nano["volumetric_iou"] == pytest.approx(0.4) and nano["volumetric_iou_ci95"] == pytest.approx([0.4, 0.4])
    assert nano["per_split"]["test_seen"] == {"trajectories": 2, "volumetric_iou": 0.5, "volumetric_iou_ci95": [0.5, 0.5],
                                              "contact_iou": 0.6, "contact_iou_ci95": [0.6, 0.6]}
    assert nano["per_split"]["test_unseen"]["volumetric_iou"] == pytest.approx(0.2)
    assert "volumetric_iou_ci95" not in rows[3]  # latency only
    comparisons = {(c["setting"], c["against"]): c for c in paired_comparisons(rows, trajectories, ("nano",))}
    assert set(comparisons) == {("nano/onnx-int8/all", "nano/torch-fp32/all"), ("tiny/torch-fp32/all", "nano/torch-fp32/all")}
    int8 = comparisons[("nano/onnx-int8/all", "nano/torch-fp32/all")]
    assert int8["kind"] == "setting" and int8["delta_volumetric_iou"] == pytest.approx([-0.1 / 3] * 3)
    assert int8["per_split"]["test_seen"]["delta_volumetric_iou"] == pytest.approx([0.0] * 3)
    assert int8["per_split"]["test_unseen"]["delta_volumetric_iou"] == pytest.approx([-0.1] * 3)
    assert comparisons[("tiny/torch-fp32/all", "nano/torch-fp32/all")]["delta_volumetric_iou"] == pytest.approx([0.2] * 3)


def test_rows_are_aligned_to_the_run_trajectories_by_name():
    rows = [bench_row("tiny/torch-fp32/all", [0.1, 0.3], [0.2, 0.4])]
    align_rows(rows, [{"name": "b"}, {"name": "a"}], [{"name": "a"}, {"name": "b"}, {"name": "c"}])
    values = rows[0]["per_trajectory"]["volumetric_iou"]
    assert values[:2] == [0.3, 0.1] and math.isnan(values[2])


def test_a_split_with_too_few_trajectories_is_named_with_its_count():
    """6 unseen trajectories gave [0.678, 0.742] on a fresh seed without a word: each split is counted."""
    assert thin_strata(["test_seen"] * 20 + ["test_unseen"] * 20) == ""
    line = thin_strata(["test_seen"] * 34 + ["test_unseen"] * 6)
    assert line.startswith("only 6 test_unseen trajectories: their intervals are wide") and "34" not in line
    assert thin_strata(["a"] * 19 + ["b"] * 3).startswith("only 19 a and 3 b trajectories")
    record = {"machine": "m", "quick": True, "accuracy_data": "d", "rows": [], "naive": {}, "targets": [],
              "trajectories": [{"name": f"t{i}", "split": "test_seen" if i < 34 else "test_unseen"} for i in range(40)]}
    assert "**Warning:** only 6 test_unseen trajectories" in markdown(record)
