"""TouchAnything Live command line: one sub-command per job; user errors print one line, exit status 2."""
from __future__ import annotations

import argparse
import errno
import os
import signal
import sys
import threading

from touchanything.app.commands import (
    bench_command,
    convert_command,
    demo_command,
    devices_command,
    eval_command,
    export_lerobot_command,
    export_onnx_command,
    grids_command,
    info_command,
    live_command,
    pose_command,
    record_command,
    replay_command,
    simulate_command,
    split_command,
    train_command,
)
from touchanything.devices.errors import Terminated, UserError

COMMANDS = (demo_command, info_command, simulate_command, convert_command, split_command, grids_command, train_command,
            eval_command, replay_command, pose_command, live_command, record_command, devices_command, export_onnx_command,
            bench_command, export_lerobot_command)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="touchanything", description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", title="commands",
                                     description="`touchanything COMMAND --help` for its options")
    for command in COMMANDS:
        command.add_parser(commands)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run one command; without one, print the commands (exit status 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    previous, previous_hook = signal.signal(signal.SIGTERM, _terminate), sys.unraisablehook
    sys.unraisablehook = _redeliver_interruptions
    try:
        return args.run(args)
    except UserError as exc:
        print(f"touchanything {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        if exc.errno != errno.ENAMETOOLONG:
            raise
        print(f"touchanything {args.command}: error: {exc.filename}: a name in this path is longer than the file "
              "system allows", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"touchanything {args.command}: interrupted", file=sys.stderr)
        return 130
    except Terminated:
        print(f"touchanything {args.command}: terminated", file=sys.stderr)
        return 128 + signal.SIGTERM
    finally:
        signal.signal(signal.SIGTERM, previous)
        sys.unraisablehook = previous_hook


def _terminate(signum: int, frame: object) -> None:
    """SIGTERM: stop as Ctrl-C does (outputs being written are removed on the way out)."""
    raise Terminated


def _redeliver_interruptions(unraisable) -> None:
    """A Ctrl-C or SIGTERM that arrived while Python ran a callback it cannot raise from (a weak reference's, a
    finaliser's) would be swallowed there: it is sent again a moment later, from another thread, to be raised
    where the command can stop (and again, should that one land in a callback too)."""
    for kind, signum in ((Terminated, signal.SIGTERM), (KeyboardInterrupt, signal.SIGINT)):
        if isinstance(unraisable.exc_value, kind):
            threading.Timer(0.01, os.kill, (os.getpid(), signum)).start()
            return
    sys.__unraisablehook__(unraisable)


if __name__ == "__main__":
    sys.exit(main())
