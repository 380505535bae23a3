"""scripts/frontier_curves.py on runs in eval's layout and an ensemble bench report: each axis's points paired
against the bundled `pico`, x read from the split files and the ensemble's K, points not measured yet left out."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from test_held_out_table import write_results

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "frontier_curves.py"
SPLITS = {"s1": "test_seen", "s2": "test_seen", "u1": "test_unseen"}


def write_run(runs: Path, run: str, values: tuple[float, float, float]) -> None:
    """The run's held-out results: volumetric IoUs of s1, s2 (seen) and u1 (unseen); contact IoU 0.5 each."""
    write_results(runs / run / "heldout_test_seen", {"s1": values[0], "s2": values[1]})
    write_results(runs / run / "heldout_test_unseen", {"u1": values[2]})


def write_bench(bench: Path, settings: dict[str, list[float]]) -> None:
    """docs/bench/ensemble_k4_heldout.json as the bench writes it: trajectories and per-trajectory values per setting."""
    bench.mkdir()
    rows = [{"setting": s, "per_trajectory": {"volumetric_iou": v, "contact_iou": [0.5] * 3}} for s, v in settings.items()]
    report = {"trajectories": [{"name": n, "split": s} for n, s in SPLITS.items()], "rows": rows}
    (bench / "ensemble_k4_heldout.json").write_text(json.dumps(report))


def test_each_axis_is_paired_against_the_bundled_pico(tmp_path):
    runs, data, bench, picture = tmp_path / "runs", tmp_path / "data", tmp_path / "bench", tmp_path / "curves.png"
    data.mkdir()
    (data / "split_train.json").write_text(json.dumps({"train": ["a", "b"]}))
    (data / "split_train_more.json").write_text(json.dumps({"train": ["a", "b", "c"]}))
    write_run(runs, "bundled_pico", (0.2, 0.4, 0.6))
    write_run(runs, "pico_162", (0.1, 0.3, 0.2))
    write_run(runs, "pico_96", (0.3, 0.5, 0.9))
    write_bench(bench, {"pico_ens/torch-fp32/all": [0.2, 0.4, 0.6], "pico_ens/torch-fp32/all/members2": [0.2, 0.4, 0.9],
                        "pico_ens/torch-fp32/all/members4": [0.5, 0.4, 0.6]})
    done = subprocess.run([sys.executable, str(SCRIPT), str(runs), "--data", str(data), "--bench", str(bench),
                           "--plot", str(picture)], capture_output=True, text=True, check=True)
    table = {tuple(c.strip() for c in line.split("|")[1:4]): [c.strip().split(" ")[0] for c in line.split("|")[4:-1]]
             for line in done.stdout.splitlines()[2:]}
    # columns: trajectories, V-IoU, Δ V-IoU, C-IoU, Δ C-IoU
    assert table[("training trajectories", "pico", "2")] == ["3", "0.200", "-0.200", "0.500", "+0.000"]
    assert table[("training trajectories", "pico", "3")][:3] == ["3", "0.400", "+0.000"]
    assert table[("input resolution (px)", "pico", "96")][:3] == ["3", "0.567", "+0.167"]  # (0.1 + 0.1 + 0.3) / 3
    assert table[("ensemble members K", "pico", "2")][2] == "+0.100"
    assert table[("ensemble members K", "pico", "4")][2] == "+0.100"
    assert len(table) == 7  # pico at 2 and 3 trajectories, at 64 and 96 px, K = 1, 2, 4: no nano, 128 px or K = 3
    assert "nano_more: not evaluated on data/heldout yet" in done.stderr
    assert "ensemble_seeds_heldout.json is missing" in done.stderr
    assert "split_train_2x.json is not written yet" in done.stderr
    assert picture.read_bytes().startswith(b"\x89PNG")


def test_unreadable_results_and_a_picture_not_named_png_are_refused_in_one_line(tmp_path):
    (tmp_path / "bundled_pico" / "heldout_test_seen").mkdir(parents=True)
    (tmp_path / "bundled_pico" / "heldout_test_seen" / "results.json").write_text("{")
    done = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path), "--bench", str(tmp_path)], capture_output=True, text=True)
    assert done.returncode != 0 and "Traceback" not in done.stderr
    assert "is not eval's all-views results (JSONDecodeError" in done.stderr
    done = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path), "--plot", str(tmp_path / "results.json")],
                          capture_output=True, text=True)
    assert done.returncode == 2 and "name it *.png" in done.stderr and not (tmp_path / "results.json").exists()
