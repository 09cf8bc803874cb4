"""Re-ranker over any OpenAI-compatible chat-completions server (vLLM, llama.cpp, LM Studio, ...).

One POST to ``{base_url}/chat/completions`` per view, with the image inlined as a base64 PNG data URL
and the reference prompt, temperature 0. Uses only the standard library (urllib): no ``openai``
package, no network access beyond ``base_url``.
"""

from __future__ import annotations

import base64
import json
import urllib.error
import urllib.request

import cv2
import numpy as np

from navbench.localize.backends.base import BackendError, check_image
from navbench.localize.vlm import format_prompt, parse_reply


def image_data_url(image: np.ndarray) -> str:
    ok, png = cv2.imencode(".png", cv2.cvtColor(check_image(image), cv2.COLOR_RGB2BGR))
    if not ok:
        raise BackendError(f"could not PNG-encode an image of shape {image.shape}")
    return "data:image/png;base64," + base64.b64encode(png.tobytes()).decode("ascii")


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

    def request_body(self, image: np.ndarray, query: str) -> dict:
        return {
            "model": self.model,
            "messages": [{
                "role": "user",
                "content": [
                    {"type": "image_url", "image_url": {"url": image_data_url(image)}},
                    {"type": "text", "text": format_prompt(query)},
                ],
            }],
            "max_tokens": self.max_tokens,
            "temperature": 0.0,
        }

    def reply(self, image: np.ndarray, query: str) -> str:
        """The server's raw answer to the reference prompt about ``query`` in ``image``."""
        headers = {"Content-Type": "application/json"}
        if self.api_key:
            headers["Authorization"] = f"Bearer {self.api_key}"
        request = urllib.request.Request(self.url, data=json.dumps(self.request_body(image, query)).encode(),
                                         headers=headers, method="POST")
        try:
            with urllib.request.urlopen(request, timeout=self.timeout) as response:
                doc = json.loads(response.read())
        except urllib.error.HTTPError as e:
            raise BackendError(f"{self.url} answered HTTP {e.code}: {e.read()[:200]!r}") from None
        except (urllib.error.URLError, TimeoutError, OSError) as e:
            raise BackendError(f"cannot reach {self.url}: {e}") from None
        except json.JSONDecodeError:
            raise BackendError(f"{self.url} did not return JSON") from None
        try:
            content = doc["choices"][0]["message"]["content"]
        except (KeyError, IndexError, TypeError):
            raise BackendError(f"{self.url} returned no choices[0].message.content: {str(doc)[:200]}") from None
        if isinstance(content, list):  # some servers return content parts
            content = "".join(part.get("text", "") for part in content if isinstance(part, dict))
        return str(content or "")

    def score(self, image: np.ndarray, query: str) -> tuple[bool, float]:
        return parse_reply(self.reply(image, query))
