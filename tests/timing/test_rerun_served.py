"""A served recording accounts for every row: what Rerun's own client receives from the data server while a finished
replay is still served holds the same rows, entity by entity, as the file the same replay writes, and the summary
says so ("0 dropped"); when the server's memory limit makes it drop its oldest rows, the summary names at least
as many as a late viewer misses, by kind."""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader

from helpers.rerun_client import free_port, interrupt, rerun_client
from helpers.terminal_signals import default_sigint
from touchanything.core.tactile_layout import TactileLayout
from touchanything.devices.episodes.episode_loader import open_episode
from touchanything.viz.frame_facts import frame_facts
from touchanything.viz.rerun_accounting import entity_kind
from touchanything.viz.rerun_recording import RerunRecording, RerunTarget

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "recordings" / "sample" / "Workbench" / "hold_and_press_button_box_yellow" / "sim0007_00001"
pytestmark = pytest.mark.filterwarnings("ignore:RRD file has no footer")  # the client is stopped: it writes none


def _rows(path: Path) -> Counter[str]:
    """{entity: its temporal rows} of the recording in `path`."""
    rows: Counter[str] = Counter()
    for chunk in RrdReader(path).stream():
        if not chunk.is_static:
            rows[chunk.entity_path.strip("/")] += chunk.num_rows
    return rows


def _follow(data_url: str, out: Path, timeout: float = 60.0) -> None:
    """Rerun's own client follows `data_url` into `out` until what it saved has not grown for two seconds, and is
    then stopped (Ctrl-C) — before the server is: it can only have what the server held while serving."""
    with rerun_client(data_url, out) as client:
        deadline, last, since = time.monotonic() + timeout, -1, time.monotonic()
        while time.monotonic() < deadline and not (last > 0 and time.monotonic() - since > 2.0):
            time.sleep(0.25)
            size = out.stat().st_size if out.exists() else 0
            if size != last:
                last, since = size, time.monotonic()
        interrupt(client)
        client.wait(30)


def test_a_served_replay_holds_every_row_of_the_file(tmp_path):
    """The replay of a bundled episode, written and served at once; the client follows it while it is still served."""
    command = [sys.executable, "-m", "touchanything.app.cli", "replay", str(SAMPLE), "--rerun", str(tmp_path / "file.rrd"),
               "--rerun-serve", str(free_port())]
    headless = {k: v for k, v in os.environ.items() if k != "DISPLAY"}  # the recording only: no dashboard, no video
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=headless,
                               preexec_fn=default_sigint)
    try:
        lines: list[str] = []
        while not any("still serving at" in line for line in lines) and process.poll() is None:
            lines.append(process.stdout.readline())
        served = next(line for line in lines if "rerun     served:" in line)
        data_url = next(line for line in lines if "web viewer at" in line).split("?url=")[1].strip()
        _follow(data_url, tmp_path / "got.rrd")
        process.send_signal(signal.SIGINT)
        assert process.wait(60) == 0
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    written, received = _rows(tmp_path / "file.rrd"), _rows(tmp_path / "got.rrd")
    assert written["world/surface/left"] > 800 and written["pressure/measured"] == 300
    assert received == written
    assert served.strip() == f"rerun     served: {sum(written.values())} rows held for any viewer, 0 dropped"


def test_what_the_data_server_drops_is_counted_by_kind(tmp_path):
    """A server memory limit far below the recording: a viewer connecting afterwards misses the oldest rows, and
    the summary names at least as many, by kind."""
    with open_episode(SAMPLE) as episode:
        joints, valid = episode.wilor.joints.reshape(-1, 42, 3), episode.wilor.valid
    measured = np.zeros((2, 21, 21), np.float32)
    facts = frame_facts(measured, None, measured, TactileLayout.default().bend)
    target = RerunTarget(tmp_path / "file.rrd", serve_port=free_port(), server_memory_limit=2 << 20)
    recording = RerunRecording(target, "small server", {})
    try:
        for frame in range(150):
            recording.log_observation(frame, frame / 30, {}, joints[frame], valid[frame], measured, facts, {})
            recording.log_prediction(frame, frame / 30, measured, facts, joints[frame], valid[frame], measured, 10.0, 8.0)
        recording.flush()
        _follow(recording.served.data_url, tmp_path / "got.rrd")
    finally:
        recording.close()
    written, received = _rows(tmp_path / "file.rrd"), _rows(tmp_path / "got.rrd")
    missed = Counter({entity_kind(e): 0 for e in written})
    for entity, rows in written.items():
        missed[entity_kind(entity)] += rows - received[entity]
    line = recording.history.line()
    assert re.fullmatch(r"rerun     served: \d+ rows; up to \d+ of the oldest dropped by the data server's memory limit "
                        r"\(2 MiB; a viewer connecting now misses them\): .*", line), line
    printed = {kind: int(rows) for kind, rows in (part.rsplit(" ", 1) for part in line.split("): ")[1].split(", "))}
    assert printed == {kind: rows for kind, rows in recording.history.dropped.items()}
    assert sum(missed.values()) > 0 and missed["hand surfaces"] > 0
    assert all(rows <= printed.get(kind, 0) for kind, rows in missed.items()), (missed, printed)
    assert sum(recording.history.rows.values()) == sum(written.values())
