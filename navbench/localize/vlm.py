"""VLM re-ranking of retrieved views: the prompt, reply parsing, and the keep rule.

The VLM is asked ``PROMPT_TEMPLATE`` about each retrieved view. Replies are parsed leniently:

* the answer is the first word "yes" or "no" (any case, any punctuation or digits around it);
  a reply with neither is garbage and counts as "no";
* visibility is the first number in the reply that lies in [0, 10], divided by 10 (so "7", "7/10",
  "visibility: 7.5" all work; numbers above 10 are skipped, not clamped, since they are rarely a score);
* a missing visibility is 0.5 for "yes" (a bare yes sorts below a confident yes and above a doubtful
  one) and 0.0 for "no" or garbage.

:func:`rerank` keeps the "yes" views sorted by visibility (ties keep retrieval order); if there is no
"yes" at all it keeps the single best view, so a query always yields at least one view to segment.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

PROMPT_TEMPLATE = "Is a {query} visible in this image? Reply ONLY: yes/no <visibility 0-10>"
# What a captioner asks about an image query's picture (its answer prompts the re-ranker and the segmenter).
CAPTION_PROMPT = "Name the object in the centre of this image with its colour, in at most five words."
CAPTION_TOKENS = 12
MISSING_VISIBILITY_YES = 0.5
MISSING_VISIBILITY_NO = 0.0

# Letters may not touch the word ("nothing", "yesterday" are not answers); digits may ("yes8").
_ANSWER = re.compile(r"(?<![a-z])(yes|no)(?![a-z])", re.IGNORECASE)
_NUMBER = re.compile(r"(?<![\d.])\d+(?:\.\d+)?")


def format_prompt(query: str) -> str:
    return PROMPT_TEMPLATE.format(query=query.strip())


def parse_reply(text: str) -> tuple[bool, float]:
    """(yes, visibility in [0, 1]) from a VLM reply; see the module docstring for the rules."""
    text = text or ""
    answer = _ANSWER.search(text)
    yes = answer is not None and answer.group(1).lower() == "yes"
    for match in _NUMBER.finditer(text):
        value = float(match.group(0))
        if 0.0 <= value <= 10.0:
            return yes, value / 10.0
    return yes, MISSING_VISIBILITY_YES if yes else MISSING_VISIBILITY_NO


@dataclass(frozen=True)
class ScoredView:
    keyframe_id: int
    retrieval_score: float  # cosine from the embedding index
    yes: bool
    visibility: float  # in [0, 1]
    reply: str = ""  # the raw VLM text, kept for logs


def rerank(views: Sequence[ScoredView]) -> list[ScoredView]:
    """Views given in retrieval order -> the kept views, best first (see the module docstring)."""
    by_visibility = sorted(views, key=lambda v: -v.visibility)  # stable: ties keep retrieval order
    kept = [v for v in by_visibility if v.yes]
    return kept if kept else by_visibility[:1]
