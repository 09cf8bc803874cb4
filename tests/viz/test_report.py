"""`navbench report`: one self-contained page with the tables and the gallery; a slow test renders it in Chromium."""

import re
import shutil
import subprocess

import pytest

from navbench.cli import main
from navbench.eval.runner import read_records
from navbench.eval.stats import intervals


def test_report_tables_gallery_and_no_external_resources(oracle_run, tmp_path):
    out = tmp_path / "report.html"
    assert main(["report", str(oracle_run), str(oracle_run), "-o", str(out)]) == 0
    page = out.read_text()
    recs = read_records(oracle_run / "episodes.jsonl")
    assert page.count('<div class="card"') == 2 * len(recs)
    assert page.count("data:image/png;base64,") == 2 * len(recs)
    for table in ("summary", "categories", "failures"):
        assert f'<div id="{table}"><table>' in page
    ci = intervals(recs)["spl"]
    spl = sum(r["spl"] for r in recs) / len(recs)
    assert f"<td>{100 * spl:.1f} [{100 * ci[0]:.1f}, {100 * ci[1]:.1f}]</td>" in page  # SPL with its interval
    cats = {r["object_category"] for r in recs}
    assert all(f'<option value="{c}">' in page for c in cats)
    # nothing the page would fetch: no http(s) URLs, no external scripts or stylesheets
    assert not re.search(r"(src|href)=\"(https?:)?//", page)
    assert "<script src" not in page and "<link" not in page


def test_report_links_videos_relative_to_the_page(run_copy, tmp_path):
    rec = read_records(run_copy / "episodes.jsonl")[0]
    (run_copy / "videos").mkdir()
    (run_copy / "videos" / f"{rec['episode_id']}.mp4").write_bytes(b"\0")
    out = tmp_path / "sub" / "report.html"
    assert main(["report", str(run_copy), "-o", str(out)]) == 0
    assert f'href="../run/videos/{rec["episode_id"]}.mp4"' in out.read_text()


def _chromium() -> str:
    """Debian's chromium, installed with apt when missing (skip when that is impossible)."""
    exe = shutil.which("chromium")
    if exe:
        return exe
    if not shutil.which("apt-get"):
        pytest.skip("chromium is not installed and apt-get is unavailable to install it")
    r = subprocess.run("apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium",
                       shell=True, capture_output=True, text=True)
    exe = shutil.which("chromium")
    if r.returncode or not exe:
        pytest.skip(f"could not install chromium with apt: {(r.stderr or r.stdout).strip()[-200:]}")
    return exe


@pytest.mark.slow
def test_report_renders_in_headless_chromium(oracle_run, tmp_path):
    exe = _chromium()
    out = tmp_path / "report.html"
    assert main(["report", str(oracle_run), "-o", str(out)]) == 0
    shot = tmp_path / "report.png"
    flags = [exe, "--headless=new", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--enable-logging=stderr",
             "--v=0", "--window-size=1280,1400"]
    r = subprocess.run(flags + [f"--screenshot={shot}", out.as_uri()], capture_output=True, text=True, timeout=120)
    assert shot.is_file() and shot.stat().st_size > 10_000, r.stderr[-500:]
    console = [line for line in r.stderr.splitlines() if "CONSOLE" in line or "Uncaught" in line]
    assert not console, console
    dom = subprocess.run(flags + ["--dump-dom", out.as_uri()], capture_output=True, text=True, timeout=120).stdout
    assert 'data-ready="1"' in dom  # the filter script ran to its end
    assert dom.count('class="card"') == len(read_records(oracle_run / "episodes.jsonl"))  # all shown, none hidden
    assert "<table>" in dom and 'id="gallery"' in dom
    import cv2
    img = cv2.imread(str(shot))
    assert img.shape[:2] == (1400, 1280)
    assert (img < 250).any(axis=2).mean() > 0.05  # not a blank page
