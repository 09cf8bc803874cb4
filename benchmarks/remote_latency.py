"""Time per step of a remote agent over HTTP: navbench's reference server (``navbench serve-agent``), the
standard-library example written from docs/remote_agent.md, the Node.js example (when ``node`` is
installed), and the same standard-library server without TCP_NODELAY and with headers and body in two
writes (what ``http.server`` does by default: the Nagle / delayed-ACK stall the document warns about).

    python benchmarks/remote_latency.py [--steps 500] [--no-naive]

Each server runs in its own process on loopback; navbench's client (``RemoteAgent``) sends a real PointNav
observation (GPS, compass, goal; and again with a 224x224 depth image added) ``--steps`` times in one
session. Printed per server and payload: median and p95 ms per ``/act`` round trip and the seconds a
500-step episode spends waiting for the agent.
"""

from __future__ import annotations

import argparse
import shutil
import socket
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"


def serve_naive(port: int) -> None:
    """The standard-library example's agent behind ``http.server``'s defaults (Nagle on, two writes)."""
    import importlib.util
    from http.server import ThreadingHTTPServer
    spec = importlib.util.spec_from_file_location("remote_agent_stdlib", EXAMPLES / "remote_agent_stdlib.py")
    ex = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ex)

    class Naive(ex.Handler):
        def setup(self):
            super(ex.Handler, self).setup()  # no TCP_NODELAY

        def answer(self, status, payload):
            import json
            body = json.dumps(payload).encode()
            self.send_response(status)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

    server = ThreadingHTTPServer(("127.0.0.1", port), Naive)
    server.daemon_threads = True
    print(f"listening on http://127.0.0.1:{server.server_address[1]}", flush=True)
    server.serve_forever()


def start(argv: list[str]) -> tuple[subprocess.Popen, str]:
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, text=True, cwd=ROOT)
    timer = threading.Timer(60, proc.kill)
    timer.start()
    line = proc.stdout.readline()
    timer.cancel()
    url = next((w for w in line.split() if w.startswith("http://")), None)
    if url is None:
        proc.kill()
        raise RuntimeError(f"{argv}: printed {line!r}, not its URL")
    return proc, url


def measure(url: str, observations: dict, episode, steps: int) -> list[float]:
    from navbench.agents.remote import RemoteAgent
    agent = RemoteAgent(url)
    try:
        agent.reset(episode)
        agent.act(observations)  # the connection is open before timing starts
        times = []
        for _ in range(steps):
            t0 = time.perf_counter()
            agent.act(observations)
            times.append((time.perf_counter() - t0) * 1000)
        return times
    finally:
        agent.close()


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=500)
    p.add_argument("--no-naive", action="store_true", help="skip the server without TCP_NODELAY (slow by design)")
    p.add_argument("--serve-naive", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.serve_naive:
        return serve_naive(0)

    from navbench.agents.check_remote import sample_observation
    plain, episode = sample_observation("pointnav", ())
    with_depth, _ = sample_observation("pointnav", ("depth",))
    servers = [("navbench serve-agent", [sys.executable, "-m", "navbench.cli", "serve-agent", "random", "--port", "0"]),
               ("stdlib example", [sys.executable, str(EXAMPLES / "remote_agent_stdlib.py"), "--port", "0"])]
    if shutil.which("node"):
        servers.append(("node example", ["node", str(EXAMPLES / "remote_agent_server.js"), "--port", "0"]))
    else:
        print("node is not installed: the Node.js example is skipped")
    if not args.no_naive:
        servers.append(("stdlib, no TCP_NODELAY", [sys.executable, __file__, "--serve-naive"]))

    print(f"{socket.gethostname()}: {args.steps} /act round trips per row, one session, loopback")
    print(f"{'server':<24} {'payload':<22} {'median ms':>9} {'p95 ms':>7} {'500 steps s':>11}")
    for name, argv in servers:
        proc, url = start(argv)
        try:
            for payload, obs in (("gps+compass+goal", plain), ("+ depth 224x224 f4", with_depth)):
                t = measure(url, obs, episode, args.steps)
                med, p95 = statistics.median(t), sorted(t)[int(0.95 * (len(t) - 1))]
                print(f"{name:<24} {payload:<22} {med:>9.2f} {p95:>7.2f} {statistics.fmean(t) * 500 / 1000:>11.2f}")
        finally:
            proc.terminate()
            proc.wait(timeout=10)


if __name__ == "__main__":
    main()
