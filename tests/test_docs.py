"""The tree describes the product, not its making: no development history, documents within their sizes."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
HISTORY = re.compile(r"\bsessions?\s+\d+|\bissues?\s*#?\d+|(?<![\w&/])#\d+\b", re.IGNORECASE)
SIZES = {"README.md": 250, "policies/MODEL_CARD.md": 250, "results/README.md": 60, "Makefile": 100}


def product_files() -> list[Path]:
    files = [ROOT / "Makefile", *ROOT.glob("*.md"), *ROOT.glob("policies/*.md"), *ROOT.glob("results/*.md"),
             *ROOT.glob("configs/**/*.toml"), *ROOT.glob("examples/**/*.py")]
    for tree in ("navbench", "benchmarks", "tests"):
        files += [p for p in (ROOT / tree).rglob("*.py") if p != Path(__file__).resolve()]
    return sorted(p for p in files if p.is_file())


def history_lines(text: str) -> list[str]:
    return [f"{i}: {line.strip()}" for i, line in enumerate(text.splitlines(), 1) if HISTORY.search(line)]


@pytest.mark.parametrize("text,found", [("trained in session 40", True), ("Sessions 9 and 10 trained", True),
                                        ("under issue #6's 1.5x", True), ("see #12", True),
                                        ("colour #ff0000 and ## headings", False), ("issue a STOP", False),
                                        ("the PointNav session ends", False)])
def test_history_pattern(text, found):
    assert bool(history_lines(text)) is found


def test_no_development_history_in_documents_or_code():
    offenders = {str(p.relative_to(ROOT)): lines[:3] for p in product_files()
                 if (lines := history_lines(p.read_text(errors="replace")))}
    assert not offenders, offenders


@pytest.mark.parametrize("name,limit", sorted(SIZES.items()))
def test_documents_stay_short(name, limit):
    n = len((ROOT / name).read_text().splitlines())
    assert n <= limit, f"{name}: {n} lines (at most {limit})"
