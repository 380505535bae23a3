"""scripts/findings_table.py on results written in eval's layout: the pooled table averages over every held-out
trajectory of both test sets (not the two means), leaves NaN trajectories out, and says n/a where a set is absent."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "findings_table.py"


def write_results(folder: Path, contact_ious: list[float]) -> None:
    trajectories = [{"path": f"t{i}.hdf5", "causal": {"volumetric_iou": 0.5, "contact_iou": c}}
                    for i, c in enumerate(contact_ious)]
    overall = {"overall": {"volumetric_iou": 0.5, "contact_iou": 0.0}}
    folder.mkdir(parents=True)
    (folder / "results.json").write_text(json.dumps({"results": [
        {"views": "all", "pose_only": False, "baseline": None, "causal": overall, "stitched": overall,
         "trajectories": trajectories}]}))


def pooled_rows(runs: Path) -> dict[str, str]:
    out = subprocess.run([sys.executable, str(SCRIPT), str(runs), "m", "m2"], capture_output=True, text=True, check=True)
    table = out.stdout.split("###")[1].splitlines()
    return {line.split("|")[1].strip(): line for line in table if line.startswith("| m")}


def test_the_pooled_table_averages_over_all_held_out_trajectories(tmp_path):
    write_results(tmp_path / "m" / "eval_test_seen", [1.0, float("nan")])
    write_results(tmp_path / "m" / "eval13_test_seen", [0.0, 0.0, 0.5])
    write_results(tmp_path / "m2" / "eval_test_seen", [0.2])
    rows = pooled_rows(tmp_path)
    cells = [c.strip() for c in rows["m"].split("|")[2:-1]]
    assert cells[:3] == ["0.500 / 1.000 (2)", "0.500 / 0.167 (3)", "0.500 / 0.375 (5)"]  # (1 + 0 + 0 + 0.5) / 4
    assert cells[3:] == ["n/a / n/a (0)"] * 3
    assert [c.strip() for c in rows["m2"].split("|")[2:5]] == ["0.500 / 0.200 (1)", "n/a / n/a (0)", "n/a / n/a (0)"]
