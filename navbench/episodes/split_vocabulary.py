"""Which object categories the ObjectNav splits use, and the synonyms ``val_seen_synonyms`` asks for.

OVON's protocol: policies train on ``TRAIN_CATEGORIES``; ``val_seen`` asks for the same categories by
their names, ``val_seen_synonyms`` by a synonym ("couch" for sofa), ``val_unseen`` for categories that
never appear in training. ``navbench generate episodes`` writes this table to
``episodes/objectnav/categories.json`` next to the splits.
"""

from __future__ import annotations

TRAIN_CATEGORIES: tuple[str, ...] = (
    "chair", "table", "sofa", "bed", "toilet", "tv_monitor",
    "plant", "cabinet", "sink", "desk", "bookshelf", "refrigerator",
)

UNSEEN_CATEGORIES: tuple[str, ...] = (
    "bathtub", "lamp", "oven", "washer", "picture", "mirror",
    "towel", "stool", "nightstand", "microwave", "counter", "rug",
)

# Names a person would use for the same thing. None may be the name of a category the scenes contain
# ("armchair" for chair would be): an agent that found that object would be scored as finding the
# wrong instance.
SYNONYMS: dict[str, tuple[str, ...]] = {
    "chair": ("seat", "dining chair"),
    "table": ("dining table", "kitchen table"),
    "sofa": ("couch", "settee"),
    "bed": ("double bed", "bedstead"),
    "toilet": ("commode", "lavatory"),
    "tv_monitor": ("television", "tv screen"),
    "plant": ("houseplant", "potted plant"),
    "cabinet": ("cupboard", "storage cabinet"),
    "sink": ("washbasin", "basin"),
    "desk": ("writing desk", "work desk"),
    "bookshelf": ("bookcase", "book shelf"),
    "refrigerator": ("fridge", "icebox"),
}


def canonical_category(name: str) -> str | None:
    """The category a split's goal name refers to (itself, or the category a synonym names)."""
    if name in TRAIN_CATEGORIES or name in UNSEEN_CATEGORIES:
        return name
    for cat, syns in SYNONYMS.items():
        if name in syns:
            return cat
    return None


def categories_table() -> dict:
    return {"train": list(TRAIN_CATEGORIES), "unseen": list(UNSEEN_CATEGORIES),
            "synonyms": {k: list(v) for k, v in SYNONYMS.items()}}
