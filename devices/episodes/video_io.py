"""Video files through PyAV: RGB frames in memory, random access by frame index, crash-safe H.264 writing."""
from __future__ import annotations

import contextlib
import errno
import itertools
import os
from collections.abc import Callable, Iterator
from fractions import Fraction
from pathlib import Path

import av
import cv2
import numpy as np

from touchanything.core.errors import DataError
from touchanything.core.output_safety import fsync_fd

MAX_FPS = 240
"""A frame rate outside 1..MAX_FPS (a damaged header: 30/65537 was seen) is not believed: the guessed rate, else
30, is used."""
SEEK_AHEAD = 45
"""Decode forward instead of seeking when the wanted frame is at most this many frames ahead."""


def to_rgb(frame: av.VideoFrame) -> np.ndarray:
    """(H, W, 3) uint8 RGB; yuv420p goes through OpenCV's SIMD conversion (BT.601 limited range, the
    same matrix swscale uses, within ±3 levels), about 1.4× faster than PyAV's rgb24 path here."""
    if frame.format.name == "yuv420p":
        return cv2.cvtColor(frame.to_ndarray(), cv2.COLOR_YUV2RGB_I420)
    return frame.to_ndarray(format="rgb24")


class VideoReader:
    """Frames of one video as (H, W, 3) uint8 RGB, by index; sequential reads decode each frame once.

    `num_frames` comes from the container's packets (fast); a truncated file can decode fewer, which
    `read` reports by returning None past the last decodable frame.
    """

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise DataError(self.path, None, "file not found")
        try:
            self._container = av.open(str(self.path))
            if not self._container.streams.video:
                raise DataError(self.path, None, "no video stream in the file")
            self._stream = self._container.streams.video[0]
            if self._stream.codec_context is None or not (self._stream.codec_context.width > 0
                                                          and self._stream.codec_context.height > 0):
                raise DataError(self.path, None, "unreadable video (no picture size: the file's header is damaged)")
            self._stream.thread_type = "AUTO"
            rates = (float(self._stream.average_rate or 0), float(self._stream.guessed_rate or 0))
            self.fps = next((rate for rate in rates if 1 <= rate <= MAX_FPS), 30.0)
            self.width = self._stream.codec_context.width
            self.height = self._stream.codec_context.height
            self.num_frames = self._count_packets()
        except DataError:
            self._container.close()
            raise
        except (av.error.FFmpegError, AttributeError, IndexError, ValueError, ZeroDivisionError) as exc:
            if hasattr(self, "_container"):
                self._container.close()
            reason = getattr(exc, "strerror", None) or str(exc) or exc.__class__.__name__
            raise DataError(self.path, None, f"unreadable video ({reason})") from None
        self._start = self._stream.start_time or 0
        self._decoder: Iterator[av.VideoFrame] | None = None
        self._next = 0

    def _count_packets(self) -> int:
        """Packets up to the end, or up to damage that stops the demuxer (what is before it stays readable)."""
        count = 0
        try:
            for packet in self._container.demux(self._stream):
                count += 1 if packet.size else 0
        except av.error.FFmpegError:
            pass
        self._container.seek(0, stream=self._stream)
        return count

    def _index_of(self, frame: av.VideoFrame) -> int:
        if frame.pts is None:
            return self._next
        return round(float((frame.pts - self._start) * self._stream.time_base) * self.fps)

    def _pts(self, index: int) -> int:
        return self._start + int(Fraction(index) / Fraction(self.fps).limit_denominator(1001) / self._stream.time_base)

    def _seek(self, index: int) -> None:
        """Position the decoder at or before `index`; fragmented MP4 seeks can land on a later key
        frame, so step back further (finally to the start) until the first frame is not past `index`."""
        back = 0
        while True:
            start = max(index - back, 0)
            self._container.seek(self._pts(start), stream=self._stream, backward=True, any_frame=False)
            decoder = self._container.decode(self._stream)
            first = next(decoder, None)
            if first is None or start == 0 or self._index_of(first) <= index:
                break
            back = max(2 * back, int(self.fps))
        self._decoder = decoder if first is None else itertools.chain([first], decoder)
        self._next = -1

    def read(self, index: int) -> np.ndarray | None:
        """Frame `index` as RGB, or None when the file ends (or stops decoding) before it."""
        if not 0 <= index < self.num_frames:
            return None
        try:
            if self._decoder is None or index < self._next or index > self._next + SEEK_AHEAD:
                self._seek(index)
            for frame in self._decoder:
                found = self._index_of(frame)
                self._next = found + 1
                if found >= index:
                    return to_rgb(frame)
        except (av.error.FFmpegError, ValueError, cv2.error):  # damage past which nothing decodes
            pass
        self._decoder = None
        return None

    def frames(self, start: int = 0) -> Iterator[np.ndarray]:
        """Consecutive frames from `start` until the last decodable one."""
        index = start
        while (image := self.read(index)) is not None:
            yield image
            index += 1

    def close(self) -> None:
        self._container.close()

    def __enter__(self) -> VideoReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _VideoFile:
    """The file FFmpeg writes a video into, through PyAV's Python I/O, so that no write error is lost: when FFmpeg
    writes its own file, the error of the flush that writes the last fragment (at close) is dropped (libavformat
    62), and a full disk left a cut file behind a successful close. Created by FFmpeg's first write (the
    encoder's first packet), as a new file (an existing path, a link included, is never opened: EEXIST); every write
    reaches the OS at once and whole. The first failure — an OSError naming
    the file, or an interruption (Ctrl-C) that landed in it — is kept in `failure` and answered to FFmpeg as an
    error code (an exception cannot pass through FFmpeg): `VideoWriter` raises it once FFmpeg returns."""

    def __init__(self, path: Path) -> None:
        self.path, self.name = path, str(path)
        self.failure: BaseException | None = None
        self._fd: int | None = None

    def _call(self, step: Callable[[int], int]) -> int:
        """`step(fd)` on the file (created first), or a negative error code for FFmpeg, the failure kept."""
        if self.failure is not None:
            return -errno.EIO
        try:
            if self._fd is None:
                self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o666)
            return step(self._fd)
        except OSError as exc:
            self.failure = OSError(exc.errno, exc.strerror, self.name)
            return -(exc.errno or errno.EIO)
        except BaseException as exc:  # an interruption: raised again by VideoWriter once FFmpeg returns
            self.failure = exc
            return -errno.EINTR

    def write(self, data: bytes) -> int:
        def write_all(fd: int) -> int:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view):]
            return len(data)
        return self._call(write_all)

    def seek(self, offset: int, whence: int = os.SEEK_SET) -> int:
        return self._call(lambda fd: os.lseek(fd, offset, whence))

    def tell(self) -> int:
        return self._call(lambda fd: os.lseek(fd, 0, os.SEEK_CUR))

    def sync(self) -> bool:
        """fsync the file; False when FFmpeg has not created it yet."""
        if self._fd is None:
            return False
        fsync_fd(self._fd, self.path)
        return True

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def raise_failure(self) -> None:
        """Raise the kept failure, if any."""
        if self.failure is not None:
            raise self.failure from None


