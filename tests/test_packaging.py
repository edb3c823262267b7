"""What a wheel carries: every file the package reads from its own folder must match a
``package-data`` pattern in ``pyproject.toml``, or an installed (not editable) voxfield
loses it: the error tables, the report template, ``py.typed``."""

from __future__ import annotations

from pathlib import Path

import pytest

# the standard library reads TOML from Python 3.11 on
tomllib = pytest.importorskip("tomllib", reason="reading pyproject.toml needs Python 3.11+")

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "voxfield"


def _package_data_patterns() -> list[str]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    return config["tool"]["setuptools"]["package-data"]["voxfield"]


def _data_files() -> list[Path]:
    """The package's files that are not Python source or caches made by running it."""
    return sorted(p for p in PACKAGE.rglob("*") if p.is_file()
                  and p.suffix not in (".py", ".pyc", ".nbi", ".nbc")
                  and "__pycache__" not in p.parts)


def test_every_data_file_of_the_package_goes_into_the_wheel():
    patterns = _package_data_patterns()
    files = _data_files()
    assert files, "the package holds no data files: the error tables are missing"
    unlisted = [p.relative_to(PACKAGE).as_posix() for p in files
                if not any(p.relative_to(PACKAGE).match(pattern) for pattern in patterns)]
    assert unlisted == [], f"add these to [tool.setuptools.package-data]: {unlisted}"


def test_every_package_data_pattern_names_a_file():
    """A pattern that matches nothing is a renamed or removed file the wheel silently
    goes without."""
    for pattern in _package_data_patterns():
        assert list(PACKAGE.glob(pattern)), f"package-data pattern {pattern!r} matches no file"


def test_the_package_says_its_annotations_are_for_type_checkers():
    assert (PACKAGE / "py.typed").is_file()
