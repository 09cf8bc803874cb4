"""The ObjectNav category table: synonyms name their category and nothing else in the scenes."""

from navbench.episodes.split_vocabulary import SYNONYMS, TRAIN_CATEGORIES, UNSEEN_CATEGORIES, canonical_category
from navbench.scene.procedural.furniture import CATEGORIES


def test_synonyms_resolve_to_their_category():
    for cat, names in SYNONYMS.items():
        assert cat in TRAIN_CATEGORIES
        for name in names:
            assert canonical_category(name) == cat


def test_no_synonym_is_the_name_of_a_scene_category():
    # An episode asking for "armchair" (meaning chair) in a house with an armchair is ill-posed: an agent
    # that finds the armchair would be scored as finding the wrong instance.
    scene_names = {c.name for c in CATEGORIES.values()}
    spelled = scene_names | {n.replace("_", " ") for n in scene_names}
    assert not [s for names in SYNONYMS.values() for s in names if s in spelled]
    assert set(TRAIN_CATEGORIES) | set(UNSEEN_CATEGORIES) <= scene_names
