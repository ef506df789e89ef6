"""The Python examples of the README and of the documentation pages run as written.

Each ```` ```python ```` block of ``README.md`` and of ``docs/**/*.md`` runs on its
own, in a scratch folder. A block that is not meant to run is written with
another language tag (```` ```py ````, ```` ```text ````).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = [README, *sorted((ROOT / "docs").rglob("*.md"))]
FENCE = re.compile(r"^```python\n(.*?)^```", re.DOTALL | re.MULTILINE)
BLOCKS = [
    (page.relative_to(ROOT).as_posix(), number, code)
    for page in PAGES
    for number, code in enumerate(FENCE.findall(page.read_text(encoding="utf-8")), start=1)
]


def test_the_documentation_has_python_examples() -> None:
    assert len(BLOCKS) >= 5
    pages = {page for page, _, _ in BLOCKS}
    assert {"docs/mazes.md", "docs/agents.md", "docs/evaluation.md"} <= pages


@pytest.mark.parametrize(
    ("page", "number", "code"), BLOCKS, ids=[f"{page}-{number}" for page, number, _ in BLOCKS]
)
def test_documentation_example_runs(
    page: str, number: int, code: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)  # the examples write files such as maze.png
    compiled = compile(code, f"{page} python block {number}", "exec")
    exec(compiled, {"__name__": f"doc_example_{number}"})
