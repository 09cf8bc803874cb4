import pytest

from navbench.localize import PROMPT_TEMPLATE, ScoredView, format_prompt, parse_reply, rerank


def test_prompt_is_the_reference_text():
    assert format_prompt(" red chair ") == "Is a red chair visible in this image? Reply ONLY: yes/no <visibility 0-10>"
    assert PROMPT_TEMPLATE.count("{query}") == 1


@pytest.mark.parametrize("reply, expected", [
    ("yes 8", (True, 0.8)),
    ("Yes, 7", (True, 0.7)),
    ("YES <9>", (True, 0.9)),
    ("yes/10", (True, 1.0)),
    ("  yes   0 ", (True, 0.0)),
    ("Yes! Visibility: 6/10.", (True, 0.6)),
    ("yes 7.5", (True, 0.75)),
    ("yes8", (True, 0.8)),
    ("no 2", (False, 0.2)),
    ("No.", (False, 0.0)),
    ("no", (False, 0.0)),
    ("yes", (True, 0.5)),  # missing number: a bare yes ranks in the middle
    ("Yes.", (True, 0.5)),
    ("yes 85", (True, 0.5)),  # out-of-range numbers are skipped, not clamped
    ("yes 85 then 4", (True, 0.4)),
    ("Nothing like that here", (False, 0.0)),  # "nothing" is not "no" ... and not yes either
    ("yesterday I saw 3 chairs", (False, 0.3)),  # no answer word: garbage counts as no
    ("", (False, 0.0)),
    ("I cannot tell.", (False, 0.0)),
    ("no, but a sofa is visible: yes 9", (False, 0.9)),  # the first answer word decides
])
def test_parse_reply_table(reply, expected):
    yes, visibility = parse_reply(reply)
    assert yes is expected[0]
    assert visibility == pytest.approx(expected[1])


def test_rerank_keeps_yes_by_visibility_else_single_best():
    views = [
        ScoredView(1, 0.9, False, 0.9),
        ScoredView(2, 0.8, True, 0.5),
        ScoredView(3, 0.7, True, 0.8),
        ScoredView(4, 0.6, True, 0.5),
    ]
    assert [v.keyframe_id for v in rerank(views)] == [3, 2, 4]  # ties keep retrieval order
    none = [ScoredView(5, 0.9, False, 0.1), ScoredView(6, 0.8, False, 0.3), ScoredView(7, 0.7, False, 0.3)]
    assert [v.keyframe_id for v in rerank(none)] == [6]
    assert rerank([]) == []
