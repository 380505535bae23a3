"""Half-written outputs, with real signals to a real child process: SIGTERM and SIGINT clean up as
Ctrl-C does, what a killed process left behind is removed (and named) by the next run writing into that folder,
and a name longer than the file system allows is one line before any work."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest

from touchanything.app.cli import main
from touchanything.app.sessions.bundled import SAMPLE_DIR
from touchanything.core.output_safety import replacing
from touchanything.core.temporary_files import PARTIAL, remove_left_behind


def start(argv: list[str], **popen) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "touchanything.app.cli", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **popen)


def wait_for_partial(folder: Path, child: subprocess.Popen, seconds: float = 120) -> Path:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        found = [p for p in folder.rglob(f"*{PARTIAL}{child.pid}")] if folder.exists() else []
        if found:
            return found[0]
        assert child.poll() is None, child.communicate()
        time.sleep(0.05)
    raise AssertionError("no half-written output appeared")


@pytest.mark.parametrize("signum, status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signal_during_convert_leaves_nothing_half_written(tmp_path, signum, status):
    out = tmp_path / "h5"
    child = start(["convert", str(SAMPLE_DIR), str(out), "--compression-level", "1"])
    wait_for_partial(out, child)
    child.send_signal(signum)
    _, err = child.communicate(timeout=120)
    assert child.returncode == status, err
    assert err.strip().splitlines()[-1].startswith("touchanything convert: ") and "Traceback" not in err
    assert not list(out.rglob(f"*{PARTIAL}*"))


@pytest.mark.parametrize("signum, status, whole_group", [(signal.SIGTERM, 143, False), (signal.SIGINT, 130, True)])
def test_a_stopped_simulate_stops_at_once_and_leaves_no_worker(tmp_path, monkeypatch, signum, status, whole_group):
    """Episodes of a minute take a worker far longer than the 15 s allowed to stop: the episodes in progress are
    abandoned, not waited for. SIGINT goes to the whole process group, as a terminal's Ctrl-C does."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    out = tmp_path / "sim"
    child = start(["simulate", str(out), "--episodes", "4", "--seconds", "60", "--workers", "2"], start_new_session=True)
    wait_for_partial(tmp_path, child)
    workers = []
    while len(workers) < 2 and child.poll() is None:
        workers = psutil.Process(child.pid).children()
        time.sleep(0.05)
    time.sleep(1.0)  # the workers are into their first episode
    os.killpg(child.pid, signum) if whole_group else child.send_signal(signum)
    try:
        _, err = child.communicate(timeout=15)
    except subprocess.TimeoutExpired:
        os.killpg(child.pid, signal.SIGKILL)
        raise AssertionError("simulate waited for the episodes in progress") from None
    assert child.returncode == status and "Traceback" not in err, err
    assert err.strip().splitlines()[-1].startswith("touchanything simulate: ")
    assert not [w for w in workers if w.is_running() and w.status() != psutil.STATUS_ZOMBIE]
    assert not out.exists() and not list(tmp_path.glob(f"*{PARTIAL}*"))


def test_sigterm_during_export_lerobot_leaves_no_half_dataset(tmp_path):
    out = tmp_path / "lerobot"
    child = start(["export-lerobot", str(SAMPLE_DIR), str(out)])
    wait_for_partial(tmp_path, child)
    child.send_signal(signal.SIGTERM)
    _, err = child.communicate(timeout=120)
    assert child.returncode == 143 and "touchanything export-lerobot: terminated" in err, err
    assert not list(tmp_path.rglob(f"*{PARTIAL}*")) and not out.exists()


def test_what_a_killed_convert_left_is_removed_and_named_by_the_next_run(tmp_path, capsys):
    out = tmp_path / "h5"
    child = start(["convert", str(SAMPLE_DIR), str(out), "--compression-level", "1"])
    partial = wait_for_partial(out, child)
    child.kill()
    child.wait(timeout=30)
    assert partial.exists()  # SIGKILL: no chance to clean up
    assert main(["convert", str(SAMPLE_DIR), str(out), "--compression-level", "1", "--overwrite"]) == 0
    err = capsys.readouterr().err
    assert f"removed {partial}: left half-written by an interrupted run (process {child.pid})" in err
    assert not list(out.rglob(f"*{PARTIAL}*"))


def test_a_running_process_keeps_its_temporary_outputs(tmp_path):
    mine = tmp_path / f".a.hdf5{PARTIAL}{os.getpid()}"
    mine.write_text("being written")
    parent = tmp_path / f".b.hdf5{PARTIAL}{os.getppid()}"
    parent.write_text("being written by a live process")
    assert remove_left_behind(tmp_path) == [] and mine.exists() and parent.exists()
    with replacing(tmp_path / "c.txt") as temporary:
        temporary.write_text("done")
    assert (tmp_path / "c.txt").read_text() == "done"


@pytest.mark.parametrize("argv", [
    ["info", "{long}"],
    ["split", "{sample}", "--out", "{tmp}/{long}.json"],
    ["grids", "{tmp}/{long}"],
    ["bench", "--quick", "--out", "{tmp}/{long}"],
])
def test_a_name_longer_than_the_file_system_allows_is_one_line(tmp_path, capsys, argv):
    long = "x" * 300
    argv = [a.format(long=long, tmp=tmp_path, sample=SAMPLE_DIR) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert "longer than the file system allows" in err


def test_a_legal_name_whose_temporary_name_is_too_long_is_refused_before_any_work(tmp_path, capsys):
    name = "r" * 248 + ".mp4"  # 252 bytes: legal, but `.<name>.partial-<pid>` is not
    assert main(["replay", str(next(SAMPLE_DIR.glob("*/*/*"))), "--out", str(tmp_path / name)]) == 2
    err = capsys.readouterr().err
    assert "the temporary name it is written under is" in err and "longer than the file system allows (255)" in err
    assert list(tmp_path.iterdir()) == []
