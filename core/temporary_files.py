"""Temporary outputs and the proof that the project made them (docs/data_safety.md, "What is removed").

Every file or folder a command writes is first written under a hidden temporary name beside its output,
`.<name>.partial-<pid>`. Before that name is created, an **ownership marker** is written beside it,
`.<name>.partial-<pid>.owner`: a small JSON record (`{"touchanything": "temporary output", "temporary": <the
name>, "kind": …, "pid", "started", "boot_id", "pid_namespace"}`) created exclusively (never over an existing
path, never through a link). Only an entry that has such a marker, naming it, is ever removed as a leftover,
and only when the process that wrote it provably no longer runs:

- same machine boot and same PID namespace: its /proc entry is gone, or holds another process (a different
  start time: the number was reused);
- another boot (`/proc/sys/kernel/random/boot_id` differs): gone, the machine restarted;
- another PID namespace (a container sharing the folder): cannot be told, so it is left alone and named.

A name alone proves nothing: `.thesis.tex.old-20240101` or `.draft.md.partial-31337` of a user's, without a
marker, is never touched, whatever its number.

Every file written through the door is also tagged, as it is renamed into place, with the extended attribute
`user.touchanything` (`tag_written`): a later command recognises its own earlier output of a fixed name (a report)
by that tag, not by the name (`written_here`). A file copied without its attributes, or on a file system without
user attributes, is not recognised: replacing it then needs `--overwrite`, the safe way round.

Kinds: `file` and `folder` (a half-written output: removed), `replaced` (an earlier output moved aside while a
folder output takes its place: put back when its place is empty, else removed), `recording` (a stream of a
recording that was cut short: data, never removed; `recorded_stream` finds it for the readers).
"""
from __future__ import annotations

import contextlib
import json
import os
import shutil
import sys
from collections.abc import Iterator
from pathlib import Path

PARTIAL = ".partial-"
"""In the name of every temporary output: `.<name>.partial-<pid>` (hidden, and with no suffix of its own, so no
reader takes a half-written `.hdf5` or `.mp4` for data)."""
OWNER = ".owner"
"""The suffix of an ownership marker: `<temporary name>.owner`."""
MARK = "touchanything temporary output"
KINDS = ("file", "folder", "replaced", "recording")
WRITTEN_ATTRIBUTE = "user.touchanything"
WRITTEN_VALUE = b"written"
_MARKER_BYTES = 4096
_SAID_ALONE: set[Path] = set()
"""The leftovers of other PID namespaces already named by this process (each is named once)."""
"""A marker is a few hundred bytes; a larger file of that name is not one."""


def temporary_path(path: Path) -> Path:
    """The hidden temporary name of `path` in its folder (a writer that chooses the format by the suffix must
    be told the format)."""
    path = Path(path)
    return path.with_name(f".{path.name}{PARTIAL}{os.getpid()}")


def marker_path(temporary: Path) -> Path:
    """The ownership marker of the temporary entry `temporary`."""
    return Path(temporary).with_name(Path(temporary).name + OWNER)


def tag_written(path: Path) -> None:
    """Tag the file `path` (a temporary about to take its place) as written by the project; a file system without
    user attributes leaves it untagged."""
    with contextlib.suppress(OSError):
        os.setxattr(path, WRITTEN_ATTRIBUTE, WRITTEN_VALUE, follow_symlinks=False)


def written_here(path: Path) -> bool:
    """`path` is a plain file (not a link) that the project wrote: it carries the tag of `tag_written`."""
    try:
        return Path(path).is_file() and not Path(path).is_symlink() and \
            os.getxattr(path, WRITTEN_ATTRIBUTE, follow_symlinks=False) == WRITTEN_VALUE
    except OSError:
        return False


def _read(path: str) -> str:
    try:
        with open(path) as handle:
            return handle.read().strip()
    except OSError:
        return ""


def _start_time(pid: int) -> str:
    """The start time of process `pid` (clock ticks after boot, /proc/PID/stat field 22); "" when there is none."""
    stat = _read(f"/proc/{pid}/stat")
    fields = stat.rpartition(")")[2].split()
    return fields[19] if len(fields) > 19 else ""


def _pid_namespace() -> str:
    try:
        return os.readlink("/proc/self/ns/pid")
    except OSError:
        return ""


def this_process() -> dict[str, object]:
    """Who writes: pid, its start time, the machine's boot id and the PID namespace."""
    pid = os.getpid()
    return {"pid": pid, "started": _start_time(pid), "boot_id": _read("/proc/sys/kernel/random/boot_id"),
            "pid_namespace": _pid_namespace()}


def owner_state(owner: dict) -> str:
    """"gone" (provably no longer runs), "running", or "unknown" (another PID namespace of this boot)."""
    here = this_process()
    if owner.get("boot_id") and here["boot_id"] and owner["boot_id"] != here["boot_id"]:
        return "gone"
    if owner.get("pid_namespace") != here["pid_namespace"]:
        return "unknown"
    pid = owner.get("pid")
    if not isinstance(pid, int) or isinstance(pid, bool) or pid <= 0:
        return "unknown"
    if here["started"]:  # /proc is there: a missing entry or another start time means gone
        started = _start_time(pid)
        return "running" if started and started == owner.get("started") else "gone"
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return "gone"
    except OSError:
        return "running"
    return "running"


