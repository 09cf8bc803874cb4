import numpy as np
import pytest

from navbench.memory import EmbeddingIndex, EmbeddingIndexError


def unit(v):
    v = np.asarray(v, dtype=np.float32)
    return v / np.linalg.norm(v)


def make_bank(rng, dim=32):
    """Keyframes 10..15 (ids not rows) with 11 a near-copy of 10 and 13 a near-copy of 12."""
    base = rng.normal(size=(6, dim)).astype(np.float32)
    base[1] = base[0] + 0.05 * rng.normal(size=dim)
    base[3] = base[2] + 0.05 * rng.normal(size=dim)
    return base, [10, 11, 12, 13, 14, 15]


def test_search_normalises_ranks_by_cosine_and_deduplicates(tmp_path):
    rng = np.random.default_rng(0)
    emb, ids = make_bank(rng)
    index = EmbeddingIndex(emb * 7.0, ids, model="test-encoder")  # scale must not matter
    q = emb[0] + emb[2]  # close to 10, 11, 12 and 13
    raw = index.search(q, k=4, dedup=None)
    cosine = {kf: float(unit(e) @ unit(q)) for kf, e in zip(ids, emb)}
    assert [kf for kf, _ in raw] == sorted([10, 11, 12, 13], key=lambda kf: -cosine[kf])
    expected = [float(unit(emb[ids.index(kf)]) @ unit(q)) for kf, _ in raw]
    assert np.allclose([s for _, s in raw], expected, atol=1e-5)
    deduped = index.search(q, k=4, dedup=0.9)
    kept = [kf for kf, _ in deduped]
    assert len(kept) == 4
    # exactly one of each near-duplicate pair survives, and it is the higher-ranked one
    rank = [kf for kf, _ in index.search(q, k=6, dedup=None)]
    for a, b in ((10, 11), (12, 13)):
        assert (a in kept) != (b in kept)
        assert min(a, b, key=rank.index) in kept
    assert [s for _, s in deduped] == sorted([s for _, s in deduped], reverse=True)
    sims = np.array([[float(unit(emb[ids.index(a)]) @ unit(emb[ids.index(b)])) for b in kept] for a in kept])
    assert (sims[~np.eye(4, dtype=bool)] < 0.9).all()


def test_dedup_widens_the_search_when_duplicates_crowd_the_top(tmp_path):
    rng = np.random.default_rng(1)
    target = rng.normal(size=16).astype(np.float32)
    dupes = target + 0.01 * rng.normal(size=(100, 16)).astype(np.float32)  # 100 copies of one view
    others = rng.normal(size=(5, 16)).astype(np.float32)
    index = EmbeddingIndex(np.concatenate([dupes, others]))
    hits = index.search(target, k=3)
    assert len(hits) == 3 and hits[0][0] < 100 and all(kf >= 100 for kf, _ in hits[1:])


def test_save_load_round_trip_and_errors(tmp_path):
    rng = np.random.default_rng(2)
    emb, ids = make_bank(rng)
    index = EmbeddingIndex(emb, ids, model="siglip2")
    index.save(tmp_path)
    loaded = EmbeddingIndex.load(tmp_path)
    assert loaded.keyframe_ids == ids and loaded.model == "siglip2" and loaded.dim == 32
    q = rng.normal(size=32)
    assert loaded.search(q, k=3) == index.search(q, k=3)
    assert np.allclose(loaded.embedding(14), unit(emb[4]), atol=1e-6)
    with pytest.raises(EmbeddingIndexError, match="query must be one 32-d"):
        index.search(np.ones(8), k=2)
    with pytest.raises(EmbeddingIndexError, match="non-zero"):
        EmbeddingIndex(np.zeros((2, 4)))
    with pytest.raises(EmbeddingIndexError, match="no embedding index at"):
        EmbeddingIndex.load(tmp_path / "missing")
    with pytest.raises(EmbeddingIndexError, match="keyframe ids"):
        EmbeddingIndex(emb, ids[:3])
