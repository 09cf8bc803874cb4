"""Re-ranker and captioner over any OpenAI-compatible chat-completions server (vLLM, llama.cpp, LM Studio, ...).

One POST to ``{base_url}/chat/completions`` per view, with the image inlined as a base64 PNG data URL
and the reference prompt (or, captioning an image query, the caption prompt), temperature 0. Uses only the
standard library (urllib): no ``openai`` package, no network access beyond ``base_url``.

:meth:`OpenAIReranker.from_url` takes ``http://HOST:PORT/v1`` and asks the server's ``/models`` which model
it serves (one, or the one ``#NAME`` after the URL names): what ``--qwen-vl URL`` gives the real stack, so N
workers share one served VLM instead of loading a copy each.
"""

from __future__ import annotations

import base64
import json
import urllib.error
import urllib.request

import cv2
import numpy as np

from navbench.localize.backends.base import BackendError, check_image
from navbench.localize.vlm import CAPTION_PROMPT, CAPTION_TOKENS, format_prompt, parse_reply


def image_data_url(image: np.ndarray) -> str:
    ok, png = cv2.imencode(".png", cv2.cvtColor(check_image(image), cv2.COLOR_RGB2BGR))
    if not ok:
        raise BackendError(f"could not PNG-encode an image of shape {image.shape}")
    return "data:image/png;base64," + base64.b64encode(png.tobytes()).decode("ascii")


MAX_ANSWER = 1 << 20  # bytes of a server's answer read at most


class OpenAIReranker:
    """:class:`~navbench.localize.backends.base.Reranker` calling a remote or local VLM server."""

    def __init__(self, base_url: str, model: str, api_key: str | None = None, timeout: float = 60.0,
                 max_tokens: int = 8) -> None:
        if not base_url.startswith(("http://", "https://")):
            raise BackendError(f"base_url must start with http:// or https://, got {base_url!r}")
        self.url = base_url.rstrip("/") + "/chat/completions"
        self.model = model
        self.api_key = api_key
        self.timeout = timeout
        self.max_tokens = max_tokens

    @classmethod
    def from_url(cls, url: str, api_key: str | None = None, timeout: float = 60.0) -> OpenAIReranker:
        """The reranker of the model ``url`` (``http://HOST:PORT/v1``, optionally ``#MODEL``) serves: the
        one model the server's ``/models`` lists, else the one named; a BackendError otherwise."""
        base, _, model = url.partition("#")
        reranker = cls(base, model or "?", api_key=api_key, timeout=timeout)
        if model:
            return reranker
        doc = reranker._call(base.rstrip("/") + "/models", None)
        try:
            served = [str(m["id"]) for m in doc["data"]]
        except (KeyError, TypeError):
            raise BackendError(f"{base}/models returned no data[].id: {str(doc)[:200]}") from None
        if len(served) != 1:
            raise BackendError(f"{base} serves {len(served)} models ({', '.join(served)[:200]}): name one as "
                               f"{base}#MODEL")
        reranker.model = served[0]
        return reranker

    def request_body(self, image: np.ndarray, query: str, prompt: str | None = None,
                     max_tokens: int | None = None) -> dict:
        return {
            "model": self.model,
            "messages": [{
                "role": "user",
                "content": [
                    {"type": "image_url", "image_url": {"url": image_data_url(image)}},
                    {"type": "text", "text": prompt if prompt is not None else format_prompt(query)},
                ],
            }],
            "max_tokens": max_tokens or self.max_tokens,
            "temperature": 0.0,
        }

    def reply(self, image: np.ndarray, query: str) -> str:
        """The server's raw answer to the reference prompt about ``query`` in ``image``."""
        return self._content(self._call(self.url, self.request_body(image, query)))

    def describe(self, image: np.ndarray) -> str:
        """Captioner for image queries: a short name of the object in the centre of ``image``."""
        body = self.request_body(image, "", CAPTION_PROMPT, CAPTION_TOKENS)
        return self._content(self._call(self.url, body)).strip().rstrip(".")

    def _call(self, url: str, body: dict | None) -> dict:
        """The JSON answer to a POST of ``body`` (a GET without one) to ``url``."""
        headers = {"Content-Type": "application/json"}
        if self.api_key:
            headers["Authorization"] = f"Bearer {self.api_key}"
        request = urllib.request.Request(url, data=None if body is None else json.dumps(body).encode(),
                                         headers=headers, method="GET" if body is None else "POST")
        try:
            with urllib.request.urlopen(request, timeout=self.timeout) as response:
                return json.loads(response.read(MAX_ANSWER))
        except urllib.error.HTTPError as e:
            raise BackendError(f"{url} answered HTTP {e.code}: {e.read()[:200]!r}") from None
        except (urllib.error.URLError, TimeoutError, OSError) as e:
            raise BackendError(f"cannot reach {url}: {e}") from None
        except (json.JSONDecodeError, UnicodeDecodeError, RecursionError):
            raise BackendError(f"{url} did not return JSON") from None

    def _content(self, doc: dict) -> str:
        try:
            content = doc["choices"][0]["message"]["content"]
        except (KeyError, IndexError, TypeError):
            raise BackendError(f"{self.url} returned no choices[0].message.content: {str(doc)[:200]}") from None
        if isinstance(content, list):  # some servers return content parts
            content = "".join(part.get("text", "") for part in content if isinstance(part, dict))
        return str(content or "")

    def score(self, image: np.ndarray, query: str) -> tuple[bool, float]:
        return parse_reply(self.reply(image, query))
