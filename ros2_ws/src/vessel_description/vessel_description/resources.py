"""
Package files: where a package's data folder is, and reading a YAML file with one-line errors.

Every package of the project finds its ``config/`` with ``data_dir`` and reads YAML with
``read_yaml``, each raising its own error type.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import yaml


def data_dir(package: str, module_file: str, folder: str) -> Path:
    """
    ``folder`` of ``package``, found from one of its modules (``__file__``).

    In the source tree it sits beside the Python package; colcon installs it to the
    package's share directory.
    """
    source = Path(module_file).resolve().parent.parent / folder
    if source.is_dir():
        return source
    try:
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory(package)) / folder
    except (ImportError, LookupError):
        return source


def read_yaml(path: str | os.PathLike, error: type[Exception], what: str) -> Any:
    """
    Return a YAML file's document.

    Raise ``error`` with one line: ``PATH: cannot read WHAT (reason)`` or ``PATH: not
    valid YAML (first line of the parser's message)``.
    """
    path = Path(path)
    try:
        return yaml.safe_load(path.read_text())
    except OSError as exc:
        raise error(f'{path}: cannot read {what} ({exc.strerror})') from None
    except yaml.YAMLError as exc:
        raise error(f'{path}: not valid YAML ({" ".join(str(exc).split())})') from None
