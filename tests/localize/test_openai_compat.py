"""OpenAIReranker against a tiny chat-completions server on 127.0.0.1, started and stopped by the test."""

import base64
import json
import socket
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import cv2
import numpy as np
import pytest

from navbench.localize.backends import BackendError, OpenAIReranker, Reranker


class FakeServer:
    """Answers POST /v1/chat/completions with queued replies and records every request."""

    def __init__(self):
        self.requests: list[dict] = []
        self.replies: list[tuple[int, object]] = []
        self.models = ["Qwen/Qwen2.5-VL-7B-Instruct"]
        server = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self):
                body = self.rfile.read(int(self.headers["Content-Length"]))
                server.requests.append({"path": self.path, "headers": dict(self.headers), "body": json.loads(body)})
                status, payload = server.replies.pop(0)
                data = payload.encode() if isinstance(payload, str) else json.dumps(payload).encode()
                self.send_response(status)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)

            def do_GET(self):  # /v1/models: the served models
                server.requests.append({"path": self.path, "headers": dict(self.headers), "body": None})
                data = json.dumps({"object": "list", "data": [{"id": m} for m in server.models]}).encode()
                self.send_response(200)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)

            def log_message(self, *args):  # keep test output clean
                pass

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/v1"
        self.thread = threading.Thread(target=self.httpd.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
        self.thread.start()

    def close(self):
        self.httpd.shutdown()
        self.httpd.server_close()
        self.thread.join(timeout=5)


@pytest.fixture
def server():
    s = FakeServer()
    yield s
    s.close()


def completion(content):
    return {"choices": [{"index": 0, "message": {"role": "assistant", "content": content}}]}


def test_request_format_and_reply_parsing(server):
    rng = np.random.default_rng(0)
    image = rng.integers(0, 256, size=(30, 40, 3), dtype=np.uint8)
    rr = OpenAIReranker(server.url + "/", "qwen2.5-vl-7b", api_key="secret-token", timeout=5.0)
    assert isinstance(rr, Reranker)
    server.replies += [(200, completion("Yes, 7")), (200, completion([{"type": "text", "text": "no 1"}]))]
    assert rr.score(image, "red chair") == (True, pytest.approx(0.7))
    assert rr.score(image, "bed") == (False, pytest.approx(0.1))

    req = server.requests[0]
    assert req["path"] == "/v1/chat/completions"
    assert req["headers"]["Authorization"] == "Bearer secret-token"
    body = req["body"]
    assert body["model"] == "qwen2.5-vl-7b" and body["temperature"] == 0.0
    (message,) = body["messages"]
    image_part, text_part = message["content"]
    prompt = "Is a red chair visible in this image? Reply ONLY: yes/no <visibility 0-10>"
    assert text_part == {"type": "text", "text": prompt}
    url = image_part["image_url"]["url"]
    assert url.startswith("data:image/png;base64,")
    decoded = cv2.imdecode(np.frombuffer(base64.b64decode(url.split(",", 1)[1]), np.uint8), cv2.IMREAD_COLOR)
    assert np.array_equal(cv2.cvtColor(decoded, cv2.COLOR_BGR2RGB), image)  # lossless, RGB order kept


def test_errors_are_one_line_backend_errors(server):
    rr = OpenAIReranker(server.url, "m", timeout=5.0)
    image = np.zeros((8, 8, 3), np.uint8)
    server.replies.append((500, {"error": "boom"}))
    with pytest.raises(BackendError, match="HTTP 500"):
        rr.score(image, "chair")
    server.replies.append((200, {"unexpected": True}))
    with pytest.raises(BackendError, match="no choices"):
        rr.score(image, "chair")
    server.replies.append((200, "not json"))
    with pytest.raises(BackendError, match="did not return JSON"):
        rr.score(image, "chair")
    assert len(server.requests) == 3 and "Authorization" not in server.requests[0]["headers"]
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(BackendError, match="cannot reach"):
        OpenAIReranker(f"http://127.0.0.1:{port}", "m", timeout=2.0).score(image, "chair")
    with pytest.raises(BackendError, match="base_url"):
        OpenAIReranker("127.0.0.1:8000", "m")


def test_a_served_vlm_is_found_by_its_url_and_captions_image_queries(server):
    from navbench.localize.benchmark import ModelDirs, model_dirs, served_vlm
    rr = OpenAIReranker.from_url(server.url)
    assert rr.model == "Qwen/Qwen2.5-VL-7B-Instruct" and server.requests[-1]["path"] == "/v1/models"
    server.replies.append((200, completion("Red armchair.")))
    assert rr.describe(np.zeros((8, 8, 3), np.uint8)) == "Red armchair"
    body = server.requests[-1]["body"]
    assert body["messages"][0]["content"][1]["text"].startswith("Name the object in the centre")
    server.models = ["a", "b"]
    with pytest.raises(BackendError, match="serves 2 models"):
        OpenAIReranker.from_url(server.url)
    assert OpenAIReranker.from_url(server.url + "#b").model == "b"
    dirs = model_dirs({"siglip2": "models/siglip2", "qwen_vl": server.url, "sam3": "models/sam3"})
    assert isinstance(dirs, ModelDirs) and dirs.qwen_vl == server.url and served_vlm(dirs.qwen_vl)
    assert str(dirs.siglip2) == "models/siglip2" and not served_vlm(dirs.siglip2)
