"""TouchAnything Live command line: one sub-command per job; user errors print one line, exit status 2."""
from __future__ import annotations

import argparse
import errno
import signal
import sys

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
from touchanything.app.interruptions import stoppable
from touchanything.core.errors import Terminated, UserError

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
    """Run one command; without one, print the commands (what `--help` prints, exit status 0)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        with stoppable():
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


if __name__ == "__main__":
    sys.exit(main())
