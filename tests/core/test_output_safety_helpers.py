"""The output rule's helpers (`core.output_safety`, `core.temporary_files`) at their edges, by value: whole folders
and report folders, names at the file system's length limit (the nearest existing folder's, 255 when the OS does not
say, every part of a path), what a dead process left behind (a running one is not signalled; another user's counts
as running), `named`, an unwritable folder, the OS's reason in one line, what is synced and how it is opened, and a
sync that fails after the rename."""
from __future__ import annotations

import errno
import os
import shutil
import stat
from pathlib import Path

import pytest

from touchanything.core import output_safety
from touchanything.core.errors import UserError
from touchanything.core.output_safety import (
    check_name_lengths,
    check_output,
    check_outside,
    check_report_folder,
    check_writable,
    describe,
    fsync_fd,
    fsync_path,
    replacing_folder,
    write_text,
)
from touchanything.core.temporary_files import OWNER, PARTIAL, temporary_path


def refused(message: str, *args, **kwargs) -> str:
    with pytest.raises(UserError) as err:
        check_output(*args, **kwargs)
    assert message in str(err.value), str(err.value)
    return str(err.value)


def test_a_whole_folder_output(tmp_path):
    episode = tmp_path / "ep"
    (episode / "inner").mkdir(parents=True)
    (episode / "chest.mp4").write_bytes(b"video")
    assert "holds the input" in refused("choose a folder outside it", tmp_path, [episode], True, whole=True)
    assert refused("is a folder of the input", episode / "inner", [episode], True, whole=True).startswith(f"{episode / 'inner'}:")
    check_output(episode / "new_dataset", [episode], whole=True)  # a new folder inside an input replaces nothing
    out = tmp_path / "out"
    out.mkdir()
    check_output(out, [episode], whole=True)  # empty: nothing to lose
    (out / "x").write_text("")
    refused("folder is not empty; pass --overwrite", out, [episode], whole=True)
    check_output(out, [episode], overwrite=True, whole=True)
    refused("exists and is not a folder", out / "x", [], whole=True)
    check_output(out, [episode], folder=True)  # a folder of named files: its files are checked one by one
    refused("is a folder; give the file to write", out, [])


def test_a_hard_link_of_an_input_file_is_that_input(tmp_path):
    source = tmp_path / "a.hdf5"
    source.write_bytes(b"data")
    os.link(source, tmp_path / "b.hdf5")
    message = refused("under another name (a hard link)", tmp_path / "b.hdf5", [source], True)
    assert message.startswith(f"{tmp_path / 'b.hdf5'}: is the input")


def test_check_outside(tmp_path):
    folder = tmp_path / "dataset"
    folder.mkdir()
    for out in (folder, folder / "sub", folder / "sub" / "deeper"):
        with pytest.raises(UserError, match="would lie inside the input"):
            check_outside(out, [tmp_path / "elsewhere", folder])
    check_outside(tmp_path / "dataset2", [folder])
    check_outside(tmp_path, [folder])
    (tmp_path / "file").write_text("")
    check_outside(tmp_path / "file" / "x", [tmp_path / "file"])  # a file is not a folder to lie inside


