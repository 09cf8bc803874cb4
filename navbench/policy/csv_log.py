"""Training progress: one CSV row per logging step (TensorBoard-free, pandas-readable) and its one-line echo."""

from __future__ import annotations

import csv
from pathlib import Path


def log_row(path: Path, row: dict, digits: int = 4) -> str:
    """Append ``row`` to the CSV at ``path`` (header on first write); return it as ``key=value`` text.

    A resumed run appends under the header already in the file, so its columns stay aligned even if this
    version logs other keys: a key the file has no column for goes to the echo only, a missing one is blank.
    """
    write_header = not path.exists() or path.stat().st_size == 0
    fields = list(row)
    if not write_header:
        with open(path, newline="") as f:
            fields = next(csv.reader(f), fields)
    with open(path, "a", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, restval="", extrasaction="ignore")
        if write_header:
            w.writeheader()
        w.writerow({k: (round(v, digits + 1) if isinstance(v, float) else v) for k, v in row.items()})
    return " ".join(f"{k}={v:.{digits}g}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items())


def keep_rows_through(path: Path, column: str, last: int) -> None:
    """Rewrite the CSV at ``path`` to the rows whose ``column`` is at most ``last``, one per value (the later
    wins), in order: a run resumed from step ``last`` logs the steps after it again, so the rows an interrupted
    run wrote past its saved state go."""
    if not path.is_file():
        return
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        fields, rows = reader.fieldnames, list(reader)
    if not fields:
        return
    kept: dict[int, dict] = {}
    for row in rows:
        try:
            step = int(float(row[column]))
        except (KeyError, TypeError, ValueError):
            continue
        if step <= last:
            kept[step] = row
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(kept[k] for k in sorted(kept))
