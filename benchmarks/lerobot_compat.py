"""Does LeRobot itself take what `export-lerobot` writes? Exports the bundled sample twice (as it is, and with
`--action observation.tactile`), times the exports, and checks each with LeRobot's own code in a side venv
(LeRobot needs Python 3.12 and its own torch, so it cannot share the project's venv; `benchmarks/
lerobot_compat_check.py` runs there). Not part of `make test`: run it by hand.

    python benchmarks/lerobot_compat.py --build            # once: makes .lerobot-venv (lerobot[dataset]==0.6.1)
    python benchmarks/lerobot_compat.py [--venv .lerobot-venv] [--out docs/bench/lerobot_compat]

Writes OUT.json (everything found) and OUT.md (the summary). Exit status 1 when a check fails.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "recordings" / "sample"
LEROBOT = "lerobot[dataset]==0.6.1"
VIDEO_TOLERANCE = 8 / 255
"""Largest difference allowed between a video feature's statistics from the source frames (what the export
writes, as LeRobot does when it records) and from the frames decoded back (H.264 at crf 20 moves a pixel by a few
of 255 levels, the extremes most)."""
NUMERIC_TOLERANCE = 1e-5


def build_venv(venv: Path) -> None:
    """A Python 3.12 venv at `venv` holding LeRobot (about 3 minutes, several GB with its torch)."""
    python = shutil.which("python3.12")
    if python is None:
        sys.exit("lerobot_compat: python3.12 not found (LeRobot 0.6 needs Python ≥ 3.12)")
    env = {**os.environ, "PYENV_VERSION": os.environ.get("PYENV_VERSION", "3.12.1")}
    subprocess.run([python, "-m", "venv", str(venv)], check=True, env=env)
    subprocess.run([str(venv / "bin" / "pip"), "install", "-q", LEROBOT], check=True)


def export(source: Path, out: Path, *extra: str) -> float:
    """Seconds `touchanything export-lerobot SOURCE OUT` takes (the whole command, start-up included)."""
    began = time.perf_counter()
    subprocess.run([str(ROOT / ".venv" / "bin" / "touchanything"), "export-lerobot", str(source), str(out), *extra],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - began


def check(venv: Path, dataset: Path, policy: bool) -> dict:
    """The findings of `lerobot_compat_check.py` run in the side venv."""
    command = [str(venv / "bin" / "python"), str(ROOT / "benchmarks" / "lerobot_compat_check.py"), str(dataset)]
    proc = subprocess.run(command + (["--policy"] if policy else []), capture_output=True, text=True,
                          env={**os.environ, "HF_HUB_OFFLINE": "1"})
    if proc.returncode != 0:
        return {"error": proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else f"exit {proc.returncode}",
                "stderr_tail": proc.stderr[-3000:]}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def failures(found: dict) -> list[str]:
    """What LeRobot did not take as it should."""
    if "error" in found:
        return [f"LeRobot failed: {found['error']}"]
    bad = [f"iteration: {key} {value}" for key, value in found["iteration"].items() if key != "frames" and value]
    if found["iteration"]["frames"] != found["frames"]:
        bad.append(f"the DataLoader gave {found['iteration']['frames']} of {found['frames']} frames")
    for key, row in found["stats"].items():
        limit = VIDEO_TOLERANCE if row["video"] else NUMERIC_TOLERANCE
        if not (row["same_keys_and_shapes"] and row["finite"] and row["max_abs_difference"] <= limit):
            bad.append(f"stats {key}: {row}")
    if "policy" in found and not found["policy"]["loss_finite"]:
        bad.append(f"policy loss {found['policy']['loss']}")
    return bad


def report(results: dict) -> str:
    """The markdown summary."""
    lines = [f"# LeRobot compatibility ({results['lerobot']})", "",
             f"`python benchmarks/lerobot_compat.py` on {results['machine']}, {results['date']}: the bundled sample "
             f"({results['episodes']} episodes of 10 s, three 640×480 views) exported, then loaded and checked with "
             "LeRobot's own code in a Python 3.12 side venv.", "",
             "| export | export time | LeRobotDataset | frames through a DataLoader | stats: numeric max Δ | stats: video max Δ "
             "| policy |",
             "|---|---|---|---|---|---|---|"]
    for name, run in results["exports"].items():
        found = run["lerobot"]
        if "error" in found:
            lines.append(f"| {name} | {run['seconds']:.1f} s | failed: {found['error']} | | | | |")
            continue
        numeric = max(r["max_abs_difference"] for r in found["stats"].values() if not r["video"])
        video = max(r["max_abs_difference"] for r in found["stats"].values() if r["video"])
        policy = (f"ACT, loss {found['policy']['loss']:.3f} (finite)" if "policy" in found else "—")
        lines.append(f"| {name} | {run['seconds']:.1f} s ({run['seconds'] / results['episodes']:.1f} s per 10-s episode) | "
                     f"{found['episodes']} episodes, {found['frames']} frames, splits {found['splits']} | "
                     f"{found['iteration']['frames']}, all finite, shapes as info.json | {numeric:.1e} | {video:.4f} | {policy} |")
    lines += ["", "Statistics compared per feature: the same keys (min, max, mean, std, count, q01–q99) and shapes "
              "(the feature's last axis; (3, 1, 1) per video) as LeRobot's `compute_episode_stats` + `aggregate_stats` "
              "give; numeric features within 1e-5, videos within 8/255 (LeRobot's recount reads the frames decoded from "
              "the export's H.264, the export's statistics the source frames, as LeRobot's recorder does).", "",
              f"Result: {'every check passed' if not results['failures'] else 'FAILED: ' + '; '.join(results['failures'])}."]
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--venv", type=Path, default=ROOT / ".lerobot-venv", help="the side venv holding LeRobot")
    parser.add_argument("--build", action="store_true", help=f"make the side venv first ({LEROBOT})")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "bench" / "lerobot_compat", help="OUT.json and OUT.md")
    args = parser.parse_args()
    if args.build:
        build_venv(args.venv)
    if not (args.venv / "bin" / "python").exists():
        sys.exit(f"lerobot_compat: {args.venv}: no venv; make it with --build")
    version = subprocess.run([str(args.venv / "bin" / "python"), "-c", "import lerobot; print(lerobot.__version__)"],
                             capture_output=True, text=True)
    if version.returncode != 0:
        sys.exit(f"lerobot_compat: {args.venv}: LeRobot does not import there; make the venv again with --build")
    results = {"lerobot": f"lerobot {version.stdout.strip()}", "machine": f"{platform.machine()}, {os.cpu_count()} cores",
               "date": time.strftime("%Y-%m-%d"), "episodes": len([p for p in SAMPLE.glob("*/*/*") if p.is_dir()]), "exports": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for name, extra, policy in (("as it is", (), False), ("--action observation.tactile", ("--action", "observation.tactile"), True)):
            out = Path(tmp) / name.replace(" ", "_").replace("-", "")
            seconds = export(SAMPLE, out, *extra)
            results["exports"][name] = {"seconds": round(seconds, 2), "lerobot": check(args.venv, out, policy)}
    results["failures"] = [f"{name}: {bad}" for name, run in results["exports"].items() for bad in failures(run["lerobot"])]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.with_suffix(".json").write_text(json.dumps(results, indent=1) + "\n")
    args.out.with_suffix(".md").write_text(report(results))
    print(report(results))
    return 1 if results["failures"] else 0


if __name__ == "__main__":
    sys.exit(main())
