"""Config files as the official loader reads them: YAML, a `_base_` file merged underneath, `$VARS` and `~`.

`_base_: base.yaml` names a file relative to the config's folder; it is read first (recursively, so a base
may name its own base) and the config is deep-merged over it: nested mappings merge, every other value is
replaced (the official `load_config_with_base`). A named base that does not exist is not an error: the
official `train.py` saves the merged config beside its checkpoints with `_base_` still in it, and that file
is complete on its own. The `_base_` key itself is dropped from the result.
"""
from __future__ import annotations

import copy
import os
from pathlib import Path

import yaml

from touchanything.core.errors import UserError

BASE_KEY = "_base_"


def deep_merge(base: dict, override: dict) -> dict:
    """Nested dicts merge; every other value (lists included) is replaced by the override's."""
    out = copy.deepcopy(base)
    for key, value in override.items():
        merge = isinstance(value, dict) and isinstance(out.get(key), dict)
        out[key] = deep_merge(out[key], value) if merge else copy.deepcopy(value)
    return out


def _expand(value):
    if isinstance(value, dict):
        return {k: _expand(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_expand(v) for v in value]
    return os.path.expanduser(os.path.expandvars(value)) if isinstance(value, str) else value


def read_yaml_mapping(path: Path) -> dict:
    """A YAML file whose top level is a mapping; one-line errors for a missing or malformed file."""
    try:
        data = yaml.safe_load(Path(path).read_text())
    except FileNotFoundError:
        raise UserError(f"{path}: config file not found") from None
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise UserError(f"{path}: not a readable YAML file ({exc.__class__.__name__})") from None
    if not isinstance(data, dict):
        raise UserError(f"{path}: expected a mapping at the top level")
    return data


def _read_with_bases(path: Path, seen: tuple[Path, ...]) -> dict:
    data = read_yaml_mapping(path)
    base_name = data.pop(BASE_KEY, None)
    if base_name is None:
        return data
    if not isinstance(base_name, str):
        raise UserError(f"{path}: {BASE_KEY}: expected a file name, got {base_name!r}")
    base = (path.parent / os.path.expanduser(base_name)).resolve()
    if base in seen:
        raise UserError(f"{path}: {BASE_KEY}: {base_name} names a config that is already being read (a cycle)")
    if not base.is_file():
        return data
    return deep_merge(_read_with_bases(base, (*seen, base)), data)


def read_config_file(path: Path) -> dict:
    """The effective config of `path`: its `_base_` chain merged underneath, strings expanded."""
    path = Path(path)
    return _expand(_read_with_bases(path, (path.resolve(),)))
