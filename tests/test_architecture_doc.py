"""``docs/architecture.md`` matches the code: every module has its row, every row its module.

Section 1.3 of the architecture notes has one table per package (``amaze``,
``evolution``, ``rl_baselines``, ``experiments``), a row per module named
relative to its package (``maze.spec``, ``jax.trainer``). A module added
without its row, or a row left behind by a module removed or renamed, fails
here.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("amaze", "evolution", "rl_baselines", "experiments")


def _documented() -> dict[str, set[str]]:
    """The module names of each package's table in section 1.3."""
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    section = text[text.index("### 1.3") : text.index("## 2.")]
    pieces = re.split(r"^`(\w+)`[ :(]", section, flags=re.M)
    tables: dict[str, set[str]] = {}
    for package, body in zip(pieces[1::2], pieces[2::2], strict=True):
        tables[package] = set(re.findall(r"^\| `([\w.]+)` \|", body, flags=re.M))
    return tables


def _modules(package: str) -> tuple[set[str], set[str]]:
    """``(modules, packages)`` under ``package``, named relative to it."""
    modules, packages = set(), set()
    for path in (ROOT / package).rglob("*.py"):
        parts = list(path.relative_to(ROOT / package).with_suffix("").parts)
        if parts[-1] == "__init__":
            if len(parts) > 1:
                packages.add(".".join(parts[:-1]))
        elif parts[-1] != "__main__":
            modules.add(".".join(parts))
    return modules, packages


@pytest.mark.parametrize("package", PACKAGES)
def test_every_module_has_its_row_and_every_row_its_module(package: str) -> None:
    tables = _documented()
    assert package in tables, f"section 1.3 has no table for {package}"
    modules, packages = _modules(package)
    rows = tables[package]
    assert not modules - rows, f"{package}: modules without a row: {sorted(modules - rows)}"
    extra = rows - modules - packages
    assert not extra, f"{package}: rows of no module: {sorted(extra)}"
