"""Mutation testing of the core modules with cosmic-ray: how many small code changes (mutants) the narrow tests of
each module notice. Not part of `make test`: run it by hand (docs/testing.md).

    python benchmarks/mutation.py --build                  # once: makes .mutation-venv (cosmic-ray==8.7.0 only)
    nice -n 10 python benchmarks/mutation.py [--modules metrics frame_facts ...] [--out docs/bench/mutation]

What is committed at HEAD is cloned into a scratch folder and mutated there (the working tree is never touched);
inside the clone `touchanything/` gets links to app/, devices/, inference/ and viz/, so that with the clone on
PYTHONPATH `import touchanything.inference...` imports the clone's (mutated) files, not the editable install's.
Per module: one unmutated run of its tests (the baseline, which sets the timeout), `cosmic-ray init`, the
operators outside `OPERATORS` and the mutants inside annotations skipped, `cosmic-ray exec` (local, one mutant at
a time), `cosmic-ray dump`. Writes OUT.json (per module: counts, score, every survivor with its diff) and OUT.md;
modules not run this time keep their earlier entry. A survivor listed in `EQUIVALENT` is reported with the reason
it cannot be killed and does not count against the score over non-equivalent mutants.
"""
from __future__ import annotations

import argparse
import ast
import json
import os
import platform
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mutation_equivalents import EQUIVALENT
from mutation_modules import MODULES, OPERATORS, Module

ROOT = Path(__file__).resolve().parents[1]
COSMIC_RAY = "cosmic-ray==8.7.0"
PYTHON = ROOT / ".venv" / "bin" / "python"
PACKAGES = ("app", "devices", "inference", "viz")
PYTEST = ("-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "-p", "no:randomly", "-p", "no:xdist",
          "--hypothesis-seed=0")

_SKIP_SCRIPT = """
import json, sys
from cosmic_ray.work_db import use_db
from cosmic_ray.work_item import WorkResult, WorkerOutcome
with use_db(sys.argv[1]) as db:
    for job_id, reason in json.loads(sys.argv[2]).items():
        db.set_result(job_id, WorkResult(output=reason, worker_outcome=WorkerOutcome.SKIPPED))
"""


def build_venv(venv: Path) -> None:
    """A venv at `venv` holding cosmic-ray only (it imports none of the project; the tests run in .venv)."""
    subprocess.run([str(PYTHON), "-m", "venv", str(venv)], check=True)
    subprocess.run([str(venv / "bin" / "pip"), "install", "-q", COSMIC_RAY], check=True)


def make_clone(scratch: Path, rev: str) -> Path:
    """Commit `rev` cloned into `scratch`/clone, its `touchanything/` linking the four packages, byte-compiled; ../shared
    linked beside it."""
    clone = scratch / "clone"
    subprocess.run(["git", "clone", "-q", "--no-hardlinks", str(ROOT), str(clone)], check=True)
    subprocess.run(["git", "checkout", "-q", "--detach", rev], cwd=clone, check=True)
    for package in PACKAGES:
        (clone / "touchanything" / package).symlink_to(Path("..") / package)
    if (ROOT.parent / "shared").is_dir():  # the official files the tests find beside the checkout (tests/conftest.py)
        (scratch / "shared").symlink_to(ROOT.parent / "shared")
    subprocess.run([str(PYTHON), "-m", "compileall", "-q", *PACKAGES, "touchanything", "tests"], cwd=clone,
                   check=True, stdout=subprocess.DEVNULL)
    return clone


def test_env(clone: Path) -> dict[str, str]:
    env = {**os.environ, "PYTHONPATH": str(clone), "PYTHONDONTWRITEBYTECODE": "1"}
    env.pop("PYTEST_ADDOPTS", None)
    return env


def test_command(module: Module) -> str:
    """The command line cosmic-ray runs per mutant (it splits it with shlex; the baseline runs the same)."""
    return shlex.join([str(PYTHON), *PYTEST, *module.pytest_args, *module.tests])


