"""What `benchmarks/mutation.py` mutates: the modules, each with the narrowest tests that cover it, and the
cosmic-ray operators run on them."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Module:
    path: str
    tests: tuple[str, ...]
    pytest_args: tuple[str, ...] = ()
    functions: tuple[str, ...] = ()
    """Only the mutants inside these functions / methods / classes (cosmic-ray's definition name); () all."""


_LEROBOT_TESTS = ("tests/devices/test_lerobot_format.py", "tests/devices/test_lerobot_writer.py", "tests/devices/test_lerobot_reader.py",
                  "tests/devices/test_lerobot_features.py", "tests/devices/test_lerobot.py")
_LEROBOT_K = ("-k", "not bundled_sample and not eval_and_replay")
"""The LeRobot writer (with its format) and reader: the export and read-back tests, without the two that export the
whole bundled sample and run eval and replay on it (25 s; they add the commands end to end)."""

MODULES = {
    "metrics": Module("inference/evaluation/metrics.py", ("tests/inference/test_metrics.py",),
                      ("-k", "not million")),  # the million-frame float64 test takes 10 s and sees no operator mutant
    "evaluation_summary": Module("inference/evaluation/evaluation.py", ("tests/inference/test_evaluation_summary.py",),
                                 functions=("trajectory_metrics", "EvaluationResult", "label", "summary",
                                            "vision_share_summary")),  # not `evaluate`: it runs a model
    "frame_facts": Module("viz/frame_facts.py", ("tests/viz/test_frame_facts.py",),
                          ("-k", "not video")),  # the replay → video, summary, recording test: 5 s, integration only
    "frame_ring": Module("inference/engine/frame_ring.py", ("tests/inference/test_frame_ring.py", "tests/inference/test_streaming.py"),
                         ("-k", "not official_offline")),  # 14 s: the stitched output against the offline protocol
    "streaming_engine": Module("inference/engine/streaming_engine.py", ("tests/inference/test_streaming.py",),
                               ("-k", "not official_offline")),
    "tactile_layout": Module("core/tactile_layout.py", ("tests/core/test_tactile_layout.py",)),
    "output_safety": Module("core/output_safety.py", ("tests/core/test_output_safety_helpers.py", "tests/timing/test_output_safety.py"),
                            ("-k", "output_safety_helpers or replacing or check_output_cases")),  # not the commands run end to end
    **{name: Module(f"devices/episodes/{name}.py", _LEROBOT_TESTS, _LEROBOT_K)
       for name in ("lerobot_writer", "lerobot_episode", "lerobot_format")},
    "lerobot_stats": Module("devices/episodes/lerobot_stats.py",
                            ("tests/devices/test_lerobot_stats.py", "tests/devices/test_lerobot_features.py"),
                            ("-k", "lerobot_stats or quantiles or statistics")),  # hand-worked, and of an export
}
"""The modules under test, in priority order, each with the narrowest tests that cover it (each mutant runs them)."""

_BINARY = ("Add_Sub", "Sub_Add", "Mul_Div", "Div_Mul", "FloorDiv_Div", "Mod_FloorDiv", "Pow_Mul", "BitAnd_BitOr",
           "BitOr_BitAnd", "BitXor_BitOr", "LShift_RShift", "RShift_LShift")
_COMPARISON = ("Lt_LtE", "Lt_GtE", "LtE_Lt", "LtE_Gt", "Gt_GtE", "Gt_LtE", "GtE_Gt", "GtE_Lt", "Eq_NotEq",
               "NotEq_Eq", "Is_IsNot", "IsNot_Is", "In_NotIn", "NotIn_In")
_UNARY = ("USub_UAdd", "Delete_Not", "Delete_Invert")
OPERATORS = (
    [f"core/ReplaceBinaryOperator_{pair}" for pair in _BINARY]
    + [f"core/ReplaceComparisonOperator_{pair}" for pair in _COMPARISON]
    + [f"core/ReplaceUnaryOperator_{pair}" for pair in _UNARY]
    + [f"core/{name}" for name in ("NumberReplacer", "AddNot", "ReplaceTrueWithFalse", "ReplaceFalseWithTrue",
                                   "ReplaceAndWithOr", "ReplaceOrWithAnd", "ReplaceBreakWithContinue",
                                   "ReplaceContinueWithBreak", "ExceptionReplacer", "RemoveDecorator",
                                   "ZeroIterationForLoop")])
"""The operators run. cosmic-ray replaces every binary operator by each of the 10 others and every comparison by
each of the 7 others (615 mutants in metrics.py alone, most of them `+` → `<<` and the like); these keep one
natural replacement per binary operator (as mutmut does), the off-by-one and the negated boundary per ordering
comparison, the negation of (in)equality, identity and membership, and every other core operator."""
