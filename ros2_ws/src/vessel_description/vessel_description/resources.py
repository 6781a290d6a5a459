"""Where a package's data folder is: beside its sources, or in its colcon share directory."""

from __future__ import annotations

from pathlib import Path


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
