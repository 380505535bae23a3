"""`--rerun-serve [PORT] [--rerun-serve-host ADDRESS]`: the printed address is the one that serves the data — Rerun's
own client following it receives the session — the data server listens on 127.0.0.1 unless another address is
asked for by name, and every refusal is one line before any work."""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request

import pytest
from rerun.chunk import RrdReader

from helpers.rerun_client import free_port, rerun_client
from helpers.rerun_reading import recording_rows
from helpers.terminal_signals import default_sigint
from touchanything.app.cli import main


def test_serving_the_recording_to_the_web_viewer(episode_dir, tmp_path):
    """`--rerun-serve PORT`: the printed address is the one the data server listens on — Rerun's own client
    following it receives the cameras and the pressure — and the data server listens on 127.0.0.1 only."""
    import psutil

    port = free_port()
    command = [sys.executable, "-m", "touchanything.app.cli", "replay", str(episode_dir), "--out", str(tmp_path / "v.mp4"),
               "--rerun-serve", str(port), "--rerun", str(tmp_path / "s.rrd")]
    headless = {k: v for k, v in os.environ.items() if k != "DISPLAY"}  # as a fresh shell, whatever earlier tests set
    # Ctrl-C as in a terminal, whatever SIGINT disposition or mask the test process has (the child inherits both)
    stderr = (tmp_path / "stderr.txt").open("w")
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=stderr, text=True, env=headless,
                               preexec_fn=default_sigint)
    try:
        lines = []
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and not any("still serving at" in line for line in lines):
            lines.append(process.stdout.readline())
        url = next(line for line in lines if "web viewer at" in line).split("web viewer at ")[1].strip()
        data = url.split("?url=")[1]
        grpc_port = int(data.removeprefix("rerun+http://127.0.0.1:").removesuffix("/proxy"))
        assert url.startswith(f"http://localhost:{port}/?url=rerun+http://127.0.0.1:") and grpc_port > 0
        assert any(f"this machine only (data on 127.0.0.1:{grpc_port}" in line for line in lines)
        listening = {(c.laddr.ip, c.laddr.port) for c in psutil.Process(process.pid).net_connections("tcp")
                     if c.status == psutil.CONN_LISTEN}
        assert ("127.0.0.1", grpc_port) in listening and ("0.0.0.0", grpc_port) not in listening, listening
        assert ("0.0.0.0", port) in listening  # Rerun's web server takes no address: the page (no data) everywhere
        with urllib.request.urlopen(f"http://localhost:{port}/", timeout=10) as page:
            assert page.status == 200 and b"<html" in page.read(4096).lower()
        with rerun_client(data, tmp_path / "got.rrd") as client:
            time.sleep(4)  # the client takes what the server holds
            process.send_signal(signal.SIGINT)
            try:
                assert process.wait(30) == 0
            except subprocess.TimeoutExpired:
                stderr.flush()
                pytest.fail(f"replay did not stop within 30 s of SIGINT; its stderr: {(tmp_path / 'stderr.txt').read_text()[-2000:]}")
            assert "stopped serving" in process.stdout.read()
            client.wait(30)  # the server went away: the client saves what it received and ends
    finally:
        process.kill()
        process.wait()
        stderr.close()
    assert len(RrdReader(tmp_path / "s.rrd").recordings()) == 1
    rows, static = recording_rows(tmp_path / "got.rrd")  # what followed the printed address received
    assert rows["/pressure/measured"].data_frames("EncodedImage:blob") == list(range(40))
    assert "AssetVideo:blob" in static["/cameras/ego"]


def test_serving_elsewhere_is_asked_for_and_said(capsys, episode_dir, tmp_path):
    from touchanything.viz.rerun_serving import ServedAt

    lan = ServedAt("192.168.1.20", 40001, 9090)
    assert lan.web_url == "http://192.168.1.20:9090/?url=rerun+http://192.168.1.20:40001/proxy"
    assert "unauthenticated on 192.168.1.20, port 40001" in lan.lines()[1] and lan.lines()[1].startswith("warning")
    assert "every interface" in ServedAt("0.0.0.0", 40001, 9090).lines()[1]
    base, web = ["replay", str(episode_dir), "--out", str(tmp_path / "v.mp4")], str(free_port())
    for extra, message in ((["--rerun-serve-host", "127.0.0.1"], "--rerun-serve-host: only with --rerun-serve"),
                           (["--rerun-serve", web, "--rerun-serve-host", "lab-pc"], "--rerun-serve-host lab-pc: not an IP address"),
                           (["--rerun-serve", web, "--rerun-serve-host", "10.255.255.1"], "10.255.255.1:0 cannot be listened on")):
        assert main(base + extra) == 2
        err = capsys.readouterr().err
        assert message in err and len(err.strip().splitlines()) == 1, err
    with socket.socket() as busy:
        busy.bind(("0.0.0.0", 0))
        busy.listen()
        assert main(base + ["--rerun-serve", str(busy.getsockname()[1])]) == 2
        assert f"the web viewer's port: 0.0.0.0:{busy.getsockname()[1]} is already in use" in capsys.readouterr().err
    assert not (tmp_path / "v.mp4").exists()

