"""Remote agents against hostile peers: the reference server stays up, small and answering; the client keeps
its deadline and its memory, and its error lines stay one printable line."""

import json
import os
import socket
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from navbench.agents.plugins import resolve_agent
from navbench.agents.remote import AgentServer, RemoteAgent, RemoteAgentError, encode_arrays
from navbench.episodes.io import load_dataset
from navbench.eval.runner import read_records

OBS = {"depth": np.ones((8, 8, 1), np.float32), "pointgoal_with_gps_compass": np.array([3.0, 0.0], np.float32),
       "gps": np.zeros(2, np.float32), "compass": np.zeros(1, np.float32)}


def _serve(spec="walkmod:WalkAgent", **kwargs):
    agent = resolve_agent(spec, {})
    return AgentServer(agent.factory, spec, ("127.0.0.1", 0), options=agent.options, **kwargs).start()


def _exchange(url, raw: bytes, timeout=5.0, half_close=False) -> bytes:
    """Send ``raw`` on a fresh connection and read the answer (until the server closes or goes quiet)."""
    host, port = url.removeprefix("http://").split(":")
    with socket.create_connection((host, int(port)), timeout=timeout) as s:
        s.sendall(raw)
        if half_close:
            s.shutdown(socket.SHUT_WR)
        out, t0 = b"", time.monotonic()
        while time.monotonic() - t0 < timeout:
            try:
                chunk = s.recv(65536)
            except TimeoutError:
                break
            if not chunk:
                break
            out += chunk
            if b"\r\n\r\n" in out:
                head, _, body = out.partition(b"\r\n\r\n")
                n = [int(x.split(b":")[1]) for x in head.split(b"\r\n") if x.lower().startswith(b"content-length")]
                if n and len(body) >= n[0]:
                    break
        return out


def _status(answer: bytes) -> int:
    return int(answer.split(b" ", 2)[1]) if answer.startswith(b"HTTP/1.") else -1


def _still_serves(url, pointnav_file):
    agent = RemoteAgent(url, timeout=5)
    agent.reset(load_dataset(pointnav_file).episodes[0])
    assert agent.act(OBS) in (0, 1, 2, 3)
    agent.close()


@pytest.mark.parametrize("headers,status", [
    ("Content-Length: -1", 411), ("", 411), ("Transfer-Encoding: chunked", 411), ("Content-Length: 1e3", 411),
    ("Content-Length: 5\r\nContent-Length: 6", 411), ("Content-Length: 99999999999", 413)])
def test_bad_content_length_is_answered_at_once(headers, status, agent_dir, pointnav_file, capfd):
    server = _serve()
    try:
        t0 = time.monotonic()
        answer = _exchange(server.url, f"POST /act HTTP/1.1\r\nHost: x\r\n{headers}\r\n\r\n".replace(
            "\r\n\r\n\r\n", "\r\n\r\n").encode())
        assert _status(answer) == status, answer[:200]
        assert time.monotonic() - t0 < 4 and b'"error"' in answer  # no half-close needed for an answer
        _still_serves(server.url, pointnav_file)
    finally:
        server.stop()
    assert "Traceback" not in capfd.readouterr().err


@pytest.mark.parametrize("path,body", [
    ("/act", lambda: struct.pack("<I", 200_000) + b"[" * 100_000 + b"]" * 100_000),
    ("/act", lambda: struct.pack("<I", 2000) + b'{"arrays": ' + b"[" * 900 + b"]" * 900 + b"}"),
    ("/act", lambda: struct.pack("<I", 0xFFFFFFFF) + b"{}"),
    ("/act", lambda: encode_arrays({"x": np.zeros(2)})[:4] + b'{"arrays": [{"name": 1, "dtype": "<f8"}]}'),
    ("/reset", lambda: b'{"session": "s", "episode": ' + b"[" * 50_000 + b"]" * 50_000 + b"}"),
    ("/reset", lambda: b'{"session": "s", "episode": {"episode_id": 1}, "config": []}'),
    ("/reset", lambda: b"[1, 2]"),
])
def test_malformed_json_is_400_never_a_traceback(path, body, agent_dir, pointnav_file, capfd):
    server = _serve()
    try:
        data = body()
        answer = _exchange(server.url, f"POST {path} HTTP/1.1\r\nHost: x\r\nContent-Length: {len(data)}\r\n\r\n"
                           .encode() + data)
        assert _status(answer) == 400, answer[:300]
        _still_serves(server.url, pointnav_file)
    finally:
        server.stop()
    assert "Traceback" not in capfd.readouterr().err


