"""Retrieval over keyframe embeddings: FAISS inner product on L2-normalised vectors (= cosine).

Near-identical views (consecutive keyframes of a slow turn, the same wall seen twice) would otherwise
fill the top-K with copies of one view; while filling the top-K, a retrieved keyframe whose own
embedding has cosine >= ``dedup`` with an already kept (higher-ranked) keyframe is skipped.

Files written beside the keyframes: ``embeddings.faiss`` (``faiss.write_index``) and
``embeddings.json`` (the keyframe id of every row, and which encoder produced the vectors).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

import faiss
import numpy as np

INDEX_FILE = "embeddings.faiss"
IDS_FILE = "embeddings.json"


class EmbeddingIndexError(ValueError):
    """Embeddings or an index file are malformed or missing; the message names the value or path."""


def l2_normalize(x: np.ndarray, what: str = "embedding") -> np.ndarray:
    x = np.atleast_2d(np.asarray(x, dtype=np.float32))
    norms = np.linalg.norm(x, axis=1, keepdims=True)
    if x.ndim != 2 or not np.isfinite(x).all() or (norms <= 1e-12).any():
        raise EmbeddingIndexError(f"{what} vectors must be finite and non-zero, got shape {x.shape}")
    return np.ascontiguousarray(x / norms)


class EmbeddingIndex:
    """Exact cosine search over one embedding per keyframe."""

    def __init__(self, embeddings: np.ndarray, keyframe_ids: Sequence[int] | None = None, model: str = "") -> None:
        vectors = l2_normalize(embeddings)
        ids = list(range(len(vectors))) if keyframe_ids is None else [int(i) for i in keyframe_ids]
        if len(ids) != len(vectors):
            raise EmbeddingIndexError(f"{len(vectors)} embeddings but {len(ids)} keyframe ids")
        if len(set(ids)) != len(ids):
            raise EmbeddingIndexError("keyframe ids must be unique")
        self.keyframe_ids = ids
        self._row_of = {kf: row for row, kf in enumerate(ids)}
        self.model = model  # which encoder made the vectors, so a mismatched query encoder is detectable
        self._vectors = vectors
        self._index = faiss.IndexFlatIP(vectors.shape[1])
        self._index.add(vectors)

    def __len__(self) -> int:
        return len(self.keyframe_ids)

    @property
    def dim(self) -> int:
        return int(self._vectors.shape[1])

    def embedding(self, keyframe_id: int) -> np.ndarray:
        if int(keyframe_id) not in self._row_of:
            raise EmbeddingIndexError(f"keyframe {keyframe_id} is not in the index")
        return self._vectors[self._row_of[int(keyframe_id)]].copy()

    def search(self, query_vec: np.ndarray, k: int = 10, dedup: float | None = 0.9) -> list[tuple[int, float]]:
        """Top-``k`` (keyframe id, cosine) for one query, best first, near-duplicates removed.

        ``dedup=None`` disables de-duplication. Fewer than ``k`` results come back only when the index
        holds fewer than ``k`` mutually distinct views.
        """
        q = l2_normalize(query_vec, "query")
        if q.shape != (1, self.dim):
            raise EmbeddingIndexError(f"query must be one {self.dim}-d vector, got shape {np.shape(query_vec)}")
        if k <= 0 or len(self) == 0:
            return []
        n = len(self)
        fetch = n if dedup is None else min(n, max(4 * k, 64))
        while True:
            scores, rows = self._index.search(q, min(fetch, n))
            kept: list[int] = []
            for row in rows[0]:
                if row < 0:
                    break
                if dedup is not None and kept and float(np.max(self._vectors[kept] @ self._vectors[row])) >= dedup:
                    continue
                kept.append(int(row))
                if len(kept) == k:
                    break
            # Too many duplicates among the fetched rows: widen the search (at most to the whole index).
            if len(kept) == k or fetch >= n:
                break
            fetch *= 4
        row_score = dict(zip(rows[0].tolist(), scores[0].tolist()))
        return [(self.keyframe_ids[r], float(row_score[r])) for r in kept]

    def save(self, directory: str | Path) -> None:
        directory = Path(directory)
        directory.mkdir(parents=True, exist_ok=True)
        faiss.write_index(self._index, str(directory / INDEX_FILE))
        meta = {"keyframe_ids": self.keyframe_ids, "model": self.model, "dim": self.dim}
        (directory / IDS_FILE).write_text(json.dumps(meta))

    @classmethod
    def load(cls, directory: str | Path) -> EmbeddingIndex:
        directory = Path(directory)
        index_path, ids_path = directory / INDEX_FILE, directory / IDS_FILE
        if not index_path.is_file() or not ids_path.is_file():
            raise EmbeddingIndexError(f"no embedding index at {directory} ({INDEX_FILE} and {IDS_FILE} needed)")
        try:
            meta = json.loads(ids_path.read_text())
            index = faiss.read_index(str(index_path))
        except (OSError, RuntimeError, json.JSONDecodeError) as e:
            raise EmbeddingIndexError(f"unreadable embedding index at {directory}: {e}") from None
        if index.ntotal != len(meta["keyframe_ids"]):
            raise EmbeddingIndexError(
                f"{index_path} holds {index.ntotal} vectors but {ids_path} lists {len(meta['keyframe_ids'])} ids")
        return cls(index.reconstruct_n(0, index.ntotal), meta["keyframe_ids"], str(meta.get("model", "")))