def annotation_lines(source: str) -> set[tuple[int, int]]:
    """(line, column) of every character inside an annotation (not evaluated: every module has
    `from __future__ import annotations`)."""
    spans = set()
    for node in ast.walk(ast.parse(source)):
        notes = []
        if isinstance(node, ast.arg | ast.AnnAssign) and node.annotation is not None:
            notes.append(node.annotation)
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and node.returns is not None:
            notes.append(node.returns)
        for note in notes:
            for line in range(note.lineno, note.end_lineno + 1):
                first = note.col_offset if line == note.lineno else 0
                last = note.end_col_offset if line == note.end_lineno else 10_000
                spans.update((line, col) for col in range(first, last))
    return spans


def run_module(name: str, module: Module, clone: Path, venv: Path, scratch: Path, earlier: dict | None = None) -> dict:
    """The mutation run of one module: counts, score, survivors. `earlier`: an earlier run's row of the same source
    whose killed mutants are taken as they are (tests added since can only kill more): only its survivors run."""
    cr = venv / "bin"
    env = test_env(clone)
    missing = [t for t in module.tests if not (clone / t).exists()]
    tests = tuple(t for t in module.tests if t not in missing)
    module = Module(module.path, tests, module.pytest_args, module.functions)
    if not tests:  # pytest without files would run the whole suite
        return {"path": module.path, "tests": list(missing), "error": "none of its tests exist at this commit"}
    began = time.perf_counter()
    baseline = subprocess.run(shlex.split(test_command(module)), cwd=clone, env=env, capture_output=True, text=True)
    baseline_s = time.perf_counter() - began
    if baseline.returncode != 0:
        return {"path": module.path, "tests": list(tests), "error": "the tests fail unmutated",
                "output_tail": baseline.stdout[-3000:]}
    timeout = round(max(20.0, 3 * baseline_s + 10), 1)
    config = scratch / f"{name}.toml"
    session = scratch / f"{name}.sqlite"
    config.write_text("\n".join([
        "[cosmic-ray]", f'module-path = "{module.path}"', f"timeout = {timeout}", "excluded-modules = []",
        f"test-command = {json.dumps(test_command(module))}", "",
        "[cosmic-ray.distributor]", 'name = "local"', "",
        "[cosmic-ray.filters.operators-filter]",
        f"exclude-operators = {json.dumps(['core/(?!(' + '|'.join(re.escape(o[5:]) for o in OPERATORS) + ')$)'])}",
        ""]))
    subprocess.run([str(cr / "cosmic-ray"), "init", str(config), str(session)], cwd=clone, check=True)
    subprocess.run([str(cr / "cr-filter-operators"), str(session), str(config)], cwd=clone, check=True)
    source = (clone / module.path).read_text()
    notes = annotation_lines(source)
    skip = {}
    retest = {(v["operator"], v["occurrence"]) for v in earlier["survivors"]} if earlier is not None else set()
    for item, result in dump(cr, session, clone):
        mutation = item["mutations"][0]
        if result is None and tuple(mutation["start_pos"]) in notes:
            skip[item["job_id"]] = "in an annotation"
        elif result is None and module.functions and mutation.get("definition_name") not in module.functions:
            skip[item["job_id"]] = "outside the functions under test"
        elif result is None and earlier is not None and (mutation["operator_name"], mutation["occurrence"]) not in retest:
            skip[item["job_id"]] = "killed in the earlier run"
    subprocess.run([str(cr / "python"), "-c", _SKIP_SCRIPT, str(session), json.dumps(skip)], check=True)
    began = time.perf_counter()
    subprocess.run([str(cr / "cosmic-ray"), "exec", str(config), str(session)], cwd=clone, env=env, check=True)
    seconds = time.perf_counter() - began
    lines = source.splitlines()
    counts = {"mutants": 0, "killed": 0, "timeouts": 0, "survived": 0, "incompetent": 0, "equivalent": 0}
    survivors = []
    for item, result in dump(cr, session, clone):
        if result is None or result["worker_outcome"] in ("skipped", "no-test"):
            continue
        counts["mutants"] += 1
        mutation = item["mutations"][0]
        if (result["worker_outcome"] != "normal" or result["test_outcome"] == "incompetent"
                or "no tests ran" in (result["output"] or "")):  # pytest ran nothing: the command, not the mutant
            counts["incompetent"] += 1
            continue
        if result["test_outcome"] == "killed":
            counts["timeouts" if result["output"] == "timeout" else "killed"] += 1
            continue
        counts["survived"] += 1
        line = mutation["start_pos"][0]
        text = lines[line - 1].strip()
        survivors.append({"line": line, "column": mutation["start_pos"][1], "operator": mutation["operator_name"],
                          "occurrence": mutation["occurrence"], "function": mutation.get("definition_name"),
                          "source": text, "diff": result["diff"]})
    survivors.sort(key=lambda s: (s["line"], s["column"], s["operator"]))
    extra = {}
    if earlier is not None:
        counts["mutants"] += earlier["mutants"] - len(retest)
        for key in ("killed", "timeouts", "incompetent"):
            counts[key] += earlier[key]
        first = earlier.get("earlier") or {key: earlier[key] for key in ("commit", "tests", "killed", "timeouts", "survived")}
        extra = {"survivors_retested_from": first["commit"], "earlier": first,  # the first full run, and all runs' time
                 "earlier_seconds": round(earlier.get("earlier_seconds", 0) + earlier["seconds"], 1)}
    return classify({**extra, "path": module.path, "tests": list(tests), "pytest_args": list(module.pytest_args),
            "missing_tests": missing, "baseline": baseline.stdout.strip().splitlines()[-1].strip("= "),
            "baseline_s": round(baseline_s, 1), "timeout_s": timeout,
            "seconds": round(seconds, 1), **counts, "functions": list(module.functions),
            "skipped_in_annotations": sum(reason == "in an annotation" for reason in skip.values()), "survivors": survivors})


