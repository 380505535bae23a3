"""Build the hand-landmark model file at install time (`make demo` / `make test` run it; `make hand-model`).

    .venv/bin/python scripts/build_hand_model.py [--out PATH] [--wheel WHEEL]

Downloads Google's `mediapipe==0.10.21` wheel from the package registry (pip, no dependencies, the
manylinux x86-64 CPython 3.11 build, whichever machine runs this: the models inside are the same bytes), takes
its palm-detection and hand-landmark models, checks their sha256 against the digests pinned in
`touchanything.devices.camera_pose.model_file` and writes the `.task` file (default: inside this Python
environment, `.venv/share/touchanything/hand_landmarker.task`). A file already there that checks out is
kept (nothing is downloaded; its time is refreshed, so make sees it up to date). `--wheel` takes a wheel
downloaded before (an offline machine).
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

from touchanything.core.errors import UserError
from touchanything.devices.camera_pose.model_file import SOURCE_WHEEL, build_model, installed_model_path, read_model

PLATFORM = ("--only-binary=:all:", "--platform", "manylinux_2_28_x86_64", "--python-version", "3.11",
            "--implementation", "cp", "--abi", "cp311")


def download_wheel(folder: Path) -> Path:
    """pip download of the source wheel into `folder`; its path."""
    command = [sys.executable, "-m", "pip", "download", SOURCE_WHEEL, "--no-deps", "--quiet", "--dest", str(folder),
               *PLATFORM]
    result = subprocess.run(command, capture_output=True, text=True)
    wheels = sorted(folder.glob("mediapipe-*.whl"))
    if result.returncode != 0 or not wheels:
        tail = (result.stderr.strip().splitlines() or ["no wheel downloaded"])[-1]
        raise UserError(f"pip could not download {SOURCE_WHEEL} ({tail})")
    return wheels[0]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=installed_model_path(), help="the .task file to write")
    parser.add_argument("--wheel", type=Path, help=f"a {SOURCE_WHEEL} wheel already downloaded")
    args = parser.parse_args()
    try:
        read_model(args.out)
        args.out.touch()
        print(f"{args.out}: hand model present and checked")
        return 0
    except UserError:
        pass
    try:
        if args.wheel is not None:
            build_model(args.wheel, args.out)
        else:
            with tempfile.TemporaryDirectory() as folder:
                build_model(download_wheel(Path(folder)), args.out)
        read_model(args.out)
    except UserError as exc:
        print(f"build_hand_model: error: {exc}", file=sys.stderr)
        return 2
    print(f"{args.out}: hand model built from {SOURCE_WHEEL} ({args.out.stat().st_size / 2**20:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
