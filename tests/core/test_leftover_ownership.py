"""Only what the project can prove it made is removed: a leftover carries an ownership marker, and its
process provably no longer runs. Real processes write the markers; a real PID namespace (`unshare`, as root) is
the process the folder's users cannot see."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.integration.test_input_links import digest
from touchanything.app.cli import main
from touchanything.core.output_safety import replacing
from touchanything.core.temporary_files import marker_path, remove_left_behind, temporary_path

CHILD = """
import sys, time
from pathlib import Path
from touchanything.core.temporary_files import mark, temporary_path
folder = Path(sys.argv[1])
for name in sys.argv[3:]:
    kind = "folder" if name.endswith("/") else "file"
    temporary = temporary_path(folder / name.rstrip("/"))
    mark(temporary, kind)
    (temporary.mkdir() or (temporary / "part").write_text("half")) if kind == "folder" else temporary.write_text("half")
    print(temporary, flush=True)
print("ready", flush=True)
if sys.argv[2] == "wait":
    time.sleep(120)
"""


def write_leftovers(folder: Path, *names: str, wait: bool = False,
                    prefix: tuple[str, ...] = ()) -> tuple[subprocess.Popen, list[Path]]:
    """A real process that marks and half-writes the temporary outputs of `names` in `folder` ("x/" a folder), then
    ends (or, `wait`, keeps running). `prefix`: a command it runs under (e.g. unshare)."""
    child = subprocess.Popen([*prefix, sys.executable, "-c", CHILD, str(folder), "wait" if wait else "end", *names],
                             stdout=subprocess.PIPE, text=True)
    made = []
    while (line := child.stdout.readline().strip()) != "ready":
        assert line, "the child ended before it was ready"
        made.append(Path(line))
    if not wait:
        child.wait(timeout=30)
    return child, made


def users_files(folder: Path) -> list[Path]:
    """Files with the names the old rule took for leftovers, none of them the project's."""
    (folder / ".thesis.tex.old-20240101").write_text("chapter 1")
    (folder / ".photos.old-1999").mkdir()
    (folder / ".photos.old-1999" / "beach.jpg").write_bytes(b"\xff\xd8jpeg")
    (folder / ".draft.md.partial-31337").write_text("draft")
    (folder / f".notes.txt.partial-{os.getpid() + 4_000_000}").write_text("above the PID limit")
    return [folder / name for name in (".thesis.tex.old-20240101", ".photos.old-1999", ".draft.md.partial-31337",
                                       f".notes.txt.partial-{os.getpid() + 4_000_000}")]


def test_a_users_files_named_like_leftovers_are_never_removed(sim_hdf5_root, tmp_path, capsys):
    home = tmp_path / "home"
    home.mkdir()
    theirs = users_files(home)
    before = digest(home)
    assert main(["split", str(sim_hdf5_root), "--out", str(home / "split.json")]) == 0
    assert "removed" not in capsys.readouterr().err
    assert sorted(home.iterdir()) == sorted([*theirs, home / "split.json"])
    assert {k: v for k, v in digest(home).items() if "split.json" not in k} == before


def test_what_an_ended_process_left_is_removed_and_named_a_running_ones_is_kept(tmp_path, capsys):
    _, ended = write_leftovers(tmp_path, "a.hdf5", "dataset/")
    running, kept = write_leftovers(tmp_path, "b.hdf5", wait=True)
    theirs = users_files(tmp_path)
    try:
        assert sorted(remove_left_behind(tmp_path)) == sorted(ended)
        assert running.poll() is None  # asked about, never signalled
    finally:
        running.kill()
        running.wait()
    assert sorted(tmp_path.iterdir()) == sorted([*theirs, *kept, marker_path(kept[0])])
    err = capsys.readouterr().err.splitlines()
    assert sorted(err) == sorted(f"removed {p}: left half-written by an interrupted run (process {p.name.rsplit('-', 1)[1]})"
                                 for p in ended)
    assert remove_left_behind(tmp_path) == [kept[0]]  # now its process has ended too


def forge(marker: Path, **changes: object) -> None:
    record = json.loads(marker.read_text())
    marker.write_text(json.dumps({**record, **changes}))


def test_a_marker_decides_not_the_name(tmp_path, capsys):
    _, (reused, rebooted, linked, elsewhere, taken) = write_leftovers(tmp_path, "a", "b", "c", "d", "e")
    forge(marker_path(reused), pid=os.getpid(), started="1")  # this process's number, another start: reused
    forge(marker_path(rebooted), boot_id="another-boot", pid=os.getpid())  # the machine restarted since
    target = tmp_path / "user.txt"
    target.write_text("the user's")
    linked.unlink()
    linked.symlink_to(target)  # not what the marker says was written
    forge(marker_path(elsewhere), temporary="user.txt")  # a marker names only its own sibling
    taken.unlink()
    taken.mkdir()  # a folder where a file was written: not ours any more
    assert sorted(remove_left_behind(tmp_path)) == sorted([reused, rebooted])
    assert target.read_text() == "the user's" and linked.is_symlink() and elsewhere.exists() and taken.is_dir()
    assert "removed" in capsys.readouterr().err


def test_a_folder_moved_aside_is_put_back_when_its_place_is_empty(tmp_path, capsys):
    _, (old,) = write_leftovers(tmp_path, "lerobot/")
    forge(marker_path(old), kind="replaced", place="lerobot")
    assert remove_left_behind(tmp_path) == []
    assert (tmp_path / "lerobot" / "part").read_text() == "half" and not marker_path(old).exists()
    assert f"restored {tmp_path / 'lerobot'}" in capsys.readouterr().err


@pytest.mark.skipif(os.geteuid() != 0 or shutil.which("unshare") is None, reason="a PID namespace needs root and unshare")
def test_a_process_of_another_pid_namespace_is_left_alone_and_named(tmp_path, capsys):
    child, made = write_leftovers(tmp_path, "c.hdf5", prefix=("unshare", "--pid", "--fork", "--mount-proc"))
    assert made and made[0].exists()
    with replacing(tmp_path / "out.txt") as temporary:  # a command writing into the shared folder
        temporary.write_text("done")
    assert made[0].exists() and marker_path(made[0]).exists()
    err = capsys.readouterr().err
    assert f"left alone {made[0]}: written by process" in err and "another PID namespace" in err
    assert temporary_path(tmp_path / "out.txt") != made[0]
