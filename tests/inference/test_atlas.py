"""The atlas read back: setting names, the choice a latency budget makes, `bench --budget-ms` and the `--setting`
option of replay, with the bad inputs of each (one line, exit 2, nothing written)."""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from helpers.atlas_file import atlas_row, write_atlas
from touchanything.app.cli import main
from touchanything.app.sessions.bundled import bundled_models, sample_episodes
from touchanything.core.errors import UserError
from touchanything.core.snapshot import VIEW_NAMES
from touchanything.inference.engine.engine_setting import EngineSetting, parse_setting
from touchanything.inference.evaluation.atlas import choose_within_budget, file_sha256, read_atlas, rows_for
from touchanything.inference.evaluation.bench_setting import settings_for


def test_every_grid_setting_reads_back_from_its_name():
    for setting in settings_for("nano", quick=False, pose_only=True):  # bench runs on the CPU; a name has no device
        assert parse_setting(setting.name()) == dataclasses.replace(setting, device="auto") and setting.device == "cpu"
    assert EngineSetting("nano", "onnx", "int8").name() == "nano/onnx-int8/all"
    assert parse_setting("nano/torch-fp32/ego+left") == EngineSetting("nano", views=("ego", "wrist_left"))
    assert parse_setting("nano/onnx-int8/all/every2").every == 2
    assert parse_setting("tiny/torch-fp32/all/stitched").output == "stitched"
    assert parse_setting("paper/torch-tf32/all").precision == "tf32"


@pytest.mark.parametrize("name, message", [
    ("nano", "not a setting name"), ("nano/onnx-bf16/all", "unknown runtime-precision 'onnx-bf16'"),
    ("nano/torch-fp32/head", "unknown views 'head'"), ("nano/torch-fp32/all/every0", "unknown part 'every0'"),
    ("nano/torch-fp32/all/fast", "unknown part 'fast'"), ("nano/torch-fp32/all/every1", "did you mean nano/torch-fp32/all?"),
])
def test_bad_setting_names_say_which_part_is_wrong(name, message):
    with pytest.raises(UserError, match=message):
        parse_setting(name)


@pytest.fixture(scope="module")
def shas() -> dict[str, str]:
    return {name: file_sha256(path) for name, path in bundled_models().items()}


@pytest.fixture
def atlas(tmp_path) -> Path:
    return write_atlas(tmp_path / "engine.json")


def test_the_atlas_rows_of_the_models_here_most_accurate_first(atlas):
    rows = rows_for(read_atlas(atlas), bundled_models(), atlas)
    assert [row.name for row in rows] == ["nano/torch-fp32/all", "nano/onnx-int8/ego", "baseline_pose/onnx-int8/all"]
    assert rows[0].accuracy_line() == ("V-IoU 0.600 [0.580, 0.620], C-IoU 0.700 [0.680, 0.720] on 108 held-out "
                                       "trajectories")


def test_a_budget_picks_the_most_accurate_setting_that_fits(atlas):
    rows = rows_for(read_atlas(atlas), bundled_models(), atlas)
    p99 = {"nano/torch-fp32/all": 9.0, "nano/onnx-int8/ego": 2.5, "baseline_pose/onnx-int8/all": 0.7}
    measured = []

    def measure(row):
        measured.append(row.name)
        return p99[row.name]

    choice = choose_within_budget(rows, 3.0, measure, progress=lambda line: None)
    assert choice.row.name == "nano/onnx-int8/ego" and choice.p99_ms == 2.5
    assert measured == ["nano/torch-fp32/all", "nano/onnx-int8/ego"]  # the less accurate one is never probed
    assert choose_within_budget(rows, 10.0, measure, progress=lambda line: None).row.name == "nano/torch-fp32/all"
    with pytest.raises(UserError, match=r"no setting fits 0.5 ms on this machine: the fastest, baseline_pose/onnx-int8/all, "
                                        r"took p99 0.70 ms here"):
        choose_within_budget(rows, 0.5, measure, progress=lambda line: None)
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(UserError, match="--budget-ms must be a finite number > 0"):
            choose_within_budget(rows, bad, measure, progress=lambda line: None)