def test_oversized_headers_are_431(agent_dir, pointnav_file):
    server = _serve()
    try:
        answer = _exchange(server.url, b"GET /info HTTP/1.1\r\n" + b"X-Pad: " + b"a" * 60_000 + b"\r\n" * 1
                           + b"X-Pad2: " + b"a" * 60_000 + b"\r\n\r\n")
        assert _status(answer) == 431
        _still_serves(server.url, pointnav_file)
    finally:
        server.stop()


def test_buffered_bodies_are_bounded_and_a_real_client_is_still_served(agent_dir, pointnav_file):
    server = _serve(max_body=8 << 20, max_buffered=16 << 20)
    socks = []
    try:
        host, port = server.url.removeprefix("http://").split(":")
        refused = 0
        for _ in range(4):  # four large bodies sent but never finished
            s = socket.create_connection((host, int(port)), timeout=5)
            socks.append(s)
            try:
                s.sendall(b"POST /act HTTP/1.1\r\nHost: x\r\nContent-Length: %d\r\n\r\n" % (8 << 20))
                s.sendall(b"\0" * (6 << 20))
                time.sleep(0.3)
                s.settimeout(0.3)
                refused += _status(s.recv(4096)) == 503
            except TimeoutError:
                pass  # still buffering this one
            except OSError:  # answered 503 and closed while the body was still coming
                refused += 1
            assert server.buffered[False] <= 16 << 20
        assert refused >= 2  # past the budget: refused, not buffered
        _still_serves(server.url, pointnav_file)
    finally:
        for s in socks:
            s.close()
        server.stop()


def test_a_dripping_request_is_cut_at_its_deadline(agent_dir, pointnav_file):
    server = _serve(request_timeout=1.0, idle_timeout=5.0)
    try:
        host, port = server.url.removeprefix("http://").split(":")
        with socket.create_connection((host, int(port)), timeout=5) as s:
            t0 = time.monotonic()
            closed = False
            for c in b"GET /info HTTP/1.1\r\nX: " + b"a" * 40:  # a byte every 0.1 s: 4 s for the whole request
                try:
                    s.sendall(bytes([c]))
                except OSError:
                    closed = True
                    break
                time.sleep(0.1)
                s.settimeout(0.01)
                try:
                    if s.recv(1) == b"":
                        closed = True
                        break
                except TimeoutError:
                    pass
            assert closed and time.monotonic() - t0 < 4.5  # 4 s to send it all; cut after 1
        _still_serves(server.url, pointnav_file)
    finally:
        server.stop()


def _rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise AssertionError("no VmRSS")


