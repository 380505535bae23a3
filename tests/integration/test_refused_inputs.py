"""Impossible settings and inputs that cannot give a meaningful result are refused with one line, before any
work, and leave every file as it was."""
from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from tests.conftest import write_episode
from touchanything.app.cli import main


def checksums(root: Path) -> dict[str, str]:
    """sha256 of every file under `root` (or of `root` itself when it is a file)."""
    files = [root] if root.is_file() else sorted(p for p in root.rglob("*") if p.is_file())
    return {str(p): hashlib.sha256(p.read_bytes()).hexdigest() for p in files}


def refused(capsys, argv: list[str], *words: str, status: int = 2) -> str:
    """Run the command line; it must exit with `status` and print one error line holding every word."""
    code = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == status, err
    assert len(err) == 1 and "Traceback" not in err[0], err
    for word in words:
        assert word in err[0], err
    return err[0]


@pytest.mark.parametrize("content", ["", "\n\n\n", '{"frame_index": 0, "left": {"raw": [NaN]}, "right": null}\n'])
def test_grids_refuses_an_empty_or_unusable_glove_stream_and_keeps_the_grids(capsys, episode_dir, content):
    (episode_dir / "jq_pressure.json").write_text(content)
    before = checksums(episode_dir)
    refused(capsys, ["grids", str(episode_dir)], "jq_pressure.json", "pressure_grids.npz left as it was", status=1)
    assert checksums(episode_dir) == before


@pytest.mark.parametrize("scale", ["inf", "nan", "-1", "0"])
def test_grids_refuses_a_scale_that_is_not_finite_positive(capsys, episode_dir, scale):
    before = checksums(episode_dir)
    refused(capsys, ["grids", str(episode_dir), "--min-scale", scale], "--min-scale", scale)
    assert checksums(episode_dir) == before


def test_grids_goes_on_after_a_bad_episode(capsys, tmp_path):
    good = write_episode(tmp_path / "Home" / "a" / "1", frames=8, size=(16, 16))
    bad = write_episode(tmp_path / "Home" / "a" / "2", frames=8, size=(16, 16))
    (bad / "jq_pressure.json").write_text("")
    assert main(["grids", str(bad), str(good)]) == 1
    captured = capsys.readouterr()
    assert f"{good}: 8 frames" in captured.out and str(bad) in captured.err


@pytest.mark.parametrize("option, value", [("--min-wilor-valid", "30"), ("--min-wilor-valid", "nan"),
                                           ("--min-wilor-valid", "-0.1"), ("--unseen-ratio", "1.5"),
                                           ("--unseen-ratio", "nan"), ("--min-frames", "-1")])
def test_split_refuses_thresholds_outside_their_domain(capsys, sim_hdf5_root, option, value):
    before = checksums(sim_hdf5_root)
    refused(capsys, ["split", str(sim_hdf5_root), option, value], option, value)
    assert checksums(sim_hdf5_root) == before


def test_split_refuses_an_empty_train_or_test_list_unless_asked(capsys, sim_hdf5_root, tmp_path):
    before = checksums(sim_hdf5_root)
    out = tmp_path / "split.json"
    refused(capsys, ["split", str(sim_hdf5_root), "--min-frames", "100000", "--out", str(out)],
            "train and test", "--allow-empty", "frames < 100000")
    assert not out.exists() and checksums(sim_hdf5_root) == before
    assert main(["split", str(sim_hdf5_root), "--min-frames", "100000", "--out", str(out), "--allow-empty"]) == 0
    assert out.exists()


@pytest.mark.parametrize("argv", [["record", "--scene", "scenes/sim.toml", "--seconds", "-5"],
                                  ["record", "--scene", "scenes/sim.toml", "--seconds", "nan"],
                                  ["live", "--scene", "scenes/sim.toml", "--headless", "--seconds", "nan"],
                                  ["live", "--scene", "scenes/sim.toml", "--headless", "--seconds", "-5"],
                                  ["live", "--scene", "scenes/sim.toml", "--headless", "--seconds", "inf"]])
def test_record_and_live_refuse_a_duration_that_is_not_finite_positive(capsys, tmp_path, argv):
    out = tmp_path / "episode"
    argv = [*argv, "--out", str(out)] if argv[0] == "record" else argv
    refused(capsys, argv, "--seconds", str(float(argv[argv.index("--seconds") + 1])))
    assert not out.exists()


@pytest.mark.parametrize("seed", ["-1", str(2**32), str(2**70)])
def test_simulate_refuses_seeds_numpy_cannot_take(capsys, tmp_path, seed):
    refused(capsys, ["simulate", str(tmp_path / "out"), "--episodes", "1", "--seed", seed], "--seed", seed)
    assert not (tmp_path / "out").exists()