class VideoWriter:
    """H.264 (libx264, yuv420p) in fragmented MP4: every completed 1 s fragment stays readable after a crash.

    `flush_packets` hands each fragment to the OS as soon as it is complete; without it FFmpeg keeps up to
    32 KiB in its own buffer, which a killed process loses (a small or still picture loses seconds).
    `sync()` asks the OS to put what it holds on the disk (fsync), so the completed fragments also survive
    a crash of the machine; `close(sync=True)` does it after the last fragment.

    Every error writing the file (a full disk, an I/O error, a quota, a read-only file system, a file-size
    limit), met while muxing a frame's packets, flushing the encoder or closing the container, is raised as an
    OSError with its errno and the file's name (`_VideoFile`): a writer that returns wrote the whole video.
    """

    def __init__(self, path: Path, fps: int = 30, crf: int = 20, preset: str = "veryfast", fragmented: bool = True,
                 codec_options: dict[str, str] | None = None, metadata: dict[str, str] | None = None) -> None:
        """`fragmented` False: a plain MP4 (index at the end; readable only once closed). `codec_options`: more
        libx264 options (e.g. {"g": "2", "bf": "0"}), over the defaults (key frame every second). `metadata`:
        the container's tags (e.g. {"comment": …}; `video_comment` reads it back)."""
        self.path = Path(path)
        self.metadata = metadata or {}
        self.fps, self.crf, self.preset = fps, crf, preset
        self.fragmented, self.codec_options = fragmented, codec_options or {}
        self._container: av.container.OutputContainer | None = None
        self._stream = None
        self._file = _VideoFile(self.path)
        self.frames_written = 0

    def _open(self, width: int, height: int) -> None:
        if width % 2 or height % 2:
            raise ValueError(f"H.264 needs even frame sizes, got {width}×{height}")
        options = {"movflags": "frag_keyframe+empty_moov+default_base_moof", "flush_packets": "1"} if self.fragmented else {}
        self._container = av.open(self._file, "w", format="mp4", options=options)
        self._container.metadata.update(self.metadata)
        self._stream = self._container.add_stream("libx264", rate=self.fps)
        self._stream.width, self._stream.height, self._stream.pix_fmt = width, height, "yuv420p"
        self._stream.options = {"crf": str(self.crf), "preset": self.preset, "g": str(self.fps), **self.codec_options}

    @contextlib.contextmanager
    def _writing(self) -> Iterator[None]:
        """Around FFmpeg's work on the file: the file's own failure is raised, in place of the error FFmpeg made
        of it, or when FFmpeg dropped it."""
        try:
            yield
        except av.error.FFmpegError:
            self._file.raise_failure()
            raise
        self._file.raise_failure()

    def write(self, rgb: np.ndarray) -> None:
        """Append one (H, W, 3) uint8 RGB frame."""
        if self._container is None:
            self._open(rgb.shape[1], rgb.shape[0])
        frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(rgb, dtype=np.uint8), format="rgb24")
        with self._writing():
            self._container.mux(self._stream.encode(frame))
        self.frames_written += 1

    def sync(self) -> bool:
        """fsync the file: every fragment FFmpeg has handed to the OS is on the disk when this returns (the
        fragment being encoded is not: it is written when complete). False when there is no file yet: FFmpeg
        creates it with the encoder's first packet, some frames after the first `write`."""
        return self._container is not None and self._file.sync()

    def close(self, sync: bool = False) -> None:
        """Write the last fragment and close the file; `sync`: fsync it after (see `sync()`). The file is closed
        also when this raises."""
        try:
            if self._container is None:
                return
            with self._writing():
                try:
                    self._container.mux(self._stream.encode())
                finally:
                    container, self._container = self._container, None
                    container.close()
            if sync:
                self._file.sync()
        finally:
            self._file.close()

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def video_comment(path: Path) -> str | None:
    """The `comment` tag of a video file's container (None: no tag, or not a video PyAV opens)."""
    try:
        with av.open(str(path)) as container:
            return container.metadata.get("comment")
    except (av.FFmpegError, OSError, ValueError):
        return None