def test_a_budget_counts_the_look_ahead_of_centre_and_stitched_outputs(atlas, shas):
    from touchanything.inference.evaluation.atlas import AtlasRow, choice_line

    rows = [row for row in (AtlasRow(parse_setting(r["setting"]), r["checkpoint_sha256"], 108, r["volumetric_iou"],
                                     tuple(r["volumetric_iou_ci95"]), r["contact_iou"], tuple(r["contact_iou_ci95"]),
                                     r["p99_ms"])
                            for r in (atlas_row("nano/torch-fp32/all/stitched", shas["nano"], 0.62, 8.0),
                                      atlas_row("nano/torch-fp32/all/centre", shas["nano"], 0.61, 8.0),
                                      atlas_row("nano/torch-fp32/all", shas["nano"], 0.60, 8.0)))]
    measured = []

    def measure(row):
        measured.append(row.name)
        return 8.0

    # 1000 / 30 × 6 = 200 ms for the centre frame, × 14 = 466.7 ms stitched: 8 + 200 fits 210 ms, 8 + 466.7 does not
    choice = choose_within_budget(rows, 210.0, measure, progress=lambda line: None)
    assert choice.row.name == "nano/torch-fp32/all/centre" and measured == ["nano/torch-fp32/all/centre"]
    assert "p99 8.00 ms here + look-ahead 200 ms, within 210 ms; 1 more accurate setting(s) show their frame too " \
           "late" in choice_line(choice, 210.0)
    measured.clear()
    choice = choose_within_budget(rows, 207.0, measure, progress=lambda line: None)  # 208 ms: over
    assert choice.row.name == "nano/torch-fp32/all" and measured == ["nano/torch-fp32/all/centre", "nano/torch-fp32/all"]
    assert choose_within_budget(rows, 475.0, measure, progress=lambda line: None).row.name == "nano/torch-fp32/all/stitched"
    with pytest.raises(UserError, match="every setting of the atlas waits longer for its output"):
        choose_within_budget(rows[:2], 150.0, measure, progress=lambda line: None)


def run_main(argv, capsys) -> tuple[int, str, str]:
    code = main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_bench_budget_probes_here_and_prints_the_command(atlas, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_main(["bench", "--budget-ms", "10000", "--quick", "--atlas", str(atlas)], capsys)
    assert code == 0, err
    assert "probe nano/torch-fp32/all: p99" in out and "fits 10000 ms" in out
    assert "setting nano/torch-fp32/all: V-IoU 0.600 [0.580, 0.620]" in out and "the most accurate setting" in out
    assert f"run it:  touchanything demo --setting nano/torch-fp32/all --atlas {atlas}" in out
    assert not (tmp_path / "recordings").exists()  # nothing written


def test_bench_budget_bad_inputs_are_one_line_and_write_nothing(atlas, tmp_path, capsys, monkeypatch, shas):
    monkeypatch.chdir(tmp_path)
    damaged = tmp_path / "damaged.json"
    damaged.write_text('{"rows": [{"setting": "nano/torch-fp32/all"')
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"rows": [atlas_row("nano/torch-fp32/all", "f" * 64, 0.6, 8.0)]}))
    empty = tmp_path / "empty.json"
    empty.write_text(json.dumps({"rows": [{"setting": "paper/torch-fp32/all", "p99_ms": 1.0, "volumetric_iou": None}]}))
    cases = [(["--budget-ms", "0"], "--budget-ms must be a finite number > 0, got 0.0"),
             (["--budget-ms", "-3"], "--budget-ms must be a finite number > 0, got -3.0"),
             (["--budget-ms", "nan"], "--budget-ms must be a finite number > 0, got nan"),
             (["--budget-ms", "inf"], "--budget-ms must be a finite number > 0, got inf"),
             (["--budget-ms", "5", "--atlas", str(tmp_path / "none.json")], "none.json: atlas not found"),
             (["--budget-ms", "5", "--atlas", str(damaged)], "damaged.json: not a readable atlas"),
             (["--budget-ms", "5", "--atlas", str(empty)], "holds no setting with both accuracy and latency"),
             (["--budget-ms", "5", "--atlas", str(other)], "measured with other weights of nano (sha256 ffffffffffff…"),
             (["--budget-ms", "0.0001", "--quick", "--atlas", str(atlas)], "no setting fits 0.0001 ms on this machine: "
                                                                            "the fastest, ")]
    for argv, message in cases:
        code, _, err = run_main(["bench", *argv], capsys)
        assert code == 2 and message in err, (argv, err)
        said = [line for line in err.strip().splitlines() if line.strip() and not line.startswith("exporting the ONNX graphs")]
        assert len(said) == 1 and "Traceback" not in err  # a probe's first ONNX use says its export's progress
    assert not (tmp_path / "recordings").exists()


def test_replay_runs_a_named_setting_and_the_video_names_it(atlas, tmp_path, capsys):
    import av

    out = tmp_path / "replay.mp4"
    code, stdout, err = run_main(["replay", str(sample_episodes()[0]), "--setting", "nano/onnx-int8/ego", "--atlas",
                                  str(atlas), "--out", str(out)], capsys)
    assert code == 0, err
    assert "setting nano/onnx-int8/ego: V-IoU 0.550 [0.530, 0.570]" in stdout and "onnx-int8" in stdout
    assert "setting   nano/onnx-int8/ego\n" in stdout  # the summary names what ran, as the video's footer does
    with av.open(str(out)) as container:
        assert sum(1 for _ in container.decode(video=0)) == 300


