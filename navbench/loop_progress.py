"""Progress of long loops on stderr: a tqdm bar on a terminal, else a plain line every 10 % (or 30 s).

``NAVBENCH_PROGRESS=0`` turns it off (``silenced()`` sets it for a block). It only prints; the loop's items
pass through unchanged.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from typing import TypeVar

T = TypeVar("T")
ENV = "NAVBENCH_PROGRESS"


@contextmanager
def silenced() -> Iterator[None]:
    """No loop progress inside the block, in this process and in the worker processes it starts."""
    before = os.environ.get(ENV)
    os.environ[ENV] = "0"
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(ENV, None)
        else:
            os.environ[ENV] = before


def progress(items: Iterable[T], total: int | None = None, desc: str = "") -> Iterator[T]:
    if os.environ.get(ENV, "1") == "0":
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
