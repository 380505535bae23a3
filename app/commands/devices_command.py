"""`touchanything devices [--listen S]`: list the attached devices a scene can use — OpenCV cameras (with
the size and fps they negotiate), OAK cameras, serial ports (listened to for JQ gloves), Vive trackers
through SteamVR — one line per kind when there are none, then a scene-file (TOML) snippet for what was found.
"""
from __future__ import annotations

import argparse
import json
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from touchanything.core.snapshot import TRACKER_ROLES, VIEW_NAMES

if TYPE_CHECKING:  # the finders import OpenCV and pyserial: only when the command runs
    from touchanything.devices.hardware.discovery import Discovery, FoundCamera, FoundOak, FoundSerialPort, FoundTracker

LISTEN_S = 0.3


def add_parser(commands: argparse._SubParsersAction) -> None:
    parser = commands.add_parser("devices", help="list the attached cameras, gloves and trackers, and a scene "
                                                 "snippet for them")
    parser.add_argument("--listen", type=float, default=LISTEN_S, metavar="S",
                        help=f"seconds to listen to each serial port for JQ glove packets (default {LISTEN_S:g}; "
                             "0: do not open the ports)")
    parser.set_defaults(run=run)


@dataclass(frozen=True)
class Findings:
    """What the finders returned, by kind."""

    opencv: Discovery[FoundCamera]
    oak: Discovery[FoundOak]
    serial: Discovery[FoundSerialPort]
    trackers: Discovery[FoundTracker]


def discover(listen_s: float) -> Findings:
    """Run every finder (nothing here raises for absent hardware or libraries)."""
    from touchanything.devices.hardware import discovery

    return Findings(discovery.find_opencv_cameras(), discovery.find_oak_cameras(),
                    discovery.find_serial_ports(listen_s=listen_s), discovery.find_openvr_trackers())


def report_lines(findings: Findings) -> list[str]:
    """One header line per kind ("none found (why)" or "N found"), then one line per device."""
    kinds = (("OpenCV cameras", findings.opencv, lambda c: f"{c.source}" + (f" ({c.device})" if c.device != str(c.source)
                                                                          else "") + f": {c.format}"),
             ("OAK cameras", findings.oak, lambda o: f"{o.device_id} ({o.name}, {o.state})"),
             ("serial ports", findings.serial, lambda p: f"{p.port} → {p.device}: {p.detail}"),
             ("Vive trackers", findings.trackers, lambda t: f"{t.serial} ({'tracking' if t.tracking else 'not tracking'})"))
    lines = []
    for title, found, describe in kinds:
        if not found.found:
            lines.append(f"{title + ':':16s}none found ({found.reason})")
            continue
        lines.append(f"{title + ':':16s}{len(found.found)} found")
        lines.extend(f"  {describe(item)}" for item in found.found)
    return lines


def toml_value(value: object) -> str:
    """A TOML literal of a str, bool, int or finite float."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float) and math.isfinite(value):
        return repr(value)
    return json.dumps(str(value))


def section(name: str, settings: dict[str, object], note: str = "", commented: bool = False) -> list[str]:
    """A TOML table; `commented` writes it as comments (a device found but not placed in the scene)."""
    lines = ([f"# {note}"] if note else []) + [f"[{name}]"] + [f"{key} = {toml_value(value)}"
                                                              for key, value in settings.items()]
    return [f"# {line}" if commented and not line.startswith("#") else line for line in lines]


def camera_sections(findings: Findings) -> list[list[str]]:
    """OAK cameras, then OpenCV cameras, on the views in order; any beyond three as comments."""
    cameras = [{"kind": "oak", "device_id": oak.device_id} for oak in findings.oak.found]
    for camera in findings.opencv.found:
        fps = {"fps": camera.format.fps} if camera.format.fps else {}
        cameras.append({"kind": "opencv", "source": camera.source, "width": camera.format.width,
                        "height": camera.format.height, **fps})
    return [section(f"cameras.{VIEW_NAMES[i]}", settings) if i < len(VIEW_NAMES)
            else section("cameras.VIEW", settings, "one more camera: give it a free view", commented=True)
            for i, settings in enumerate(cameras)]


def glove_sections(findings: Findings) -> list[list[str]]:
    """A [gloves.<side>] for each side heard (the first port carrying it); unknown ports as comments."""
    blocks, placed = [], set()
    for port in findings.serial.found:
        for side in port.sides:
            if side not in placed:
                placed.add(side)
                blocks.append(section(f"gloves.{side}", {"port": port.port}))
        if not port.sides:
            blocks.append(section("gloves.SIDE", {"port": port.port}, f"{port.detail}; left or right if it is a "
                                  "JQ glove", commented=True))
    return blocks


def tracker_sections(findings: Findings) -> list[list[str]]:
    """[trackers] with the serials found mapped to the roles in order (check which tracker is where)."""
    serials = [tracker.serial for tracker in findings.trackers.found]
    if not serials:
        return []
    roles = {serial: role for serial, role in zip(serials, TRACKER_ROLES)}
    lines = ["[trackers]", "", "[trackers.roles]", "# roles assigned in the order found: check which tracker is where"]
    lines += [f"{toml_value(serial)} = {toml_value(role)}" for serial, role in roles.items()]
    lines += [f"# {toml_value(serial)} = \"ROLE\"  (one more tracker)" for serial in serials[len(TRACKER_ROLES):]]
    return [lines]


def scene_snippet(findings: Findings) -> str:
    """The scene-file tables for what was found ("" when nothing was)."""
    blocks = camera_sections(findings) + glove_sections(findings) + tracker_sections(findings)
    return "\n\n".join("\n".join(block) for block in blocks)


def run(args: argparse.Namespace) -> int:
    from touchanything.core.errors import UserError

    if not (math.isfinite(args.listen) and args.listen >= 0):
        raise UserError(f"--listen must be a number of seconds ≥ 0, got {args.listen}")
    findings = discover(args.listen)
    print("\n".join(report_lines(findings)))
    snippet = scene_snippet(findings)
    if not snippet:
        print("\nnothing found to put in a scene file (scenes/sim.toml runs the simulated rig without hardware)")
        return 0
    print("\n# Scene file snippet (TOML) for what was found: check the views, sides and roles against your rig,"
          "\n# then add [hands] and [pose] for the Rokoko mocap (docs/devices.md, \"Scenes\").\n")
    print(snippet)
    return 0
