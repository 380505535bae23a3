"""The hand-landmark model file: MediaPipe's Tasks `.task` bundle, built at install time, checked at run time.

No mediapipe wheel from 0.10.30 on carries the hand models, and nothing may be downloaded at run time. So
`scripts/build_hand_model.py` (run by `make demo` / `make test`, or `make hand-model`) downloads Google's own
`mediapipe==0.10.21` wheel from the package registry, takes its palm-detection and hand-landmark models
(checked against the digests pinned here) and writes the `.task` file: a zip holding them as
`hand_detector.tflite` and `hand_landmarks_detector.tflite`, which the Tasks API's HandLandmarker loads. It
lives inside the environment (`<sys.prefix>/share/touchanything/hand_landmarker.task`, i.e. `.venv/share/…`),
never in git. At run time the file is read and its members are checked against the same digests.
"""
from __future__ import annotations

import hashlib
import io
import os
import sys
import zipfile
from pathlib import Path

from touchanything.core.errors import UserError

SOURCE_WHEEL = "mediapipe==0.10.21"
MEMBERS = {
    "hand_detector.tflite": ("mediapipe/modules/palm_detection/palm_detection_full.tflite",
                             "1b14e9422c6ad006cde6581a46c8b90dd573c07ab7f3934b5589e7cea3f89a54"),
    "hand_landmarks_detector.tflite": ("mediapipe/modules/hand_landmark/hand_landmark_full.tflite",
                                       "11c272b891e1a99ab034208e23937a8008388cf11ed2a9d776ed3d01d0ba00e3"),
}
"""Member of the .task file → (its path in the source wheel, its sha256)."""
BUILD_COMMAND = "make hand-model (or: python scripts/build_hand_model.py)"


def installed_model_path() -> Path:
    """Where the install step puts the .task file: inside the running Python environment."""
    return Path(sys.prefix) / "share" / "touchanything" / "hand_landmarker.task"


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def read_model(path: Path | None = None) -> bytes:
    """The bytes of a checked .task file (default: the installed one); UserError (one line saying how to
    build it) when it is missing, unreadable or not the pinned models."""
    path = Path(path) if path is not None else installed_model_path()
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise UserError(f"{path}: hand model file not found; build it with `{BUILD_COMMAND}`") from None
    except OSError as exc:
        raise UserError(f"{path}: cannot read the hand model file ({exc.strerror})") from None
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as bundle:
            members = {name: bundle.read(name) for name in MEMBERS if name in bundle.namelist()}
    except (zipfile.BadZipFile, OSError, ValueError, EOFError):
        members = {}
    problems = [name for name, (_, digest) in MEMBERS.items() if name not in members or _digest(members[name]) != digest]
    if problems:
        raise UserError(f"{path}: not the pinned hand model ({', '.join(problems)} missing or changed); rebuild it "
                        f"with `{BUILD_COMMAND}`")
    return data


def build_model(wheel: Path, out: Path) -> None:
    """Write the .task file `out` from the models in the `mediapipe==0.10.21` wheel `wheel`, checked against
    the pinned digests (UserError otherwise); the same wheel always gives the same file. Written to a
    temporary file and renamed: a reader never sees a partial file."""
    try:
        with zipfile.ZipFile(wheel) as source:
            models = {name: source.read(inside) for name, (inside, _) in MEMBERS.items()}
    except (OSError, zipfile.BadZipFile, KeyError) as exc:
        raise UserError(f"{wheel}: not a mediapipe wheel holding the hand models ({exc})") from None
    for name, data in models.items():
        inside, digest = MEMBERS[name]
        if _digest(data) != digest:
            raise UserError(f"{wheel}: {inside} has sha256 {_digest(data)}, expected {digest}")
    out.parent.mkdir(parents=True, exist_ok=True)
    partial = out.with_name(out.name + ".partial")
    with zipfile.ZipFile(partial, "w", zipfile.ZIP_STORED) as bundle:
        for name, data in models.items():  # fixed entry times: the same wheel gives the same bytes
            bundle.writestr(zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0)), data)
    os.replace(partial, out)
