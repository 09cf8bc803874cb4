import json
import shutil
from pathlib import Path

import pytest


@pytest.fixture
def copy_run(tmp_path):
    """``copy_run(src, name, **config)``: the run ``src`` copied to ``tmp_path/name`` with ``config`` set in its
    config.json and, where it records a protocol, there too (what a run under those settings would have written)."""
    def copy(src: Path, name: str, **config) -> Path:
        d = tmp_path / name
        shutil.copytree(src, d, ignore=shutil.ignore_patterns("videos"))
        cfg = json.loads((d / "config.json").read_text())
        (d / "config.json").write_text(json.dumps({**cfg, **config}))
        prov = d / "provenance.json"
        if prov.is_file():
            doc = json.loads(prov.read_text())
            doc["protocol"].update({k: v for k, v in config.items() if k in doc["protocol"]})
            prov.write_text(json.dumps(doc))
        return d
    return copy
