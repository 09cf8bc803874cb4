"""Names habitat-lab's out-of-scope modules (rearrangement, physics, batch rendering) annotate with: importable,
and constructing one raises in one line."""

from __future__ import annotations

COVERAGE = "navbench's habitat_sim covers navigation"


def placeholder(qualname: str, what: str) -> type:
    """A class named ``qualname`` whose construction raises NotImplementedError naming ``what``."""

    def __init__(self, *args, **kwargs):
        raise NotImplementedError(f"{qualname}: {COVERAGE} ({what})")

    return type(qualname.rpartition(".")[2], (), {"__init__": __init__,
                                                    "__doc__": f"Not supported: {COVERAGE} ({what})."})
