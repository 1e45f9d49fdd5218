"""The package's docstring names every subpackage, so a reader finds them all from there."""

from __future__ import annotations

from paths import REPO

import wovenskin


def test_the_package_docstring_names_every_subpackage():
    root = REPO / "wovenskin"
    subpackages = sorted(p.name for p in root.iterdir() if (p / "__init__.py").exists())
    missing = [name for name in subpackages if f":mod:`wovenskin.{name}`" not in wovenskin.__doc__]
    assert not missing, f"wovenskin/__init__.py does not name {missing}"
    modules = sorted(p.stem for p in root.glob("*.py") if p.stem != "__init__")
    assert all(name in wovenskin.__doc__ for name in modules)