def test_the_footer_names_the_setting_first():
    from touchanything.core.snapshot import Snapshot
    from touchanything.viz.replay_frame import footer_text

    snapshot = Snapshot(7, 0, {}, np.zeros((42, 3), np.float32), np.array([True, True]))
    assert footer_text(snapshot, 300, None, None, "nano/onnx-int8/ego").startswith("nano/onnx-int8/ego  |  Frame 0007/300")
    assert footer_text(snapshot, 300, None, None).startswith("Frame 0007/300")


def test_setting_option_conflicts_are_refused(atlas, tmp_path, capsys):
    episode = str(sample_episodes()[0])
    out = ["--out", str(tmp_path / "x.mp4")]
    cases = [(["--setting", "nano/onnx-int8/ego", "--runtime", "onnx"], "drop --runtime"),
             (["--setting", "nano/onnx-int8/ego", "--views", "all"], "drop --views"),
             (["--budget-ms", "5"], "--budget-ms needs --setting auto"),
             (["--setting", "auto"], "--setting auto needs --budget-ms"),
             (["--setting", "nano/onnx-int8/ego", "--budget-ms", "5"], "--budget-ms goes with --setting auto"),
             (["--setting", "nano/onnx-int8/all"], "setting nano/onnx-int8/all is not in the atlas"),
             (["--setting", "nano/onnx"], "is not a setting name")]
    for argv, message in cases:
        code, _, err = run_main(["replay", episode, *argv, "--atlas", str(atlas), *out], capsys)
        assert code == 2 and message in err, (argv, err)
    assert not (tmp_path / "x.mp4").exists()


def test_every_knob_of_a_setting_reaches_the_engine(atlas):
    from touchanything.app.commands.replay_command import given_choice
    from touchanything.app.sessions.setting_choice import setting_request

    class Args:
        setting, budget_ms, device = "nano/onnx-int8/ego", None, "cpu"
        checkpoint = config = runtime = precision = views = onnx = None

    Args.atlas = atlas
    request = setting_request(Args)
    picked = request.pick("cpu")
    choice = picked.model_choice("cpu")
    assert choice.setting == dataclasses.replace(picked.row.setting, device="cpu") and choice.setting.views == ("ego",)
    assert choice.setting.name() == "nano/onnx-int8/ego"
    Args.views = [("ego",), ("ego", "wrist_right")]  # --views ego ego+right: their union
    assert given_choice(Args).setting.views == ("ego", "wrist_right")
    Args.views = None
    assert given_choice(Args).setting.views == VIEW_NAMES
    assert request.inputs == (bundled_models()["nano"],)


def test_a_faster_setting_the_atlas_cannot_tell_apart_is_preferred(shas):
    """At 33 ms the picker took pico/torch-fp32/all (p99 31.7 ms) over pico/onnx-int8/all, 3× faster, paired
    −0.001 [−0.001, +0.000]: a faster setting whose paired V-IoU difference holds 0 is preferred; one that is
    worse on every trajectory is not."""
    from touchanything.inference.evaluation.atlas import AtlasRow, choice_line

    strata = ("test_seen",) * 30 + ("test_unseen",) * 20
    base = np.linspace(0.3, 0.8, 50)

    def row(name: str, viou: np.ndarray, p99: float) -> AtlasRow:
        return AtlasRow(parse_setting(name), shas["nano"], 50, float(viou.mean()), (0.0, 1.0), 0.7, (0.6, 0.8), p99,
                        tuple(viou), strata)

    wiggle = np.where(np.arange(50) % 2, 0.009, -0.011)  # mean −0.001, ±0.01 per trajectory: no measured difference
    fp32 = row("nano/torch-fp32/all", base, 30.0)
    int8 = row("nano/onnx-int8/all", base + wiggle, 10.0)
    worse = row("nano/onnx-int8/ego", base - 0.05, 3.0)  # 0.05 below on every trajectory: told apart
    measured = []

    def measure(r):
        measured.append(r.name)
        return r.atlas_p99_ms

    rows = sorted([fp32, int8, worse], key=lambda r: -r.volumetric_iou)
    choice = choose_within_budget(rows, 33.0, measure, progress=lambda line: None)
    assert choice.row is int8 and measured == [rows[0].name, "nano/onnx-int8/all"]
    assert choice.tied_with[0] == rows[0].name and choice.tied_with[1][1] <= 0.0 <= choice.tied_with[1][2]
    assert f"as accurate as {rows[0].name} (paired ΔV-IoU" in choice_line(choice, 33.0)
    assert "more accurate setting(s) took longer" not in choice_line(choice, 33.0)
    alone = [fp32, worse]
    measured.clear()
    assert choose_within_budget(alone, 33.0, measure, progress=lambda line: None).row is fp32 and measured == [fp32.name]
    no_values = [dataclasses.replace(r, per_trajectory_viou=(), strata=()) for r in rows]  # an atlas without them
    assert choose_within_budget(no_values, 33.0, measure, progress=lambda line: None).row.name == rows[0].name
