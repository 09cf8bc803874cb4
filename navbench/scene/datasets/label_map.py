"""Raw annotation names of HM3D and MP3D (including mpcat40 names) -> navbench's ObjectNav categories.

Lookup is on the lower-cased name with ``_``/``#`` read as spaces. Names in :data:`STRUCTURE` are
walls, floors and ceilings: their faces get instance id -1, as the procedural houses' structure does.
A name in neither table keeps its own (normalised, ``_`` for spaces) name as its category, so the
oracle still sees it as an object; MP3D ObjectNav's own mpcat40 categories that navbench does not
have (``chest_of_drawers``, ``seating``, ``cushion``, ``shower``, ...) keep their names this way.

=============  ===========================================================================
category       raw names
=============  ===========================================================================
chair          chair, armchair, office chair, dining chair, desk chair, recliner
sofa           sofa, couch, sofa chair, sectional sofa, loveseat
bed            bed, double bed, single bed, bunk bed
toilet         toilet
tv_monitor     tv, television, tv monitor, tv_monitor, monitor, computer monitor, tv screen
plant          plant, potted plant, flower pot, houseplant, flowers
table          table, dining table, coffee table, side table, end table, kitchen table
cabinet        cabinet, kitchen cabinet, cupboard, wardrobe
sink           sink, kitchen sink, bathroom sink, washbasin
desk           desk, computer desk, writing desk
bookshelf      bookshelf, bookcase, book shelf, shelving
refrigerator   refrigerator, fridge
bathtub        bathtub, bath tub, tub, bath
lamp           lamp, floor lamp, table lamp, desk lamp, lighting
oven           oven, stove, oven and stove, range
washer         washing machine, washer, washer dryer
picture        picture, painting, photo, poster, picture frame, art
mirror         mirror, bathroom mirror
towel          towel, bath towel, hand towel
stool          stool, bar stool, footstool
nightstand     nightstand, night stand, bedside table, bedside cabinet
microwave      microwave, microwave oven
counter        counter, kitchen counter, countertop, kitchen island
rug            rug, carpet, mat, floor mat
=============  ===========================================================================
"""

from __future__ import annotations

_TABLE: dict[str, tuple[str, ...]] = {
    "chair": ("chair", "armchair", "office chair", "dining chair", "desk chair", "recliner"),
    "sofa": ("sofa", "couch", "sofa chair", "sectional sofa", "loveseat"),
    "bed": ("bed", "double bed", "single bed", "bunk bed"),
    "toilet": ("toilet",),
    "tv_monitor": ("tv", "television", "tv monitor", "monitor", "computer monitor", "tv screen"),
    "plant": ("plant", "potted plant", "flower pot", "houseplant", "flowers"),
    "table": ("table", "dining table", "coffee table", "side table", "end table", "kitchen table"),
    "cabinet": ("cabinet", "kitchen cabinet", "cupboard", "wardrobe"),
    "sink": ("sink", "kitchen sink", "bathroom sink", "washbasin"),
    "desk": ("desk", "computer desk", "writing desk"),
    "bookshelf": ("bookshelf", "bookcase", "book shelf", "shelving"),
    "refrigerator": ("refrigerator", "fridge"),
    "bathtub": ("bathtub", "bath tub", "tub", "bath"),
    "lamp": ("lamp", "floor lamp", "table lamp", "desk lamp", "lighting"),
    "oven": ("oven", "stove", "oven and stove", "range"),
    "washer": ("washing machine", "washer", "washer dryer"),
    "picture": ("picture", "painting", "photo", "poster", "picture frame", "art"),
    "mirror": ("mirror", "bathroom mirror"),
    "towel": ("towel", "bath towel", "hand towel"),
    "stool": ("stool", "bar stool", "footstool"),
    "nightstand": ("nightstand", "night stand", "bedside table", "bedside cabinet"),
    "microwave": ("microwave", "microwave oven"),
    "counter": ("counter", "kitchen counter", "countertop", "kitchen island"),
    "rug": ("rug", "carpet", "mat", "floor mat"),
}
RAW_TO_CATEGORY: dict[str, str] = {raw: cat for cat, raws in _TABLE.items() for raw in raws}
STRUCTURE: frozenset[str] = frozenset({"wall", "floor", "ceiling", "void", "unlabeled", "unlabelled", "unknown",
                                       "remove", "misc", "objects", "beam", "column"})


def normalise(raw: str) -> str:
    return " ".join(raw.replace("_", " ").replace("#", " ").strip().lower().split())


def map_category(raw: str) -> str | None:
    """navbench category for a raw annotation name; None for structure (walls, floors, ceilings)."""
    name = normalise(raw)
    if name in STRUCTURE or not name:
        return None
    return RAW_TO_CATEGORY.get(name, name.replace(" ", "_"))
