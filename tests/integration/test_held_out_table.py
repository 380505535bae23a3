"""scripts/held_out_table.py on results written in eval's layout: per split and over both, each model's mean and
its paired difference against the reference, on the held-out set or, with --set fresh, on the fresh seed."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "held_out_table.py"


def write_results(folder: Path, values: dict[str, float]) -> None:
    """One results.json (all views, causal) whose trajectories have these volumetric IoUs (contact IoU 0.5)."""
    folder.mkdir(parents=True)
    trajectories = [{"path": path, "causal": {"volumetric_iou": v, "contact_iou": 0.5}} for path, v in values.items()]
    (folder / "results.json").write_text(json.dumps({"results": [{"views": "all", "trajectories": trajectories}]}))


def rows(runs: Path, *extra: str) -> dict[str, list[str]]:
    out = subprocess.run([sys.executable, str(SCRIPT), str(runs), "ref", "new", "--against", "ref", *extra],
                         capture_output=True, text=True, check=True).stdout
    return {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]]
            for line in out.splitlines() if line.startswith("| ref") or line.startswith("| new")}


def test_the_fresh_set_is_read_from_its_own_folders(tmp_path):
    for model, seen, unseen in (("ref", [0.2, 0.4], [0.6]), ("new", [0.3, 0.5], [0.9])):
        write_results(tmp_path / model / "fresh_test_seen", {"s1": seen[0], "s2": seen[1]})
        write_results(tmp_path / model / "fresh_test_unseen", {"u1": unseen[0]})
        write_results(tmp_path / model / "heldout_test_seen", {"h1": 0.1})
        write_results(tmp_path / model / "heldout_test_unseen", {"h2": 0.1})
    fresh = rows(tmp_path, "--set", "fresh")
    # columns: seen V-IoU, seen C-IoU, unseen V-IoU, unseen C-IoU, both V-IoU, both C-IoU
    assert [fresh["new"][i].split(" ")[0] for i in (0, 2, 4)] == ["0.400", "0.900", "0.567"]  # (0.3 + 0.5 + 0.9) / 3
    assert fresh["new − ref"][4].split(" ")[0] == "+0.167"  # (0.1 + 0.1 + 0.3) / 3
    assert rows(tmp_path)["new"][4].split(" ")[0] == "0.100"  # the held-out set, the default


def test_a_missing_or_mismatched_evaluation_is_one_line(tmp_path):
    for model in ("ref", "new"):
        write_results(tmp_path / model / "heldout_test_seen", {"s1": 0.2})
    write_results(tmp_path / "ref" / "heldout_test_unseen", {"u1": 0.2})
    missing = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path), "ref", "new", "--against", "ref"],
                             capture_output=True, text=True)
    assert missing.returncode == 1 and "Traceback" not in missing.stderr
    missing_file = tmp_path / "new" / "heldout_test_unseen" / "results.json"
    assert missing.stderr.strip() == (f"held_out_table.py: {missing_file} is missing (touchanything eval ... "
                                      f"--views all --out {missing_file.parent})")
    write_results(tmp_path / "new" / "heldout_test_unseen", {"u2": 0.2})
    other = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path), "ref", "new", "--against", "ref"],
                           capture_output=True, text=True)
    assert other.returncode == 1 and other.stderr.count("\n") == 1 and "different trajectories" in other.stderr
    (tmp_path / "new" / "heldout_test_unseen" / "results.json").write_text("{half")
    damaged = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path), "ref", "new", "--against", "ref"],
                             capture_output=True, text=True)
    assert damaged.returncode == 1 and "Traceback" not in damaged.stderr
    assert damaged.stderr.startswith(f"held_out_table.py: a results.json under {tmp_path} is not eval's all-views "
                                     "results (JSONDecodeError: ")
    (tmp_path / "new" / "heldout_test_unseen" / "results.json").write_text("[]")
    other_shape = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path), "ref", "new", "--against", "ref"],
                                 capture_output=True, text=True)
    assert other_shape.returncode == 1 and "(TypeError: " in other_shape.stderr and "Traceback" not in other_shape.stderr
    (tmp_path / "new" / "heldout_test_unseen" / "results.json").unlink()
    (tmp_path / "new" / "heldout_test_unseen" / "results.json").mkdir()
    folder = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path), "ref", "new", "--against", "ref"],
                            capture_output=True, text=True)
    assert folder.stderr.strip() == (f"held_out_table.py: {tmp_path / 'new' / 'heldout_test_unseen' / 'results.json'} "
                                     "cannot be read (Is a directory)")
