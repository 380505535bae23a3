"""`touchanything pose VIDEO --out wilor_hands.json`: the hands of every frame of a plain video, estimated
from the camera (bare hands), written in the official WiLoR JSON-lines format, with a progress bar."""
from __future__ import annotations

import argparse
from pathlib import Path

from touchanything.core.output_safety import add_overwrite_argument


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("pose", help="estimate the hands in a video (bare hands) into a wilor_hands.json file")
    parser.add_argument("video", type=Path, help="any video file PyAV reads")
    parser.add_argument("--out", type=Path, required=True, help="the .json file to write (e.g. wilor_hands.json beside "
                                                                "the episode's chest.mp4)")
    parser.add_argument("--mirror", action="store_true", help="the video is mirrored (a selfie webcam): swap the "
                                                              "left and right labels")
    add_overwrite_argument(parser, "--out")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from touchanything.app.sessions.pose_file import write_pose_file
    from touchanything.devices.camera_pose.estimator import CameraPoseConfig

    bars: list[tqdm] = []

    def show(done: int, total: int) -> None:
        """The progress bar appears once the inputs were checked (an error is then one line on its own)."""
        if not bars:
            bars.append(tqdm(total=total, unit="frame", desc="pose"))
        bars[0].update(done - bars[0].n)

    try:
        summary = write_pose_file(args.video, args.out, CameraPoseConfig(mirror=args.mirror), args.overwrite, show)
    finally:
        for bar in bars:
            bar.close()
    print(summary.pose_line())
    if summary.frames and not any(summary.hands):
        print("no hand   found in any frame: the camera estimate finds bare hands only — gloved hands (EgoTouch's tactile "
              "gloves, the bundled sample's) are not detected (docs/camera_pose.md)")
    print(f"wrote     {args.out}")
    return 0
