"""Progress of long loops on stderr: a tqdm bar on a terminal, else a plain line every 10 % (or 30 s).

``NAVBENCH_PROGRESS=0`` turns it off. It only prints; the loop's items pass through unchanged.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterable, Iterator
from typing import TypeVar

T = TypeVar("T")


def progress(items: Iterable[T], total: int | None = None, desc: str = "") -> Iterator[T]:
    if os.environ.get("NAVBENCH_PROGRESS", "1") == "0":
        yield from items
        return
    if total is None and hasattr(items, "__len__"):
        total = len(items)  # type: ignore[arg-type]
    if sys.stderr.isatty():
        from tqdm import tqdm
        yield from tqdm(items, total=total, desc=desc, leave=False, file=sys.stderr)
        return
    last_t, last_pct = time.monotonic(), 0
    n = 0
    for n, item in enumerate(items, 1):
        yield item
        pct = 100 * n // total if total else 0
        now = time.monotonic()
        if (total and (pct >= last_pct + 10 or n == total)) or now - last_t >= 30:
            of = f"/{total} ({pct}%)" if total else ""
            print(f"{desc}: {n}{of}", file=sys.stderr, flush=True)
            last_t, last_pct = now, pct - pct % 10