def classify(row: dict) -> dict:
    """`row` with each survivor's `EQUIVALENT` reason (None: not explained) and the scores (re-applied when only
    the report is written, so that an explanation added later counts without a new run)."""
    for s in row["survivors"]:
        s["mutated"] = next((d[1:].strip() for d in s["diff"].splitlines() if d.startswith("+") and not d.startswith("+++")), "")
        s["equivalent"] = EQUIVALENT.get((row["path"], s["mutated"]))
    row["equivalent"] = sum(s["equivalent"] is not None for s in row["survivors"])
    caught = row["killed"] + row["timeouts"]
    row["score"] = round(caught / max(row["mutants"] - row["incompetent"], 1), 4)
    row["score_non_equivalent"] = round(caught / max(row["mutants"] - row["incompetent"] - row["equivalent"], 1), 4)
    return row


def dump(cr: Path, session: Path, clone: Path) -> list[tuple[dict, dict | None]]:
    out = subprocess.run([str(cr / "cosmic-ray"), "dump", str(session)], cwd=clone, check=True, capture_output=True,
                         text=True).stdout
    return [tuple(json.loads(line)) for line in out.splitlines() if line.strip()]


def minutes(row: dict) -> str:
    if "survivors_retested_from" not in row:
        return f"{row['seconds'] / 60:.1f} min"
    return (f"{row['earlier_seconds'] / 60:.1f} min (from {row['survivors_retested_from']}), then the survivors again: "
            f"{row['seconds'] / 60:.1f} min")


