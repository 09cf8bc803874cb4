"""Object descriptions from scene annotations, and their "perfect grounding" back to instances.

A description names a category and optionally its colour, its room (by type) and a nearby object::

    the blue chair in the kitchen next to the table

:func:`parse` reads such text (or a bare category name or synonym, e.g. an ObjectNav goal "couch");
:func:`ground` matches the parsed words against the annotations - category, colour, room type and
the "next to" relation - and returns every instance that fits. That is the grounding an ideal
vision-language model would do; it never looks up which instance a query was generated from.
:func:`describe_unique` generates the shortest description (category and colour, then room, then a
nearby object) that grounds to exactly one instance; the GOAT split generator and the oracle
captioner both use it, so generation and grounding share one definition of every word.

"Next to": the two objects are in the same room and the gap between their AABBs in the xz plane is
at most ``NEAR_GAP`` metres (a sofa behind the laundry wall is not "next to" the washer).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from navbench.episodes.split_vocabulary import SYNONYMS
from navbench.scene.annotations import ObjectAnnotation
from navbench.scene.procedural.furniture import CATEGORIES, COLOURS, ROOM_TYPES

NEAR_GAP = 0.75  # metres between AABBs (xz) for "next to"
VOCABULARY: tuple[str, ...] = tuple(CATEGORIES)  # every object category of the procedural scenes


def phrase(name: str) -> str:
    """How a category or room type is written in text: underscores become spaces."""
    return name.replace("_", " ")


def _phrase_table() -> list[tuple[str, str]]:
    """(phrase, category), longest phrase first so "coffee table" wins over "table"."""
    table = {phrase(c): c for c in VOCABULARY}
    for cat, synonyms in SYNONYMS.items():
        for s in synonyms:
            table.setdefault(s, cat)  # a scene category of the same name keeps its own meaning
    return sorted(table.items(), key=lambda kv: (-len(kv[0]), kv[0]))


_PHRASES = _phrase_table()
_ROOM_PHRASES = sorted(((phrase(r), r) for r in ROOM_TYPES), key=lambda kv: -len(kv[0]))
_WORDS = re.compile(r"[^a-z0-9]+")


def _normalise(text: str) -> str:
    return " " + _WORDS.sub(" ", text.lower().replace("_", " ")).strip() + " "


def _find(text: str, table: list[tuple[str, str]]) -> str | None:
    """The value of the earliest phrase of ``table`` in ``text`` (longest phrase on ties)."""
    best: tuple[int, int, str] | None = None
    for p, value in table:
        i = text.find(f" {p} ")
        if i >= 0 and (best is None or (i, -len(p)) < best[:2]):
            best = (i, -len(p), value)
    return None if best is None else best[2]


def room_type(room_name: str) -> str:
    """Annotated room names are types with an optional ``_2``-style suffix."""
    return re.sub(r"_\d+$", "", room_name)


@dataclass(frozen=True)
class Description:
    category: str
    colour: str | None = None
    room: str | None = None  # room type
    near: str | None = None  # category of an object next to it

    def text(self) -> str:
        words = ["the"] + ([self.colour] if self.colour else []) + [phrase(self.category)]
        if self.room:
            words += ["in", "the", phrase(self.room)]
        if self.near:
            words += ["next", "to", "the", phrase(self.near)]
        return " ".join(words)


def parse(text: str) -> Description | None:
    """Read a description or a bare category/synonym; None if no category is named."""
    t = _normalise(text)
    head, _, near_part = t.partition(" next to ")
    obj_part, _, room_part = head.partition(" in ")
    obj_part, room_part, near_part = (f" {p.strip()} " for p in (obj_part, room_part, near_part))
    category = _find(obj_part, _PHRASES)
    if category is None:
        return None
    colour = _find(obj_part, [(c, c) for c in COLOURS])
    room = _find(room_part, _ROOM_PHRASES)
    near = _find(near_part, _PHRASES)
    return Description(category, colour, room, near)


def _gap_xz(a: ObjectAnnotation, b: ObjectAnnotation) -> float:
    lo_a, hi_a = np.asarray(a.aabb_min)[[0, 2]], np.asarray(a.aabb_max)[[0, 2]]
    lo_b, hi_b = np.asarray(b.aabb_min)[[0, 2]], np.asarray(b.aabb_max)[[0, 2]]
    gap = np.maximum(0.0, np.maximum(lo_a - hi_b, lo_b - hi_a))
    return float(np.hypot(*gap))


def neighbours(obj: ObjectAnnotation, objects: Mapping[int, ObjectAnnotation]) -> list[ObjectAnnotation]:
    """Other objects "next to" ``obj``, nearest first."""
    near = [(g, o.id, o) for o in objects.values()
            if o.id != obj.id and o.room == obj.room and (g := _gap_xz(obj, o)) <= NEAR_GAP]
    return [o for _, _, o in sorted(near, key=lambda t: t[:2])]


def matches(obj: ObjectAnnotation, desc: Description, objects: Mapping[int, ObjectAnnotation]) -> bool:
    if obj.category != desc.category:
        return False
    if desc.colour is not None and obj.colour != desc.colour:
        return False
    if desc.room is not None and room_type(obj.room) != desc.room:
        return False
    if desc.near is not None and not any(o.category == desc.near for o in neighbours(obj, objects)):
        return False
    return True


def ground(query: str | Description, objects: Mapping[int, ObjectAnnotation]) -> list[int]:
    """Ids of every annotated instance the description fits (empty if it names no category)."""
    desc = parse(query) if isinstance(query, str) else query
    if desc is None:
        return []
    return sorted(o.id for o in objects.values() if matches(o, desc, objects))


def describe_unique(obj: ObjectAnnotation, objects: Mapping[int, ObjectAnnotation]) -> Description | None:
    """The shortest description that grounds to exactly ``obj`` (None if none does).

    Tried in order: colour + category; + room; + room and each neighbouring object's category
    (nearest first, other categories than its own).
    """
    base = Description(obj.category, obj.colour or None)
    room = room_type(obj.room) if obj.room else None
    options = [base]
    if room:
        options.append(Description(base.category, base.colour, room))
    for other in neighbours(obj, objects):
        if other.category != obj.category:
            options.append(Description(base.category, base.colour, room, other.category))
    for desc in options:
        if ground(desc.text(), objects) == [obj.id]:  # through the text, as a reader would parse it
            return desc
    return None


def describe_with_room(obj: ObjectAnnotation, objects: Mapping[int, ObjectAnnotation]) -> Description | None:
    """Like :func:`describe_unique` but always naming the room (and a neighbour when one exists and the
    description stays unique), the GOAT-style "the blue chair in the kitchen next to the table"."""
    room = room_type(obj.room) if obj.room else None
    options = []
    for other in neighbours(obj, objects):
        if other.category != obj.category:
            options.append(Description(obj.category, obj.colour or None, room, other.category))
    options.append(Description(obj.category, obj.colour or None, room))
    for desc in options:
        if ground(desc.text(), objects) == [obj.id]:  # through the text, as a reader would parse it
            return desc
    return None
