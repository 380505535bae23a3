"""The installed layout: one `touchanything` namespace, every package listed, imports only downwards, no cycles."""
from __future__ import annotations

import ast
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
FOLDERS = ("app", "core", "devices", "inference", "viz")
DATA_PACKAGES = ("touchanything.models", "touchanything.sample")
"""Packages of bundled files, no code (docs/layout.md: found through importlib.resources)."""
LAYERS = (
    ("touchanything.core",),
    ("touchanything.devices",),
    ("touchanything.devices.camera_pose",),
    ("touchanything.devices.episodes", "touchanything.devices.hardware"),
    ("touchanything.devices.rig",),
    ("touchanything.devices.sim",),
    ("touchanything.inference", "touchanything.inference.model"),
    ("touchanything.inference.engine", "touchanything.inference.training"),
    ("touchanything.inference.evaluation",),
    ("touchanything.viz",),
    ("touchanything.viz.dashboard",),
    ("touchanything.app.sessions",),
    ("touchanything.app.commands",),
    ("touchanything.app",),
    ("touchanything",),
)
"""Packages from the bottom of the dataflow up: a module imports from its own package or a lower layer only."""
RANK = {package: rank for rank, packages in enumerate(LAYERS) for package in packages}


def module_files() -> dict[str, Path]:
    """Installed module name → source file, for every module of the project."""
    files = {"touchanything": ROOT / "touchanything" / "__init__.py"}
    for folder in FOLDERS:
        for path in (ROOT / folder).rglob("*.py"):
            parts = path.relative_to(ROOT).with_suffix("").parts
            name = ".".join(("touchanything",) + (parts[:-1] if parts[-1] == "__init__" else parts))
            files[name] = path
    return files


def package_of(module: str, files: dict[str, Path]) -> str:
    return module if files[module].name == "__init__.py" else module.rpartition(".")[0]


def project_imports(path: Path, files: dict[str, Path]) -> set[str]:
    """The project modules a file imports at module level or in functions (`from pkg import module` counts
    as the module)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        names = []
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            names = [f"{node.module}.{alias.name}" if f"{node.module}.{alias.name}" in files else node.module
                     for alias in node.names]
        found |= {name for name in names if name in files}
    return found


def test_every_package_folder_is_installed_and_nothing_else():
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    on_disk = {package_of(m, files) for files in [module_files()] for m in files}
    assert listed == on_disk | set(DATA_PACKAGES)
    assert set(RANK) == on_disk, "every package has a layer in this test"


def test_imports_go_down_the_dataflow_only():
    files = module_files()
    upward = []
    for module, path in files.items():
        here = package_of(module, files)
        for target in project_imports(path, files):
            there = package_of(target, files)
            if there != here and (RANK[there] > RANK[here] or RANK[there] == RANK[here]):
                upward.append(f"{module} imports {target}")
    assert not upward, "\n".join(upward)


def test_no_import_cycles():
    files = module_files()
    graph = {module: project_imports(path, files) - {module} for module, path in files.items()}
    state: dict[str, int] = {}

    def visit(module: str, stack: list[str]) -> list[str] | None:
        state[module] = 1
        for target in sorted(graph[module]):
            if state.get(target) == 1:
                path = stack + [module]
                return path[path.index(target):] + [target]
            if target not in state and (cycle := visit(target, stack + [module])):
                return cycle
        state[module] = 2
        return None

    for module in sorted(graph):
        cycle = visit(module, []) if module not in state else None
        assert cycle is None, " → ".join(cycle)