def test_names_at_the_file_systems_limit(tmp_path):
    limit = os.pathconf(tmp_path, "PC_NAME_MAX")
    extra = len(f".{PARTIAL}{os.getpid()}{OWNER}")  # its marker adds a dot, ".partial-", the process id, ".owner"
    check_name_lengths(tmp_path / "new" / ("a" * (limit - extra)))
    with pytest.raises(UserError, match=f"the temporary name it is written under is {limit + 1} bytes, longer than the file "
                                        f"system allows \\({limit}\\)"):
        check_name_lengths(tmp_path / "new" / ("a" * (limit - extra + 1)))
    with pytest.raises(UserError, match=f"the name {'é' * 24}… is {2 * (limit // 2 + 1)} bytes"):
        check_name_lengths(tmp_path / "new" / ("é" * (limit // 2 + 1)) / "x")  # bytes count, not characters
    check_name_lengths(Path("relative") / "x")


def test_a_report_folder_replaces_its_own_files_unless_kept(tmp_path):
    out = tmp_path / "report"
    out.mkdir()
    write_text(out / "summary.md", "earlier")  # written by the project
    (out / "rows.json").write_text("a user's")
    with pytest.raises(UserError, match="rows.json: exists; pass --overwrite"):
        check_report_folder(out, ["summary.md", "rows.json"])
    check_report_folder(out, ["summary.md", "rows.json"], overwrite=True)
    (out / "rows.json").unlink()
    check_report_folder(out, ["summary.md", "rows.json"])
    with pytest.raises(UserError, match="summary.md: exists; pass --overwrite"):
        check_report_folder(out, ["summary.md"], keep=True)
    check_report_folder(out, ["summary.md"], keep=True, overwrite=True)
    (out / "rows.json").mkdir()
    with pytest.raises(UserError, match="rows.json: is a folder"):
        check_report_folder(out, ["summary.md", "rows.json"])


def test_check_writable_walks_up_to_the_nearest_existing_folder(tmp_path):
    check_writable(tmp_path / "a" / "b" / "c")
    (tmp_path / "file").write_text("")
    with pytest.raises(UserError, match=f"cannot be created \\({tmp_path / 'file'} is not a folder\\)"):
        check_writable(tmp_path / "file" / "sub")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]  # the probe is removed


def test_describe_gives_the_os_reason_in_one_line():
    assert describe(OSError(errno.ENOSPC, "HDF5 said something else")) == "No space left on device"
    assert describe(OSError(None, "its own reason")) == "its own reason"
    assert describe(OSError("first line\nsecond line")) == "first line"
    assert describe(OSError()) == "OSError"


def test_the_temporary_name_is_hidden_beside_the_output(tmp_path):
    assert temporary_path(tmp_path / "a.hdf5") == tmp_path / f".a.hdf5.partial-{os.getpid()}"


def test_fsync_of_a_special_file_is_not_an_error_and_a_failure_names_the_path(tmp_path):
    fsync_path(Path("/dev/null"))
    fsync_path(tmp_path, directory=True)
    with pytest.raises(OSError) as err:
        fsync_path(tmp_path / "absent")
    assert err.value.filename == str(tmp_path / "absent") and err.value.errno == errno.ENOENT
    read, write = os.pipe()
    os.close(read)
    os.close(write)
    with pytest.raises(OSError) as err:
        fsync_fd(write, tmp_path / "closed")
    assert err.value.filename == str(tmp_path / "closed") and err.value.errno == errno.EBADF


def test_a_sync_that_fails_keeps_the_complete_file_and_says_so(tmp_path, monkeypatch):
    def failing(fd):
        raise OSError(errno.EIO, "I/O error")

    monkeypatch.setattr(output_safety.os, "fsync", failing)
    out = tmp_path / "sub" / "r.md"
    with pytest.raises(UserError, match=r"r.md: written, but not confirmed on the disk \(Input/output error\)"):
        write_text(out, "complete")
    assert out.read_text() == "complete" and sorted(p.name for p in out.parent.iterdir()) == ["r.md"]


def test_a_folder_replaces_an_empty_one_and_leaves_no_old_copy(tmp_path):
    out = tmp_path / "dataset"
    with replacing_folder(out) as folder:
        (folder / "a").write_text("1")
    out_b = tmp_path / "empty"
    out_b.mkdir()
    with replacing_folder(out_b) as folder:
        (folder / "b").write_text("2")
    with replacing_folder(out, overwrite=True) as folder:
        (folder / "c").write_text("3")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dataset", "empty"]
    assert [p.name for p in out.iterdir()] == ["c"] and [p.name for p in out_b.iterdir()] == ["b"]


def fake_pathconf(small: Path, limit: int = 100):
    """os.pathconf as on a file system whose folder `small` allows names of `limit` bytes (others 255)."""
    def pathconf(path, name):
        assert name == "PC_NAME_MAX"
        if not Path(path).exists():
            raise FileNotFoundError(errno.ENOENT, "No such file or directory", str(path))
        return limit if Path(path) == small else 255
    return pathconf


def test_the_limit_is_the_one_of_the_nearest_existing_folder(tmp_path, monkeypatch):
    small = tmp_path / "small"
    small.mkdir()
    monkeypatch.setattr(output_safety.os, "pathconf", fake_pathconf(small))
    for out in (small / ("a" * 101), small / "new" / ("a" * 101), small / "new" / ("a" * 101) / "x"):
        with pytest.raises(UserError, match=r"bytes, longer than the file system allows \(100\)"):
            check_name_lengths(out)
    check_name_lengths(tmp_path / ("a" * 101))


@pytest.mark.parametrize("error", [OSError(errno.EINVAL, "Invalid argument"), ValueError("unrecognized configuration name")])
def test_without_a_limit_from_the_os_names_may_have_255_bytes(tmp_path, monkeypatch, error):
    def unknown(path, name):
        raise error

    monkeypatch.setattr(output_safety.os, "pathconf", unknown)
    extra = len(f".{PARTIAL}{os.getpid()}{OWNER}")
    check_name_lengths(tmp_path / ("a" * (255 - extra)))
    with pytest.raises(UserError, match=r"\(255\)"):
        check_name_lengths(tmp_path / ("a" * (256 - extra)))


def test_every_part_of_a_relative_path_is_checked(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(UserError, match="the name aaaaaaaaaaaaaaaaaaaaaaaa… is 300 bytes"):
        check_name_lengths(Path("new") / ("a" * 300) / "x")


def test_sync_fsyncs_a_file_or_everything_under_a_folder(tmp_path, monkeypatch):
    synced = []
    monkeypatch.setattr(output_safety, "fsync_path", lambda path, directory=False: synced.append((path, directory)))
    (tmp_path / "d" / "e").mkdir(parents=True)
    (tmp_path / "d" / "f").write_text("")
    (tmp_path / "d" / "e" / "g").write_text("")
    output_safety.sync(tmp_path / "d" / "f")
    assert synced == [(tmp_path / "d" / "f", False)]
    synced.clear()
    output_safety.sync(tmp_path / "d")
    assert sorted(synced) == sorted([(tmp_path / "d" / "f", False), (tmp_path / "d", True), (tmp_path / "d" / "e" / "g", False),
                                     (tmp_path / "d" / "e", True)])


def test_a_folder_output_is_probed_inside_it(tmp_path, monkeypatch):
    probed = []
    mkstemp = output_safety.tempfile.mkstemp
    monkeypatch.setattr(output_safety.tempfile, "mkstemp", lambda **kw: probed.append(kw["dir"]) or mkstemp(**kw))
    out = tmp_path / "out"
    out.mkdir()
    check_output(out, [], folder=True)
    check_output(out, [], whole=True)
    check_output(out / "r.md", [])
    assert probed == [out, out, out]


def test_a_failed_file_sync_is_reported_even_when_the_folder_syncs(tmp_path, monkeypatch):
    fsync = os.fsync

    def files_fail(fd):
        if stat.S_ISREG(os.fstat(fd).st_mode):
            raise OSError(errno.EIO, "I/O error")
        fsync(fd)

    monkeypatch.setattr(output_safety.os, "fsync", files_fail)
    with pytest.raises(UserError, match="not confirmed on the disk"):
        write_text(tmp_path / "r.md", "complete")
    assert (tmp_path / "r.md").read_text() == "complete"


def test_a_file_is_opened_read_only_to_be_synced(tmp_path, monkeypatch):
    flags = []
    real_open = os.open
    monkeypatch.setattr(output_safety.os, "open", lambda path, flag: flags.append(flag) or real_open(path, flag))
    (tmp_path / "f").write_text("")
    fsync_path(tmp_path / "f")
    fsync_path(tmp_path, directory=True)
    assert flags == [os.O_RDONLY, os.O_RDONLY | os.O_DIRECTORY]


def test_a_folder_output_may_go_into_folders_that_do_not_exist_yet(tmp_path):
    out = tmp_path / "a" / "b" / "dataset"
    with replacing_folder(out) as folder:
        (folder / "x").write_text("1")
    assert (out / "x").read_text() == "1" and sorted(p.name for p in out.parent.iterdir()) == ["dataset"]


def test_the_first_part_of_an_absolute_path_is_checked(monkeypatch):
    monkeypatch.setattr(output_safety.os, "pathconf", fake_pathconf(Path("/")))
    with pytest.raises(UserError, match=r"the name aaaaaaaaaaaaaaaaaaaaaaaa… is 150 bytes, longer than the file system allows \(100\)"):
        check_name_lengths(Path("/" + "a" * 150) / "x")


def test_the_first_part_of_a_relative_path_is_checked(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(output_safety.os, "pathconf", fake_pathconf(Path(".")))
    with pytest.raises(UserError, match=r"the name aaaaaaaaaaaaaaaaaaaaaaaa… is 150 bytes, longer than the file system allows \(100\)"):
        check_name_lengths(Path("a" * 150) / "x")


def test_named_owns_only_files_of_its_names_that_the_project_wrote(tmp_path):
    write_text(tmp_path / "summary.md", "")
    write_text(tmp_path / "other.md", "")
    (tmp_path / "rows.json").mkdir()
    (tmp_path / "theirs.md").write_text("a user's file of the name")
    (tmp_path / "link.md").symlink_to(tmp_path / "summary.md")
    shutil.copy(tmp_path / "summary.md", tmp_path / "copy.md")  # a copy without its attributes
    own = output_safety.named("summary.md", "rows.json", "theirs.md", "link.md", "copy.md")
    names = ("summary.md", "other.md", "rows.json", "absent.md", "theirs.md", "link.md", "copy.md")
    assert [own(tmp_path / n) for n in names] == [True, False, False, False, False, False, False]


def test_a_folder_that_refuses_new_files_is_not_writable(tmp_path, monkeypatch):
    def refused(**kw):
        raise PermissionError(errno.EACCES, "Permission denied")

    monkeypatch.setattr(output_safety.tempfile, "mkstemp", refused)
    with pytest.raises(UserError, match=r"not writable \(Permission denied\)"):
        check_writable(tmp_path)


def test_write_text_makes_the_folders_and_syncs_the_file_then_its_folder(tmp_path, monkeypatch):
    opened = []
    real_open = os.open
    monkeypatch.setattr(output_safety.os, "open", lambda path, flag, *mode: opened.append((Path(path), flag))
                        or real_open(path, flag, *mode))
    out = tmp_path / "a" / "b" / "r.md"
    write_text(out, "x")
    assert out.read_text() == "x"
    marker = (temporary_path(out).with_name(temporary_path(out).name + OWNER),
              os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW)  # the ownership marker, written first
    assert opened == [marker, (temporary_path(out), os.O_RDONLY), (out.parent, os.O_RDONLY | os.O_DIRECTORY)]
