"""The report's modules stay readable: short functions, modules of a few hundred lines."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2] / "experiments"
MODULES = (
    "comparisons",
    "curves",
    "evaluations",
    "figures",
    "plotting",
    "report",
    "report_runs",
    "report_tables",
    "stats",
    "study",
)
#: The longest function, in lines (its decorators and docstring included).
MAX_FUNCTION_LINES = 80
MAX_MODULE_LINES = 600


@pytest.mark.parametrize("module", MODULES)
def test_functions_are_at_most_80_lines_and_modules_600(module: str) -> None:
    path = ROOT / f"{module}.py"
    text = path.read_text()
    assert len(text.splitlines()) <= MAX_MODULE_LINES
    long = [
        f"{node.name} ({node.end_lineno - node.lineno + 1} lines)"
        for node in ast.walk(ast.parse(text))
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
        and node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES
    ]
    assert not long, f"{path.name}: {', '.join(long)}"
