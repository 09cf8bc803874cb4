"""Training progress: one CSV row per logging step (TensorBoard-free, pandas-readable) and its one-line echo."""

from __future__ import annotations

import csv
from pathlib import Path


def log_row(path: Path, row: dict, digits: int = 4) -> str:
    """Append ``row`` to the CSV at ``path`` (header on first write); return it as ``key=value`` text."""
    write_header = not path.exists()
    with open(path, "a", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(row))
        if write_header:
            w.writeheader()
        w.writerow({k: (round(v, digits + 1) if isinstance(v, float) else v) for k, v in row.items()})
    return " ".join(f"{k}={v:.{digits}g}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items())