def test_serve_agent_stays_small_under_idle_connections_and_floods(agent_dir, pointnav_file):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(agent_dir), os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.Popen([sys.executable, "-m", "navbench.cli", "serve-agent", "walkmod:WalkAgent", "--port",
                             str(port)], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    url, idle = f"http://127.0.0.1:{port}", []
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                _still_serves(url, pointnav_file)
                break
            except RemoteAgentError:
                assert time.monotonic() < deadline and proc.poll() is None, "server did not start"
                time.sleep(0.3)
        before = _rss_mb(proc.pid)
        for _ in range(500):
            idle.append(socket.create_connection(("127.0.0.1", port), timeout=5))
        for k in range(200):  # malformed requests, one connection each
            raw = [b"POST /act HTTP/1.1\r\nContent-Length: -1\r\n\r\n", b"\x16\x03\x01garbage\r\n\r\n",
                   b"POST /reset HTTP/1.1\r\nContent-Length: 9\r\n\r\n[[[[[[[[[",
                   b"GET /" + b"a" * 70_000 + b" HTTP/1.1\r\n\r\n"][k % 4]
            with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
                s.sendall(raw)
                s.settimeout(5)
                try:
                    s.recv(4096)
                except OSError:
                    pass
            if k % 50 == 0:
                _still_serves(url, pointnav_file)
        _still_serves(url, pointnav_file)
        grown = _rss_mb(proc.pid) - before
        assert grown < 150, f"server grew by {grown:.0f} MB"
        assert proc.poll() is None
    finally:
        for s in idle:
            s.close()
        proc.terminate()
        _, err = proc.communicate(timeout=30)
    assert b"Traceback" not in err, err.decode()[-2000:]


# ------------------------------------------------------------------------------------- hostile servers
class _Hostile:
    """A loopback server answering every connection with ``behave(conn)``; ``stop()`` ends it."""

    def __init__(self, behave):
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.sock.settimeout(0.2)
        self.url = f"http://127.0.0.1:{self.sock.getsockname()[1]}"
        self.behave, self.done = behave, threading.Event()
        self.thread = threading.Thread(target=self._loop, daemon=True)
        self.thread.start()

    def _loop(self):
        while not self.done.is_set():
            try:
                conn, _ = self.sock.accept()
            except TimeoutError:
                continue
            threading.Thread(target=self._one, args=(conn,), daemon=True).start()

    def _one(self, conn):
        with conn:
            conn.settimeout(5)
            try:
                while not self.done.is_set():
                    req = b""
                    while b"\r\n\r\n" not in req:
                        chunk = conn.recv(65536)
                        if not chunk:
                            return
                        req += chunk
                    head, _, body = req.partition(b"\r\n\r\n")
                    n = [int(x.split(b":")[1]) for x in head.split(b"\r\n") if x.lower().startswith(b"content-length")]
                    while n and len(body) < n[0]:
                        body += conn.recv(65536)
                    path = head.split(b" ")[1].decode()
                    if not self.behave(conn, path, self.done):
                        return
            except OSError:
                return

    def stop(self):
        self.done.set()
        self.thread.join(timeout=5)
        self.sock.close()


def _ok(conn, payload):
    data = json.dumps(payload).encode()
    conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nContent-Length: %d\r\n\r\n" % len(data) + data)
    return True


INFO = {"protocol": "navbench-agent/1", "name": "x", "sensors": ["depth"], "episode_log": False}


def _act_behaviour(kind):
    def behave(conn, path, done):
        if path == "/info":
            return _ok(conn, INFO)
        if path == "/reset":
            return _ok(conn, {"ok": True})
        if kind == "endless":
            conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Type: application/json\r\n\r\n")
            chunk = b"[" * (1 << 20)
            t0 = time.monotonic()
            while not done.is_set() and time.monotonic() - t0 < 20:
                conn.sendall(chunk)  # until the client hangs up
            return False
        if kind == "drip":
            for c in b'HTTP/1.1 200 OK\r\nContent-Length: 12\r\n\r\n{"action": 1}':
                if done.is_set():
                    return False
                conn.sendall(bytes([c]))
                time.sleep(0.1)
            return False
        if kind == "garbage":
            conn.sendall(b"HTTP/1.1 500 \x1b[2J\r\nContent-Length: 24\r\n\r\n\x1b[31m\x07evil\r\x08\x08\x00 line\nnext")
            return False
        if kind == "badline":
            conn.sendall(b"\x1b]0;owned\x07 nonsense\r\n\r\n")
            return False
        raise AssertionError(kind)
    return behave


@pytest.mark.parametrize("kind", ["endless", "drip", "garbage", "badline"])
def test_a_hostile_server_fails_the_call_within_its_deadline(kind, pointnav_file):
    server = _Hostile(_act_behaviour(kind))
    try:
        agent = RemoteAgent(server.url, timeout=1.5)
        agent.reset(load_dataset(pointnav_file).episodes[0])
        t0 = time.monotonic()
        with pytest.raises(RemoteAgentError) as err:
            agent.act(OBS)
        assert time.monotonic() - t0 < 4  # the deadline is 1.5 s
        line = str(err.value)
        assert line.startswith(server.url + "/act: ") and line.isprintable(), repr(line)
        if kind == "drip":
            assert "timed out after 1.5 s" in line
        agent.close()
    finally:
        server.stop()


def test_a_run_against_a_misbehaving_server_fails_its_episodes_with_exit_3(pointnav_file, tmp_path, capsys):
    from navbench.cli import main
    server = _Hostile(_act_behaviour("drip"))
    try:
        t0 = time.monotonic()
        code = main(["run", "--episodes", str(pointnav_file), "--limit", "1", "--agent", server.url,
                     "--agent-opt", "timeout=1", "--out", str(tmp_path / "run"), "-q"])
        assert code == 3 and time.monotonic() - t0 < 60
    finally:
        server.stop()
    (rec,) = read_records(tmp_path / "run" / "episodes.jsonl")
    assert rec["failed"] and "timed out after 1 s" in rec["failure_reason"]
