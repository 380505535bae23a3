"""Reading a JSON file whose failures name the file (`DataError`), for the data and layout files."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from touchanything.core.errors import DataError


def read_json_file(path: Path) -> Any:
    """The JSON value in `path`; DataError naming the file when it is missing or not readable JSON."""
    try:
        return json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise DataError(path, None, "file not found") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DataError(path, None, f"not a readable JSON file ({exc})") from None
    except RecursionError:
        raise DataError(path, None, "not a readable JSON file (nested too deeply)") from None