def mark(temporary: Path, kind: str, **facts: object) -> Path:
    """Write the ownership marker of `temporary` (which must not exist yet) before it is created; return the
    marker's path. OSError when either name is taken (the marker is created exclusively, never followed)."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
    temporary = Path(temporary)
    if os.path.lexists(temporary):
        raise FileExistsError(17, "a temporary name of this process is taken", str(temporary))
    marker = marker_path(temporary)
    record = {"touchanything": MARK, "temporary": temporary.name, "kind": kind, **this_process(), **facts}
    fd = os.open(marker, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644)
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(json.dumps(record) + "\n")
    except BaseException:
        os.unlink(marker)  # created above by this call: ours
        raise
    return marker


def unmark(temporary: Path) -> None:
    """Remove the marker of `temporary` (its entry is gone or has taken its place)."""
    with contextlib.suppress(FileNotFoundError):
        os.unlink(marker_path(temporary))


def read_marker(marker: Path) -> dict | None:
    """The record of a marker, or None when `marker` is not one the project wrote: not a plain file, too large,
    not the JSON record, or naming another entry than its own sibling."""
    try:
        if not Path(marker).is_file() or Path(marker).is_symlink() or os.path.getsize(marker) > _MARKER_BYTES:
            return None
        record = json.loads(Path(marker).read_text())
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    if not isinstance(record, dict) or record.get("touchanything") != MARK or record.get("kind") not in KINDS:
        return None
    temporary = record.get("temporary")
    return record if isinstance(temporary, str) and temporary + OWNER == Path(marker).name else None


def _markers(folder: Path) -> Iterator[tuple[Path, dict]]:
    try:
        names = [entry.name for entry in os.scandir(folder) if entry.name.endswith(OWNER) and PARTIAL in entry.name]
    except OSError:
        return
    for name in names:
        if (record := read_marker(Path(folder) / name)) is not None:
            yield Path(folder) / name, record


def _say(line: str) -> None:
    """A line on stderr that does not run into a progress bar drawn there."""
    from tqdm import tqdm

    tqdm.write(line, file=sys.stderr)


def _is_kind(entry: Path, kind: str) -> bool:
    """The entry is still what the marker says it wrote: a plain file, or a real folder."""
    if entry.is_symlink():
        return False
    return entry.is_dir() if kind in ("folder", "replaced") else entry.is_file()


def _clear(marker: Path, record: dict) -> Path | None:
    """Remove (or put back) the leftover a gone process's marker names, then the marker; what was removed."""
    entry = marker.with_name(record["temporary"])
    kind = record["kind"]
    if os.path.lexists(entry) and not _is_kind(entry, kind):
        return None  # something else now has that name: not ours to touch
    if kind == "replaced" and entry.exists() and isinstance(record.get("place"), str) \
            and "/" not in record["place"] and not os.path.lexists(entry.with_name(record["place"])):
        os.replace(entry, entry.with_name(record["place"]))
        _say(f"restored {entry.with_name(record['place'])}: an interrupted run (process {record['pid']}) had moved "
             "it aside")
        os.unlink(marker)
        return None
    if entry.is_dir():
        shutil.rmtree(entry)
    elif os.path.lexists(entry):
        os.unlink(entry)
    else:
        os.unlink(marker)
        return None
    os.unlink(marker)
    return entry


def remove_left_behind(folder: Path) -> list[Path]:
    """Remove the temporary outputs in `folder` whose marker proves this project wrote them and whose process
    provably no longer runs (each named on stderr); leftovers of a process in another PID namespace are named
    and left alone, recordings cut short are data and stay. Returns what was removed."""
    removed = []
    for marker, record in _markers(folder):
        if record["kind"] == "recording":
            continue
        state = owner_state(record)
        if state == "unknown" and marker not in _SAID_ALONE:
            _SAID_ALONE.add(marker)
            _say(f"left alone {marker.with_name(record['temporary'])}: written by process {record.get('pid')} of "
                 "another PID namespace, which this one cannot see; remove it once that run has ended")
            continue
        if state in ("running", "unknown"):
            continue
        with contextlib.suppress(OSError):
            if (entry := _clear(marker, record)) is not None:
                removed.append(entry)
                _say(f"removed {entry}: left half-written by an interrupted run (process {record['pid']})")
    return removed


def recorded_stream(folder: Path, name: str) -> Path | None:
    """The temporary file of stream `name` of a recording in `folder` that has not renamed its streams into place
    (cut short, or still recording), or None. When there are several, the newest marker's."""
    found = [(marker.stat().st_mtime, marker.with_name(record["temporary"]))
             for marker, record in _markers(folder)
             if record["kind"] == "recording" and record.get("name") == name]
    found = [(when, path) for when, path in found if path.is_file() and not path.is_symlink()]
    return max(found)[1] if found else None
