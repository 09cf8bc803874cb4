"""A remote agent server written from docs/remote_agent.md with Python's standard library only (no numpy,
no navbench): what a team with its own stack would write to be evaluated by ``navbench run --agent URL``.

    python examples/remote_agent_stdlib.py --port 8765            # prints "listening on http://127.0.0.1:8765"
    navbench check-agent http://127.0.0.1:8765
    navbench run --task pointnav --split val --agent http://127.0.0.1:8765

The agent is habitat-baselines' GoalFollower idea on PointNav (it reads no image, so ``sensors`` is
empty): STOP within 0.2 m of the goal, forward when the goal is within 15 degrees ahead, else turn
towards it. On ObjectNav, with no goal position, it walks forward and turns left every fifth step.
"""

from __future__ import annotations

import argparse
import json
import math
import socket
import struct
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

PROTOCOL = "navbench-agent/1"
STOP, FORWARD, LEFT, RIGHT = 0, 1, 2, 3
FORMATS = {"<f4": "f", "<f8": "d", "<i4": "i", "<i8": "q", "|u1": "B"}  # the dtypes this agent unpacks


def decode_arrays(body: bytes) -> tuple[dict, dict]:
    """``uint32 LE N | N bytes of JSON header | arrays``: the header (with ``session``) and, per array, its
    (dtype, shape, bytes). ValueError if the body does not add up."""
    if len(body) < 4:
        raise ValueError("body shorter than its 4-byte header length")
    (n,) = struct.unpack_from("<I", body)
    header = json.loads(body[4:4 + n])
    offset, arrays = 4 + n, {}
    for spec in header.get("arrays", []):
        size = math.prod(spec["shape"]) * int(spec["dtype"][2:])  # "<f4" -> 4 bytes an element
        if offset + size > len(body):
            raise ValueError(f"array {spec['name']!r}: body ends before its {size} bytes")
        arrays[spec["name"]] = (spec["dtype"], spec["shape"], body[offset:offset + size])
        offset += size
    if offset != len(body):
        raise ValueError(f"{len(body) - offset} bytes after the last array")
    return header, arrays


def values(array: tuple) -> tuple:
    """A small array's numbers (the goal, GPS, compass)."""
    dtype, shape, raw = array
    return struct.unpack(f"<{math.prod(shape)}{FORMATS[dtype]}", raw)


class GoalFollower:
    def __init__(self) -> None:
        self.steps = 0

    def reset(self, episode: dict) -> None:
        self.steps = 0

    def act(self, arrays: dict) -> int:
        self.steps += 1
        if "pointgoal_with_gps_compass" not in arrays:
            return LEFT if self.steps % 5 == 0 else FORWARD
        rho, theta = values(arrays["pointgoal_with_gps_compass"])
        if rho < 0.2:
            return STOP
        if abs(theta) < math.radians(15):
            return FORWARD
        return LEFT if theta > 0 else RIGHT  # theta is counter-clockwise positive

    def log(self) -> dict:
        return {"steps": self.steps}


class Handler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"  # keep-alive: one connection per client for the whole run
    sessions: dict = {}
    lock = threading.Lock()

    def setup(self) -> None:
        super().setup()
        self.connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)  # else ~40 ms a step

    def log_message(self, format, *args) -> None:  # a request per step: too many to print
        pass

    def answer(self, status: int, payload: dict) -> None:
        body = json.dumps(payload).encode()
        head = (f"HTTP/1.1 {status} {self.responses.get(status, ('',))[0]}\r\nContent-Type: application/json\r\n"
                f"Content-Length: {len(body)}\r\n\r\n").encode()
        self.wfile.write(head + body)  # headers and body in one send

    def do_GET(self) -> None:
        if self.path != "/info":
            return self.answer(404, {"error": f"no such endpoint: GET {self.path}"})
        self.answer(200, {"protocol": PROTOCOL, "name": "stdlib-goal-follower", "sensors": [], "episode_log": True})

    def do_POST(self) -> None:
        body = self.rfile.read(int(self.headers.get("Content-Length", 0)))
        try:
            if self.path == "/act":
                request, arrays = decode_arrays(body)
            else:
                request = json.loads(body or b"{}")
            session = str(request["session"])
        except (ValueError, KeyError, TypeError) as exc:
            return self.answer(400, {"error": f"bad request: {exc}".replace("\n", " ")})
        with self.lock:
            if self.path == "/reset":
                agent = self.sessions.setdefault(session, GoalFollower())
            elif self.path == "/close":
                self.sessions.pop(session, None)
                return self.answer(200, {"ok": True})
            elif self.path in ("/act", "/log"):
                agent = self.sessions.get(session)
                if agent is None:
                    return self.answer(400, {"error": f"unknown session {session!r}: POST /reset first"})
            else:
                return self.answer(404, {"error": f"no such endpoint: POST {self.path}"})
        if self.path == "/reset":
            agent.reset(request.get("episode", {}))
            return self.answer(200, {"ok": True})
        if self.path == "/act":
            return self.answer(200, {"action": agent.act(arrays)})
        return self.answer(200, {"log": agent.log()})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--port", type=int, default=8765, help="0 picks a free port")
    args = parser.parse_args()
    server = ThreadingHTTPServer((args.host, args.port), Handler)
    server.daemon_threads = True
    print(f"listening on http://{args.host}:{server.server_address[1]}", flush=True)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass


if __name__ == "__main__":
    main()
