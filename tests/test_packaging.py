"""The wheel's package list is the package folders: a folder left out ships a fitode that cannot fit."""
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _pyproject() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())


def test_every_package_folder_is_in_the_wheel():
    tool = _pyproject()["tool"]["setuptools"]
    mapping = tool["package-dir"]
    found = set()
    for package, folder in mapping.items():
        base = ROOT / folder
        for init in base.rglob("__init__.py"):
            if "__pycache__" in init.parts:
                continue
            rel = init.parent.relative_to(base).parts
            found.add(".".join((package, *rel)))
    assert found == set(tool["packages"]), (
        f"missing from pyproject's packages: {sorted(found - set(tool['packages']))}; "
        f"listed but not a package folder: {sorted(set(tool['packages']) - found)}")


def test_runtime_imports_are_runtime_dependencies():
    deps = " ".join(_pyproject()["project"]["dependencies"])
    # the swing's circle fit imports scipy at run time (train/observe/circle.py)
    assert "scipy" in deps
