"""What the fuzz tests share: the outcome a reader must have, the CLI in-process, JSON mutations."""

from __future__ import annotations

import contextlib
import copy
import io
from pathlib import Path
from typing import Any

from hypothesis import strategies as st

# What navbench.cli.main turns into one line and exit code 2.
USER_ERRORS = (ValueError, FileNotFoundError, ImportError)


def check_user_error(exc: BaseException, path: str | Path) -> None:
    """``exc`` is a user error whose first line (all the CLI prints) names ``path``."""
    assert isinstance(exc, USER_ERRORS), f"{type(exc).__name__} escapes the CLI: {exc!r}"
    first = str(exc).splitlines()[0] if str(exc) else ""
    assert str(path) in first, f"error does not name {path}: {first!r}"


def read_or_error(reader, path: str | Path, *args, **kwargs):
    """``reader(path)``'s result, or None after checking it failed as a user error naming the file."""
    try:
        return reader(path, *args, **kwargs)
    except USER_ERRORS as exc:
        check_user_error(exc, path)
        return None


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    """``navbench.cli.main(argv)`` in-process: (exit code, stdout, stderr); argparse exits count too."""
    from navbench.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as e:
            code = e.code if isinstance(e.code, int) else 2
    return code, out.getvalue(), err.getvalue()


def assert_cli_error(argv: list[str], names: str | Path | None = None) -> str:
    """The CLI answers ``argv`` with exit 2 and exactly one stderr line (naming ``names`` if given)."""
    code, _, err = run_cli(argv)
    lines = err.strip("\n").splitlines()
    assert code == 2, f"{argv}: exit {code}, stderr {err!r}"
    assert len(lines) == 1, f"{argv}: {len(lines)} stderr lines: {err!r}"
    assert lines[0].startswith("navbench"), lines[0]
    if names is not None:
        assert str(names) in lines[0], f"{argv}: {lines[0]!r} does not name {names}"
    return lines[0]

# Any JSON value, kept small; includes the non-finite floats Python's json reads and writes.
json_scalars = st.one_of(st.none(), st.booleans(), st.integers(-2**70, 2**70),
                         st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=8))
json_values = st.recursive(json_scalars, lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=6), c,
                                                                                          max_size=3),
                           max_leaves=6)


def paths(doc: Any, prefix: tuple = (), limit: int = 400) -> list[tuple]:
    """Every path (tuple of keys/indices) into ``doc``, breadth-first, at most ``limit``."""
    out, queue = [], [(prefix, doc)]
    while queue and len(out) < limit:
        p, node = queue.pop(0)
        out.append(p)
        if isinstance(node, dict):
            queue.extend((p + (k,), v) for k, v in node.items())
        elif isinstance(node, list):
            queue.extend((p + (i,), v) for i, v in enumerate(node[:3]))
    return out


def _get(doc: Any, path: tuple) -> Any:
    for k in path:
        doc = doc[k]
    return doc


def apply(doc: Any, path: tuple, op: str, value: Any) -> Any:
    """A copy of ``doc`` with ``op`` applied at ``path``: "swap" (replace), "drop" (delete),
    "extra" (add a key / element), "nest" (bury the value in 64 lists)."""
    doc = copy.deepcopy(doc)
    if not path:
        return value if op == "swap" else doc
    parent, key = _get(doc, path[:-1]), path[-1]
    if op == "swap":
        parent[key] = value
    elif op == "drop":
        del parent[key]
    elif op == "extra":
        node = parent[key]
        if isinstance(node, dict):
            node["__fuzz__"] = value
        elif isinstance(node, list):
            node.append(value)
        else:
            parent[key] = [node, value]
    elif op == "nest":
        v = parent[key]
        for _ in range(64):
            v = [v]
        parent[key] = v
    return doc


@st.composite
def mutations(draw, doc: Any) -> Any:
    """One to three mutations of ``doc`` at paths drawn from its structure."""
    for _ in range(draw(st.integers(1, 3))):
        ps = paths(doc)
        path = draw(st.sampled_from(ps))
        op = draw(st.sampled_from(("swap", "drop", "extra", "nest")))
        doc = apply(doc, path, op, draw(json_values))
    return doc
