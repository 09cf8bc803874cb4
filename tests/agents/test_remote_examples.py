"""Servers written from docs/remote_agent.md alone (examples/: Python standard library, Node.js) pass
``navbench check-agent`` and run episodes; check-agent flags one that breaks the protocol; the client
ends its session with ``/close``."""

import contextlib
import importlib.util
import json
import shutil
import subprocess
import sys
import threading
import time
from http.server import ThreadingHTTPServer
from pathlib import Path

import pytest

import navbench
from navbench.agents.check_remote import check_server
from navbench.agents.plugins import resolve_agent
from navbench.agents.remote import AgentServer
from navbench.cli import main
from navbench.eval.runner import read_records

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def start_example(argv: list[str]) -> tuple[subprocess.Popen, str]:
    """Start an example server on a free loopback port; its process and URL (from its first line)."""
    proc = subprocess.Popen([*argv, "--port", "0"], stdout=subprocess.PIPE, text=True)
    timer = threading.Timer(30, proc.kill)  # a server that never prints fails the test, not hangs it
    timer.start()
    line = proc.stdout.readline()
    timer.cancel()
    assert line.startswith("listening on http://127.0.0.1:"), line
    return proc, line.split()[-1]


@pytest.fixture
def example_server(request):
    proc, url = start_example(request.param)
    yield url
    proc.terminate()
    proc.wait(timeout=10)


SERVERS = [pytest.param([sys.executable, str(EXAMPLES / "remote_agent_stdlib.py")], id="python-stdlib"),
           pytest.param(["node", str(EXAMPLES / "remote_agent_server.js")], id="node",
                        marks=pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed"))]


@pytest.fixture(scope="module")
def near_goals_file(tmp_path_factory, scene_path) -> Path:
    """Six PointNav episodes of 1-3 m, straight ones kept: the examples' agents head straight for the goal."""
    import numpy as np

    from navbench.episodes.generate import GeneratorConfig, pointnav_episodes
    from navbench.episodes.io import save_dataset
    from navbench.episodes.types import EpisodeDataset
    from navbench.paths import SCENES_DIR

    eps = pointnav_episodes(scene_path, SCENES_DIR, 6, np.random.default_rng(7),
                            GeneratorConfig(min_geodesic=1.0, max_geodesic=3.0, low_ratio_reject_prob=0.0))
    return save_dataset(EpisodeDataset(episodes=eps), tmp_path_factory.mktemp("near") / "near.json.gz")


@pytest.mark.parametrize("example_server", SERVERS, indirect=True)
def test_example_server_passes_check_agent_and_runs_episodes(example_server, near_goals_file, tmp_path):
    checks = check_server(example_server, steps=20, log=lambda line: None)
    assert [c.line() for c in checks if not c.ok and not c.warning] == []
    assert {"GET /info", "POST /close frees the session", "unknown session -> error"} <= {c.name for c in checks}
    summary = navbench.evaluate(example_server, episodes=near_goals_file, out=tmp_path / "run")
    records = read_records(tmp_path / "run" / "episodes.jsonl")
    assert summary["num_failed"] == 0 and summary["success"] > 0
    # /log's answer lands in each episode's record
    assert all(r["log"] == {"steps": r["num_steps"]} for r in records) and any(r["num_steps"] > 1 for r in records)


def _example_module():
    spec = importlib.util.spec_from_file_location("remote_agent_stdlib", EXAMPLES / "remote_agent_stdlib.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@contextlib.contextmanager
def serving(handler):
    """``http://127.0.0.1:PORT`` of a server running ``handler`` in a thread, stopped on exit."""
    server = ThreadingHTTPServer(("127.0.0.1", 0), handler)
    server.daemon_threads = True
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()


def test_check_agent_flags_a_server_that_breaks_the_protocol(capsys):
    ex = _example_module()

    class Broken(ex.Handler):
        """Answers actions by name, serves any session, forgets nothing on /close, errors in plain text."""
        sessions: dict = {}

        def do_POST(self):
            if self.path == "/act":
                self.rfile.read(int(self.headers.get("Content-Length", 0)))
                return self.answer(200, {"action": "move_forward"})
            if self.path == "/close":
                self.rfile.read(int(self.headers.get("Content-Length", 0)))
                return self.answer(200, {"ok": True})
            return super().do_POST()

        def do_GET(self):
            if self.path != "/info":
                body = b"not found"
                self.wfile.write(b"HTTP/1.1 404 Not Found\r\nContent-Length: 9\r\n\r\n" + body)
                return
            super().do_GET()

    with serving(Broken) as url:
        assert main(["check-agent", url, "--steps", "5"]) == 1
    out = capsys.readouterr().out
    assert "FAIL  POST /act (session A): action 'move_forward': expected an integer 0-3" in out, out
    assert "FAIL  unknown endpoint -> error: HTTP 404 without a JSON {\"error\": str} body" in out, out
    assert "FAIL  unknown session -> error: answered 200" in out, out
    assert "check(s) failed" in out.splitlines()[-1]


def test_check_agent_warns_of_the_nagle_stall_of_a_server_without_tcp_nodelay():
    ex = _example_module()

    class Naive(ex.Handler):
        """http.server's defaults: Nagle on, headers and body in two writes."""
        sessions: dict = {}

        def setup(self):
            super(ex.Handler, self).setup()

        def answer(self, status, payload):
            body = json.dumps(payload).encode()
            self.send_response(status)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

    with serving(Naive) as url:
        checks = check_server(url, steps=20, log=lambda line: None)
    latency = next(c for c in checks if c.name.startswith("latency"))
    assert not latency.ok and latency.warning and "TCP_NODELAY" in latency.detail, latency.line()
    assert all(c.ok for c in checks if c is not latency)  # slow, yet it follows the protocol


def test_check_agent_tells_a_slow_agent_from_a_stalled_connection():
    ex = _example_module()

    class Thinking(ex.Handler):
        """Fast connection (TCP_NODELAY), slow agent: 40 ms per /act."""
        sessions: dict = {}

        def do_POST(self):
            if self.path == "/act":
                time.sleep(0.04)
            super().do_POST()

    with serving(Thinking) as url:
        checks = check_server(url, steps=10, log=lambda line: None)
    latency = next(c for c in checks if c.name.startswith("latency"))
    assert latency.warning and "the time is the agent's own" in latency.detail, latency.line()


def test_check_agent_of_nothing_listening_is_one_line_and_exit_2(capsys):
    import socket
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    assert main(["check-agent", f"http://127.0.0.1:{port}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"127.0.0.1:{port}/info" in err, err


def test_the_client_ends_its_session_with_close(agent_dir, pointnav_file, tmp_path):
    agent = resolve_agent("walkmod:WalkAgent", {"stop_after": 5})
    server = AgentServer(agent.factory, "walkmod:WalkAgent", ("127.0.0.1", 0), options=agent.options).start()
    opened = []
    make = server.make_agent
    server.make_agent = lambda cfg: opened.append(1) or make(cfg)
    try:
        summary = navbench.evaluate(server.url, episodes=pointnav_file, out=tmp_path / "run")
    finally:
        server.stop()
    assert summary["num_failed"] == 0 and opened == [1]  # one session was held during the run ...
    assert len(server.sessions) == 0  # ... and freed at its end