def report(results: dict, before: dict | None = None) -> str:
    """The markdown summary; `before`: an earlier run's results (an earlier commit's tests) to show beside."""
    before = (before or {}).get("modules", {})
    title = "# Mutation testing of the core modules" + (" — before" if results.get("before_run") else "")
    lines = [title, "",
             f"`nice -n 10 python benchmarks/mutation.py` ({results['tool']}, local distributor, one mutant at a "
             f"time; docs/testing.md), last run on {results['machine']}, {results['date']}: each module's mutants "
             "run against the narrow tests named below, on a clone of the commit in the table (never the working "
             "tree). Operators: one natural replacement per binary operator, the off-by-one and the negated "
             "boundary per ordering comparison, the negation of ==, is, in, and every other core operator "
             "(`OPERATORS`); mutants inside annotations are skipped (not evaluated).", "",
             "A timeout counts as killed; \"not made\": cosmic-ray failed to build the mutant (its ExceptionReplacer cannot "
             "rewrite a dotted name such as `json.JSONDecodeError`), left out of the scores. Score = killed / mutants; "
             "the target is ≥ 90 % of the non-equivalent "
             "mutants killed in each module, each survivor either killed by a test or explained as equivalent. "
             "\"Before\": the same mutants against the same narrow selection as it was before the mutation run "
             "(tests elsewhere in the suite may kill more: the commands run end to end, for the output rule) "
             f"({', '.join(sorted({row.get('commit', '?') for row in before.values()})) or 'not run'}; "
             "`--rev`, `mutation_before.json`).", "",
             "| module | commit | tests | mutants | killed | timeouts | survived | equivalent | not made | score | "
             "score (non-equivalent) | before | baseline run | time |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, row in results["modules"].items():
        only = f": only {', '.join(f'`{f}`' for f in row['functions'])}" if row.get("functions") else ""
        where = f"| {name} (`{row['path']}`{only}) | {row.get('commit', '')} "
        if "error" in row:
            lines.append(f"{where}| {', '.join(row['tests'])} | {row['error']} | | | | | | | | | | |")
            continue
        tests = ", ".join(f"`{t}`" for t in row["tests"]) + (f" `{' '.join(row['pytest_args'])}`" if row["pytest_args"] else "")
        old = before.get(name)
        earlier = (f"{100 * old['score_non_equivalent']:.1f} % ({old['survived'] - old['equivalent']} not equivalent)"
                   if old and "score" in old else "—")
        lines.append(f"{where}| {tests} | {row['mutants']} | {row['killed']} | {row['timeouts']} | {row['survived']} | "
                     f"{row['equivalent']} | {row['incompetent']} | {100 * row['score']:.1f} % | "
                     f"{100 * row['score_non_equivalent']:.1f} % | "
                     f"{earlier} | {row['baseline_s']} s ({row.get('baseline', '')}) | {minutes(row)} |")
    for name, row in results["modules"].items():
        if "error" in row:
            continue
        lines += ["", f"## {name}: {row['survived']} survivor{'s' if row['survived'] != 1 else ''}", ""]
        old = before.get(name, {})
        added = [t for t in row["tests"] if t in old.get("missing_tests", []) or t in old.get("tests", []) and "error" in old]
        if old:
            state = (f"no narrow test existed ({old['error']})" if "error" in old else
                     f"{old['killed'] + old['timeouts']} of {old['mutants']} killed, "
                     f"{old['survived'] - old['equivalent']} survivors not equivalent")
            lines += [f"Before ({old.get('commit', '?')}): {state}. Tests added: "
                      f"{', '.join(f'`{t}`' for t in added) or 'none'}.", ""]
        if "earlier" in row:
            first = row["earlier"]
            lines += [f"First run ({first['commit']}, tests {', '.join(f'`{t}`' for t in first['tests'])} as they were then): "
                      f"{first['killed'] + first['timeouts']} of {row['mutants']} killed, {first['survived']} survived; "
                      "its survivors ran again against the tests added since.", ""]
        if row.get("history"):
            lines += [row["history"], ""]
        if not row["survivors"]:
            lines.append("None: every mutant was killed.")
        for s in row["survivors"]:
            verdict = f"equivalent: {s['equivalent']}" if s["equivalent"] else "**not killed, not explained**"
            diff = [d for d in s["diff"].splitlines() if d.startswith(("+", "-")) and not d.startswith(("+++", "---"))]
            lines += [f"- `{row['path']}:{s['line']}` ({s['function']}) `{s['operator'].removeprefix('core/')}`: {verdict}",
                      "  ```diff", *(f"  {d}" for d in diff), "  ```"]
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--venv", type=Path, default=ROOT / ".mutation-venv", help="the side venv holding cosmic-ray")
    parser.add_argument("--build", action="store_true", help=f"make the side venv first ({COSMIC_RAY})")
    parser.add_argument("--modules", nargs="+", choices=list(MODULES), default=list(MODULES), help="a subset (default: all)")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "bench" / "mutation", help="OUT.json and OUT.md")
    parser.add_argument("--rev", default="HEAD", help="the commit to mutate and test (default HEAD; an earlier one "
                        "gives the score before tests were added: its missing test files are left out)")
    parser.add_argument("--survivors-only", action="store_true", help="run only the survivors of OUT.json's earlier run "
                        "of each module (its killed mutants stay killed: added tests only kill more); a module whose "
                        "source changed since runs in full")
    parser.add_argument("--report-only", action="store_true", help="run nothing: apply `EQUIVALENT` to OUT.json "
                        "(and OUT_before.json) and write OUT.md again")
    parser.add_argument("--keep", action="store_true", help="keep the scratch folder (the clone and the sessions)")
    args = parser.parse_args()
    before_file = args.out.with_name(args.out.name + "_before.json")
    before = json.loads(before_file.read_text()) if before_file.exists() and not args.out.name.endswith("_before") else None
    if args.report_only:
        results = json.loads(args.out.with_suffix(".json").read_text())
        results["before_run"] = args.out.name.endswith("_before")
        for data, path in ((results, args.out.with_suffix(".json")), (before, before_file)):
            if data is not None:
                data["modules"] = {name: row if "error" in row else classify(row) for name, row in data["modules"].items()}
                path.write_text(json.dumps(data, indent=1, ensure_ascii=False) + "\n")
        args.out.with_suffix(".md").write_text(report(results, before))
        return 0
    if args.build:
        build_venv(args.venv)
    if not (args.venv / "bin" / "cosmic-ray").exists():
        sys.exit(f"mutation: {args.venv}: no cosmic-ray there; make the venv with --build")
    previous = json.loads(args.out.with_suffix(".json").read_text()) if args.out.with_suffix(".json").exists() else {}
    version = subprocess.run([str(args.venv / "bin" / "cosmic-ray"), "--version"], capture_output=True, text=True)
    commit = subprocess.run(["git", "rev-parse", "--short", args.rev], cwd=ROOT, capture_output=True, text=True,
                            check=True).stdout.strip()
    results = {"before_run": args.out.name.endswith("_before"), "tool": version.stdout.strip(),
               "machine": f"{platform.machine()}, {os.cpu_count()} cores",
               "date": time.strftime("%Y-%m-%d"), "commit": commit,
               "modules": {name: row for name, row in previous.get("modules", {}).items() if name in MODULES}}
    scratch = Path(tempfile.mkdtemp(prefix="mutation-"))
    began = time.perf_counter()
    try:
        clone = make_clone(scratch, commit)
        for name in args.modules:
            print(f"mutation: {name} ({MODULES[name].path}) ...", flush=True)
            earlier = results["modules"].get(name) if args.survivors_only else None
            if earlier is not None and ("error" in earlier or subprocess.run(
                    ["git", "diff", "--quiet", earlier["commit"], commit, "--", MODULES[name].path], cwd=ROOT).returncode != 0):
                print(f"mutation: {name}: the source changed since {earlier.get('commit')} (or that run failed): every mutant runs")
                earlier = None
            row = run_module(name, MODULES[name], clone, args.venv, scratch, earlier)
            row["commit"] = commit
            if "history" in results["modules"].get(name, {}):
                row["history"] = results["modules"][name]["history"]
            results["modules"][name] = row
            results["modules"] = {key: results["modules"][key] for key in MODULES if key in results["modules"]}
            args.out.parent.mkdir(parents=True, exist_ok=True)
            args.out.with_suffix(".json").write_text(json.dumps(results, indent=1, ensure_ascii=False) + "\n")
            args.out.with_suffix(".md").write_text(report(results, before))
            print(f"mutation: {name}: {row.get('score_non_equivalent', row.get('error'))}", flush=True)
    finally:
        if args.keep:
            print(f"mutation: scratch kept at {scratch}")
        else:
            shutil.rmtree(scratch, ignore_errors=True)
    results["seconds"] = round(time.perf_counter() - began, 1)
    print(report(results, before))
    unexplained = [name for name, row in results["modules"].items() if name in args.modules
                   and ("error" in row or any(s["equivalent"] is None for s in row["survivors"]))]
    return 1 if unexplained else 0


if __name__ == "__main__":
    sys.exit(main())
